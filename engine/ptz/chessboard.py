"""OpenCV chessboard calibration (Zhang's method), a convenience beside the paper's DLT."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypedDict

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics, dist5
from engine.errors import CalibrationError

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class ChessboardResult:
    intrinsics: Intrinsics
    rms_px: float
    per_view_rms_px: tuple[float, ...]
    used_images: tuple[str, ...]
    skipped_images: tuple[str, ...]
    #: why each of ``skipped_images`` was left out (same order)
    skipped_reasons: tuple[str, ...] = ()

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
            "used_images": list(self.used_images),
            "skipped": list(self.skipped_images),
            "skipped_reasons": list(self.skipped_reasons),
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
    *,
    fix_k3: bool = False,
    zero_tangent: bool = False,
) -> ChessboardResult:
    """Find corners (sub-pixel) in every image and run cv2.calibrateCamera.

    ``fix_aspect_ratio`` reproduces OpenCV's sample flag (CALIB_FIX_ASPECT_RATIO, the flag
    stored in ``left_intrinsics.yml``).
    """
    import math

    if not (math.isfinite(square_m) and square_m > 0):  # before reading any image
        raise CalibrationError(f"square size must be a positive number of metres, got {square_m}")
    grays = [(str(p), read_calibration_image(p)) for p in images]
    return calibrate_chessboard_images(grays, pattern_cols_rows, square_m, fix_aspect_ratio,
                                       fix_k3=fix_k3, zero_tangent=zero_tangent)


def calibrate_chessboard_images(
    grays: Sequence[tuple[str, NDArray[np.uint8]]],
    pattern_cols_rows: tuple[int, int] = (9, 6),
    square_m: float = 0.025,
    fix_aspect_ratio: bool = False,
    *,
    fix_k3: bool = False,
    zero_tangent: bool = False,
) -> ChessboardResult:
    """:func:`calibrate_chessboard` on named grey images in memory (a lens sample from live
    frames or rendered views).

    ``fix_k3`` / ``zero_tangent`` fix k3 and p1, p2 at 0 (OpenCV's CALIB_FIX_K3 and
    CALIB_ZERO_TANGENT_DIST): the lens-file workflow's simpler model, better conditioned at
    long focal lengths where the distortion is small."""
    import math

    import cv2

    if not (math.isfinite(square_m) and square_m > 0):
        raise CalibrationError(f"square size must be a positive number of metres, got {square_m}")
    cols, rows = pattern_cols_rows
    obj = np.zeros((rows * cols, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square_m
    size = _common_size([g.shape[1::-1] for _, g in grays])
    obj_pts, img_pts, used, skipped, reasons = [], [], [], [], []
    min_side = 4 * (max(cols, rows) + 1)
    for path, gray in grays:
        wh = (gray.shape[1], gray.shape[0])
        why = ""
        if wh == size[::-1] and wh != size:
            why = (f"portrait {wh[0]}x{wh[1]} in a {size[0]}x{size[1]} set, and no EXIF "
                   "orientation says which way it was turned")
        elif wh != size:
            why = f"size {wh[0]}x{wh[1]} differs from the set's {size[0]}x{size[1]}"
        elif min(wh) < min_side:
            why = f"{wh[0]}x{wh[1]} px is too small for a {cols}x{rows} chessboard"
        if why:
            skipped.append(path)
            reasons.append(why)
            continue
        try:
            ok, corners = cv2.findChessboardCorners(
                gray, (cols, rows),
                flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE,
            )
        except cv2.error:
            ok = False
        if not ok:
            skipped.append(path)
            reasons.append(f"no {cols}x{rows} chessboard found")
            continue
        corners = cv2.cornerSubPix(
            gray, corners, (11, 11), (-1, -1),
            (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 1e-3),
        )
        obj_pts.append(obj)
        img_pts.append(corners)
        used.append(path)
    if len(used) < 3:
        named = (f"{Path(p).name}: {r}" for p, r in zip(skipped, reasons, strict=True))
        detail = f" (skipped: {'; '.join(named)})"
        raise CalibrationError(
            f"chessboard {cols}x{rows} found in {len(used)} of {len(grays)} image(s); need >= 3"
            + (detail[:400] if skipped else "")
        )
    flags = cv2.CALIB_FIX_ASPECT_RATIO if fix_aspect_ratio else 0
    if fix_k3:
        flags |= cv2.CALIB_FIX_K3
    if zero_tangent:
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
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
        dist_k1k2p1p2k3=dist5(d),
    )
    return ChessboardResult(cam, float(rms), tuple(per_view), tuple(used), tuple(skipped),
                            tuple(reasons))


def read_calibration_image(path: str | Path) -> NDArray[np.uint8]:
    """A calibration photo as 8-bit grey in the sensor's own layout: EXIF orientation is
    ignored (a phone's portrait shot stays as the sensor saw it); a missing, empty, truncated
    or undecodable file raises CalibrationError naming it."""
    import cv2

    from engine.errors import SourceError
    from engine.sources.images import read_image

    try:
        return read_image(path, cv2.IMREAD_GRAYSCALE | cv2.IMREAD_IGNORE_ORIENTATION)
    except SourceError as exc:
        raise CalibrationError(str(exc)) from None


def _common_size(sizes: Sequence[tuple[int, int]]) -> tuple[int, int]:
    """The most common (width, height) of the set, counting a portrait shot as its landscape
    size (so 20 landscape + 3 portrait photos give the landscape size)."""
    from collections import Counter

    if not sizes:
        raise CalibrationError("no calibration images given")
    counts = Counter((max(w, h), min(w, h)) for w, h in sizes)
    land = counts.most_common(1)[0][0]
    exact = Counter((w, h) for w, h in sizes if (w, h) in (land, (land[1], land[0])))
    return max(exact, key=lambda s: (exact[s], s[0] >= s[1]))


class OpenCVIntrinsics(TypedDict):
    """What :func:`read_opencv_yaml_intrinsics` reads."""

    K: F64  # camera matrix (3, 3)
    dist: F64  # distortion coefficients, OpenCV's order
    rms_px: float  # avg_reprojection_error


def read_opencv_yaml_intrinsics(path: str | Path) -> OpenCVIntrinsics:
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
    return {"K": np.asarray(K, dtype=np.float64),
            "dist": np.asarray(dist, dtype=np.float64).ravel(), "rms_px": float(err)}


def lens_sample_from_chessboard(
    grays: Sequence[NDArray[np.uint8]],
    zoom_raw: int,
    focus_raw: int = 0,
    pattern_cols_rows: tuple[int, int] = (9, 6),
    square_m: float = 0.025,
    *,
    entrance_pupil_m: float = 0.0,
    names: Sequence[str] | None = None,
) -> tuple[Any, ChessboardResult]:
    """One lens-file sample (:class:`engine.lens.LensSample`) at the current encoders from
    chessboard views taken there (k1, k2 with k3 and tangential fixed at 0)."""
    from engine.lens import LensSample

    labels = list(names) if names is not None else [f"view {i + 1}" for i in range(len(grays))]
    res = calibrate_chessboard_images(list(zip(labels, grays, strict=True)), pattern_cols_rows,
                                      square_m, fix_k3=True, zero_tangent=True)
    sample = LensSample.from_intrinsics(
        res.intrinsics, zoom_raw, focus_raw, entrance_pupil_m, rms_px=res.rms_px,
        note=f"chessboard {pattern_cols_rows[0]}x{pattern_cols_rows[1]}, "
        f"{len(res.used_images)} views")
    return sample, res
