"""Reading a keyframe depth map at an annotated pixel (for annotation and SBA, sec. 6.1).

Depth maps are metres with 0 (or NaN) where invalid. Both readers refuse a depth edge, where
the pixel may belong to either surface.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray


def depth_at(
    depth_m: NDArray[np.floating],
    u: float,
    v: float,
    radius: int = 1,
    max_rel_spread: float = math.inf,
) -> float:
    """Median valid depth in a (2r+1)^2 window around the nearest pixel; NaN if none, or if
    the window's depths spread more than ``max_rel_spread`` x median (a depth edge, where
    the pixel may belong to either surface)."""
    h, w = depth_m.shape
    iu, iv = round(u), round(v)
    if not (0 <= iu < w and 0 <= iv < h):
        return math.nan
    win = depth_m[max(0, iv - radius) : iv + radius + 1, max(0, iu - radius) : iu + radius + 1]
    vals = win[np.isfinite(win) & (win > 0)]
    if not vals.size:
        return math.nan
    med = float(np.median(vals))
    if float(vals.max() - vals.min()) > max_rel_spread * med:
        return math.nan
    return med


def depth_plane(
    depth_m: NDArray[np.floating],
    u: float,
    v: float,
    radius: int = 2,
    max_rel_spread: float = math.inf,
) -> tuple[float, float]:
    """Depth at the sub-pixel position (u, v) and its local noise: a plane
    ``z = a + b (u' - u) + c (v' - v)`` fitted to the valid depths of the (2r+1)^2 window
    around the nearest pixel, evaluated at (u, v); the noise is the fit's RMS residual.

    Unlike :func:`depth_at` (the window median at the nearest pixel) this has no bias of up to
    half a pixel times the depth gradient on slanted surfaces (floors and walls seen at a
    grazing angle), which at studio distances is centimetres. (NaN, NaN) where the window has
    fewer than 6 valid depths or spreads more than ``max_rel_spread`` x median (a depth
    edge)."""
    h, w = depth_m.shape
    iu, iv = round(u), round(v)
    if not (0 <= iu < w and 0 <= iv < h):
        return math.nan, math.nan
    u0, u1 = max(0, iu - radius), min(w, iu + radius + 1)
    v0, v1 = max(0, iv - radius), min(h, iv + radius + 1)
    win = np.asarray(depth_m[v0:v1, u0:u1], dtype=np.float64)
    vv, uu = np.mgrid[v0:v1, u0:u1]
    ok = np.isfinite(win) & (win > 0)
    if ok.sum() < 6:
        return math.nan, math.nan
    z = win[ok]
    med = float(np.median(z))
    if float(z.max() - z.min()) > max_rel_spread * med:
        return math.nan, math.nan
    A = np.column_stack([np.ones(z.size), uu[ok] - u, vv[ok] - v])
    coef, *_ = np.linalg.lstsq(A, z, rcond=None)
    res = z - A @ coef
    dof = max(1, z.size - 3)
    return float(coef[0]), float(math.sqrt(float(res @ res) / dof))
