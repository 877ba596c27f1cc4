"""The ``presenter`` tracker end to end on small generated frames (no Qt)."""

from __future__ import annotations

import dataclasses
import json
import queue
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from engine.evaluation.boxes import iou_xywh
from engine.frames import Frame
from engine.loop import SetParams, run_tracking
from engine.presenter.control import RobotCameraCommand
from engine.presenter.model import model_from_box, save_model
from engine.presenter.params import PresenterParams
from engine.presenter.scene import presenter_frames
from engine.sources.base import Source
from engine.trackers import available_trackers, create_tracker
from engine.trackers.base import TrackState
from tests.conftest import shared_path

ROOT = Path(__file__).resolve().parents[2]


def _frames(n: int, **kw: object) -> list[Frame]:
    return [Frame(index=f.index, timestamp_s=f.index / 30.0, color_bgr=f.bgr,
                  gt_box_xywh=f.box_xywh)
            for f in presenter_frames(n, 320, 240, **kw)]  # type: ignore[arg-type]


class ListSource(Source):
    def __init__(self, frames: list[Frame]) -> None:
        self._frames = frames

    @property
    def intrinsics(self) -> None:
        return None

    def __len__(self) -> int:
        return len(self._frames)

    def frames(self):  # type: ignore[no-untyped-def]
        yield from self._frames


def test_registry_has_presenter_and_opencv_peers() -> None:
    specs = available_trackers()
    for name in ("presenter", "kcf", "mil", "csrt"):
        assert specs[name].output == "box"


def test_tracks_a_walking_presenter() -> None:
    frames = _frames(40, speed_px=2.0)
    tracker = create_tracker("presenter")
    ious = []
    for f in frames:
        r = tracker.track(f)
        assert r.state == TrackState.TRACKING
        ious.append(float(iou_xywh(np.array(f.gt_box_xywh), np.array(r.box_xywh))[0]))
    assert np.median(ious) > 0.6
    assert r.overlay is not None
    assert len(r.overlay.boxes_xywh) == 4


def test_loss_is_detected_and_the_presenter_reacquired() -> None:
    leave, back = 30, 55
    frames = _frames(85, speed_px=1.0, leave=(leave, back))
    tracker = create_tracker("presenter")
    states = [tracker.track(f) for f in frames]
    lost_at = next(i for i in range(leave, back) if states[i].state == TrackState.LOST)
    assert lost_at - leave <= 5
    # no false lock on the set while the presenter is away, and the output holds
    assert all(s.state == TrackState.LOST for s in states[lost_at:back])
    assert states[back - 1].box_xywh == states[lost_at].box_xywh
    found = next(i for i in range(back, len(frames)) if states[i].state == TrackState.TRACKING)
    assert found - back <= 15
    iou = iou_xywh(np.array(frames[found + 2].gt_box_xywh), np.array(states[found + 2].box_xywh))
    assert float(iou[0]) > 0.3
    # while searching, the filter uses the larger diffuse particle set
    assert states[lost_at + 2].details.n_particles == PresenterParams().reinit_particles


def test_particle_count_change_mid_run_takes_effect() -> None:
    frames = _frames(12)
    tracker = create_tracker("presenter")
    commands: queue.Queue = queue.Queue()
    counts = []
    for rec in run_tracking(ListSource(frames), tracker, commands=commands):
        counts.append(rec.result.details.n_particles)
        if rec.seq == 4:
            commands.put(SetParams(dataclasses.replace(tracker.params, n_particles=250,
                                                       jitter_cutoff_hz=2.0)))
    assert counts[:5] == [100] * 5
    assert counts[5:] == [250] * 7
    assert tracker._view.jitter.cutoff_hz == 2.0


def test_initialised_from_a_saved_model_and_sends_udp(tmp_path: Path) -> None:
    frames = _frames(6)
    model = model_from_box(frames[0].color_bgr, frames[0].gt_box_xywh)  # type: ignore[arg-type]
    save_model(tmp_path / "model", model, frames[0].color_bgr)  # type: ignore[arg-type]
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(5.0)
    try:
        params = PresenterParams(model_path=str(tmp_path / "model"), control_udp=True,
                                 control_port=rx.getsockname()[1], target_x_frac=0.25)
        tracker = create_tracker("presenter", params)
        bare = ListSource([dataclasses.replace(f, gt_box_xywh=None) for f in frames])
        direct = create_tracker("presenter", params).track(bare._frames[0])
        rx.settimeout(0.2)
        with pytest.raises(TimeoutError):  # track() itself does no I/O ...
            rx.recvfrom(65536)
        [robot] = direct.commands_of(RobotCameraCommand)
        assert robot.target == ("127.0.0.1", rx.getsockname()[1])
        rx.settimeout(5.0)
        # ... the pipeline's robot-control sink (the tracker brings it) sends the messages
        recs = list(run_tracking(bare, tracker))
        msgs = [json.loads(rx.recvfrom(65536)[0]) for _ in frames]
    finally:
        rx.close()
    r = recs[-1].result
    assert r.state == TrackState.TRACKING
    msg = msgs[0]
    assert [m["seq"] for m in msgs] == list(range(1, len(frames) + 1))
    assert msg["seq"] == 1
    assert msg["target"]["x_px"] == 80.0
    assert r.details.control.e_f_px[0] == r.details.filtered_xyh[0] - 80.0


def test_opencv_peers_track_generated_frames() -> None:
    frames = _frames(8)
    for name in ("kcf", "csrt"):
        tracker = create_tracker(name)
        results = [tracker.track(f) for f in frames]
        assert all(r.box_xywh is not None for r in results)


def test_bench_presenter_json_line() -> None:
    shared_path("otb_girl")
    proc = subprocess.run(
        [sys.executable, "-m", "app.cli", "bench", "presenter", "--json", "--frames", "12",
         "--sequences", "otb_girl", "--trackers", "presenter,kcf"],
        cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    for name in ("presenter", "kcf"):
        assert set(out["otb_girl"][name]) >= {"success_auc", "precision_20px", "fps"}


def test_bench_presenter_speed_only_runs_the_frame_rate_parts() -> None:
    import argparse

    from engine.bench import presenter as bench

    parser = argparse.ArgumentParser()
    bench.add_arguments(parser)
    out = bench.run(parser.parse_args(["--speed-only", "--frames", "6"]))
    assert set(out) == {*bench.SPEED_SEQUENCES, "colour_summary", "speed"}
    for seq in bench.SPEED_SEQUENCES:
        assert set(out[seq]) == set(bench.SPEED_TRACKERS)
    assert out["colour_summary"]["fps_ratio_to_csrt"] > 0
    assert set(out["speed"]["median_stage_ms"]) >= {"motion_ms", "likelihood_ms", "total_ms"}
