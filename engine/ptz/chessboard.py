"""OpenCV chessboard calibration (Zhang's method), a convenience beside the paper's DLT."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics
from engine.errors import CalibrationError

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class ChessboardResult:
    intrinsics: Intrinsics
    rms_px: float
    per_view_rms_px: tuple[float, ...]
    used_images: tuple[str, ...]
    skipped_images: tuple[str, ...]

    def to_json_dict(self) -> dict[str, object]:
        c = self.intrinsics
        return {
            "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy,
            "width": c.width, "height": c.height,
            "k1": c.dist_k1k2p1p2k3[0], "k2": c.dist_k1k2p1p2k3[1],
            "p1": c.dist_k1k2p1p2k3[2], "p2": c.dist_k1k2p1p2k3[3],
            "k3": c.dist_k1k2p1p2k3[4],
            "rms_px": self.rms_px,
            "per_view_rms_px": list(self.per_view_rms_px),
            "n_used": len(self.used_images),
            "skipped": list(self.skipped_images),
        }


def parse_pattern(text: str) -> tuple[int, int]:
    """``"9x6"`` -> (9, 6) inner corners (columns, rows)."""
    try:
        a, b = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise CalibrationError(
            f"pattern {text!r}: expected COLSxROWS inner corners, e.g. 9x6"
        ) from None
    if a < 2 or b < 2:
        raise CalibrationError(f"pattern {text!r}: needs at least 2x2 inner corners")
    return a, b


def calibrate_chessboard(
    images: Sequence[str | Path],
    pattern_cols_rows: tuple[int, int] = (9, 6),
    square_m: float = 0.025,
    fix_aspect_ratio: bool = False,
) -> ChessboardResult:
    """Find corners (sub-pixel) in every image and run cv2.calibrateCamera.

    ``fix_aspect_ratio`` reproduces OpenCV's sample flag (CALIB_FIX_ASPECT_RATIO, the flag
    stored in ``left_intrinsics.yml``).
    """
    import cv2

    if square_m <= 0:
        raise CalibrationError(f"square size must be positive, got {square_m}")
    cols, rows = pattern_cols_rows
    obj = np.zeros((rows * cols, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square_m
    obj_pts, img_pts, used, skipped = [], [], [], []
    size: tuple[int, int] | None = None
    for p in images:
        path = Path(p)
        gray = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if gray is None:
            raise CalibrationError(f"{path}: cannot read image")
        if size is None:
            size = (gray.shape[1], gray.shape[0])
        elif size != (gray.shape[1], gray.shape[0]):
            raise CalibrationError(f"{path}: size {gray.shape[1]}x{gray.shape[0]} != {size}")
        ok, corners = cv2.findChessboardCorners(
            gray, (cols, rows), cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        )
        if not ok:
            skipped.append(str(path))
            continue
        corners = cv2.cornerSubPix(
            gray, corners, (11, 11), (-1, -1),
            (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 1e-3),
        )
        obj_pts.append(obj)
        img_pts.append(corners)
        used.append(str(path))
    if len(used) < 3 or size is None:
        raise CalibrationError(
            f"chessboard {cols}x{rows} found in {len(used)} of {len(images)} image(s); need >= 3"
        )
    flags = cv2.CALIB_FIX_ASPECT_RATIO if fix_aspect_ratio else 0
    K0 = np.eye(3)
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj_pts, img_pts, size, K0, None,
                                                     flags=flags)
    per_view = []
    for o, m, rv, tv in zip(obj_pts, img_pts, rvecs, tvecs, strict=True):
        proj, _ = cv2.projectPoints(o, rv, tv, K, dist)
        diff = proj.reshape(-1, 2) - m.reshape(-1, 2)
        per_view.append(float(np.sqrt(np.mean(np.sum(diff**2, axis=1)))))
    d = np.asarray(dist, dtype=np.float64).ravel()[:5]
    cam = Intrinsics(
        fx=float(K[0, 0]), fy=float(K[1, 1]), cx=float(K[0, 2]), cy=float(K[1, 2]),
        width=size[0], height=size[1],
        dist_k1k2p1p2k3=tuple(float(v) for v in d),  # type: ignore[arg-type]
    )
    return ChessboardResult(cam, float(rms), tuple(per_view), tuple(used), tuple(skipped))


def read_opencv_yaml_intrinsics(path: str | Path) -> dict[str, object]:
    """camera_matrix, distortion_coefficients and avg_reprojection_error of an OpenCV YAML."""
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    if not fs.isOpened():
        raise CalibrationError(f"{path}: cannot open OpenCV YAML")
    try:
        K = fs.getNode("camera_matrix").mat()
        dist = fs.getNode("distortion_coefficients").mat()
        err = fs.getNode("avg_reprojection_error").real()
    finally:
        fs.release()
    if K is None or dist is None:
        raise CalibrationError(f"{path}: no camera_matrix/distortion_coefficients")
    return {"K": np.asarray(K, float), "dist": np.asarray(dist, float).ravel(), "rms_px": err}
