"""Reference point selection by image-gradient magnitude, sec. 3.4 eq. (14) and sec. 4.5.

The gradient magnitude ``G = |dI/du| + |dI/dv|`` of the level-0 (320x240) reference image is
histogrammed as ``h = histogram(G / 2)`` over 256 bins; the threshold bin ``B_t`` satisfies
eq. (15): ``sum_{k > B_t} h(k) < n <= sum_{k >= B_t} h(k)``. All points above ``B_t``
(P_good) are taken and the rest are drawn from the points in ``B_t`` (P_semi), evenly spread
over the image, so that exactly ``n`` points are selected (fewer only when fewer candidates
exist).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

N_BINS = 256


def gradient_magnitude(img: NDArray[np.float32]) -> NDArray[np.float32]:
    """|dI/du| + |dI/dv| by central differences (0 on the one-pixel border)."""
    g = np.zeros_like(img, dtype=np.float32)
    g[1:-1, 1:-1] = 0.5 * (
        np.abs(img[1:-1, 2:] - img[1:-1, :-2]) + np.abs(img[2:, 1:-1] - img[:-2, 1:-1])
    )
    return g


def threshold_bin(h: NDArray[np.int64], n: int) -> int:
    """B_t of eq. (15) for a 256-bin histogram ``h`` (0 if fewer than n points in total)."""
    above = 0  # sum_{k > B_t} h(k)
    for b in range(h.shape[0] - 1, -1, -1):
        if above + int(h[b]) >= n:
            return b
        above += int(h[b])
    return 0


def select_points(
    grad_mag: NDArray[np.float32], candidate: NDArray[np.bool_], n: int
) -> NDArray[np.int64]:
    """Flat indices of exactly ``min(n, candidates)`` pixels with the strongest gradients."""
    if n <= 0:
        raise ValueError(f"number of points must be positive, got {n}")
    flat_idx = np.flatnonzero(candidate.ravel())
    if flat_idx.size <= n:
        return flat_idx
    bins = np.clip((grad_mag.ravel()[flat_idx] * 0.5).astype(np.int64), 0, N_BINS - 1)
    h = np.bincount(bins, minlength=N_BINS)
    bt = threshold_bin(h, n)
    good = flat_idx[bins > bt]  # P_good
    semi = flat_idx[bins == bt]  # P_semi
    need = n - good.size
    if need > 0:
        pick = np.linspace(0, semi.size - 1, need).round().astype(np.int64)
        # linspace rounding can repeat an index only when need > semi.size, excluded by eq. (15)
        semi = semi[pick]
    else:
        semi = semi[:0]
    return np.sort(np.concatenate([good, semi]))
