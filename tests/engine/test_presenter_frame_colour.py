"""The one-pass colour kernels (engine.presenter.frame_colour) give what the three-step
pipeline gave (cv2.transform gains, cv2.cvtColor HSV, likelihood's integral and queries), bit
for bit; and the presenter tracker's results are the same with either."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest

from engine.arrays import u8
from engine.presenter import extent as ex
from engine.presenter import frame_colour as fc
from engine.presenter import likelihood as lk


def _reference_bins(bgr: np.ndarray, roi: tuple[int, int, int, int], step: int,
                    gains: np.ndarray | None) -> np.ndarray:
    x0, y0, x1, y1 = roi
    return u8(cv2.cvtColor(lk.apply_gains(bgr[y0:y1:step, x0:x1:step], gains),
                           cv2.COLOR_BGR2HSV))


def test_hsv_equals_opencv_on_every_colour() -> None:
    c = np.arange(1 << 24, dtype=np.uint32)
    img = np.stack([(c >> 16) & 255, (c >> 8) & 255, c & 255], -1).astype(np.uint8)
    img = img.reshape(4096, 4096, 3)
    assert np.array_equal(fc.hsv_image(img), cv2.cvtColor(img, cv2.COLOR_BGR2HSV))


def test_gain_table_equals_cv2_transform() -> None:
    rng = np.random.default_rng(1)
    for _ in range(20):
        gains = rng.uniform(0.4, 2.5, 3)
        h, w = (int(v) for v in rng.integers(1, 90, 2))
        img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        lut = fc.gain_lut(gains)
        mine = np.stack([lut[img[..., k], k] for k in range(3)], -1)
        assert np.array_equal(mine, lk.apply_gains(img, gains))
        assert np.array_equal(fc.hsv_image(img[::2, 1::3], gains),
                              _reference_bins(img, (1, 0, w, h), 1, gains)[::2, ::3])


def _scene(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    # flat patches too: grey, dark, saturated (every kind of bin)
    img[10:60, 20:70] = (90, 90, 90)
    img[60:100, 80:150] = (20, 30, 200)
    img[0:20, 100:160] = (10, 10, 10)
    return cv2.GaussianBlur(img, (5, 5), 0)


@pytest.mark.parametrize("soft", [True, False])
def test_roi_integral_equals_binned_integral(soft: bool) -> None:
    img = _scene(2)
    gains = lk.grey_world_gains(img)
    for roi, step, cell in (((0, 0, 160, 120), 1, 1), ((7, 3, 151, 117), 2, 3),
                            ((40, 20, 100, 95), 1, 5), ((0, 0, 160, 120), 4, 2)):
        ref = lk.binned_integral(_reference_bins(img, roi, step, gains), 10, cell,
                                 pixel_weight=float(step * step), soft=soft)
        got, used = fc.roi_integral(img, roi, step, cell, 10, gains, lk.S_MIN_DEFAULT,
                                    lk.V_MIN_DEFAULT, float(step * step), soft)
        ri = fc.RoiIntegral(got, used, lk.n_bins_total(10), cell, (0, 0, 1, 1), (1, 1))
        assert np.array_equal(ri.full(), ref)
        assert np.array_equal(used, np.flatnonzero(ref[-1, -1] > 0))


def _reference_context(img: np.ndarray, roi: tuple[int, int, int, int], step: int,
                       cell: int) -> tuple[np.ndarray, fc.RoiIntegral]:
    gains = lk.grey_world_gains(img)
    ref = lk.binned_integral(_reference_bins(img, roi, step, gains), 10, cell // step,
                             pixel_weight=float(step * step))
    got, used = fc.roi_integral(img, roi, step, cell // step, 10, gains, lk.S_MIN_DEFAULT,
                                lk.V_MIN_DEFAULT, float(step * step), True)
    x0, y0, x1, y1 = roi
    ri = fc.RoiIntegral(got, used, lk.n_bins_total(10), cell, (x0, y0, x1 - x0, y1 - y0),
                        (img.shape[1], img.shape[0]))
    return ref, ri


def test_queries_equal_likelihood_queries() -> None:
    img = _scene(3)
    rng = np.random.default_rng(4)
    roi = (10, 5, 150, 118)
    ref, ri = _reference_context(img, roi, 2, 4)
    rel = np.array([[0.1, 0.0, 0.9, 0.3], [0.0, 0.3, 1.0, 0.7], [0.2, 0.7, 0.8, 1.0]])
    # particles inside, across the image border and across the region's border
    states = np.column_stack([rng.uniform(-20, 180, 200), rng.uniform(-20, 140, 200),
                              rng.uniform(5, 90, 200)])
    sqrt_ref = np.sqrt(rng.dirichlet(np.ones(110) * 0.3, 3))
    sqrt_ref[:, ::7] = 0.0
    pooled = np.sqrt(rng.dirichlet(np.ones(110) * 0.3))
    wh = (img.shape[1], img.shape[0])
    roi_xywh = ri.roi_xywh
    for ring_weight in (0.0, 1.0, 0.5):
        want = lk.colour_residuals(ref, 4, roi_xywh, wh, states, rel, 0.5, sqrt_ref)
        if ring_weight > 0:
            want = want + ring_weight * lk.ring_similarity(ref, 4, roi_xywh, wh, states, 0.5,
                                                           0.25, pooled)
        got = fc.colour_b2(ri, states, rel, 0.5, sqrt_ref, ring_weight, 0.25, pooled)
        assert np.array_equal(got, want)
    for outside in (1.0, 0.3):
        assert np.array_equal(fc.patch_b2(ri, states, rel, 0.5, sqrt_ref, outside),
                              lk.patch_residuals(ref, 4, roi_xywh, wh, states, rel, 0.5,
                                                 sqrt_ref, outside))
    for box in ((3.0, 4.0, 50.0, 60.0), (0.0, 0.0, 140.0, 113.0), (10.5, 20.25, 7.5, 9.0)):
        assert np.array_equal(ri.rect_counts(box), lk.rect_histogram(ref, 4, box))


def _reference_extent(bgr: np.ndarray, gains: np.ndarray | None, xyh: np.ndarray,
                      aspect: float, fg_hist: np.ndarray, n_bins: int,
                      w_max_frac: float = 2.2,
                      lut: np.ndarray | None = None) -> tuple[float, float] | None:
    # engine.presenter.extent.measure_extent as it was in numpy (defaults inlined; the
    # gains applied by cv2.transform, so no table)
    search_frac, top_skip_frac, bg_from_frac, col_frac, max_gap_px, w_min_frac = (
        1.6, 0.25, 1.2, 0.15, 8.0, 0.7)
    step = ex.STEP
    H, W = bgr.shape[:2]
    x, y, h = (float(v) for v in xyh)
    w0 = h * aspect
    if w0 < 4 or h < 4:
        return None
    y0, y1 = int(max(y - h / 2 + top_skip_frac * h, 0)), int(min(y + h / 2, H))
    xa, xb = int(max(x - search_frac * w0, 0)), int(min(x + search_frac * w0, W))
    if y1 - y0 < 4 or xb - xa < 4:
        return None
    strip = lk.apply_gains(np.ascontiguousarray(bgr[y0:y1:step, xa:xb:step]), gains)
    bins = lk.bin_map(u8(cv2.cvtColor(strip, cv2.COLOR_BGR2HSV)), n_bins)
    cols = xa + step * np.arange(bins.shape[1]) + 0.5 * step
    outer = np.abs(cols - x) > bg_from_frac * w0
    if int(outer.sum()) < 3:
        return None
    g = np.bincount(bins[:, outer].ravel(), minlength=len(fg_hist)).astype(np.float64)
    g /= max(g.sum(), 1.0)
    ratio = fg_hist / np.maximum(fg_hist + g, 1e-12)
    fg_cols = np.mean(ratio[bins] > 0.5, axis=0) >= col_frac
    c = int(np.clip(np.searchsorted(cols, x), 0, len(cols) - 1))
    max_gap = max(int(max_gap_px / step), 1)
    lo = hi = c
    for rng_, side in ((range(c - 1, -1, -1), "lo"), (range(c + 1, len(cols)), "hi")):
        gap = 0
        for i in rng_:
            if fg_cols[i]:
                gap = 0
                if side == "lo":
                    lo = i
                else:
                    hi = i
            else:
                gap += 1
                if gap > max_gap:
                    break
    left, right = cols[lo] - 0.5 * step, cols[hi] + 0.5 * step
    width = float(np.clip(right - left, w_min_frac * w0, w_max_frac * w0))
    centre = float(np.clip(0.5 * (left + right), x - ex.SHIFT * w0, x + ex.SHIFT * w0))
    return centre, width


def test_extent_equals_the_numpy_version() -> None:
    img = _scene(5)
    gains = lk.grey_world_gains(img)
    rng = np.random.default_rng(6)
    fg = rng.dirichlet(np.ones(110) * 0.2)
    for x, y, h in ((110.0, 80.0, 40.0), (30.0, 40.0, 60.0), (150.0, 60.0, 30.0),
                    (80.0, 60.0, 3.0), (5.0, 110.0, 50.0)):
        xyh = np.array([x, y, h])
        assert ex.measure_extent(img, gains, xyh, 0.4, fg, 10) == _reference_extent(
            img, gains, xyh, 0.4, fg, 10)


# ----------------------------------------------------------------------------- the tracker


def _reference_kernels(monkeypatch: pytest.MonkeyPatch) -> None:
    """Swap the tracker's colour kernels for the three-step pipeline's functions."""

    def roi_integral(bgr: Any, roi: Any, step: int, cell: int, n: int, gains: Any, s_min: int,
                     v_min: int, pixel_weight: float, soft: bool, lut: Any = None) -> Any:
        ih = lk.binned_integral(_reference_bins(bgr, roi, step, gains), n, cell, s_min, v_min,
                                pixel_weight, soft)
        return ih, np.arange(ih.shape[2])  # every bin stored: the integral as it was

    def colour_b2(ri: Any, states: Any, rel: Any, aspect: float, sqrt_ref: Any,
                  ring_weight: float = 0.0, ring_margin: float = 0.25,
                  sqrt_pooled: Any = None) -> Any:
        b2 = lk.colour_residuals(ri.integral, ri.cell, ri.roi_xywh, ri.image_wh, states, rel,
                                 aspect, sqrt_ref)
        if ring_weight > 0:
            b2 = b2 + ring_weight * lk.ring_similarity(
                ri.integral, ri.cell, ri.roi_xywh, ri.image_wh, states, aspect, ring_margin,
                sqrt_pooled)
        return b2

    def patch_b2(ri: Any, states: Any, rel: Any, aspect: float, sqrt_ref: Any,
                 outside_b2: float = 1.0) -> Any:
        return lk.patch_residuals(ri.integral, ri.cell, ri.roi_xywh, ri.image_wh, states, rel,
                                  aspect, sqrt_ref, outside_b2)

    monkeypatch.setattr(fc, "roi_integral", roi_integral)
    monkeypatch.setattr(fc, "colour_b2", colour_b2)
    monkeypatch.setattr(fc, "patch_b2", patch_b2)
    monkeypatch.setattr(ex, "measure_extent", _reference_extent)
    import engine.presenter.view as view

    monkeypatch.setattr(view, "measure_extent", _reference_extent)


def _run(spec: str, kind: str) -> list[tuple[Any, ...]]:
    from engine.bench.presenter import make_tracker
    from engine.bench.presenter_scenarios import frames_of

    tracker = make_tracker(kind)
    out = []
    for f in frames_of(spec):
        r = tracker.track(f)
        d = r.details
        out.append((r.state, r.box_xywh, d.raw_xyh, d.p_col, d.loss_z, d.filtered_xyh))
    return out


@pytest.mark.parametrize("kind", ["presenter", "paper"])
def test_tracker_results_are_the_same_with_the_reference_kernels(
        kind: str, monkeypatch: pytest.MonkeyPatch) -> None:
    # the studio's rail walk: part-box model, ring term, background levels, width fit
    spec = "synthetic:frames=40,presenter=1,seed=3,path=rail,width=320,height=240"
    fast = _run(spec, kind)
    with monkeypatch.context() as m:
        _reference_kernels(m)
        ref = _run(spec, kind)
    assert len(fast) == len(ref) == 40
    for a, b in zip(fast, ref, strict=True):
        assert a[0] == b[0]
        assert np.array_equal(np.hstack(a[1:]), np.hstack(b[1:]), equal_nan=True)


def test_exposure_normalisation_brings_a_darker_frame_to_the_reference_level() -> None:
    """``grey_world_gains(level=...)``: a frame at 40 % exposure is balanced to the reference
    frame's mean grey (so its pixels land in the reference's bins), at most 4x either way,
    and without ``level`` the gains are the plain grey-world ones."""
    img = _scene(5)
    level = lk.frame_grey_level(img)
    dark = np.clip(img.astype(np.float64) * 0.4 + 0.5, 0, 255).astype(np.uint8)
    g = lk.grey_world_gains(dark, level=level)
    assert np.allclose(lk.frame_grey_level(lk.apply_gains(dark, g)), level, rtol=0.03)
    plain = lk.grey_world_gains(dark)
    assert np.array_equal(lk.grey_world_gains(dark, level=None), plain)
    assert np.allclose(g / plain, 1.0 / 0.4, rtol=0.03)
    black = np.full_like(img, 3)
    cap = lk.grey_world_gains(black, level=level) / lk.grey_world_gains(black)
    assert np.allclose(cap, lk.MAX_EXPOSURE_GAIN)
