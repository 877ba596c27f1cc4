"""Particle filter over the 2D model state s = (x, y, h) (VR-TV paper, Sec. III-C.2, 5, 6).

- prediction, eq. (1): s_t = s_{t-1} + v_t, v ~ N(0, diag(sigma_x^2, sigma_y^2, sigma_h^2));
- deterministic (systematic) resampling over the previous weights every frame (the paper's
  ref. [10]; :func:`engine.particles.systematic_resample`, shared with the beacon filter); the
  output particle count may differ from the input (a count change mid-run, or the larger
  diffuse set used while re-acquiring);
- weights from the fused likelihood, eq. (5), normalised to sum 1;
- output: the weighted mean state, eq. (6).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def predict(particles: F64, sigma_xyh: tuple[float, float, float], rng: np.random.Generator,
            h_limits: tuple[float, float]) -> F64:
    """Random-walk prediction, eq. (1); scale kept in ``h_limits``."""
    noise = rng.standard_normal(particles.shape) * np.asarray(sigma_xyh, dtype=np.float64)
    out = particles + noise
    np.clip(out[:, 2], h_limits[0], h_limits[1], out=out[:, 2])
    return out


def normalise(weights: F64) -> F64:
    """w_i / sum_j w_j (eq. 5's normalisation); uniform if every weight vanished."""
    total = float(np.sum(weights))
    if not np.isfinite(total) or total <= 0.0:
        return np.full(len(weights), 1.0 / len(weights))
    return np.asarray(weights, dtype=np.float64) / total


def weighted_mean(particles: F64, weights: F64) -> F64:
    """s_t = sum_i w_i s_i, eq. (6) (weights already normalised)."""
    return np.asarray(weights @ particles, dtype=np.float64)


def mode_mean(particles: F64, weights: F64, bandwidth_xy: tuple[float, float],
              iterations: int = 4) -> F64:
    """The weighted mean of the dominant mode (beyond eq. 6): mean-shift on (x, y) from the
    weighted mean with a Gaussian kernel, then the kernel-weighted mean of (x, y, h).

    With two people in view the particle cloud splits; eq. (6)'s mean lies between them,
    the mode's mean on the one most particles follow (the paper, Sec. III-C.6: "a more robust
    evaluation of the particle average can be considered").
    """
    w = np.asarray(weights, dtype=np.float64)
    centre = np.asarray(w @ particles, dtype=np.float64)
    bx, by = max(bandwidth_xy[0], 1e-6), max(bandwidth_xy[1], 1e-6)
    k = w
    for _ in range(iterations):
        dx = (particles[:, 0] - centre[0]) / bx
        dy = (particles[:, 1] - centre[1]) / by
        k = w * np.exp(-0.5 * (dx * dx + dy * dy))
        s = float(k.sum())
        if not s > 0:
            return np.asarray(w @ particles, dtype=np.float64)
        centre = np.asarray((k / s) @ particles, dtype=np.float64)
    return centre


def gaussian_cloud(mean_xyh: F64, sigma_xyh: tuple[float, float, float], n: int,
                   rng: np.random.Generator) -> F64:
    return np.asarray(mean_xyh, dtype=np.float64) + rng.standard_normal((n, 3)) * np.asarray(
        sigma_xyh, dtype=np.float64)


def diffuse_cloud(image_wh: tuple[int, int], h_range: tuple[float, float], n: int,
                  rng: np.random.Generator) -> F64:
    """The diffuse prior used for (re-)initialisation: uniform over the image and scale range."""
    W, H = image_wh
    out = np.empty((n, 3))
    out[:, 0] = rng.uniform(0.0, W, n)
    out[:, 1] = rng.uniform(0.0, H, n)
    out[:, 2] = rng.uniform(h_range[0], h_range[1], n)
    return out
