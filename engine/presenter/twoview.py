"""Two views: the second camera's image position -> floor point -> distance d (VR-TV paper,
Sec. III-A, C.6).

The calibration and the second view's frame payload live in :mod:`engine.floor` (a source
attaches them; the studio project stores the calibration); re-exported here. The presenter's
floor point is the bottom centre of the second view's box (the feet are on the floor, where
the homography is exact); d is its distance to the robot. The output is (x1, y1, d).

Scale from the floor (``PresenterParams.floor_scale``, beyond the paper): the second view is
calibrated, and a person standing on the floor at a given place has a given image height
there, so its filter does not random-walk h (eq. 1) but takes each hypothesis's h from its
position (:class:`StandingPerson`): the box of a person as tall as the first frame's box says
(:func:`standing_height_m`), standing where the hypothesis's box centre is
(:meth:`FloorCalibration.standing_box_px`). A random walk in h drifts (a box a little
taller than the person matches the colours as well) and moves the foot point with it: with
the overhead view's about 1.4 cm of floor per pixel, a 10 px drift is 7 cm of d. With a zoom
lens the height follows the encoders each frame.

Lean (``floor_lean``): a vertical's image leans towards the nadir's image (below a camera
looking down), by as much as the box is wide at the edges of a wide lens. The patches follow
the lean at the estimate (:meth:`StandingPerson.patch_boxes`), the box is centred on the
body's axis, and the floor point is located from the leaning segment
(:meth:`FloorCalibration.locate` with ``lean_px``). Measured (``bench presenter`` two_view,
rail walk from the image's left edge to its right): with the first frame's patch geometry
the second view fell behind and was LOST 43 of 300 frames.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.floor import (
    FloorCalibration,
    OverheadView,
    calibrate_floor,
    load_floor_calibration,
    save_floor_calibration,
)

__all__ = ["FloorCalibration", "OverheadView", "StandingPerson", "calibrate_floor",
           "foot_point", "fuse", "load_floor_calibration", "save_floor_calibration",
           "standing_height_m"]

F64 = NDArray[np.float64]
#: secant steps of :func:`standing_height_m` (the box height is smooth and monotonic in the
#: person's height; 8 leave far under 0.01 px)
HEIGHT_STEPS = 8


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


def standing_height_m(calib: FloorCalibration, box_xywh: tuple[float, float, float, float],
                      encoders: Any = None) -> float | None:
    """The height (m) of the upright person whose box this is, in the model
    :meth:`FloorCalibration.standing_box_px` inverts: that method at the box's centre with
    this height gives the box's height (secant steps). None where the calibration has no
    camera or the box does not stand on the floor it sees."""
    x, y, w, h = (float(v) for v in box_xywh)
    u, v = np.array([x + 0.5 * w]), np.array([y + 0.5 * h])

    def height_px(height_m: float) -> float:
        got = calib.standing_box_px(u, v, height_m, encoders, np.array([h]))
        return float("nan") if got is None else float(got[0][0])

    a, b = 1.0, 2.0
    fa, fb = height_px(a) - h, height_px(b) - h
    for _ in range(HEIGHT_STEPS):
        if not (math.isfinite(fa) and math.isfinite(fb)) or fb == fa:
            break
        a, fa, b = b, fb, b - fb * (b - a) / (fb - fa)
        fb = height_px(b) - h
    if not (math.isfinite(b) and math.isfinite(fb) and b > 0 and abs(fb) < 0.5):
        return None
    return float(b)


class StandingPerson:
    """The second view's person model from its floor calibration: someone ``height_m`` tall
    (:func:`standing_height_m` of the first box) standing upright on the floor. ``encoders``
    are the view's lens encoders at the current frame (a zoom lens; the tracker sets them).

    - :meth:`heights`: each hypothesis's box height at its box centre (the scale model that
      replaces eq. (1)'s random walk in h, ``PresenterParams.floor_scale``);
    - :meth:`patch_boxes`: the patches moved across the box with the person's lean at the
      estimate (``floor_lean``). A model with the first frame's geometry puts a person seen
      leaning left at the image's left edge (head left, feet right) on one leaning right at
      its right edge: the torso patch lands beside the person. Here a patch at height
      fraction f of the box sits ``lean x (1/2 - f)`` px right of the body's axis, plus its
      own offset in the first frame with that frame's lean taken out (zero mean over the
      patches); the box is centred on the axis - its centre is then the axis' midpoint,
      :meth:`FloorCalibration.locate`'s model, not the first box's centre, which a stride
      or a swinging arm moves off it - and as wide as the upright body plus the lean.
    """

    def __init__(self, calib: FloorCalibration, height_m: float,
                 first_box_xywh: tuple[float, float, float, float], rel_boxes: F64,
                 encoders: Any = None) -> None:
        self.calib = calib
        self.height_m = float(height_m)
        self.encoders = encoders
        rel = np.asarray(rel_boxes, dtype=np.float64)
        self.rel_first = rel.copy()
        x, y, w, h = (float(v) for v in first_box_xywh)
        self.first_box_xywh = (x, y, w, h)
        lean0 = self._lean(x + 0.5 * w, y + 0.5 * h, h) or 0.0
        self._lean_last = lean0
        self._f = 0.5 * (rel[:, 1] + rel[:, 3])  # height fraction of each patch's centre
        upright = x + 0.5 * (rel[:, 0] + rel[:, 2]) * w - lean0 * (0.5 - self._f)  # px
        axis = float(np.mean(upright))
        self.axis_x0 = axis  # the axis' midpoint u in the first frame
        # per patch, in units of the box height: offset from the axis, half width
        self._own = (upright - axis) / h
        self._half = 0.5 * (rel[:, 2] - rel[:, 0]) * w / h
        # the upright body's width (units of h): the first box less its lean, at least
        # wide enough for the patches upright
        self._body = max((w - abs(lean0)) / h, 2.0 * float(np.max(np.abs(self._own)
                                                                   + self._half)))

    @classmethod
    def from_first_box(cls, calib: FloorCalibration | None,
                       box_xywh: tuple[float, float, float, float] | None, rel_boxes: F64,
                       encoders: Any = None) -> StandingPerson | None:
        """The model for the person in the second view's first box (None without a
        calibration that knows heights, or a box that is not a standing person on its
        floor)."""
        if calib is None or box_xywh is None:
            return None
        height = standing_height_m(calib, box_xywh, encoders)
        if height is None:
            return None
        return cls(calib, height, box_xywh, rel_boxes, encoders)

    def first_state(self) -> tuple[float, float, float]:
        """The (x, y, h) state of the first box with x on the body's axis."""
        _x, y, _w, h = self.first_box_xywh
        return (self.axis_x0, y + 0.5 * h, h)

    def _lean(self, u: float, v: float, h: float) -> float | None:
        got = self.calib.standing_box_px(np.array([u]), np.array([v]), self.height_m,
                                         self.encoders, np.array([h]))
        if got is None or not math.isfinite(float(got[1][0])):
            return None
        return float(got[1][0])

    def lean_at(self, xyh: Any) -> float:
        """The lean (px) of the person at state ``xyh`` (the last known where the floor is
        not seen)."""
        x, y, h = (float(v) for v in xyh)
        lean = self._lean(x, y, h)
        return self._lean_last if lean is None else lean

    def heights(self, particles_xyh: F64) -> F64 | None:
        """Box heights (px) of the (x, y, h) rows (NaN: keep the row's)."""
        got = self.calib.standing_box_px(particles_xyh[:, 0], particles_xyh[:, 1],
                                         self.height_m, self.encoders, particles_xyh[:, 2])
        return None if got is None else got[0]

    def patch_boxes(self, xyh: F64) -> tuple[F64, float]:
        """Relative patch boxes (x0, y0, x1, y1 of the main box) and the main box's aspect
        (width / height) at state ``xyh``: the first frame's patch sizes and heights, moved
        across by the lean there (the last known lean where the floor is not seen)."""
        x, y, h = (float(v) for v in xyh)
        lean = self._lean(x, y, h)
        if lean is None:
            lean = self._lean_last
        self._lean_last = lean
        width = self._body * h + abs(lean)  # px
        half = self._half * h / width
        cx = 0.5 + (self._own * h + lean * (0.5 - self._f)) / width
        cx = np.clip(cx, half, 1.0 - half)
        rel = self.rel_first.copy()
        rel[:, 0], rel[:, 2] = cx - half, cx + half
        return rel, width / h
