"""Compiled nearest-keyframe search of Tykkälä 2014 sec. 6.2 (eq. (19)-(21)), per frame.

:meth:`engine.keyframes.store.KeyframeStore.nearest_with_metric` runs once per tracked frame;
in numpy it is some thirty small-array operations (0.1-0.4 ms, most of it call overhead), here
one loop over the keyframes (microseconds). Imported lazily (numba), ``cache=True``; every
argument has one fixed type (float64 C-contiguous arrays, floats): one specialisation.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _metric_one(Tk: np.ndarray, k: int, T: np.ndarray, pts: np.ndarray, uv: np.ndarray,
                cam: np.ndarray, far_px: float) -> float:
    """Eq. (21) for keyframe ``k``: mean pixel discrepancy of the test points under
    dT_k = T_kf_cam = T_kf_world T_world_cam (points behind the camera count ``far_px``)."""
    fx, fy, cx, cy = cam[0], cam[1], cam[2], cam[3]
    # R_kc = R_k^T R, t_kc = R_k^T (t - t_k), eq. (19)
    R = np.empty((3, 3))
    t = np.empty(3)
    for a in range(3):
        for b in range(3):
            R[a, b] = Tk[k, 0, a] * T[0, b] + Tk[k, 1, a] * T[1, b] + Tk[k, 2, a] * T[2, b]
        t[a] = (Tk[k, 0, a] * (T[0, 3] - Tk[k, 0, 3]) + Tk[k, 1, a] * (T[1, 3] - Tk[k, 1, 3])
                + Tk[k, 2, a] * (T[2, 3] - Tk[k, 2, 3]))
    s = 0.0
    n: int = pts.shape[0]
    for i in range(n):
        px, py, pz = pts[i, 0], pts[i, 1], pts[i, 2]
        qx = R[0, 0] * px + R[0, 1] * py + R[0, 2] * pz + t[0]
        qy = R[1, 0] * px + R[1, 1] * py + R[1, 2] * pz + t[1]
        qz = R[2, 0] * px + R[2, 1] * py + R[2, 2] * pz + t[2]
        if qz <= 0.05:
            s += far_px
            continue
        z = max(qz, 1e-6)
        du = fx * qx / z + cx - uv[i, 0]
        dv = fy * qy / z + cy - uv[i, 1]
        s += math.sqrt(du * du + dv * dv)
    return s / n


@njit(cache=True, nogil=True)
def nearest(Tk: np.ndarray, T: np.ndarray, pts: np.ndarray, uv: np.ndarray, cam: np.ndarray,
            far_px: float, theta_max_rad: float, d_max_m: float) -> tuple[int, bool, float]:
    """(index, in_omega, metric) of the nearest keyframe of the stack ``Tk`` (K, 4, 4) to the
    pose ``T``: the smallest eq. (21) metric over the pre-selected set Omega of eq. (20)
    (angle and distance), or over every keyframe when Omega is empty."""
    K = Tk.shape[0]
    omega = np.zeros(K, dtype=np.bool_)
    any_omega = False
    for k in range(K):
        tr = 0.0
        for a in range(3):
            tr += Tk[k, 0, a] * T[0, a] + Tk[k, 1, a] * T[1, a] + Tk[k, 2, a] * T[2, a]
        theta = math.acos(min(max((tr - 1.0) * 0.5, -1.0), 1.0))
        dx = T[0, 3] - Tk[k, 0, 3]
        dy = T[1, 3] - Tk[k, 1, 3]
        dz = T[2, 3] - Tk[k, 2, 3]
        if abs(theta) < theta_max_rad and math.sqrt(dx * dx + dy * dy + dz * dz) < d_max_m:
            omega[k] = True
            any_omega = True
    best = -1
    best_m = np.inf
    for k in range(K):
        if any_omega and not omega[k]:
            continue
        m = _metric_one(Tk, k, T, pts, uv, cam, far_px)
        if m < best_m or best < 0:
            best, best_m = k, m
    return best, any_omega, best_m


@njit(cache=True, nogil=True)
def metric(Tk: np.ndarray, T: np.ndarray, pts: np.ndarray, uv: np.ndarray, cam: np.ndarray,
           far_px: float) -> float:
    """Eq. (21) between the pose ``T`` and the single keyframe pose ``Tk`` (1, 4, 4)."""
    return _metric_one(Tk, 0, T, pts, uv, cam, far_px)
