"""Statistics the benches share: bootstrap confidence intervals over seeds, paired differences.

Benches run each setting on the same seeds, so a difference between two settings is taken per
seed (paired) and its interval comes from resampling the seeds.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

#: bootstrap resamples of the seeds
N_BOOT = 2000


def boot_indices(n: int, n_boot: int = N_BOOT, seed: int = 0) -> NDArray[np.intp]:
    """(n_boot, n) seed indices drawn with replacement (the same draws for every setting
    that shares the seeds keeps the comparison paired)."""
    return np.random.default_rng(seed).integers(0, n, size=(n_boot, n))


def quantile_stat(q: float) -> Callable[[F64], F64]:
    """A statistic over the last axis: the q-th percentile."""

    def stat(x: F64) -> F64:
        return np.asarray(np.percentile(x, q, axis=-1), dtype=np.float64)

    return stat


def mean_stat(x: F64) -> F64:
    return np.asarray(np.mean(x, axis=-1), dtype=np.float64)


def bootstrap_ci(values: Sequence[float] | F64, stat: Callable[[F64], F64] = mean_stat,
                 level: float = 0.95, n_boot: int = N_BOOT, seed: int = 0
                 ) -> tuple[float, float]:
    """Percentile-bootstrap interval of ``stat`` over the seeds' ``values``."""
    v = np.asarray(values, dtype=np.float64)
    if v.size < 2:
        x = float(stat(v)) if v.size else float("nan")
        return (x, x)
    reps = stat(v[boot_indices(v.size, n_boot, seed)])
    a = 100.0 * (1.0 - level) / 2.0
    return (float(np.percentile(reps, a)), float(np.percentile(reps, 100.0 - a)))


def paired_difference(a: Sequence[float] | F64, b: Sequence[float] | F64,
                      level: float = 0.95) -> dict[str, float | list[float]]:
    """Per-seed ``a - b``: its mean, bootstrap interval and the fraction of seeds where
    ``a < b``."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    lo, hi = bootstrap_ci(d, mean_stat, level)
    return {"mean_diff": float(np.mean(d)), "ci95": [lo, hi],
            "fraction_a_lower": float(np.mean(d < 0.0))}


def first_crossing(grid: Sequence[float], curve: Sequence[float] | F64, target: float
                   ) -> float:
    """The smallest x of ``grid`` (ascending) at which ``curve`` reaches ``target`` (<=),
    interpolated in log x between the grid point before and the first one that reaches it;
    ``inf`` if none does."""
    c = np.asarray(curve, dtype=np.float64)
    ok = np.flatnonzero(c <= target)
    if ok.size == 0:
        return float("inf")
    j = int(ok[0])
    if j == 0:
        return float(grid[0])
    x0, x1 = np.log(float(grid[j - 1])), np.log(float(grid[j]))
    y0, y1 = float(c[j - 1]), float(c[j])
    f = (y0 - target) / (y0 - y1) if y0 != y1 else 1.0
    return float(np.exp(x0 + f * (x1 - x0)))
