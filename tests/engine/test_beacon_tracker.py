"""Beacon sources (simulator, CSV, UDP) and the ``beacon-slam`` tracker through the loop."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from engine.beacons.io import save_layout, send_ranges
from engine.beacons.simulator import PAPER_LAYOUT
from engine.errors import SourceError
from engine.frames import Frame
from engine.loop import SetParams, run_tracking
from engine.sources import open_source
from engine.sources.beacons import BeaconTruth, RangeReadings
from engine.trackers import create_tracker, get_spec
from engine.trackers.base import TrackState


def test_spec_is_registered() -> None:
    spec = get_spec("beacon-slam")
    assert spec.output == "position2d"
    assert not spec.needs_image
    assert not spec.needs_depth


def test_simulator_source_frames() -> None:
    src = open_source("beacons:steps=20,seed=3,dropout=0.2")
    frames = list(src.frames())
    assert len(frames) == len(src) == 21
    f = frames[5]
    assert f.color_bgr is None
    assert set(f.payload(RangeReadings).ranges) <= set(PAPER_LAYOUT)
    assert f.gt_T_world_cam is not None
    assert f.gt_T_world_cam[0, 3] == pytest.approx(f.payload(BeaconTruth).gt_xy[0])
    assert dict(f.payload(RangeReadings).layout) == PAPER_LAYOUT


@pytest.mark.parametrize("spec", ["beacons:nope=1", "beacons:noise=x", "beacons:dropout=2",
                                  "beacons-csv:", "beacons-udp:port=x"])
def test_bad_specs_raise_source_error(spec: str) -> None:
    with pytest.raises(SourceError):
        open_source(spec)


def test_tracker_runs_on_simulator_through_the_loop() -> None:
    import queue

    src = open_source("beacons:seed=2")
    tr = create_tracker("beacon-slam", n_particles=150)
    cmds: queue.Queue = queue.Queue()
    recs = []
    for rec in run_tracking(src, tr, commands=cmds):
        recs.append(rec)
        if rec.seq == 60:
            cmds.put(SetParams(tr.params.__class__(n_particles=80, map_adjust_p=0.1)))
    assert recs[0].result.state is TrackState.INITIALIZING
    last = recs[-1].result
    assert last.state.is_good
    T = last.T_world_cam
    assert T is not None
    assert T.shape == (4, 4)
    np.testing.assert_array_equal(T[:3, :3], np.eye(3))
    assert T[2, 3] == 0.0
    assert last.details.particles_xy.shape == (80, 2)
    assert last.details.beacons_cov.shape == (4, 2, 2)
    err = [np.hypot(*(r.result.T_world_cam[:2, 3] - r.frame.payload(BeaconTruth).gt_xy))
           for r in recs]
    assert float(np.sqrt(np.mean(np.square(err)))) < 1.5


def test_csv_source_with_layout_and_bad_lines(tmp_path: Path) -> None:
    layout = tmp_path / "layout.json"
    save_layout(layout, PAPER_LAYOUT)
    truth = np.array(list(PAPER_LAYOUT.values()))
    lines = ["timestamp,beacon_id,range_m"]
    for t in range(15):
        s = np.array([0.1 * t, 0.05 * t])
        for bid, r in zip(PAPER_LAYOUT, np.linalg.norm(truth - s, axis=1), strict=True):
            lines.append(f"{0.1 * t:.3f},{bid},{r:.4f}")
    lines += ["garbage line", "2.0,X,3.0"]
    log = tmp_path / "ranges.csv"
    log.write_text("\n".join(lines) + "\n")
    src = open_source(f"beacons-csv:{log},layout={layout}")
    assert len(src) == 15
    tr = create_tracker("beacon-slam", known_beacons=True)
    recs = list(run_tracking(src, tr))
    stats = recs[-1].frame.payload(RangeReadings).input_stats
    assert stats["malformed"] == 1
    assert stats["unknown_ids"] == 1
    assert recs[-1].result.details.input_stats["unknown_id_names"] == ["X"]
    np.testing.assert_allclose(recs[-1].result.T_world_cam[:2, 3], [1.4, 0.7], atol=0.3)


def test_udp_source_receives_and_sends_heartbeats() -> None:
    src = open_source("beacons-udp:port=0,heartbeat=0.05,idle_timeout=1.0")
    port = src.listener.port
    truth = np.array(list(PAPER_LAYOUT.values()))

    def sender() -> None:
        time.sleep(0.1)
        for t in range(5):
            r = np.linalg.norm(truth - [0.1 * t, 0.0], axis=1)
            send_ranges(port, 0.1 * t, dict(zip(PAPER_LAYOUT, r.tolist(), strict=True)))
            time.sleep(0.02)

    th = threading.Thread(target=sender)
    th.start()
    tr = create_tracker("beacon-slam")
    try:
        frames: list[Frame] = []
        results = []
        for rec in run_tracking(src, tr):
            frames.append(rec.frame)
            results.append(rec.result)
            if sum(1 for f in frames if f.payload(RangeReadings).ranges) == 5:
                break
    finally:
        th.join()
        src.close()
    with_data = [f for f in frames if f.payload(RangeReadings).ranges]
    assert len(with_data) == 5
    # heartbeat frames kept the loop alive
    assert any(not f.payload(RangeReadings).ranges for f in frames)
    assert results[-1].details.step == 4
