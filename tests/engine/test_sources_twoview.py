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
