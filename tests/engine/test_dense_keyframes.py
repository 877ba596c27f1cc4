"""Keyframe store (persistence, errors) and nearest-keyframe search, eq. (19)-(21)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from engine.dense.keyframes import (
    INDEX_NAME,
    KeyframeStore,
    KeyframeStoreError,
    frustum_metric,
    frustum_test_points,
)
from engine.dense.sweep import sweep
from engine.dense.testscene import PlaneScene, small_intrinsics
from engine.geometry import R_from_pan_tilt_roll_deg, make_T, se3_exp
from engine.sources.base import Source
from engine.trackers import create_tracker
from engine.trackers.base import TrackState


def _store(n: int = 3) -> KeyframeStore:
    intr = small_intrinsics()
    rng = np.random.default_rng(0)
    st = KeyframeStore(intr)
    for k in range(n):
        T = se3_exp(np.array([0.1 * k, 0.0, 0.0, 0.0, 0.02 * k, 0.0]))
        gray = rng.integers(0, 255, (intr.height, intr.width), dtype=np.uint8)
        depth = rng.uniform(0.5, 4.0, (intr.height, intr.width)).astype(np.float32)
        depth[0, :10] = 0.0
        st.add(T, gray, depth)
    return st


def test_round_trip(tmp_path: Path) -> None:
    st = _store()
    st.save(tmp_path / "kf")
    back = KeyframeStore.load(tmp_path / "kf")
    assert len(back) == 3
    assert back.intrinsics == st.intrinsics
    for a, b in zip(st.keyframes, back.keyframes, strict=True):
        assert a.id == b.id
        np.testing.assert_allclose(a.T_world_cam, b.T_world_cam, atol=1e-12)
        np.testing.assert_array_equal(a.gray, b.gray)
        np.testing.assert_allclose(a.depth_m, b.depth_m, atol=1.0 / 5000)
    # only JSON + PNG, no pickle
    assert sorted(p.suffix for p in (tmp_path / "kf").iterdir()) == [".json"] + [".png"] * 6


def test_corrupt_and_incompatible_stores_fail_clearly(tmp_path: Path) -> None:
    folder = tmp_path / "kf"
    _store().save(folder)
    index = folder / INDEX_NAME
    good = index.read_text()
    index.write_text(good[: len(good) // 2])
    with pytest.raises(KeyframeStoreError, match=r"keyframes\.json: corrupt JSON"):
        KeyframeStore.load(folder)
    raw = json.loads(good)
    raw["version"] = 99
    index.write_text(json.dumps(raw))
    with pytest.raises(KeyframeStoreError, match="version 99 is not supported"):
        KeyframeStore.load(folder)
    raw = json.loads(good)
    index.write_text(json.dumps(raw))
    (folder / "kf_0001_depth.png").write_bytes(b"not a png")
    with pytest.raises(KeyframeStoreError, match=r"kf_0001_depth\.png: missing or not a readable"):
        KeyframeStore.load(folder)
    with pytest.raises(KeyframeStoreError, match="not found"):
        KeyframeStore.load(tmp_path / "nowhere")
    # the tracker reports the same error when built on a broken store
    with pytest.raises(KeyframeStoreError):
        create_tracker("dense", keyframes_dir=str(folder))


def test_nearest_keyframe_eq19_21() -> None:
    intr = small_intrinsics()
    st = KeyframeStore(intr)
    blank = np.zeros((intr.height, intr.width), np.uint8)
    depth = np.ones((intr.height, intr.width), np.float32)
    for x in (0.0, 0.5, 1.0, 1.5):
        st.add(make_T(np.eye(3), [x, 0.0, 0.0]), blank, depth)
    kf, in_omega = st.nearest(make_T(np.eye(3), [0.6, 0.0, 0.05]), math.radians(30), 0.4)
    assert kf is not None
    assert kf.id == 1
    assert in_omega
    # Omega empty (too far from all): the overall nearest is returned, flagged
    kf, in_omega = st.nearest(make_T(np.eye(3), [3.0, 0.0, 0.0]), math.radians(30), 0.4)
    assert kf is not None
    assert kf.id == 3
    assert not in_omega
    # rotation about the optical axis is seen by the test-point metric (eq. 21)
    pts = frustum_test_points(intr)
    assert pts.shape[0] == 3 * 30
    T0 = np.eye(4)
    R0 = R_from_pan_tilt_roll_deg(0, 0, 0)
    T_roll = make_T(R_from_pan_tilt_roll_deg(0, 0, 5) @ R0.T, [0, 0, 0])
    assert frustum_metric(intr, T_roll, T0, pts) > 1.0
    assert frustum_metric(intr, T0, T0, pts) == pytest.approx(0.0)


class _ListSource(Source):
    def __init__(self, frames: list) -> None:  # type: ignore[type-arg]
        self._frames = frames
        self.name = "test frames"

    @property
    def intrinsics(self):  # type: ignore[no-untyped-def]
        return self._frames[0].intrinsics

    def __len__(self) -> int:
        return len(self._frames)

    def frames(self):  # type: ignore[no-untyped-def]
        yield from self._frames


def test_sweep_builds_a_store_that_dense_tracks_against(tmp_path: Path) -> None:
    scene = PlaneScene(small_intrinsics(), room_scale=0.45)

    def pose(i: int) -> np.ndarray:
        return make_T(np.eye(3), [0.01 * i, 0.0, 0.0])

    frames = [scene.frame(i, pose(i)) for i in range(0, 24)]
    res = sweep(_ListSource(frames), create_tracker("dense", n_points=1024).params.__class__(
        n_points=1024, kf_add_dist_m=0.08))
    assert len(res.store) >= 3
    res.store.save(tmp_path / "kf")
    tr = create_tracker("dense", n_points=1024, keyframes_dir=str(tmp_path / "kf"))
    out = [tr.track(scene.frame(i, pose(i) @ make_T(np.eye(3), [0, 0.01, 0]))) for i in (5, 6, 7)]
    assert all(r.state.is_good or r.state == TrackState.RELOCALIZING for r in out)
    for i, r in zip((5, 6, 7), out, strict=True):
        assert r.keyframe_id is not None
        assert np.linalg.norm(r.T_world_cam[:3, 3] - (pose(i)[:3, 3] + [0, 0.01, 0])) < 2e-3


def test_store_for_another_camera_is_refused(tmp_path: Path) -> None:
    _store().save(tmp_path / "kf")
    tr = create_tracker("dense", n_points=1024, keyframes_dir=str(tmp_path / "kf"))
    other = small_intrinsics(distorted=False)  # same size, different distortion
    scene = PlaneScene(other, room_scale=0.45)
    with pytest.raises(KeyframeStoreError, match="different camera"):
        tr.track(scene.frame(0, np.eye(4)))
