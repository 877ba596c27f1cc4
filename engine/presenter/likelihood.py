"""Colour and motion likelihoods of the multi-patch model (VR-TV paper, Sec. III-C.3-5).

Histograms
    Joint hue-saturation histograms with N x N bins (N = 10 in the paper), plus N brightness
    bins for pixels whose hue is undefined (saturation < ``s_min`` or value < ``v_min``), as
    in the paper's reference [6] (Pérez et al. 2002): a grey or black region still has a
    histogram instead of collapsing into one arbitrary hue bin. ``n_bins_total = N*N + N``.

Integral histograms
    The cost of one patch histogram must not grow with the patch area. For every frame one
    integral histogram is built over the region the particles cover (``binned_integral``),
    on a grid of ``cell x cell`` pixels chosen so that the grid has at most ``max_cells``
    cells a side; a patch's histogram is then 4 corner look-ups per bin, bilinearly
    interpolated between grid nodes (uniform spread inside a cell). With ``cell = 1`` and
    integer rectangles it equals the direct histogram exactly (tested).

Equations
    eq. (2)  B_p = sqrt(1 - sum_n sqrt(q*_p(n) q_p(s, n)))        ``bhattacharyya``
    eq. (3)  P(z_col | s) = exp(-sum_p B_p^2 / lambda_col)         ``colour_likelihood``
    eq. (4)  P(z_mot | s) = exp(-E^2 / lambda_mot)                  ``motion_likelihood``
             E = fraction of non-motion pixels under the patches (the paper counts pixels;
             a fraction keeps lambda_mot independent of the presenter's size in the image).
    eq. (5)  w = P(z_col | s) P(z_mot | s)                          ``engine.presenter.filter``
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit
from numpy.typing import NDArray

from engine.arrays import u8

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]

S_MIN_DEFAULT = 26  # 0.1 of the 8-bit range, Pérez et al. [6]
V_MIN_DEFAULT = 51  # 0.2 of the 8-bit range
SOFT_DEFAULT = True  # bilinear hue-saturation votes (``soft=True``). Measured: success AUC
# neutral (mean over the colour sequences 0.537 soft vs 0.543 hard, 3 seeds: within noise), but
# the loss scenario re-acquires in 3-4 frames instead of 11 (6 seeds): a presenter coming back
# under slightly different light no longer flips hue bins


def n_bins_total(n: int) -> int:
    """Number of histogram bins: N x N hue-saturation bins + N brightness bins."""
    return n * n + n


def bin_map(hsv_u8: NDArray[np.uint8], n: int, s_min: int = S_MIN_DEFAULT,
            v_min: int = V_MIN_DEFAULT) -> NDArray[np.int32]:
    """Bin index of every pixel of an OpenCV 8-bit HSV image (H in 0..179)."""
    h = hsv_u8[..., 0].astype(np.int32)
    s = hsv_u8[..., 1].astype(np.int32)
    v = hsv_u8[..., 2].astype(np.int32)
    chroma = (s >= s_min) & (v >= v_min)
    hs = np.minimum(h * n // 180, n - 1) * n + s * n // 256
    grey = n * n + v * n // 256
    return np.where(chroma, hs, grey).astype(np.int32)


def direct_histogram(hsv_u8: NDArray[np.uint8], xywh: tuple[int, int, int, int], n: int,
                     s_min: int = S_MIN_DEFAULT, v_min: int = V_MIN_DEFAULT,
                     soft: bool | None = None) -> F64:
    """Un-normalised histogram (counts) of an integer rectangle, computed pixel by pixel.

    ``soft`` (default ``SOFT_DEFAULT``): bilinear votes as in ``binned_integral``.
    """
    soft = SOFT_DEFAULT if soft is None else soft
    x, y, w, h = (round(v) for v in xywh)
    H, W = hsv_u8.shape[:2]
    x0, y0, x1, y1 = max(x, 0), max(y, 0), min(x + w, W), min(y + h, H)
    out = np.zeros(n_bins_total(n))
    if x1 <= x0 or y1 <= y0:
        return out
    roi = np.ascontiguousarray(hsv_u8[y0:y1, x0:x1])
    if soft:
        # the same voting as the integral histogram (one cell per pixel): its last node
        return np.asarray(binned_integral(roi, n, 1, s_min, v_min, soft=True)[-1, -1],
                          dtype=np.float64)
    b = bin_map(roi, n, s_min, v_min)
    np.add.at(out, b.ravel(), 1.0)
    return out


def chromatic_fraction(hsv_u8: NDArray[np.uint8], xywh: tuple[int, int, int, int],
                       s_min: int = S_MIN_DEFAULT, v_min: int = V_MIN_DEFAULT) -> float:
    """Fraction of the rectangle's pixels that have a defined hue (for the grey-patch check)."""
    x, y, w, h = (round(v) for v in xywh)
    H, W = hsv_u8.shape[:2]
    x0, y0, x1, y1 = max(x, 0), max(y, 0), min(x + w, W), min(y + h, H)
    if x1 <= x0 or y1 <= y0:
        return 0.0
    roi = hsv_u8[y0:y1, x0:x1]
    return float(np.mean((roi[..., 1] >= s_min) & (roi[..., 2] >= v_min)))


#: exposure normalisation never scales a frame by more than this (or less than its inverse):
#: a covered lens or a black frame is not amplified into noise
MAX_EXPOSURE_GAIN = 4.0


def _channel_means(bgr: NDArray[np.uint8], step: int) -> F64:
    """The frame's B, G, R means over every ``step``-th pixel."""
    return np.asarray(cv2.mean(np.ascontiguousarray(bgr[::step, ::step]))[:3], dtype=np.float64)


def frame_grey_level(bgr: NDArray[np.uint8], step: int = 8) -> float:
    """The frame's mean grey level (mean of the channel means, every ``step``-th pixel)."""
    return float(_channel_means(bgr, step).mean())


def grey_world_gains(bgr: NDArray[np.uint8], step: int = 8,
                     level: float | None = None) -> F64:
    """Per-channel gains that make the frame's mean grey (von Kries / grey-world balance).

    Cameras re-balance white continuously outdoors; dividing out the frame's mean colour keeps
    the hue-saturation histograms comparable with the reference (a pre-processing step; the
    studio's controlled light needs it less). With ``level`` (the reference frame's
    :func:`frame_grey_level`) the mean grey is also brought to that level, within
    :data:`MAX_EXPOSURE_GAIN`: exposure normalisation (beyond the paper), what a camera's
    auto-exposure does, for lights that come up or go down during a shot; without it a darker
    frame's pixels fall below the hue threshold into the brightness bins, and its grey pixels
    into darker brightness bins, than the reference's.
    """
    m = _channel_means(bgr, step)
    grey = m.mean()
    if level is not None and math.isfinite(level) and level > 0.0:
        grey = float(np.clip(level, grey / MAX_EXPOSURE_GAIN, grey * MAX_EXPOSURE_GAIN))
    return np.asarray(grey / np.maximum(m, 1.0), dtype=np.float64)


def apply_gains(bgr: NDArray[np.uint8], gains: F64 | None) -> NDArray[np.uint8]:
    if gains is None:
        return bgr
    return u8(cv2.transform(bgr, np.diag(gains)))  # per-channel gain, saturating uint8


def bhattacharyya(q: F64, q_ref: F64) -> float:
    """Bhattacharyya distance of two histograms (normalised here), eq. (2)."""
    q = np.asarray(q, dtype=np.float64)
    r = np.asarray(q_ref, dtype=np.float64)
    sq, sr = q.sum(), r.sum()
    if sq <= 0 or sr <= 0:
        return 1.0
    bc = float(np.sum(np.sqrt((q / sq) * (r / sr))))
    return math.sqrt(max(1.0 - bc, 0.0))


def colour_likelihood(sum_b2: F64 | float, lambda_col: float) -> F64:
    """P(z_col | s) = exp(-sum_p B_p^2 / lambda_col), eq. (3)."""
    return np.exp(-np.asarray(sum_b2, dtype=np.float64) / lambda_col)


def motion_likelihood(e_nonmotion: F64 | float, lambda_mot: float) -> F64:
    """P(z_mot | s) = exp(-E^2 / lambda_mot), eq. (4)."""
    e = np.asarray(e_nonmotion, dtype=np.float64)
    return np.exp(-(e * e) / lambda_mot)


# ----------------------------------------------------------------------------- integral


@njit(cache=True, nogil=True)
def _binned_integral(hsv: NDArray[np.uint8], n: int, cell: int, s_min: int, v_min: int,
                     inc: np.float32, soft: bool) -> F32:
    H, W = hsv.shape[0], hsv.shape[1]
    hc = (H + cell - 1) // cell
    wc = (W + cell - 1) // cell
    nb = n * n + n
    out = np.zeros((hc + 1, wc + 1, nb), np.float32)
    for y in range(H):
        cy = y // cell + 1
        for x in range(W):
            cx = x // cell + 1
            h = int(hsv[y, x, 0])
            s = int(hsv[y, x, 1])
            v = int(hsv[y, x, 2])
            if s >= s_min and v >= v_min:
                if soft:
                    # bilinear vote between the two nearest bin centres in hue (circular) and
                    # saturation: a small hue shift moves weight instead of flipping a bin
                    fh = (h + 0.5) * n / 180.0 - 0.5
                    fs = (s + 0.5) * n / 256.0 - 0.5
                    h0 = math.floor(fh)
                    ah = fh - h0
                    h1 = (h0 + 1) % n
                    h0 = h0 % n
                    if fs <= 0.0:
                        s0 = 0
                        s1 = 0
                        a_s = 0.0
                    elif fs >= n - 1:
                        s0 = n - 1
                        s1 = n - 1
                        a_s = 0.0
                    else:
                        s0 = int(fs)
                        s1 = s0 + 1
                        a_s = fs - s0
                    out[cy, cx, h0 * n + s0] += inc * (1.0 - ah) * (1.0 - a_s)
                    out[cy, cx, h0 * n + s1] += inc * (1.0 - ah) * a_s
                    out[cy, cx, h1 * n + s0] += inc * ah * (1.0 - a_s)
                    out[cy, cx, h1 * n + s1] += inc * ah * a_s
                    continue
                hb = h * n // 180
                if hb > n - 1:
                    hb = n - 1
                b = hb * n + s * n // 256
            else:
                b = n * n + v * n // 256
            out[cy, cx, b] += inc
    for cy in range(1, hc + 1):
        for cx in range(1, wc + 1):
            for b in range(nb):
                out[cy, cx, b] += out[cy - 1, cx, b] + out[cy, cx - 1, b] - out[cy - 1, cx - 1, b]
    return out


def binned_integral(hsv_roi: NDArray[np.uint8], n: int, cell: int = 1,
                    s_min: int = S_MIN_DEFAULT, v_min: int = V_MIN_DEFAULT,
                    pixel_weight: float = 1.0, soft: bool | None = None) -> F32:
    """Integral histogram (rows+1, cols+1, N*N+N) of an HSV region on a ``cell`` px grid.

    ``pixel_weight``: what one pixel counts for; 4 when the region was subsampled by 2 in
    each direction, so that counts stay in full-resolution pixels. ``soft``: each chromatic
    pixel votes bilinearly for the two nearest hue (circular) and saturation bin centres
    instead of one bin (default ``SOFT_DEFAULT``).
    """
    return _binned_integral(np.ascontiguousarray(hsv_roi), n, max(int(cell), 1), s_min, v_min,
                            np.float32(pixel_weight),
                            bool(SOFT_DEFAULT if soft is None else soft))


@njit(cache=True, nogil=True, inline="always")
def _corner(ih: F32, u: float, v: float,
            sign: float) -> tuple[int, int, int, int, float, float, float, float]:
    # bilinear interpolation of the integral histogram at grid coordinates (u, v): the four
    # nodes (rows iv, iv1; columns iu, iu1) and their signed weights
    hc = ih.shape[0] - 1
    wc = ih.shape[1] - 1
    u = min(max(u, 0.0), float(wc))
    v = min(max(v, 0.0), float(hc))
    iu = min(int(u), wc - 1) if wc > 0 else 0
    iv = min(int(v), hc - 1) if hc > 0 else 0
    fu = u - iu
    fv = v - iv
    w00 = sign * (1 - fu) * (1 - fv)
    w01 = sign * fu * (1 - fv)
    w10 = sign * (1 - fu) * fv
    w11 = sign * fu * fv
    return iu, min(iu + 1, wc), iv, min(iv + 1, hc), w00, w01, w10, w11


@njit(cache=True, nogil=True)
def _rect_hist(ih: F32, cell: float, x0: float, y0: float, x1: float, y1: float,
               out: F64) -> None:
    # counts of the rectangle: + (x1, y1) - (x0, y1) - (x1, y0) + (x0, y0), each corner
    # bilinear between four nodes; one pass over the bins, each bin summed from 0 corner
    # by corner in that order
    au, au1, av, av1, a00, a01, a10, a11 = _corner(ih, x1 / cell, y1 / cell, 1.0)
    bu, bu1, bv, bv1, b00, b01, b10, b11 = _corner(ih, x0 / cell, y1 / cell, -1.0)
    cu, cu1, cv, cv1, c00, c01, c10, c11 = _corner(ih, x1 / cell, y0 / cell, -1.0)
    du, du1, dv, dv1, d00, d01, d10, d11 = _corner(ih, x0 / cell, y0 / cell, 1.0)
    ra00, ra01, ra10, ra11 = ih[av, au], ih[av, au1], ih[av1, au], ih[av1, au1]
    rb00, rb01, rb10, rb11 = ih[bv, bu], ih[bv, bu1], ih[bv1, bu], ih[bv1, bu1]
    rc00, rc01, rc10, rc11 = ih[cv, cu], ih[cv, cu1], ih[cv1, cu], ih[cv1, cu1]
    rd00, rd01, rd10, rd11 = ih[dv, du], ih[dv, du1], ih[dv1, du], ih[dv1, du1]
    for k in range(out.shape[0]):
        acc = 0.0 + (a00 * ra00[k] + a01 * ra01[k] + a10 * ra10[k] + a11 * ra11[k])
        acc = acc + (b00 * rb00[k] + b01 * rb01[k] + b10 * rb10[k] + b11 * rb11[k])
        acc = acc + (c00 * rc00[k] + c01 * rc01[k] + c10 * rc10[k] + c11 * rc11[k])
        out[k] = acc + (d00 * rd00[k] + d01 * rd01[k] + d10 * rd10[k] + d11 * rd11[k])


def rect_histogram(integral: F32, cell: int, xywh: tuple[float, float, float, float]) -> F64:
    """Counts of a rectangle (coordinates relative to the integral's origin) from the integral."""
    x, y, w, h = xywh
    out = np.zeros(integral.shape[2])
    _rect_hist(integral, float(cell), float(x), float(y), float(x + w), float(y + h), out)
    return out


@njit(cache=True, nogil=True)
def _rect_b2(ih: F32, cell: float, ox: float, oy: float, roi_w: float, roi_h: float,
             img_w: int, img_h: int, px0: float, py0: float, px1: float, py1: float,
             sqrt_ref: F64, hist: F64, outside_b2: float) -> float:
    # B^2 = 1 - sum_n sqrt(q(n) q*(n)) of the image rectangle (px0, py0)-(px1, py1), its part
    # outside the image counted at outside_b2 per pixel (1: matching nothing)
    area = (px1 - px0) * (py1 - py0)
    vx0 = max(px0, 0.0)
    vy0 = max(py0, 0.0)
    vx1 = min(px1, float(img_w))
    vy1 = min(py1, float(img_h))
    if area <= 0.0:
        return 1.0
    if vx1 - vx0 <= 0.0 or vy1 - vy0 <= 0.0:
        return outside_b2
    rx0 = min(max(vx0 - ox, 0.0), roi_w)
    ry0 = min(max(vy0 - oy, 0.0), roi_h)
    rx1 = min(max(vx1 - ox, 0.0), roi_w)
    ry1 = min(max(vy1 - oy, 0.0), roi_h)
    _rect_hist(ih, cell, rx0, ry0, rx1, ry1, hist)
    total = 0.0
    for b in range(hist.shape[0]):
        if hist[b] < 0.0:
            hist[b] = 0.0
        total += hist[b]
    if total <= 1e-9:
        return 1.0
    # sqrt(q(n)) first, in a loop of its own (vectorised: the same correctly rounded
    # divisions and roots), then the sum in bin order
    for b in range(hist.shape[0]):
        hist[b] = math.sqrt(hist[b] / total)
    bc = 0.0
    for b in range(hist.shape[0]):
        bc += hist[b] * sqrt_ref[b]
    vis = min((vx1 - vx0) * (vy1 - vy0) / area, 1.0)
    return vis * max(1.0 - bc, 0.0) + (1.0 - vis) * outside_b2


@njit(cache=True, nogil=True)
def _patch_residuals(ih: F32, cell: float, ox: float, oy: float, roi_w: float, roi_h: float,
                     img_w: int, img_h: int, particles: F64, rel: F64, aspect: float,
                     sqrt_ref: F64, outside_b2: float, out: F64) -> None:
    n_part = particles.shape[0]
    n_patch = rel.shape[0]
    hist = np.empty(sqrt_ref.shape[1])
    for i in range(n_part):
        hh = particles[i, 2]
        ww = hh * aspect
        left = particles[i, 0] - 0.5 * ww
        top = particles[i, 1] - 0.5 * hh
        for p in range(n_patch):
            # B_p^2, eq. (2)
            out[i, p] = _rect_b2(ih, cell, ox, oy, roi_w, roi_h, img_w, img_h,
                                 left + rel[p, 0] * ww, top + rel[p, 1] * hh,
                                 left + rel[p, 2] * ww, top + rel[p, 3] * hh, sqrt_ref[p],
                                 hist, outside_b2)


def patch_residuals(integral: F32, cell: int, roi_xywh: tuple[int, int, int, int],
                    image_wh: tuple[int, int], particles_xyh: F64, rel_boxes: F64,
                    aspect: float, sqrt_ref: F64, outside_b2: float = 1.0) -> F64:
    """B_p^2 (eq. 2) of every patch p at every particle (x, y, h): shape (particles, patches).

    The part of a patch outside the image counts ``outside_b2`` per pixel: 1 (the default)
    = matching nothing; less lets the filter follow a person out through the image border.
    """
    ox, oy, rw, rh = roi_xywh
    parts = np.ascontiguousarray(particles_xyh, dtype=np.float64)
    rel = np.ascontiguousarray(rel_boxes, dtype=np.float64)
    out = np.empty((parts.shape[0], rel.shape[0]))
    _patch_residuals(integral, float(cell), float(ox), float(oy), float(rw), float(rh),
                     int(image_wh[0]), int(image_wh[1]), parts, rel, float(aspect),
                     np.ascontiguousarray(sqrt_ref, dtype=np.float64), float(outside_b2), out)
    return out


def colour_residuals(integral: F32, cell: int, roi_xywh: tuple[int, int, int, int],
                     image_wh: tuple[int, int], particles_xyh: F64, rel_boxes: F64,
                     aspect: float, sqrt_ref: F64, outside_b2: float = 1.0) -> F64:
    """sum_p B_p^2 for every particle (x, y, h): the exponent of eq. (3) times lambda_col."""
    return np.asarray(patch_residuals(integral, cell, roi_xywh, image_wh, particles_xyh,
                                      rel_boxes, aspect, sqrt_ref, outside_b2).sum(axis=1),
                      dtype=np.float64)


@njit(cache=True, nogil=True)
def _ring_similarity(ih: F32, cell: float, ox: float, oy: float, roi_w: float, roi_h: float,
                     img_w: int, img_h: int, particles: F64, aspect: float, margin: float,
                     sqrt_ref: F64, out: F64) -> None:
    nb = sqrt_ref.shape[0]
    inner = np.empty(nb)
    outer = np.empty(nb)
    for i in range(particles.shape[0]):
        hh = particles[i, 2]
        ww = hh * aspect
        cx = particles[i, 0]
        cy = particles[i, 1]
        ix0, iy0, ix1, iy1 = cx - 0.5 * ww, cy - 0.5 * hh, cx + 0.5 * ww, cy + 0.5 * hh
        mx = margin * ww
        my = margin * hh
        ox0 = max(ix0 - mx, 0.0)
        oy0 = max(iy0 - my, 0.0)
        ox1 = min(ix1 + mx, float(img_w))
        oy1 = min(iy1 + my, float(img_h))
        if ox1 - ox0 <= 0.0 or oy1 - oy0 <= 0.0:
            out[i] = 0.0
            continue
        _rect_hist(ih, cell, min(max(ox0 - ox, 0.0), roi_w), min(max(oy0 - oy, 0.0), roi_h),
                   min(max(ox1 - ox, 0.0), roi_w), min(max(oy1 - oy, 0.0), roi_h), outer)
        vx0 = min(max(ix0, ox0), ox1)
        vy0 = min(max(iy0, oy0), oy1)
        vx1 = min(max(ix1, ox0), ox1)
        vy1 = min(max(iy1, oy0), oy1)
        if vx1 > vx0 and vy1 > vy0:
            _rect_hist(ih, cell, min(max(vx0 - ox, 0.0), roi_w),
                       min(max(vy0 - oy, 0.0), roi_h), min(max(vx1 - ox, 0.0), roi_w),
                       min(max(vy1 - oy, 0.0), roi_h), inner)
        else:
            inner[:] = 0.0
        total = 0.0
        for b in range(nb):
            outer[b] = max(outer[b] - inner[b], 0.0)
            total += outer[b]
        # a ring mostly outside the image says nothing about the size
        ring_area = (ox1 - ox0) * (oy1 - oy0) - (vx1 - vx0) * (vy1 - vy0)
        if total <= 1e-9 or ring_area < 0.25 * ((ww + 2 * mx) * (hh + 2 * my) - ww * hh):
            out[i] = 0.0
            continue
        bc = 0.0
        for b in range(nb):
            bc += math.sqrt(outer[b] / total) * sqrt_ref[b]
        out[i] = bc


def ring_similarity(integral: F32, cell: int, roi_xywh: tuple[int, int, int, int],
                    image_wh: tuple[int, int], particles_xyh: F64, aspect: float,
                    margin: float, sqrt_ref: F64) -> F64:
    """Bhattacharyya coefficient of the ring around each particle's main box with the target.

    The ring is the box grown by ``margin`` times its width and height on every side, minus
    the box (clipped to the image). A box smaller than the target has target colours in its
    ring (coefficient near 1); a box that encloses the target has background there. 0 where
    the ring lies mostly outside the image (no evidence either way).
    """
    ox, oy, rw, rh = roi_xywh
    parts = np.ascontiguousarray(particles_xyh, dtype=np.float64)
    out = np.empty(parts.shape[0])
    _ring_similarity(integral, float(cell), float(ox), float(oy), float(rw), float(rh),
                     int(image_wh[0]), int(image_wh[1]), parts, float(aspect), float(margin),
                     np.ascontiguousarray(sqrt_ref, dtype=np.float64), out)
    return out


@njit(cache=True, nogil=True)
def _motion_residuals(S: NDArray[np.int32], particles: F64, rel: F64, aspect: float,
                      scale: float) -> F64:
    img_h = S.shape[0] - 1
    img_w = S.shape[1] - 1
    n_part = particles.shape[0]
    out = np.empty(n_part)
    for i in range(n_part):
        hh = particles[i, 2] / scale
        ww = hh * aspect
        left = particles[i, 0] / scale - 0.5 * ww
        top = particles[i, 1] / scale - 0.5 * hh
        moving = 0.0
        area = 0.0
        for p in range(rel.shape[0]):
            x0 = round(left + rel[p, 0] * ww)
            y0 = round(top + rel[p, 1] * hh)
            x1 = round(left + rel[p, 2] * ww)
            y1 = round(top + rel[p, 3] * hh)
            if x1 <= x0 or y1 <= y0:
                continue
            cx0 = min(max(x0, 0), img_w)
            cy0 = min(max(y0, 0), img_h)
            cx1 = min(max(x1, 0), img_w)
            cy1 = min(max(y1, 0), img_h)
            # "the covered area" of eq. (4) is the part inside the image
            area += (cx1 - cx0) * (cy1 - cy0)
            moving += S[cy1, cx1] - S[cy0, cx1] - S[cy1, cx0] + S[cy0, cx0]
        out[i] = 1.0 if area <= 0 else 1.0 - moving / area
    return out


def motion_residuals(motion_integral: NDArray[np.int32], particles_xyh: F64, rel_boxes: F64,
                     aspect: float, scale: int = 1) -> F64:
    """E for every particle: fraction of non-motion pixels under its patches (eq. 4).

    ``scale``: the motion image's subsampling (2 = half resolution).
    """
    return _motion_residuals(motion_integral,
                             np.ascontiguousarray(particles_xyh, dtype=np.float64),
                             np.ascontiguousarray(rel_boxes, dtype=np.float64), float(aspect),
                             float(scale))


@njit(cache=True, nogil=True)
def _motion_update(gray: NDArray[np.uint8], step: int, prev: NDArray[np.uint8],
                   mhi_prev: NDArray[np.uint8], threshold: int, duration: int,
                   mhi: NDArray[np.uint8], S: NDArray[np.int32]) -> None:
    # one pass over gray[::step, ::step]: the saturating decay, |g - prev| > threshold sets
    # the duration (cv2.absdiff, cv2.subtract, the masked set), prev updated in place, and S
    # the integral image of mhi > 0 (cv2.integral, CV_32S)
    H, W = prev.shape
    for x in range(W + 1):
        S[0, x] = 0
    for y in range(H):
        S[y + 1, 0] = 0
        run = 0
        for x in range(W):
            g = gray[y * step, x * step]
            # signed differences (int() of a uint8 is unsigned in numba)
            d = abs(np.int64(g) - np.int64(prev[y, x]))
            m = np.int64(mhi_prev[y, x]) - 1
            if m < 0:
                m = np.int64(0)
            if d > threshold:
                m = np.int64(duration)
            mhi[y, x] = m
            prev[y, x] = g
            if m > 0:
                run += 1
            S[y + 1, x + 1] = S[y, x + 1] + run


@njit(cache=True, nogil=True)
def _mask_integral(img: NDArray[np.uint8], floor: int) -> NDArray[np.int32]:
    # cv2.integral((img > floor).astype(np.uint8), sdepth=cv2.CV_32S) in one pass
    H, W = img.shape
    S = np.empty((H + 1, W + 1), np.int32)
    for x in range(W + 1):
        S[0, x] = 0
    for y in range(H):
        S[y + 1, 0] = 0
        run = 0
        for x in range(W):
            if img[y, x] > floor:
                run += 1
            S[y + 1, x + 1] = S[y, x + 1] + run
    return S


class MotionHistory:
    """Absolute motion history image z_mot (Bobick & Davis, the paper's ref. [8]).

    A pixel whose grey level changed by more than ``threshold`` since the last frame is set to
    ``duration_frames``; every other pixel decays by one per frame. Motion pixels are > 0.
    """

    def __init__(self, duration_frames: int = 8, threshold: int = 20) -> None:
        self.duration_frames = int(duration_frames)
        self.threshold = int(threshold)
        self._prev: NDArray[np.uint8] | None = None
        self.mhi: NDArray[np.uint8] | None = None
        self._integral: NDArray[np.int32] | None = None  # of mhi > 0, made by update()

    def reset(self) -> None:
        self._prev = None
        self.mhi = None
        self._integral = None

    def update(self, gray_u8: NDArray[np.uint8], step: int = 1) -> NDArray[np.uint8]:
        """Feed one grey frame, ``gray_u8[::step, ::step]`` (any strides: a colour frame's
        channel view needs no copy); returns the motion history image (uint8, 0 = no
        motion), a new array every frame."""
        step = max(int(step), 1)
        shape = ((gray_u8.shape[0] + step - 1) // step, (gray_u8.shape[1] + step - 1) // step)
        if self._prev is None or self._prev.shape != shape or self.mhi is None:
            self._prev = np.ascontiguousarray(gray_u8[::step, ::step])
            self.mhi = np.zeros(shape, np.uint8)
            self._integral = np.zeros((shape[0] + 1, shape[1] + 1), np.int32)
            return self.mhi
        mhi = np.empty(shape, np.uint8)
        integral = np.empty((shape[0] + 1, shape[1] + 1), np.int32)
        _motion_update(gray_u8, step, self._prev, self.mhi, self.threshold,
                       min(self.duration_frames, 255), mhi, integral)
        self.mhi = mhi
        self._integral = integral
        return mhi

    def motion_integral(self, recent_frames: int = 0) -> NDArray[np.int32]:
        """Integral image (H+1, W+1) of the motion mask (MHI > 0); with ``recent_frames``
        > 0 only of the pixels that changed in the last ``recent_frames`` frames."""
        assert self.mhi is not None
        if recent_frames > 0:
            return _mask_integral(self.mhi, max(min(self.duration_frames, 255) - recent_frames,
                                                0))
        if self._integral is None:
            self._integral = _mask_integral(self.mhi, 0)
        return self._integral  # made with the motion history image by update()
