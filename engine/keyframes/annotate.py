"""Semi-automatic annotation for bundle adjustment (Tykkälä 2014 sec. 6.1, Fig. 11).

The operator clicks a physical point in one keyframe; from that keyframe's depth and the
current poses the point is predicted in the other keyframes (back-project with the inverse
Caltech model, transform, project with eq. (2)-(4)) and snapped there by local patch
matching: normalised cross-correlation of a patch around the click, searched around the
prediction, with a parabola fit through the correlation peak for sub-pixel position.
The operator then only confirms or corrects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypedDict, Unpack

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics, backproject, project
from engine.geometry import invert
from engine.keyframes.depth_sample import depth_at
from engine.keyframes.store import Keyframe

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Prediction:
    """Where a clicked point should appear in another keyframe."""

    uv: tuple[float, float] | None  # None: not visible there
    X_world: tuple[float, float, float] | None
    reason: str = ""  # why not visible ("" when visible)


@dataclass(frozen=True, slots=True)
class Snap:
    uv: tuple[float, float]
    score: float  # NCC peak in [-1, 1]
    moved_px: float  # distance from the prediction
    ok: bool  # score >= min_score and the peak is not on the search border


def point_from_click(
    intr: Intrinsics,
    T_world_cam: F64,
    depth_m: NDArray[np.floating],
    uv: tuple[float, float],
    radius: int = 2,
) -> F64 | None:
    """World point under pixel ``uv`` of a keyframe (median depth in a small window)."""
    z = depth_at(depth_m, uv[0], uv[1], radius)
    if not math.isfinite(z):
        return None
    p_cam = backproject(intr, np.array([uv], dtype=np.float64), np.array([z]))[0]
    return np.asarray(T_world_cam[:3, :3] @ p_cam + T_world_cam[:3, 3])


def predict(
    intr: Intrinsics,
    X_world: F64 | None,
    T_world_dst: F64,
    depth_dst: NDArray[np.floating] | None = None,
    occlusion_rel: float = 0.1,
) -> Prediction:
    """Project a world point into a keyframe; flags points behind, outside or occluded."""
    if X_world is None:
        return Prediction(None, None, "no depth at the clicked pixel")
    X = (float(X_world[0]), float(X_world[1]), float(X_world[2]))
    T_cw = invert(T_world_dst)
    p = T_cw[:3, :3] @ np.asarray(X_world) + T_cw[:3, 3]
    if p[2] <= 0.05:
        return Prediction(None, X, "behind the camera")
    uv = project(intr, p[None])[0]
    if not (0 <= uv[0] <= intr.width - 1 and 0 <= uv[1] <= intr.height - 1):
        return Prediction(None, X, "outside the image")
    if depth_dst is not None:
        z = depth_at(depth_dst, float(uv[0]), float(uv[1]), 1)
        if math.isfinite(z) and z < p[2] * (1.0 - occlusion_rel):
            return Prediction(None, X, f"occluded (surface at {z:.2f} m before {p[2]:.2f} m)")
    return Prediction((float(uv[0]), float(uv[1])), X)


def _parabola_offset(m: float, left: float, right: float) -> float:
    """Vertex of the parabola through (-1, left), (0, m), (1, right), clamped to +-0.5."""
    den = left - 2.0 * m + right
    if den >= 0.0:  # not a maximum
        return 0.0
    return float(np.clip(0.5 * (left - right) / den, -0.5, 0.5))


def local_affine(
    intr: Intrinsics,
    T_world_src: F64,
    depth_src: NDArray[np.floating],
    uv_src: tuple[float, float],
    T_world_dst: F64,
    radius: int = 7,
) -> F64 | None:
    """2x2 map of small pixel offsets around ``uv_src`` to offsets in the destination view.

    The patch pixels are back-projected with the source depth (those within 10 % of the
    centre depth: one surface) and projected into the destination; the least-squares affine
    fit captures the perspective and scale change of a wide baseline."""
    z0 = depth_at(depth_src, uv_src[0], uv_src[1], 2)
    if not math.isfinite(z0):
        return None
    h, w = depth_src.shape
    u0, v0 = round(uv_src[0]), round(uv_src[1])
    du, dv = np.meshgrid(np.arange(-radius, radius + 1), np.arange(-radius, radius + 1))
    uu, vv = (u0 + du).ravel(), (v0 + dv).ravel()
    ok = (uu >= 0) & (uu < w) & (vv >= 0) & (vv < h)
    uu, vv, du, dv = uu[ok], vv[ok], du.ravel()[ok], dv.ravel()[ok]
    z = np.asarray(depth_src, dtype=np.float64)[vv, uu]
    same = np.isfinite(z) & (np.abs(z - z0) < 0.1 * z0)
    if same.sum() < 6:
        return None
    p = backproject(intr, np.column_stack([uu[same], vv[same]]).astype(np.float64), z[same])
    T = invert(T_world_dst) @ T_world_src
    q = p @ T[:3, :3].T + T[:3, 3]
    if np.any(q[:, 2] <= 0.05):
        return None
    uv_d = project(intr, q)
    src_off = np.column_stack([du[same], dv[same], np.ones(same.sum())]).astype(np.float64)
    sol, *_ = np.linalg.lstsq(src_off, uv_d, rcond=None)
    A = sol[:2].T  # dst offset = A @ src offset
    if not np.all(np.isfinite(A)) or abs(np.linalg.det(A)) < 0.1:
        return None
    return np.asarray(A)


def snap(
    gray_src: NDArray[np.uint8],
    uv_src: tuple[float, float],
    gray_dst: NDArray[np.uint8],
    uv_pred: tuple[float, float],
    *,
    A: F64 | None = None,
    patch_radius: int = 7,
    search_radius: int = 12,
    min_score: float = 0.95,
) -> Snap:
    """Refine ``uv_pred`` to the best NCC match of the patch around ``uv_src``, sub-pixel.

    With ``A`` (see :func:`local_affine`) the destination is resampled into the source
    patch's frame first, so that perspective and scale changes do not spoil the match.

    ``min_score``: the snap error grows fast as the NCC peak drops (built-in studio, 2 px
    click error: median 0.05 px at scores >= 0.99, 0.1 px at 0.95-0.98, 0.17 px at 0.9-0.95,
    0.7 px at 0.8-0.9), and SBA turns 0.1 px into centimetres on distant points, so only
    clear matches are suggested; the operator clicks the others."""
    import cv2

    ps = 2 * patch_radius + 1
    half = patch_radius + search_radius
    ss = 2 * half + 1
    src = np.asarray(gray_src, dtype=np.float32)
    dst = np.asarray(gray_dst, dtype=np.float32)
    tmpl = cv2.getRectSubPix(src, (ps, ps), (float(uv_src[0]), float(uv_src[1])))
    M = np.eye(2) if A is None else np.asarray(A, dtype=np.float64)
    # region(i, j) = dst(uv_pred + M @ (j - half, i - half))
    aff = np.array(
        [
            [M[0, 0], M[0, 1], uv_pred[0] - half * (M[0, 0] + M[0, 1])],
            [M[1, 0], M[1, 1], uv_pred[1] - half * (M[1, 0] + M[1, 1])],
        ],
        np.float64,
    )
    region = cv2.warpAffine(
        dst,
        aff,
        (ss, ss),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_REPLICATE,
    )
    if float(tmpl.std()) < 1e-3:
        return Snap((float(uv_pred[0]), float(uv_pred[1])), 0.0, 0.0, False)
    ncc = cv2.matchTemplate(region, tmpl, cv2.TM_CCOEFF_NORMED)
    _, score, _, (ix, iy) = cv2.minMaxLoc(ncc)
    n = ncc.shape[0]
    dx = dy = 0.0
    on_border = ix in (0, n - 1) or iy in (0, n - 1)
    if 0 < ix < n - 1:
        dx = _parabola_offset(ncc[iy, ix], ncc[iy, ix - 1], ncc[iy, ix + 1])
    if 0 < iy < n - 1:
        dy = _parabola_offset(ncc[iy, ix], ncc[iy - 1, ix], ncc[iy + 1, ix])
    off = M @ np.array([ix + dx - search_radius, iy + dy - search_radius])
    uv = (float(uv_pred[0] + off[0]), float(uv_pred[1] + off[1]))
    return Snap(
        uv,
        float(score),
        float(math.hypot(off[0], off[1])),
        bool(score >= min_score and not on_border),
    )


class SnapOptions(TypedDict, total=False):
    """The keyword options of :func:`snap` (patch and search sizes, acceptance score)."""

    patch_radius: int
    search_radius: int
    min_score: float


def predict_and_snap(
    intr: Intrinsics,
    src: Keyframe,
    uv_src: tuple[float, float],
    dst: Keyframe,
    **snap_kw: Unpack[SnapOptions],
) -> tuple[Prediction, Snap | None]:
    """Predict a click on keyframe ``src`` in keyframe ``dst`` and snap it."""
    X = point_from_click(intr, src.T_world_cam, src.depth_m, uv_src)
    pred = predict(intr, X, dst.T_world_cam, dst.depth_m)
    if pred.uv is None:
        return pred, None
    A = local_affine(intr, src.T_world_cam, src.depth_m, uv_src, dst.T_world_cam)
    s = snap(src.gray, uv_src, dst.gray, pred.uv, A=A, **snap_kw)
    return pred, s
