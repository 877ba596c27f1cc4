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

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8
from engine.presenter.likelihood import apply_gains, bin_map

F64 = NDArray[np.float64]

SHIFT = 0.25
STEP = 2  # pixel subsampling of the strip (each way)


def measure_extent(bgr: NDArray[np.uint8], gains: F64 | None, xyh: F64, aspect: float,
                   fg_hist: F64, n_bins: int, search_frac: float = 1.6,
                   top_skip_frac: float = 0.25,
                   bg_from_frac: float = 1.2, col_frac: float = 0.15,
                   max_gap_px: float = 8.0, w_min_frac: float = 0.7,
                   w_max_frac: float = 2.2) -> tuple[float, float] | None:
    """(centre x, width) of the foreground around the estimate, or None if not measurable."""
    H, W = bgr.shape[:2]
    x, y, h = (float(v) for v in xyh)
    w0 = h * aspect
    if w0 < 4 or h < 4:
        return None
    y0, y1 = int(max(y - h / 2 + top_skip_frac * h, 0)), int(min(y + h / 2, H))
    xa, xb = int(max(x - search_frac * w0, 0)), int(min(x + search_frac * w0, W))
    if y1 - y0 < 4 or xb - xa < 4:
        return None
    strip = apply_gains(np.ascontiguousarray(bgr[y0:y1:STEP, xa:xb:STEP]), gains)
    bins = bin_map(u8(cv2.cvtColor(strip, cv2.COLOR_BGR2HSV)), n_bins)
    cols = xa + STEP * np.arange(bins.shape[1]) + 0.5 * STEP  # image x of each strip column
    outer = np.abs(cols - x) > bg_from_frac * w0
    if int(outer.sum()) < 3:
        return None  # no background visible beside the target (image edge)
    nb = len(fg_hist)
    g = np.bincount(bins[:, outer].ravel(), minlength=nb).astype(np.float64)
    g /= max(g.sum(), 1.0)
    ratio = fg_hist / np.maximum(fg_hist + g, 1e-12)
    fg_cols = np.mean(ratio[bins] > 0.5, axis=0) >= col_frac
    c = int(np.clip(np.searchsorted(cols, x), 0, len(cols) - 1))
    max_gap = max(int(max_gap_px / STEP), 1)
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
    for i in range(c + 1, len(cols)):
        if fg_cols[i]:
            hi, gap = i, 0
        else:
            gap += 1
            if gap > max_gap:
                break
    left, right = cols[lo] - 0.5 * STEP, cols[hi] + 0.5 * STEP
    width = float(np.clip(right - left, w_min_frac * w0, w_max_frac * w0))
    centre = float(np.clip(0.5 * (left + right), x - SHIFT * w0, x + SHIFT * w0))
    return centre, width
