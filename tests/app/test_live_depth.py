"""Live page with an RGB-D source: the colour / depth / both view, the skip count, and the
"camera disconnected" state of a live source."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from engine.frames import Frame
from engine.loop import FrameRecord
from engine.trackers.base import TrackResult, TrackState


def test_bag_runs_and_the_view_toggles_colour_depth_both(  # type: ignore[no-untyped-def]
    qtbot, window, live, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("pyrealsense2", reason="the RealSense SDK has no wheel here")
    from engine.sources.realsense_bag import write_realsense_bag
    from engine.sources.synthetic import SyntheticSource

    bag = tmp_path / "s.bag"
    src = SyntheticSource.from_options({"frames": "60", "width": "160", "height": "120"})
    write_realsense_bag(src.frames(), bag, src.intrinsics)
    live.source_picker.set_spec(str(bag))
    live.tracker_box.setCurrentIndex(live.tracker_box.findData("opencv-odometry"))
    live.view_box.setCurrentIndex(live.view_box.findData("depth"))
    shown = []  # what each drawn frame put on screen: (mode, image shape, skipped read-out)
    real_draw = live.draw

    def draw(record: FrameRecord) -> None:
        real_draw(record)
        shown.append((live.view_mode, live.image_view.image_rgb.shape,
                      live.readouts["skipped"].text()))

    monkeypatch.setattr(live, "draw", draw)
    run = window.ctx.run
    with qtbot.waitSignal(run.finished, timeout=120_000):
        live.start()  # the recording plays every frame to its end
    assert run.frames_received == 60
    assert shown
    # every frame drawn in the chosen mode; a recording played every frame skips nothing
    assert set(shown) == {("depth", (120, 160, 3), "0  (0/s)")}
    # after the run the last frame stays on screen (the end is seen twice: by the finished
    # signal and by the display clock) and the switch redraws it at once
    live.display_tick()
    live.run_ended(run.status())
    assert live.image_view.info.toPlainText() == "stopped after 60 frames: the last frame shown"
    depth = live.image_view.image_rgb
    assert float(depth.astype(np.float32).var()) > 100.0  # false colour, not blank
    shapes = {}
    for mode in ("colour", "depth", "both"):
        live.view_box.setCurrentIndex(live.view_box.findData(mode))
        shapes[mode] = live.image_view.image_rgb.shape
    assert shapes == {"colour": (120, 160, 3), "depth": (120, 160, 3), "both": (120, 320, 3)}
    both = live.image_view.image_rgb
    np.testing.assert_array_equal(both[:, 160:], depth)  # colour left, depth right
    assert float(np.abs(both[:, :160].astype(int) - depth.astype(int)).mean()) > 10.0


def _record(seq: int, frame: Frame, state: TrackState, skipped_per_s: float) -> FrameRecord:
    result = TrackResult(state=state, T_world_cam=np.eye(4))
    return FrameRecord(seq, frame, result, "dense", 5.0, 20.0, 0, skipped_per_s=skipped_per_s)


def test_skip_rate_and_camera_disconnected_are_shown(qtbot, window, live) -> None:  # type: ignore[no-untyped-def]
    img = np.full((48, 64, 3), 90, np.uint8)
    depth = np.full((48, 64), 2.0, np.float32)
    live.draw(_record(0, Frame(0, 0.0, img, depth_m=depth, skipped_before=2),
                      TrackState.TRACKING, 25.0))
    assert live.readouts["skipped"].text() == "2  (25/s)"
    assert "skipping 25 frames/s" in live.image_view.info.toPlainText()
    lost = Frame(1, 0.1, None, link_lost_reason="camera disconnected")
    live.draw(_record(1, lost, TrackState.LOST, 0.0))
    assert live.status_light.text == "LOST · camera disconnected"
    assert "camera disconnected, reconnecting" in live.image_view.info.toPlainText()
    assert live.image_view.image_rgb is not None  # the last picture stays on screen
