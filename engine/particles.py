"""Particle-filter helpers shared by the presenter (VR-TV) and beacon (Yang 2007) filters."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def systematic_resample(weights: F64, n_out: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """Indices of ``n_out`` particles drawn by systematic (low-variance) resampling.

    One uniform offset u ~ U[0, 1) and the comb (u + k) / n_out, k = 0..n_out-1, through the
    cumulative normalised weights: particle i is drawn n_out * w_i times on average (exactly
    the floor or the ceiling of it), so heavy particles are duplicated and light ones dropped
    (Yang 2007 sec. III.B; the VR-TV paper's deterministic resampling, its ref. [10]). Weights
    need not sum to 1; if they are all zero or not finite the draw is uniform. Draws exactly
    one ``rng.random()``. ``n_out`` may differ from ``len(weights)`` (a count change).
    """
    w = np.asarray(weights, dtype=np.float64)
    total = w.sum()
    w = np.full(len(w), 1.0 / len(w)) if not np.isfinite(total) or total <= 0 else w / total
    cdf = np.cumsum(w)
    cdf[-1] = 1.0
    comb = (rng.random() + np.arange(n_out)) / n_out
    return np.searchsorted(cdf, comb, side="right").astype(np.intp)


def effective_sample_size(weights: F64) -> float:
    """1 / sum w_i^2 of normalised weights (M for uniform weights, 1 for a single particle)."""
    return float(1.0 / np.sum(np.asarray(weights, dtype=np.float64) ** 2))
