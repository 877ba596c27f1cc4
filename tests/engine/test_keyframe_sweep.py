"""Recording keyframe sweeps for the Keyframes page (sec. 6.1)."""

from __future__ import annotations

import numpy as np
import pytest

from engine.errors import ParamsError
from engine.keyframes.sweep import SweepParams, record_sweep
from engine.sources import open_source


def test_record_append_delete() -> None:
    src = open_source("synthetic:frames=40,width=320,height=240,path=rail,cycle_s=3")
    seen = []
    rec = record_sweep(
        src,
        SweepParams(kf_add_dist_m=0.1, kf_add_angle_deg=5, keep_every=2),
        on_progress=seen.append,
    )
    assert rec.frames_processed == 40
    assert rec.lost_frames == 0
    assert not rec.stopped
    assert len(rec.store) >= 4
    assert [s.frames for s in seen] == list(range(1, 41))
    new = [s.new_keyframe for s in seen if s.new_keyframe is not None]
    assert [k.id for k in new] == [k.id for k in rec.store.keyframes]
    assert new[0].thumbnail.shape[1] == 96
    assert not new[0].thumbnail.flags.writeable
    assert len(rec.frames) >= 10
    assert all(f.index in rec.trajectory for f in rec.frames)
    kf_ids = {k.id for k in rec.store.keyframes}
    # tracked poses are accurate on the clean studio
    errs = [
        np.linalg.norm(T[:3, 3] - src.frame(i).gt_T_world_cam[:3, 3])
        for i, T in list(rec.trajectory.items())[::10]
    ]
    assert max(errs) < 0.02
    # a second sweep appends to the store and continues the ids
    src2 = open_source("synthetic:frames=30,width=320,height=240,path=pan,cycle_s=3")
    rec2 = record_sweep(src2, SweepParams(kf_add_dist_m=0.1, kf_add_angle_deg=5), store=rec.store)
    assert len(rec2.store) > len(rec.store)
    assert kf_ids <= {k.id for k in rec2.store.keyframes}
    assert len(rec.store) == len(kf_ids)  # the first store is unchanged
    smaller = rec2.store.without(max(kf_ids))
    assert len(smaller) == len(rec2.store) - 1
    moved = smaller.with_poses({0: np.eye(4)})
    np.testing.assert_array_equal(moved.by_id(0).T_world_cam, np.eye(4))


def test_stop_and_params() -> None:
    rec_calls: list[int] = []
    src = open_source("synthetic:frames=40,width=160,height=120")
    rec = record_sweep(src, SweepParams(max_frames=3))
    assert rec.frames_processed == 3
    rec = record_sweep(
        src,
        SweepParams(max_frames=5),
        should_stop=lambda: rec_calls.append(1) or len(rec_calls) > 2,
    )
    assert rec.stopped
    assert rec.frames_processed == 2
    with pytest.raises(ParamsError):
        SweepParams(kf_add_dist_m=0)
