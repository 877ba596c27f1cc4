"""Pinhole camera with 5-parameter Brown/Caltech lens distortion.

Projection follows Tykkälä 2014 eq. (2): ``u = K D(N(R p + t), alpha)`` where ``N``
dehomogenises and ``D`` is the Caltech model of eq. (3)-(4)::

    D(x) = (1 + k1 r^2 + k2 r^4 + k3 r^6) x + dx
    dx   = [2 p1 x y + p2 (r^2 + 2 x^2),  p1 (r^2 + 2 y^2) + 2 p2 x y]

with ``r^2 = x^2 + y^2``: the same model and coefficient order (k1, k2, p1, p2, k3) as
OpenCV's ``projectPoints``. Distortion is applied to points, images are never undistorted.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import SupportsFloat

import numpy as np
from numpy.typing import NDArray

from engine.errors import CalibrationError

F64 = NDArray[np.float64]
#: Caltech distortion coefficients in OpenCV's order (k1, k2, p1, p2, k3)
Dist5 = tuple[float, float, float, float, float]


def dist5(values: Iterable[SupportsFloat]) -> Dist5:
    """Five distortion coefficients (k1, k2, p1, p2, k3) as floats; CalibrationError if the
    count is not five."""
    v = tuple(float(x) for x in values)
    if len(v) != 5:
        raise CalibrationError(f"distortion needs 5 values (k1,k2,p1,p2,k3), got {len(v)}")
    return v[0], v[1], v[2], v[3], v[4]


@dataclass(frozen=True, slots=True)
class Intrinsics:
    """Pinhole intrinsics, image size, Caltech distortion and the depth PNG scale."""

    fx: float = field(default=525.0, metadata={"help": "focal length x (px)"})
    fy: float = field(default=525.0, metadata={"help": "focal length y (px)"})
    cx: float = field(default=319.5, metadata={"help": "principal point x (px)"})
    cy: float = field(default=239.5, metadata={"help": "principal point y (px)"})
    width: int = field(default=640, metadata={"help": "image width (px)"})
    height: int = field(default=480, metadata={"help": "image height (px)"})
    dist_k1k2p1p2k3: Dist5 = (0.0, 0.0, 0.0, 0.0, 0.0)
    depth_scale: float = field(default=5000.0, metadata={"help": "depth PNG units per metre"})
    rolling_shutter_s: float = field(default=0.0, metadata={
        "help": "colour sensor readout time, first row to last (s); 0 = global shutter"})

    def __post_init__(self) -> None:
        vals = [self.fx, self.fy, self.cx, self.cy, self.depth_scale, *self.dist_k1k2p1p2k3]
        if not all(math.isfinite(v) for v in vals):
            raise CalibrationError(f"intrinsics contain a non-finite value: {vals}")
        if self.fx <= 0 or self.fy <= 0:
            raise CalibrationError(
                f"focal lengths must be positive, got fx={self.fx} fy={self.fy}"
            )
        if self.width <= 0 or self.height <= 0:
            raise CalibrationError(f"image size must be positive, got {self.width}x{self.height}")
        if len(self.dist_k1k2p1p2k3) != 5:
            raise CalibrationError(
                f"distortion needs 5 values (k1,k2,p1,p2,k3), got {len(self.dist_k1k2p1p2k3)}"
            )
        if self.depth_scale <= 0:
            raise CalibrationError(f"depth_scale must be positive, got {self.depth_scale}")
        if not (math.isfinite(self.rolling_shutter_s) and 0.0 <= self.rolling_shutter_s < 1.0):
            raise CalibrationError(
                f"rolling_shutter_s must be in [0, 1) s, got {self.rolling_shutter_s}")

    @property
    def K(self) -> F64:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def dist(self) -> F64:
        return np.asarray(self.dist_k1k2p1p2k3, dtype=np.float64)

    @property
    def has_distortion(self) -> bool:
        return any(v != 0.0 for v in self.dist_k1k2p1p2k3)

    @property
    def size_wh(self) -> tuple[int, int]:
        return (self.width, self.height)

    def scaled(self, factor: float) -> Intrinsics:
        """Intrinsics of an image resized by ``factor`` (pixel-centre convention)."""
        return Intrinsics(
            fx=self.fx * factor,
            fy=self.fy * factor,
            cx=(self.cx + 0.5) * factor - 0.5,
            cy=(self.cy + 0.5) * factor - 0.5,
            width=round(self.width * factor),
            height=round(self.height * factor),
            dist_k1k2p1p2k3=self.dist_k1k2p1p2k3,
            depth_scale=self.depth_scale,
            rolling_shutter_s=self.rolling_shutter_s,
        )

    def to_json_dict(self) -> dict[str, object]:
        d = asdict(self)
        d["distortion"] = list(d.pop("dist_k1k2p1p2k3"))
        return d


def distort_normalized(xy: F64, dist_k1k2p1p2k3: F64) -> F64:
    """Apply the Caltech model, eq. (3)-(4), to (N, 2) normalised image points."""
    k1, k2, p1, p2, k3 = (float(v) for v in dist_k1k2p1p2k3)
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([x * radial + dx, y * radial + dy], axis=1)


def undistort_normalized(xy_d: F64, dist_k1k2p1p2k3: F64, iterations: int = 20) -> F64:
    """Invert :func:`distort_normalized` by fixed-point iteration (as OpenCV does)."""
    k1, k2, p1, p2, k3 = (float(v) for v in dist_k1k2p1p2k3)
    xd, yd = xy_d[:, 0], xy_d[:, 1]
    x, y = xd.copy(), yd.copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        x = (xd - dx) / radial
        y = (yd - dy) / radial
    return np.stack([x, y], axis=1)


def project(cam: Intrinsics, p_cam: F64) -> F64:
    """Project (N, 3) camera-frame points to (N, 2) pixels, eq. (2). z <= 0 gives NaN."""
    p_cam = np.asarray(p_cam, dtype=np.float64)
    z = p_cam[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = p_cam[:, :2] / z[:, None]
    xy[z <= 0] = np.nan
    if cam.has_distortion:
        xy = distort_normalized(xy, cam.dist)
    return np.stack([cam.fx * xy[:, 0] + cam.cx, cam.fy * xy[:, 1] + cam.cy], axis=1)


def pixels_to_normalized(cam: Intrinsics, uv: F64) -> F64:
    """Undistorted normalised coordinates (x/z, y/z) of (N, 2) pixels."""
    uv = np.asarray(uv, dtype=np.float64)
    xy = np.stack([(uv[:, 0] - cam.cx) / cam.fx, (uv[:, 1] - cam.cy) / cam.fy], axis=1)
    if cam.has_distortion:
        xy = undistort_normalized(xy, cam.dist)
    return xy


def backproject(cam: Intrinsics, uv: F64, depth_m: F64) -> F64:
    """3D camera-frame points of (N, 2) pixels at depths z (metres along the optical axis)."""
    xy = pixels_to_normalized(cam, uv)
    z = np.asarray(depth_m, dtype=np.float64).reshape(-1)
    return np.stack([xy[:, 0] * z, xy[:, 1] * z, z], axis=1)


def backproject_depth_image(cam: Intrinsics, depth_m: NDArray[np.floating]) -> F64:
    """(H, W, 3) camera-frame points of a depth image; invalid depth (0/NaN) gives NaN."""
    h, w = depth_m.shape
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    z = depth_m.astype(np.float64).ravel()
    z = np.where(z > 0, z, np.nan)
    return backproject(cam, uv, z).reshape(h, w, 3)


#: accepted ranges of camera.json values (far beyond real cameras, far inside float range)
FOCAL_MAX_PX = 1e7
SIZE_MAX_PX = 100_000
DIST_MAX = 1e4
DEPTH_SCALE_MAX = 1e9


def intrinsics_from_json(
    raw: object, where: str, error: type[Exception] = CalibrationError
) -> Intrinsics:
    """Intrinsics from a ``camera.json``-style object (also embedded in keyframe stores and
    sessions); every value goes through :func:`engine.validate.number`, so a non-number,
    ``nan``, ``1e400``, a 400-digit integer, ``fx: 1e308`` or ``width: 160.5`` raises
    ``error`` with one line naming ``where`` and the key."""
    from engine.validate import number

    if not isinstance(raw, dict):
        raise error(f"{where}: expected a JSON object, got {type(raw).__name__}")
    missing = [k for k in ("fx", "fy", "cx", "cy", "width", "height") if k not in raw]
    if missing:
        raise error(f"{where}: missing key(s) {', '.join(missing)}")
    dist = raw.get("distortion", [0.0] * 5)
    if not isinstance(dist, list) or len(dist) != 5:
        raise error(f"{where}: 'distortion' must be a list of 5 numbers")

    def num(key: str, lo: float | None = None, hi: float | None = None,
            gt: float | None = None) -> float:
        return number(raw[key], f"{where}: '{key}'", lo=lo, hi=hi, gt=gt, error=error)

    def size(key: str) -> int:
        return number(raw[key], f"{where}: '{key}'", integer=True, lo=1, hi=SIZE_MAX_PX,
                      error=error)

    fx, fy = num("fx", gt=0, hi=FOCAL_MAX_PX), num("fy", gt=0, hi=FOCAL_MAX_PX)
    cx = num("cx", lo=-FOCAL_MAX_PX, hi=FOCAL_MAX_PX)
    cy = num("cy", lo=-FOCAL_MAX_PX, hi=FOCAL_MAX_PX)
    width, height = size("width"), size("height")
    coeffs = dist5(
        number(v, f"{where}: 'distortion'[{i}]", lo=-DIST_MAX, hi=DIST_MAX, error=error)
        for i, v in enumerate(dist)
    )
    depth_scale = number(raw.get("depth_scale", 5000.0), f"{where}: 'depth_scale'", gt=0,
                         hi=DEPTH_SCALE_MAX, error=error)
    readout = number(raw.get("rolling_shutter_s", 0.0), f"{where}: 'rolling_shutter_s'",
                     lo=0.0, hi=0.999, error=error)
    try:
        return Intrinsics(fx=fx, fy=fy, cx=cx, cy=cy, width=width, height=height,
                          dist_k1k2p1p2k3=coeffs, depth_scale=depth_scale,
                          rolling_shutter_s=readout)
    except CalibrationError as exc:
        raise error(f"{where}: {exc}") from None


def load_camera_json(path: str | Path) -> Intrinsics:
    """Read ``camera.json`` (fx, fy, cx, cy, width, height, distortion[5], depth_scale)."""
    path = Path(path)
    from engine.persist import read_json_file

    raw = read_json_file(path, CalibrationError, missing="file not found")
    return intrinsics_from_json(raw, str(path))


def save_camera_json(cam: Intrinsics, path: str | Path) -> None:
    """Write ``camera.json`` atomically."""
    from engine.persist import atomic_write_text

    atomic_write_text(Path(path), json.dumps(cam.to_json_dict(), indent=2) + "\n")


#: readout time of the Kinect v1's colour (and depth) sensor, first row to last. Not
#: published; calibrated without ground truth as the readout whose rolling-shutter model
#: (engine.dense) leaves the smallest photometric residual: the mean weighted RMS residual
#: of ``dense`` over TUM fr1_xyz (36 frames) on a 2.5 ms grid: 0 ms 9.00, 10 ms 7.39, 15
#: ms 6.86, 20 ms 6.55, 22.5 ms 6.50, 25 ms 6.54, 27.5 ms 6.64, 30 ms 6.81 grey levels
#: (two thirds of the 33 ms frame, as rolling-shutter VGA sensors at 30 Hz scan)
KINECT_V1_READOUT_S = 0.0225

# TUM RGB-D default calibrations (https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats)
# fr1 and fr2 were recorded with Kinect v1s (the rolling-shutter readout above); fr3 with an
# Asus Xtion, whose readout is not calibrated here (0: no rolling-shutter model)
TUM_DEFAULTS: dict[str, Intrinsics] = {
    "freiburg1": Intrinsics(
        517.3, 516.5, 318.6, 255.3, 640, 480, (0.2624, -0.9531, -0.0054, 0.0026, 1.1633), 5000.0,
        KINECT_V1_READOUT_S,
    ),
    "freiburg2": Intrinsics(
        520.9, 521.0, 325.1, 249.7, 640, 480, (0.2312, -0.7849, -0.0033, -0.0001, 0.9172), 5000.0,
        KINECT_V1_READOUT_S,
    ),
    "freiburg3": Intrinsics(535.4, 539.2, 320.1, 247.6, 640, 480, (0.0,) * 5, 5000.0),
}


def tum_default_for(folder_name: str) -> Intrinsics | None:
    """TUM default intrinsics from a folder name containing fr1/fr2/fr3 or freiburgN."""
    name = folder_name.lower()
    for n in ("1", "2", "3"):
        if f"freiburg{n}" in name or f"fr{n}" in name:
            return TUM_DEFAULTS[f"freiburg{n}"]
    return None
