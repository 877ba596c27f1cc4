"""Two views: overhead image position -> floor point -> distance d (VR-TV paper, Sec. III-A, C.6).

The overhead camera's calibration is a floor homography ``H_floor_img`` estimated from four
clicked image points whose floor coordinates (metres, robot-base frame) are known. The
overhead tracker's (x2, y2) - the presenter's image position seen from above - maps to a
floor point; d is its distance to the robot's floor position. The output is (x1, y1, d).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.frames import FramePayload, readonly
from engine.persist import atomic_write_json
from engine.presenter import PresenterError

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class OverheadView(FramePayload):
    """A second (overhead) view of the same instant, for the floor distance d.

    ``box_xywh`` is the presenter's box in it on the first frame (initialises the second
    filter); ``floor_calibration`` maps its image to the floor.
    """

    light: ClassVar[bool] = False
    color_bgr: NDArray[np.uint8]
    box_xywh: tuple[float, float, float, float] | None = None
    floor_calibration: FloorCalibration | None = None

    def __post_init__(self) -> None:
        readonly(self.color_bgr)


@dataclass(frozen=True, slots=True)
class FloorCalibration:
    """Homography image(px) -> floor(m) and the robot's floor position (m)."""

    H_floor_img: F64
    robot_floor_xy_m: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        self.H_floor_img.flags.writeable = False

    def floor_point(self, u: float, v: float) -> tuple[float, float]:
        p = self.H_floor_img @ np.array([u, v, 1.0])
        if abs(p[2]) < 1e-12:
            raise PresenterError(f"image point ({u:.1f}, {v:.1f}) maps to infinity on the floor")
        return (float(p[0] / p[2]), float(p[1] / p[2]))

    def distance_m(self, u: float, v: float) -> float:
        """d: floor distance of the overhead image point (x2, y2) from the robot."""
        fx, fy = self.floor_point(u, v)
        return float(np.hypot(fx - self.robot_floor_xy_m[0], fy - self.robot_floor_xy_m[1]))


def calibrate_floor(image_pts_px: Sequence[Sequence[float]],
                    floor_pts_m: Sequence[Sequence[float]],
                    robot_floor_xy_m: tuple[float, float] = (0.0, 0.0)) -> FloorCalibration:
    """Homography from exactly four clicked points and their known floor coordinates."""
    img = np.asarray(image_pts_px, dtype=np.float64)
    flo = np.asarray(floor_pts_m, dtype=np.float64)
    if img.shape != (4, 2) or flo.shape != (4, 2):
        n_img = img.shape[0] if img.ndim else 0
        n_flo = flo.shape[0] if flo.ndim else 0
        raise PresenterError(f"floor calibration needs 4 image and 4 floor points, got "
                             f"{n_img} and {n_flo}")
    for name, pts in (("image", img), ("floor", flo)):
        # any three collinear points make the homography degenerate
        for i in range(4):
            a, b, c = (pts[j] for j in range(4) if j != i)
            u, w = b - a, c - a
            if abs(u[0] * w[1] - u[1] * w[0]) < 1e-6 * max(1.0, float(np.ptp(pts)) ** 2):
                raise PresenterError(f"floor calibration: three {name} points are collinear")
    H = cv2.getPerspectiveTransform(img.astype(np.float32), flo.astype(np.float32))
    return FloorCalibration(np.asarray(H, dtype=np.float64), robot_floor_xy_m)


def fuse(x1: float, y1: float, overhead_xy2: tuple[float, float] | None,
         calib: FloorCalibration | None) -> tuple[float, float, float | None]:
    """The controller's input (x1, y1, d); d is None without an overhead view."""
    if overhead_xy2 is None or calib is None:
        return (x1, y1, None)
    return (x1, y1, calib.distance_m(*overhead_xy2))


def save_floor_calibration(path: Path, calib: FloorCalibration,
                           image_pts_px: Sequence[Sequence[float]],
                           floor_pts_m: Sequence[Sequence[float]]) -> None:
    atomic_write_json(Path(path), {
        "format": "studiotrack.floor_homography", "version": 1,
        "image_points_px": [list(map(float, p)) for p in image_pts_px],
        "floor_points_m": [list(map(float, p)) for p in floor_pts_m],
        "robot_floor_xy_m": list(calib.robot_floor_xy_m),
        "H_floor_img": calib.H_floor_img.tolist(),
    })


def load_floor_calibration(path: Path) -> FloorCalibration:
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        return calibrate_floor(doc["image_points_px"], doc["floor_points_m"],
                               tuple(doc.get("robot_floor_xy_m", (0.0, 0.0))))
    except FileNotFoundError:
        raise PresenterError(f"{path}: no such floor calibration") from None
    except (json.JSONDecodeError, KeyError, TypeError, RecursionError) as exc:
        raise PresenterError(f"{path}: malformed floor calibration ({exc})") from None
