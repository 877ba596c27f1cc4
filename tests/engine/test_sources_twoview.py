"""``twoview:``: two recordings paired by time stamp, the overhead view as a payload."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from engine.errors import SourceError
from engine.floor import OverheadView, calibrate_floor, save_floor_calibration
from engine.sources import open_source


def _folder(path: Path, times: list[float], shade: int) -> None:
    path.mkdir()
    for k, t in enumerate(times):
        img = np.full((24, 32, 3), shade, np.uint8)
        img[0, 0] = k  # which frame this is
        cv2.imwrite(str(path / f"{t:.6f}.png"), img)


def test_frames_are_paired_by_time_stamp(tmp_path: Path) -> None:
    _folder(tmp_path / "front", [0.0, 0.1, 0.2, 0.3, 0.4], 50)
    # the overhead runs at another rate and misses 0.3
    _folder(tmp_path / "over", [0.02, 0.09, 0.19, 0.45], 200)
    calib = calibrate_floor([(0, 0), (31, 0), (31, 23), (0, 23)],
                            [(0, 0), (1, 0), (1, 1), (0, 1)])
    save_floor_calibration(tmp_path / "floor.json", calib)
    src = open_source(f"twoview:front={tmp_path / 'front'},over={tmp_path / 'over'},"
                      f"floor={tmp_path / 'floor.json'},over_box=1:2:10:12,max_dt_s=0.03")
    frames = list(src.frames())
    assert len(frames) == 5
    views = [f.payload(OverheadView) for f in frames]
    got = [None if v is None else int(v.color_bgr[0, 0, 0]) for v in views]
    assert got == [0, 1, 2, None, None]  # 0.3 and 0.4 have no overhead frame within 30 ms
    assert views[0].box_xywh == (1.0, 2.0, 10.0, 12.0)
    assert views[1].box_xywh is None  # the box initialises the second filter only
    assert views[0].floor_calibration is not None
    assert views[2].timestamp_s == pytest.approx(0.19)
    assert src.pairs == 3
    assert src.unpaired == 2
    # a known delay between the cameras
    src = open_source(f"twoview:front={tmp_path / 'front'},over={tmp_path / 'over'},"
                      "over_offset_s=-0.15,max_dt_s=0.03")
    got = [f.payload(OverheadView) for f in src.frames()]
    assert got[3] is not None
    assert int(got[3].color_bgr[0, 0, 0]) == 3  # 0.45 - 0.15 = 0.30


def test_a_nested_spec_and_errors(tmp_path: Path) -> None:
    _folder(tmp_path / "over", [0.0, 1 / 30, 2 / 30], 100)
    src = open_source(f"twoview:front=synthetic:frames=3;width=32;height=24,"
                      f"over={tmp_path / 'over'}")
    assert sum(f.payload(OverheadView) is not None for f in src.frames()) == 3
    with pytest.raises(SourceError, match="needs over="):
        open_source("twoview:front=synthetic")
    with pytest.raises(SourceError, match="over_box"):
        open_source(f"twoview:front=synthetic,over={tmp_path / 'over'},over_box=1:2")
    with pytest.raises(SourceError, match="unknown option"):
        open_source(f"twoview:front=synthetic,over={tmp_path / 'over'},bogus=1")
    with pytest.raises(SourceError, match="floor"):
        open_source(f"twoview:front=synthetic,over={tmp_path / 'over'},"
                    f"floor={tmp_path / 'none.json'}")


def test_a_real_rig_recording_gives_the_floor_distance_end_to_end(tmp_path: Path) -> None:
    """Two recordings (the built-in studio's overhead frames written as a time-stamped image
    folder, the frontal camera as a source) with a floor.json: the tracker measures d."""
    from engine.floor import OverheadView as Over
    from engine.trackers import create_tracker

    spec = "frames=12;width=320;height=240;presenter=1;path=static;seed=3"
    studio = list(open_source(f"synthetic:{spec.replace(';', ',')},views=2").frames())
    (tmp_path / "over").mkdir()
    truth = []
    for f in studio:
        o = f.payload(Over)
        assert o is not None
        cv2.imwrite(str(tmp_path / "over" / f"{f.timestamp_s + 0.004:.6f}.png"), o.color_bgr)
        truth.append(o.floor_xy_m_true)
    calib = studio[0].payload(Over).floor_calibration
    save_floor_calibration(tmp_path / "floor.json", calib)
    x, y, w, h = studio[0].payload(Over).box_xywh
    src = open_source(f"twoview:front=synthetic:{spec},over={tmp_path / 'over'},"
                      f"floor={tmp_path / 'floor.json'},over_box={x}:{y}:{w}:{h}")
    tracker = create_tracker("presenter")
    errs = []
    rx, ry = calib.robot_floor_xy_m
    for f, (tx, ty) in zip(src.frames(), truth, strict=True):
        d = tracker.track(f).details
        if d.d_m is not None:
            errs.append(abs(d.d_m - float(np.hypot(tx - rx, ty - ry))))
    assert src.pairs == 12
    assert len(errs) >= 10
    assert float(np.median(errs)) < 0.1
