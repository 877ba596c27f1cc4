"""Map Adjustment, eq. (12): the paper's own step between weighting and resampling.

"For each particle, after applying the motion model and weighting, when the observation is
received, each feature's state is then adjusted so that the difference between the predicted
observation and real observation is smaller"::

    movement = p * (d - d') / r        applied to the vector (f - s), r = |f - s| = d'

i.e. a step of length p (d - d') along the unit vector from camera to beacon (p = 1 puts the
beacon on the measured circle). Extension (``map_adjust_anneal``, beyond the paper): the gain
``max(p, 1 / (k + 1))`` for the k-th reading of a beacon (:func:`annealed_gain`), a running
mean of the range circles that settles as the beacon is seen more. Extension
(``map_adjust_gain = "kalman"``, beyond the paper): each particle's beacon a Gaussian kernel
updated by a Kalman step (:func:`kalman_map_adjustment`), its gain set by the kernel's width.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def map_adjustment(
    cam_xy: F64, beacons_xy: F64, measured_m: F64, p: float | F64
) -> F64:
    """Eq. (12): move each beacon estimate along the camera->beacon line by p (d - d').

    ``cam_xy`` (M, 2), ``beacons_xy`` (M, k, 2), ``measured_m`` (k,) -> adjusted (M, k, 2).
    movement = p (d - d') / r applied to (f - s), with r = d' = |f - s|.
    """
    diff = beacons_xy - cam_xy[:, None, :]
    r = np.hypot(diff[..., 0], diff[..., 1])
    scale = np.asarray(p) * (measured_m[None, :] - r) / np.maximum(r, 1e-9)
    return beacons_xy + scale[:, :, None] * diff


def annealed_gain(p: float, n_reads: F64) -> F64:
    """``max(p, 1 / (k + 1))`` per beacon with k = ``n_reads`` readings used so far."""
    return np.maximum(p, 1.0 / (n_reads + 1.0))


def kalman_map_adjustment(
    cam_xy: F64, beacons_xy: F64, beacons_cov: F64, measured_m: F64, range_sigma_m: float,
) -> tuple[F64, F64]:
    """Eq. (12) with a Kalman gain per particle and beacon (FastSLAM-style, Montemerlo 2002).

    Each particle's beacon is a Gaussian kernel N(f, P) instead of a point. The range of
    eq. (8), linearised along the line of sight ``u`` (``h = u^T``), updates it::

        s = u^T P u + sigma_r^2,   K = P u / s,   f <- f + K (d - d'),   P <- P - K u^T P

    Eq. (12)'s ``p (d - d') u`` is this step for ``P`` isotropic (``p = u^T P u / s``): the
    gain is large while the kernel is wide and falls as the beacon is measured from
    different places, by the information each reading carries. ``cam_xy`` (M, 2),
    ``beacons_xy`` (M, k, 2), ``beacons_cov`` (M, k, 2, 2), ``measured_m`` (k,) -> adjusted
    beacons and covariances (new arrays).
    """
    f = np.array(beacons_xy, dtype=np.float64)
    cov = np.array(beacons_cov, dtype=np.float64)
    _kalman_update(np.ascontiguousarray(cam_xy, dtype=np.float64), f, cov,
                   np.ascontiguousarray(measured_m, dtype=np.float64), float(range_sigma_m))
    return f, cov


def kernel_range_sigma(cam_xy: F64, beacons_xy: F64, beacons_cov: F64,
                       range_sigma_m: float) -> F64:
    """Std of d - d' with each particle's beacon kernel integrated out, eq. (10):
    ``sqrt(u^T P u + sigma_r^2)`` per particle and beacon, (M, k)."""
    out = np.empty(beacons_xy.shape[:2])
    _kernel_sigma(np.ascontiguousarray(cam_xy, dtype=np.float64),
                  np.ascontiguousarray(beacons_xy, dtype=np.float64),
                  np.ascontiguousarray(beacons_cov, dtype=np.float64), float(range_sigma_m),
                  out)
    return out


@njit(cache=True, nogil=True, inline="always")
def _line_of_sight(cam: F64, f: F64, m: int, k: int) -> tuple[float, float, float]:
    """Range and unit vector from particle ``m``'s camera to its beacon ``k``."""
    dx = f[m, k, 0] - cam[m, 0]
    dy = f[m, k, 1] - cam[m, 1]
    r = math.hypot(dx, dy)
    rr = max(r, 1e-9)
    return r, dx / rr, dy / rr


@njit(cache=True, nogil=True)
def _kalman_update(cam: F64, f: F64, cov: F64, measured: F64, sigma: float) -> None:
    var_r = sigma * sigma
    for m in range(f.shape[0]):
        for k in range(f.shape[1]):
            r, ux, uy = _line_of_sight(cam, f, m, k)
            a = cov[m, k, 0, 0]
            b = 0.5 * (cov[m, k, 0, 1] + cov[m, k, 1, 0])
            c = cov[m, k, 1, 1]
            pux = a * ux + b * uy
            puy = b * ux + c * uy
            s = ux * pux + uy * puy + var_r
            kx = pux / s
            ky = puy / s
            innov = measured[k] - r
            f[m, k, 0] += kx * innov
            f[m, k, 1] += ky * innov
            cov[m, k, 0, 0] = a - kx * pux
            off = b - 0.5 * (kx * puy + ky * pux)
            cov[m, k, 0, 1] = off
            cov[m, k, 1, 0] = off
            cov[m, k, 1, 1] = c - ky * puy


@njit(cache=True, nogil=True)
def _kernel_sigma(cam: F64, f: F64, cov: F64, sigma: float, out: F64) -> None:
    var_r = sigma * sigma
    for m in range(f.shape[0]):
        for k in range(f.shape[1]):
            _, ux, uy = _line_of_sight(cam, f, m, k)
            v = (ux * ux * cov[m, k, 0, 0] + ux * uy * (cov[m, k, 0, 1] + cov[m, k, 1, 0])
                 + uy * uy * cov[m, k, 1, 1])
            out[m, k] = math.sqrt(var_r + max(v, 0.0))
