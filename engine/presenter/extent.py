"""Box width from a local foreground/background colour ratio (beyond the VR-TV paper).

The paper's state (x, y, h) has a fixed aspect ratio: the output box is the model's main
region scaled by h. A walking presenter's bounding box spans the stride and the arm swing
(up to twice the standing width), which a fixed aspect cannot follow, and HS histograms barely
constrain width (a wider box just adds background to every patch). So the width is measured
after the filter, not sampled by it:

1. a horizontal strip over the estimated box's rows below ``top_skip_frac`` of its height
   (the head band never widens with the stride or the arm swing, and skipping it keeps a
   head-height distractor beside the presenter out), ``search_frac`` model widths each side;
2. foreground colours: the model's patch histograms pooled by patch area (the reference the
   filter matches); background colours: the strip's outer columns (beyond
   ``bg_from_frac`` model widths from the centre), as in Comaniciu et al.'s
   background-weighted histogram (the colours common around the target);
3. per pixel the ratio r = f(b) / (f(b) + g(b)) of its bin; a pixel is foreground-like when
   r > 0.5 and a column is foreground when at least ``col_frac`` of its pixels are;
4. the extent grows from the centre column while columns are foreground (gaps of up to
   ``max_gap_px`` bridged: a dark gap between the legs);
5. width and centre are clipped to [``w_min_frac``, ``w_max_frac``] model widths and half a
   model width of shift, and the caller smooths them over time.

It only sets the *output* box; the particle filter's state, likelihood and loss test are the
paper's.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from engine.presenter.frame_colour import hard_bins
from engine.presenter.likelihood import S_MIN_DEFAULT, V_MIN_DEFAULT

F64 = NDArray[np.float64]

SHIFT = 0.25
STEP = 2  # pixel subsampling of the strip (each way)


def measure_extent(bgr: NDArray[np.uint8], gains: F64 | None, xyh: F64, aspect: float,
                   fg_hist: F64, n_bins: int, search_frac: float = 1.6,
                   top_skip_frac: float = 0.25,
                   bg_from_frac: float = 1.2, col_frac: float = 0.15,
                   max_gap_px: float = 8.0, w_min_frac: float = 0.7,
                   w_max_frac: float = 2.2,
                   lut: NDArray[np.uint8] | None = None) -> tuple[float, float] | None:
    """(centre x, width) of the foreground around the estimate, or None if not measurable
    (``lut``: ``frame_colour.gain_lut(gains)`` when the caller has made it)."""
    H, W = bgr.shape[:2]
    x, y, h = (float(v) for v in xyh)
    w0 = h * aspect
    if w0 < 4 or h < 4:
        return None
    y0, y1 = int(max(y - h / 2 + top_skip_frac * h, 0)), int(min(y + h / 2, H))
    xa, xb = int(max(x - search_frac * w0, 0)), int(min(x + search_frac * w0, W))
    if y1 - y0 < 4 or xb - xa < 4:
        return None
    bins = hard_bins(bgr, (xa, y0, xb, y1), STEP, n_bins, gains, S_MIN_DEFAULT, V_MIN_DEFAULT,
                     lut)
    got = _extent(bins, float(xa), float(x), w0, np.ascontiguousarray(fg_hist, np.float64),
                  bg_from_frac, col_frac, max(int(max_gap_px / STEP), 1), w_min_frac,
                  w_max_frac)
    return None if got[1] < 0 else (float(got[0]), float(got[1]))


@njit(cache=True, nogil=True)
def _extent(bins: NDArray[np.int32], xa: float, x: float, w0: float, fg_hist: F64,
            bg_from_frac: float, col_frac: float, max_gap: int, w_min_frac: float,
            w_max_frac: float) -> tuple[float, float]:
    # steps 2-5 of the module docstring; width -1 = not measurable
    rows, n_cols = bins.shape
    cols = np.empty(n_cols)
    for i in range(n_cols):
        cols[i] = xa + STEP * i + 0.5 * STEP  # image x of each strip column
    outer = np.abs(cols - x) > bg_from_frac * w0
    if int(outer.sum()) < 3:
        return 0.0, -1.0  # no background visible beside the target (image edge)
    nb = fg_hist.shape[0]
    g = np.zeros(nb)
    for r in range(rows):
        for i in range(n_cols):
            if outer[i]:
                g[bins[r, i]] += 1.0
    g /= max(g.sum(), 1.0)
    ratio = fg_hist / np.maximum(fg_hist + g, 1e-12)
    fg_cols = np.empty(n_cols, np.bool_)
    for i in range(n_cols):
        k = 0
        for r in range(rows):
            if ratio[bins[r, i]] > 0.5:
                k += 1
        fg_cols[i] = k / rows >= col_frac
    c = min(max(int(np.searchsorted(cols, x)), 0), n_cols - 1)
    lo = hi = c
    gap = 0
    for i in range(c - 1, -1, -1):
        if fg_cols[i]:
            lo, gap = i, 0
        else:
            gap += 1
            if gap > max_gap:
                break
    gap = 0
    for i in range(c + 1, n_cols):
        if fg_cols[i]:
            hi, gap = i, 0
        else:
            gap += 1
            if gap > max_gap:
                break
    left, right = cols[lo] - 0.5 * STEP, cols[hi] + 0.5 * STEP
    width = min(max(right - left, w_min_frac * w0), w_max_frac * w0)
    centre = min(max(0.5 * (left + right), x - SHIFT * w0), x + SHIFT * w0)
    return centre, width
