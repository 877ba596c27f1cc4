"""Statistics of the particle cloud and the Liu-West kernel move of its beacon states."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def weighted_mean_cov(x: F64, w: F64) -> tuple[F64, F64]:
    """Weighted mean and covariance of samples ``x`` (M, ..., 2) with weights (M,)."""
    m = x.shape[0]
    flat = x.reshape(m, -1, x.shape[-1])  # (M, K, 2)
    mean = w @ flat.reshape(m, -1)
    mean = mean.reshape(flat.shape[1:])
    d = flat - mean
    cov = np.matmul((d * w[:, None, None]).transpose(1, 2, 0), d.transpose(1, 0, 2))
    return mean.reshape(x.shape[1:]), cov.reshape(*x.shape[1:], x.shape[-1])


def liu_west_roughen(x: F64, weights: F64, h: float, rng: np.random.Generator) -> F64:
    """Kernel move of resampled states ``x`` (M, k, 2) (Liu & West 2001 shrinkage).

    Extension (``roughen_h``, beyond the paper):
    ``x <- a x + (1 - a) mean + h N(0, cov)`` with ``a = sqrt(1 - h^2)`` per 2D block: the
    weighted mean and covariance of the cloud are kept, but duplicated particles become
    distinct, so the map keeps exploring instead of collapsing onto a few resampled copies
    (sample impoverishment). The noise scales with the cloud's own spread: it shrinks as the
    map converges.
    """
    mean, cov = weighted_mean_cov(x, weights)  # (k, 2), (k, 2, 2)
    a = math.sqrt(1.0 - h * h)
    L = np.linalg.cholesky(cov + 1e-12 * np.eye(2))  # lower triangular (k, 2, 2)
    z = rng.standard_normal(x.shape)
    # L z per particle and beacon, written out (2 x 2): an einsum over these small axes
    # cost more than the rest of the move
    noise = np.empty_like(z)
    noise[..., 0] = L[None, :, 0, 0] * z[..., 0]
    noise[..., 1] = L[None, :, 1, 0] * z[..., 0] + L[None, :, 1, 1] * z[..., 1]
    return a * x + (1.0 - a) * mean[None] + h * noise
