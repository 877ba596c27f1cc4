"""numba kernels of the depth fusion (:mod:`engine.keyframes.fusion`), imported when fusion runs so
that start-up stays fast. ``cache=True`` keeps the compiled code between runs."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from engine.arrays import F32, F64, I32, U8


@njit(cache=True, nogil=True)
def warp_into_keyframe(
    buf: F32,
    cnt: I32,
    depth: F32,
    gray: U8,
    kf_gray: U8,
    rays_xy: F64,
    T: F64,
    intr: F64,
    dist: F64,
    has_dist: bool,
    stride: int,
    zmin: float,
    zmax: float,
    tol: int,
) -> int:
    """Warp one frame's depth into a keyframe and append inverse depths per keyframe pixel.

    ``T`` = T_kf_cam (4x4); ``intr`` = (fx, fy, cx, cy); ``rays_xy`` (H, W, 2) undistorted
    normalised rays of the frame pixels. Projection is eq. (2)-(4); a sample is kept only
    when the grey values agree within ``tol`` (colour-deviation outlier rejection, sec. 6.1).
    Returns the number of samples added.
    """
    H, W = depth.shape
    cap = buf.shape[1]
    fx, fy, cx, cy = intr[0], intr[1], intr[2], intr[3]
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    added = 0
    for v in range(0, H, stride):
        for u in range(0, W, stride):
            z = depth[v, u]
            if not (z > zmin and z < zmax):
                continue
            x = rays_xy[v, u, 0] * z
            y = rays_xy[v, u, 1] * z
            qx = T[0, 0] * x + T[0, 1] * y + T[0, 2] * z + T[0, 3]
            qy = T[1, 0] * x + T[1, 1] * y + T[1, 2] * z + T[1, 3]
            qz = T[2, 0] * x + T[2, 1] * y + T[2, 2] * z + T[2, 3]
            if qz <= zmin:
                continue
            a = qx / qz
            b = qy / qz
            if has_dist:
                r2 = a * a + b * b
                rad = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
                da = 2.0 * p1 * a * b + p2 * (r2 + 2.0 * a * a)
                db = p1 * (r2 + 2.0 * b * b) + 2.0 * p2 * a * b
                a = a * rad + da
                b = b * rad + db
            iu = math.floor(fx * a + cx + 0.5)
            iv = math.floor(fy * b + cy + 0.5)
            if iu < 0 or iv < 0 or iu >= W or iv >= H:
                continue
            if abs(int(gray[v, u]) - int(kf_gray[iv, iu])) > tol:
                continue
            p = iv * W + iu
            c = cnt[p]
            if c < cap:
                buf[p, c] = 1.0 / qz
                cnt[p] = c + 1
                added += 1
    return added


@njit(cache=True, nogil=True)
def robust_inverse_depth(
    buf: F32, cnt: I32, delta: float, min_samples: int, out: F32
) -> None:
    """Per pixel: median m of the inverse depths, mean of the samples within m +- delta
    (Fig. 10); ``out`` keeps 0 where fewer than ``min_samples`` samples are in the window."""
    n = cnt.shape[0]
    for p in range(n):
        c = cnt[p]
        if c == 0:
            continue
        s = np.sort(buf[p, :c])
        m = 0.5 * (s[(c - 1) // 2] + s[c // 2])
        acc = 0.0
        k = 0
        for i in range(c):
            if abs(s[i] - m) <= delta:
                acc += s[i]
                k += 1
        if k >= min_samples:
            out[p] = acc / k
