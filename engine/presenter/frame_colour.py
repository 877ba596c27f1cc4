"""One pass over a frame region: colour balance, HSV, histogram votes (compiled, exact).

The presenter tracker's colour pipeline per frame was three OpenCV/numba steps, each with its
own image: the grey-world gains (``cv2.transform`` of a strided region: a copy first), the
HSV conversion (``cv2.cvtColor``) and the integral histogram's votes
(``likelihood.binned_integral``). Here one compiled loop reads the frame's pixels in place
and does all three, with results equal to the three-step pipeline bit for bit:

- gains: a per-channel table made by ``cv2.transform`` itself from a 256-value ramp (a
  diagonal colour matrix maps each channel on its own, so the table is what the transform
  gives every pixel; checked against it in the tests);
- HSV: OpenCV's 8-bit BGR->HSV (H in 0..179) in integer arithmetic, its fixed-point
  division tables (``hsv_shift`` = 12) rebuilt here; checked against ``cv2.cvtColor`` on all
  2^24 colours in the tests;
- votes: the same bins, bilinear weights and order of accumulation as
  ``likelihood._binned_integral`` (the weights of each hue and saturation value taken from
  tables computed with the same expressions), and the same prefix-sum recurrence.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit
from numpy.typing import NDArray

from engine.arrays import u8
from engine.presenter.likelihood import _patch_residuals, _rect_hist

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
U8 = NDArray[np.uint8]

HSV_SHIFT = 12  # OpenCV's fixed-point shift of its 8-bit RGB->HSV conversion


def _division_tables() -> tuple[I64, I64]:
    # OpenCV: sdiv[i] = saturate_cast<int>((255 << shift) / (1. * i)),
    # hdiv180[i] = saturate_cast<int>((180 << shift) / (6. * i)); saturate_cast rounds half
    # to even, as np.rint
    i = np.arange(1, 256, dtype=np.float64)
    sdiv = np.zeros(256, np.int64)
    hdiv = np.zeros(256, np.int64)
    sdiv[1:] = np.rint((255 << HSV_SHIFT) / (1.0 * i)).astype(np.int64)
    hdiv[1:] = np.rint((180 << HSV_SHIFT) / (6.0 * i)).astype(np.int64)
    return sdiv, hdiv


SDIV, HDIV = _division_tables()

IDENTITY_LUT: U8 = np.ascontiguousarray(
    np.repeat(np.arange(256, dtype=np.uint8)[:, None], 3, axis=1))


def gain_lut(gains: F64 | None) -> U8:
    """(256, 3) uint8: what ``cv2.transform(img, diag(gains))`` makes of each channel value."""
    if gains is None:
        return IDENTITY_LUT
    ramp = np.ascontiguousarray(IDENTITY_LUT[None, :, :])
    return np.ascontiguousarray(u8(cv2.transform(ramp, np.diag(gains)))[0])


@njit(cache=True, nogil=True, inline="always")
def _hsv(b: int, g: int, r: int, sdiv: I64, hdiv: I64) -> tuple[int, int, int]:
    # OpenCV's RGB2HSV_b (8-bit, hue range 180)
    v = max(b, g, r)
    vmin = min(b, g, r)
    diff = v - vmin
    vr = -1 if v == r else 0
    vg = -1 if v == g else 0
    s = (diff * sdiv[v] + (1 << (HSV_SHIFT - 1))) >> HSV_SHIFT
    h = (vr & (g - b)) + (~vr & ((vg & (b - r + 2 * diff)) + (~vg & (r - g + 4 * diff))))
    h = (h * hdiv[diff] + (1 << (HSV_SHIFT - 1))) >> HSV_SHIFT
    if h < 0:
        h += 180
    return h, s, v


@njit(cache=True, nogil=True)
def _hsv_image(bgr: U8, lut: U8, sdiv: I64, hdiv: I64) -> U8:
    H, W = bgr.shape[0], bgr.shape[1]
    out = np.empty((H, W, 3), np.uint8)
    for y in range(H):
        for x in range(W):
            h, s, v = _hsv(int(lut[bgr[y, x, 0], 0]), int(lut[bgr[y, x, 1], 1]),
                           int(lut[bgr[y, x, 2], 2]), sdiv, hdiv)
            out[y, x, 0] = h
            out[y, x, 1] = s
            out[y, x, 2] = v
    return out


def hsv_image(bgr: U8, gains: F64 | None = None) -> U8:
    """``cv2.cvtColor(apply_gains(bgr, gains), COLOR_BGR2HSV)`` in one pass (any strides)."""
    return _hsv_image(bgr, gain_lut(gains), SDIV, HDIV)


@njit(cache=True, nogil=True)
def _bin_tables(n: int) -> tuple[I64, I64, F64, I64, I64, F64, I64, I64, I64]:
    # per hue / saturation / value: the bilinear vote of likelihood._binned_integral (the
    # same expressions) and the hard bins (integer divisions once per value, not per pixel)
    h0s = np.empty(180, np.int64)
    h1s = np.empty(180, np.int64)
    ahs = np.empty(180)
    hbs = np.empty(180, np.int64)
    for h in range(180):
        fh = (h + 0.5) * n / 180.0 - 0.5
        h0 = math.floor(fh)
        ahs[h] = fh - h0
        h1s[h] = (h0 + 1) % n
        h0s[h] = h0 % n
        hbs[h] = min(h * n // 180, n - 1)
    s0s = np.empty(256, np.int64)
    s1s = np.empty(256, np.int64)
    ass = np.empty(256)
    sbs = np.empty(256, np.int64)
    vbs = np.empty(256, np.int64)
    for s in range(256):
        fs = (s + 0.5) * n / 256.0 - 0.5
        if fs <= 0.0:
            s0s[s] = 0
            s1s[s] = 0
            ass[s] = 0.0
        elif fs >= n - 1:
            s0s[s] = n - 1
            s1s[s] = n - 1
            ass[s] = 0.0
        else:
            s0 = int(fs)
            s0s[s] = s0
            s1s[s] = s0 + 1
            ass[s] = fs - s0
        sbs[s] = s * n // 256
        vbs[s] = n * n + s * n // 256  # the brightness bin of value s
    return h0s, h1s, ahs, s0s, s1s, ass, hbs, sbs, vbs


@njit(cache=True, nogil=True)
def _roi_integral(bgr: U8, x0: int, y0: int, x1: int, y1: int, step: int, cell: int,
                  lut: U8, sdiv: I64, hdiv: I64, n: int, s_min: int, v_min: int,
                  inc: np.float32, soft: bool) -> tuple[F32, I64]:
    H = (y1 - y0 + step - 1) // step  # rows of bgr[y0:y1:step]
    W = (x1 - x0 + step - 1) // step
    hc = (H + cell - 1) // cell
    wc = (W + cell - 1) // cell
    nb = n * n + n
    h0s, h1s, ahs, s0s, s1s, ass, hbs, sbs, vbs = _bin_tables(n)
    # the bilinear votes' factors of likelihood._binned_integral, per hue and saturation
    # value: its vote inc * (1 - ah) * (1 - as) is (inc * (1 - ah)) * (1 - as), the same
    # products in the same order
    wh0 = np.empty(180)
    wh1 = np.empty(180)
    for h in range(180):
        wh0[h] = inc * (1.0 - ahs[h])
        wh1[h] = inc * ahs[h]
    ws0 = np.empty(256)
    ws1 = np.empty(256)
    # saturation bin pairs: (0, 0), (k, k + 1) for k < n - 1, (n - 1, n - 1): 0..n
    spair = np.empty(256, np.int64)
    for v in range(256):
        ws0[v] = 1.0 - ass[v]
        ws1[v] = ass[v]
        if s1s[v] == s0s[v]:
            spair[v] = 0 if s0s[v] == 0 else n
        else:
            spair[v] = s0s[v] + 1
    # pass 1: per pixel one code, h * 256 + s for a chromatic pixel, -1 - its brightness bin
    # for a grey one; which (hue, saturation pair) and brightness bins occur
    code = np.empty((H, W), np.int32)
    seen = np.zeros(180 * (n + 1), np.bool_)
    hit = np.zeros(nb, np.bool_)
    for y in range(H):
        yy = y0 + y * step
        for x in range(W):
            xx = x0 + x * step
            h, s, v = _hsv(int(lut[bgr[yy, xx, 0], 0]), int(lut[bgr[yy, xx, 1], 1]),
                           int(lut[bgr[yy, xx, 2], 2]), sdiv, hdiv)
            if s >= s_min and v >= v_min:
                code[y, x] = h * 256 + s
                if soft:
                    seen[h * (n + 1) + spair[s]] = True
                else:
                    hit[hbs[h] * n + sbs[s]] = True
            else:
                code[y, x] = -1 - vbs[v]
                hit[vbs[v]] = True
    if soft:
        # the four bins each seen (hue, saturation pair) votes for
        for h in range(180):
            for sp in range(n + 1):
                if seen[h * (n + 1) + sp]:
                    s0 = 0 if sp == 0 else (n - 1 if sp == n else sp - 1)
                    s1 = s0 if sp == 0 or sp == n else s0 + 1
                    hit[h0s[h] * n + s0] = True
                    hit[h0s[h] * n + s1] = True
                    hit[h1s[h] * n + s0] = True
                    hit[h1s[h] * n + s1] = True
    used = np.flatnonzero(hit)
    chan = np.full(nb, -1, np.int64)
    for k in range(used.shape[0]):
        chan[used[k]] = k
    # pass 2: the votes (likelihood._binned_integral's, in its order), one channel per used
    # bin; each row of cells is zeroed just before its first votes and summed into the
    # integral (the same recurrence, row by row) as soon as its last pixel row is in
    nk = used.shape[0]
    out = np.empty((hc + 1, wc + 1, nk), np.float32)
    out[0] = 0.0
    for y in range(H):
        cy = y // cell + 1
        if y % cell == 0:
            out[cy] = 0.0
        for cx in range(1, wc + 1):
            cell_hist = out[cy, cx]
            for x in range((cx - 1) * cell, min(cx * cell, W)):
                c = code[y, x]
                if c < 0:
                    cell_hist[chan[-1 - c]] += inc
                    continue
                h = c >> 8
                s = c & 255
                if soft:
                    h0 = h0s[h] * n
                    h1 = h1s[h] * n
                    s0 = s0s[s]
                    s1 = s1s[s]
                    a0 = wh0[h]
                    a1 = wh1[h]
                    b0 = ws0[s]
                    b1 = ws1[s]
                    cell_hist[chan[h0 + s0]] += a0 * b0
                    cell_hist[chan[h0 + s1]] += a0 * b1
                    cell_hist[chan[h1 + s0]] += a1 * b0
                    cell_hist[chan[h1 + s1]] += a1 * b1
                else:
                    cell_hist[chan[hbs[h] * n + sbs[s]]] += inc
        if y % cell == cell - 1 or y == H - 1:
            row = out[cy]
            above = out[cy - 1]
            for cx in range(1, wc + 1):
                r = row[cx]
                left = row[cx - 1]
                a = above[cx]
                al = above[cx - 1]
                for k in range(nk):
                    r[k] += a[k] + left[k] - al[k]
    return out, used


class RoiIntegral:
    """The integral histogram of a frame region, stored for the bins that got votes.

    ``integral`` (rows+1, cols+1, K) float32 on ``cell``-pixel cells, origin
    ``roi_xywh[:2]``; channel k holds bin ``used[k]`` (ascending); every other bin is 0
    everywhere. ``image_wh``: the size of the image the rectangles are clipped to.
    """

    __slots__ = ("cell", "image_wh", "integral", "n_bins_total", "roi_xywh", "used")

    def __init__(self, integral: F32, used: I64, n_bins_total: int, cell: int,
                 roi_xywh: tuple[int, int, int, int], image_wh: tuple[int, int]) -> None:
        self.integral = integral
        self.used = used
        self.n_bins_total = n_bins_total
        self.cell = cell
        self.roi_xywh = roi_xywh
        self.image_wh = image_wh

    def compact(self, per_bin: F64) -> F64:
        """``per_bin[..., used]`` (contiguous): a reference on the stored channels."""
        return np.ascontiguousarray(np.asarray(per_bin, dtype=np.float64)[..., self.used])

    def full(self) -> F32:
        """The integral over all N*N+N bins (``likelihood.binned_integral``'s)."""
        out = np.zeros((*self.integral.shape[:2], self.n_bins_total), np.float32)
        out[..., self.used] = self.integral
        return out

    def rect_counts(self, xywh: tuple[float, float, float, float]) -> F64:
        """``likelihood.rect_histogram`` (all bins) of a rectangle relative to the origin."""
        x, y, w, h = xywh
        c = np.zeros(len(self.used))
        _rect_hist(self.integral, float(self.cell), float(x), float(y), float(x + w),
                   float(y + h), c)
        out = np.zeros(self.n_bins_total)
        out[self.used] = c
        return out


def roi_integral(bgr: U8, roi_xyxy: tuple[int, int, int, int], step: int, cell: int, n: int,
                 gains: F64 | None, s_min: int, v_min: int, pixel_weight: float,
                 soft: bool, lut: U8 | None = None) -> tuple[F32, I64]:
    """``likelihood.binned_integral`` of ``cvtColor(apply_gains(bgr[y0:y1:step,
    x0:x1:step], gains), BGR2HSV)`` (``cell`` in subsampled pixels) without the copies,
    stored for the bins with votes: (integral (rows+1, cols+1, K), used (K,) bin indices).
    ``lut``: ``gain_lut(gains)`` when the caller has made it already (once per frame)."""
    x0, y0, x1, y1 = roi_xyxy
    return _roi_integral(bgr, int(x0), int(y0), int(x1), int(y1), max(int(step), 1),
                         max(int(cell), 1), gain_lut(gains) if lut is None else lut, SDIV,
                         HDIV, int(n), int(s_min),
                         int(v_min), np.float32(pixel_weight), bool(soft))


@njit(cache=True, nogil=True)
def _hard_bins(bgr: U8, x0: int, y0: int, x1: int, y1: int, step: int, lut: U8, sdiv: I64,
               hdiv: I64, n: int, s_min: int, v_min: int) -> NDArray[np.int32]:
    H = (y1 - y0 + step - 1) // step
    W = (x1 - x0 + step - 1) // step
    _h0, _h1, _ah, _s0, _s1, _as, hbs, sbs, vbs = _bin_tables(n)
    out = np.empty((H, W), np.int32)
    for y in range(H):
        yy = y0 + y * step
        for x in range(W):
            xx = x0 + x * step
            h, s, v = _hsv(int(lut[bgr[yy, xx, 0], 0]), int(lut[bgr[yy, xx, 1], 1]),
                           int(lut[bgr[yy, xx, 2], 2]), sdiv, hdiv)
            if s >= s_min and v >= v_min:
                out[y, x] = hbs[h] * n + sbs[s]
            else:
                out[y, x] = vbs[v]
    return out


def hard_bins(bgr: U8, roi_xyxy: tuple[int, int, int, int], step: int, n: int,
              gains: F64 | None, s_min: int, v_min: int,
              lut: U8 | None = None) -> NDArray[np.int32]:
    """``likelihood.bin_map(cvtColor(apply_gains(bgr[y0:y1:step, x0:x1:step], gains)))``:
    each pixel's hard bin, in one pass (``lut``: ``gain_lut(gains)`` if made already)."""
    x0, y0, x1, y1 = roi_xyxy
    return _hard_bins(bgr, int(x0), int(y0), int(x1), int(y1), max(int(step), 1),
                      gain_lut(gains) if lut is None else lut, SDIV, HDIV, int(n), int(s_min),
                      int(v_min))


# ----------------------------------------------------------------------------- queries
# The query kernels are likelihood's own (_rect_hist, _patch_residuals), run on the stored
# channels only: a bin without votes is +0.0 in every rectangle there too, and adding +0.0
# changes no sum, so the results are the same bit for bit. References come compacted to the
# same channels (``RoiIntegral.compact``).


@njit(cache=True, nogil=True)
def _ring_bc(ih: F32, cell: float, ox: float, oy: float, roi_w: float, roi_h: float,
             img_w: int, img_h: int, cx: float, cy: float, hh: float, aspect: float,
             margin: float, sqrt_ref: F64, inner: F64, outer: F64) -> float:
    # likelihood._ring_similarity for one state
    ww = hh * aspect
    ix0, iy0, ix1, iy1 = cx - 0.5 * ww, cy - 0.5 * hh, cx + 0.5 * ww, cy + 0.5 * hh
    mx = margin * ww
    my = margin * hh
    ox0 = max(ix0 - mx, 0.0)
    oy0 = max(iy0 - my, 0.0)
    ox1 = min(ix1 + mx, float(img_w))
    oy1 = min(iy1 + my, float(img_h))
    if ox1 - ox0 <= 0.0 or oy1 - oy0 <= 0.0:
        return 0.0
    _rect_hist(ih, cell, min(max(ox0 - ox, 0.0), roi_w), min(max(oy0 - oy, 0.0), roi_h),
               min(max(ox1 - ox, 0.0), roi_w), min(max(oy1 - oy, 0.0), roi_h), outer)
    vx0 = min(max(ix0, ox0), ox1)
    vy0 = min(max(iy0, oy0), oy1)
    vx1 = min(max(ix1, ox0), ox1)
    vy1 = min(max(iy1, oy0), oy1)
    if vx1 > vx0 and vy1 > vy0:
        _rect_hist(ih, cell, min(max(vx0 - ox, 0.0), roi_w), min(max(vy0 - oy, 0.0), roi_h),
                   min(max(vx1 - ox, 0.0), roi_w), min(max(vy1 - oy, 0.0), roi_h), inner)
    else:
        inner[:] = 0.0
    nk = outer.shape[0]
    total = 0.0
    for k in range(nk):
        outer[k] = max(outer[k] - inner[k], 0.0)
        total += outer[k]
    ring_area = (ox1 - ox0) * (oy1 - oy0) - (vx1 - vx0) * (vy1 - vy0)
    if total <= 1e-9 or ring_area < 0.25 * ((ww + 2 * mx) * (hh + 2 * my) - ww * hh):
        return 0.0
    for k in range(nk):
        outer[k] = math.sqrt(outer[k] / total)  # vectorised, as in likelihood._rect_b2
    bc = 0.0
    for k in range(nk):
        bc += outer[k] * sqrt_ref[k]
    return bc


@njit(cache=True, nogil=True)
def _colour_b2(ih: F32, cell: float, ox: float, oy: float, roi_w: float, roi_h: float,
               img_w: int, img_h: int, particles: F64, rel: F64, aspect: float,
               sqrt_ref: F64, ring_weight: float, margin: float, sqrt_pooled: F64) -> F64:
    n_part = particles.shape[0]
    n_patch = rel.shape[0]
    b2 = np.empty((n_part, n_patch))
    _patch_residuals(ih, cell, ox, oy, roi_w, roi_h, img_w, img_h, particles, rel, aspect,
                     sqrt_ref, 1.0, b2)
    out = np.empty(n_part)
    inner = np.empty(ih.shape[2])
    outer = np.empty(ih.shape[2])
    for i in range(n_part):
        s = 0.0
        for p in range(n_patch):
            s += b2[i, p]
        if ring_weight > 0:
            # the ring term beyond eq. (3)
            s = s + ring_weight * _ring_bc(ih, cell, ox, oy, roi_w, roi_h, img_w, img_h,
                                           particles[i, 0], particles[i, 1], particles[i, 2],
                                           aspect, margin, sqrt_pooled, inner, outer)
        out[i] = s
    return out


def colour_b2(ri: RoiIntegral, particles_xyh: F64, rel_boxes: F64, aspect: float,
              sqrt_ref: F64, ring_weight: float = 0.0, ring_margin: float = 0.25,
              sqrt_pooled: F64 | None = None) -> F64:
    """sum_p B_p^2 (eq. 2-3) + ``ring_weight`` x the ring's Bhattacharyya coefficient with
    ``sqrt_pooled`` for every particle: ``likelihood.colour_residuals`` +
    ``ring_weight * likelihood.ring_similarity``, in one call."""
    ox, oy, rw, rh = ri.roi_xywh
    pooled = ri.compact(sqrt_ref[0] if sqrt_pooled is None else sqrt_pooled)
    return _colour_b2(ri.integral, float(ri.cell), float(ox), float(oy), float(rw), float(rh),
                      int(ri.image_wh[0]), int(ri.image_wh[1]),
                      np.ascontiguousarray(particles_xyh, dtype=np.float64), rel_boxes,
                      float(aspect), ri.compact(sqrt_ref), float(ring_weight),
                      float(ring_margin), pooled)


def patch_b2(ri: RoiIntegral, particles_xyh: F64, rel_boxes: F64, aspect: float,
             sqrt_ref: F64, outside_b2: float = 1.0) -> F64:
    """B_p^2 (particles, patches): ``likelihood.patch_residuals`` on a :class:`RoiIntegral`."""
    ox, oy, rw, rh = ri.roi_xywh
    parts = np.ascontiguousarray(particles_xyh, dtype=np.float64)
    out = np.empty((parts.shape[0], rel_boxes.shape[0]))
    _patch_residuals(ri.integral, float(ri.cell), float(ox), float(oy), float(rw), float(rh),
                     int(ri.image_wh[0]), int(ri.image_wh[1]), parts, rel_boxes, float(aspect),
                     ri.compact(sqrt_ref), float(outside_b2), out)
    return out
