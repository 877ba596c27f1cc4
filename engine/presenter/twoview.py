"""Two views: the second camera's image position -> floor point -> distance d (VR-TV paper,
Sec. III-A, C.6).

The calibration and the second view's frame payload live in :mod:`engine.floor` (a source
attaches them; the studio project stores the calibration); re-exported here. The presenter's
floor point is the bottom centre of the second view's box (the feet are on the floor, where
the homography is exact); d is its distance to the robot. The output is (x1, y1, d).
"""

from __future__ import annotations

from engine.floor import (
    FloorCalibration,
    OverheadView,
    calibrate_floor,
    load_floor_calibration,
    save_floor_calibration,
)

__all__ = ["FloorCalibration", "OverheadView", "calibrate_floor", "foot_point",
           "fuse", "load_floor_calibration", "save_floor_calibration"]


def foot_point(xyh: tuple[float, float, float], aspect: float) -> tuple[float, float]:
    """Image point of the presenter on the floor: the bottom centre of the box (x, y, h)."""
    del aspect  # the box's bottom centre does not depend on its width
    x, y, h = xyh
    return (float(x), float(y) + 0.5 * float(h))


def fuse(x1: float, y1: float, overhead_xy2: tuple[float, float] | None,
         calib: FloorCalibration | None) -> tuple[float, float, float | None]:
    """The controller's input (x1, y1, d); d is None without a second view."""
    if overhead_xy2 is None or calib is None:
        return (x1, y1, None)
    return (x1, y1, calib.distance_m(*overhead_xy2))
