"""Compiled pieces of one tracking frame's small-array work (``engine.presenter.view``).

Each replaces a handful of numpy calls on 100-600 particles or 3 patches, whose cost was the
calls themselves (~1-5 us each, tens per frame), with one compiled call, and gives the same
numbers bit for bit:

- sums are numpy's own pairwise summation (``pairwise_sum``: eight accumulators up to 128
  elements, halves above; checked against ``np.sum`` in the tests), cumulative sums are
  sequential as ``np.cumsum``'s;
- the random numbers are still drawn by the caller's ``np.random.Generator``, in the same
  order; ``exp`` and matrix products stay numpy's (their vectorised implementations may
  round differently from the compiled ones).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from engine.presenter.likelihood import _patch_residuals, _rect_hist

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

PW_BLOCKSIZE = 128  # numpy's pairwise-summation block


@njit(cache=True, nogil=True)
def _block_sum(a: F64, lo: int, n: int) -> float:
    # numpy's pairwise_sum for n <= PW_BLOCKSIZE: eight accumulators, then the rest in order
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    m = n - n % 8
    while i < m:
        j = lo + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    res = float(((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7)))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True, nogil=True)
def pairwise_sum(a: F64, lo: int, n: int) -> float:
    """``np.sum(a[lo:lo + n])`` for a contiguous float64 ``a``, in numpy's order: blocks of
    up to ``PW_BLOCKSIZE``, above that the sum of the two halves (the first a multiple of 8
    long). The halving runs on an explicit stack: numba's cache cannot hold a recursive
    function (a cached one crashes when loaded)."""
    if n <= PW_BLOCKSIZE:
        return _block_sum(a, lo, n)
    # nodes (lo, n, children done); values of finished nodes in order
    node_lo = np.empty(64, np.int64)
    node_n = np.empty(64, np.int64)
    node_st = np.empty(64, np.int64)
    vals = np.empty(64)
    top = 0
    nv = 0
    node_lo[0], node_n[0], node_st[0] = lo, n, 0
    while top >= 0:
        c_lo, c_n, st = node_lo[top], node_n[top], node_st[top]
        if c_n <= PW_BLOCKSIZE:
            vals[nv] = _block_sum(a, c_lo, c_n)
            nv += 1
            top -= 1
            continue
        n2 = c_n // 2
        n2 -= n2 % 8
        if st == 0:
            node_st[top] = 1
            top += 1
            node_lo[top], node_n[top], node_st[top] = c_lo, n2, 0
        elif st == 1:
            node_st[top] = 2
            top += 1
            node_lo[top], node_n[top], node_st[top] = c_lo + n2, c_n - n2, 0
        else:
            vals[nv - 2] = vals[nv - 2] + vals[nv - 1]
            nv -= 1
            top -= 1
    return float(vals[0])


@njit(cache=True, nogil=True)
def resample_predict(weights: F64, u: float, n_out: int, particles: F64, noise: F64,
                     sigma: F64, h_lo: float, h_hi: float, drift_x: float,
                     drift_y: float) -> F64:
    """Systematic resampling (``engine.particles.systematic_resample`` with its uniform draw
    ``u``), the random walk of eq. (1) (``filter.predict``: ``noise`` the standard normal
    draws, (n_out, 3)) and the constant-velocity drift, in one pass."""
    n = weights.shape[0]
    total = pairwise_sum(weights, 0, n)
    cdf = np.empty(n)
    acc = 0.0
    if not math.isfinite(total) or total <= 0:
        for i in range(n):
            acc += 1.0 / n
            cdf[i] = acc
    else:
        for i in range(n):
            acc += weights[i] / total
            cdf[i] = acc
    cdf[n - 1] = 1.0
    out = np.empty((n_out, 3))
    for k in range(n_out):
        v = (u + k) / n_out
        # searchsorted(cdf, v, side="right"): the first index whose cdf exceeds v
        a, b = 0, n
        while a < b:
            mid = (a + b) >> 1
            if v < cdf[mid]:
                b = mid
            else:
                a = mid + 1
        for c in range(3):
            out[k, c] = particles[a, c] + noise[k, c] * sigma[c]
        out[k, 2] = min(max(out[k, 2], h_lo), h_hi)
        out[k, 0] += drift_x
        out[k, 1] += drift_y
    return out


@njit(cache=True, nogil=True)
def roi_bounds(states: F64, aspect: float, grow: float, img_w: int,
               img_h: int) -> tuple[int, int, int, int]:
    """The image region (x0, y0, x1, y1) the states' boxes, grown by ``grow``, cover (one
    pixel more each side, clipped to the image)."""
    min_x = np.inf
    min_y = np.inf
    max_x = -np.inf
    max_y = -np.inf
    for i in range(states.shape[0]):
        hs = states[i, 2]
        gw = grow * (hs * aspect) / 2
        gh = grow * hs / 2
        min_x = min(min_x, states[i, 0] - gw)
        max_x = max(max_x, states[i, 0] + gw)
        min_y = min(min_y, states[i, 1] - gh)
        max_y = max(max_y, states[i, 1] + gh)
    x0 = max(math.floor(min_x) - 1, 0)
    y0 = max(math.floor(min_y) - 1, 0)
    x1 = min(math.ceil(max_x) + 1, img_w)
    y1 = min(math.ceil(max_y) + 1, img_h)
    return x0, y0, x1, y1


@njit(cache=True, nogil=True)
def median_small(v: F64) -> float:
    """``np.median`` of a short vector (NaN if any element is)."""
    n = v.shape[0]
    s = np.sort(v)
    if math.isnan(s[n - 1]):
        return math.nan
    if n % 2:
        return float(s[n // 2])
    return float((s[n // 2 - 1] + s[n // 2]) / 2)


@njit(cache=True, nogil=True)
def probe_residuals(ih: F32, cell: float, ox: float, oy: float, roi_w: float, roi_h: float,
                    img_w: int, img_h: int, state: F64, rel: F64, aspect: float,
                    sqrt_ref: F64, sqrt_ref0: F64) -> tuple[float, F64]:
    """At one state (1, 3): sum_p B_p^2 against the tracking reference (eq. 2-3, no ring
    term) and B_p^2 per patch against the loss test's reference."""
    b2 = np.empty((1, rel.shape[0]))
    _patch_residuals(ih, cell, ox, oy, roi_w, roi_h, img_w, img_h, state, rel, aspect,
                     sqrt_ref, 1.0, b2)
    s = 0.0
    for p in range(rel.shape[0]):
        s += b2[0, p]
    fixed = np.empty((1, rel.shape[0]))
    _patch_residuals(ih, cell, ox, oy, roi_w, roi_h, img_w, img_h, state, rel, aspect,
                     sqrt_ref0, 1.0, fixed)
    return s, fixed[0]


@njit(cache=True, nogil=True)
def patch_hists(ih: F32, cell: float, ox: float, oy: float, img_w: int, img_h: int,
                x: float, y: float, h: float, rel: F64, aspect: float, used: I64,
                n_bins_total: int, out: F64) -> bool:
    """Normalised patch histograms (P, N*N+N) at state (x, y, h) into ``out``, as
    ``view.ViewTracker._patch_hists`` made them from ``model.boxes_at`` and
    ``RoiIntegral.rect_counts``; False if a patch is not wholly inside the image or empty."""
    w = h * aspect
    left, top = x - w / 2.0, y - h / 2.0
    c = np.empty(used.shape[0])
    full = np.zeros(n_bins_total)
    for k in range(rel.shape[0]):
        bx = left + rel[k, 0] * w
        by = top + rel[k, 1] * h
        bw = (rel[k, 2] - rel[k, 0]) * w
        bh = (rel[k, 3] - rel[k, 1]) * h
        if bx < 0 or by < 0 or bx + bw > img_w or by + bh > img_h:
            return False
        rx, ry = bx - ox, by - oy
        _rect_hist(ih, cell, rx, ry, rx + bw, ry + bh, c)
        full[:] = 0.0
        for j in range(used.shape[0]):
            full[used[j]] = max(c[j], 0.0)
        total = pairwise_sum(full, 0, n_bins_total)
        if total <= 0:
            return False
        for b in range(n_bins_total):
            out[k, b] = full[b] / total
    return True


@njit(cache=True, nogil=True)
def background_bounds(k: F64, w: float, h: float, img_w: int,
                      img_h: int) -> tuple[F64, F64, F64, F64]:
    """The uniform draws' bounds of the background boxes' centres (``view.
    ViewTracker._background_levels``): boxes of (w, h) x ``k``, wholly inside the image where
    they fit."""
    n = k.shape[0]
    lo_x = np.empty(n)
    hi_x = np.empty(n)
    lo_y = np.empty(n)
    hi_y = np.empty(n)
    for i in range(n):
        ws = w * k[i]
        hs = h * k[i]
        lo_x[i] = ws / 2
        hi_x[i] = max(img_w - ws / 2, ws / 2 + 1e-6)
        lo_y[i] = hs / 2
        hi_y[i] = max(img_h - hs / 2, hs / 2 + 1e-6)
    return lo_x, hi_x, lo_y, hi_y


@njit(cache=True, nogil=True)
def background_boxes(k: F64, cx: F64, cy: F64, x: float, y: float, w: float, h: float,
                     img_w: int, img_h: int, max_keep: int) -> F64:
    """The first ``max_keep`` sampled boxes (centre x, centre y, h) that overlap the box
    (x, y, w, h) by IoU < 0.1 and fit in the image."""
    n = k.shape[0]
    out = np.empty((max_keep, 3))
    m = 0
    for i in range(n):
        if m >= max_keep:
            break
        ws = w * k[i]
        hs = h * k[i]
        ix = min(cx[i] + ws / 2, x + w / 2) - max(cx[i] - ws / 2, x - w / 2)
        iy = min(cy[i] + hs / 2, y + h / 2) - max(cy[i] - hs / 2, y - h / 2)
        ix = max(ix, 0.0)
        iy = max(iy, 0.0)
        inter = ix * iy
        iou = inter / (ws * hs + w * h - inter)
        if iou < 0.1 and ws <= img_w and hs <= img_h:
            out[m, 0] = cx[i]
            out[m, 1] = cy[i]
            out[m, 2] = hs
            m += 1
    return out[:m]


@njit(cache=True, nogil=True)
def _quantile_sorted(s: F64, q: float) -> float:
    # np.quantile's 'linear' method on sorted values (NaN sorted last): virtual index
    # (n - 1) q, numpy's _lerp between its neighbours
    n = s.shape[0]
    if math.isnan(s[n - 1]):
        return math.nan
    v = (n - 1) * q
    if v >= n - 1:
        return float(s[n - 1])
    p = math.floor(v)
    a = s[p]
    b = s[p + 1]
    g = v - p
    d = b - a
    if g >= 0.5:
        return float(b - d * (1 - g))
    return float(a + d * g)


@njit(cache=True, nogil=True)
def quantile_columns(r: F64, q: float) -> F64:
    """``np.quantile(r, q, axis=0)`` (method 'linear') of a 2-D array."""
    out = np.empty(r.shape[1])
    for j in range(r.shape[1]):
        out[j] = _quantile_sorted(np.sort(r[:, j]), q)
    return out


@njit(cache=True, nogil=True)
def quantile(v: F64, q: float) -> float:
    """``np.quantile(v, q)`` (method 'linear') of a 1-D array."""
    return _quantile_sorted(np.sort(v), q)

