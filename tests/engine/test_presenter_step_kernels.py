"""The compiled per-frame pieces of the presenter tracker give numpy's numbers bit for bit."""

from __future__ import annotations

import cv2
import numpy as np

from engine.arrays import i32, u8
from engine.particles import systematic_resample
from engine.presenter import filter as pf
from engine.presenter import frame_colour as fc
from engine.presenter import step_kernels as sk
from engine.presenter.likelihood import MotionHistory


def test_pairwise_sum_is_numpys_sum() -> None:
    rng = np.random.default_rng(1)
    for n in (*range(1, 300), 600, 1111, 5000):
        a = rng.standard_normal(n) * 10.0 ** rng.uniform(-3, 3, n)
        assert sk.pairwise_sum(a, 0, n) == a.sum()
        lo = int(rng.integers(0, n))
        assert sk.pairwise_sum(a, lo, n - lo) == a[lo:].sum()


def test_resample_predict_is_resample_then_predict_then_drift() -> None:
    rng = np.random.default_rng(2)
    for n_in, n_out in ((100, 100), (600, 300), (100, 600), (7, 100)):
        particles = rng.uniform(0, 300, (n_in, 3))
        weights = pf.normalise(rng.exponential(1.0, n_in) ** 4)
        sigma = (3.5, 2.25, 0.75)
        h_limits = (60.0, 140.0)
        drift = np.array([1.5, -0.25])
        seed = int(rng.integers(1 << 30))
        ref_rng = np.random.default_rng(seed)
        idx = systematic_resample(weights, n_out, ref_rng)
        ref = pf.predict(particles[idx], sigma, ref_rng, h_limits)
        ref[:, :2] += 0.5 * drift
        got_rng = np.random.default_rng(seed)
        u = got_rng.random()
        noise = got_rng.standard_normal((n_out, 3))
        got = sk.resample_predict(weights, u, n_out, particles, noise, np.asarray(sigma),
                                  h_limits[0], h_limits[1], 0.5 * float(drift[0]),
                                  0.5 * float(drift[1]))
        assert np.array_equal(got, ref)
    # all weights zero: a uniform draw, as systematic_resample's
    zero = np.zeros(50)
    particles = rng.uniform(0, 300, (50, 3))
    ref = particles[systematic_resample(zero, 50, np.random.default_rng(3))]
    got = sk.resample_predict(zero, np.random.default_rng(3).random(), 50, particles,
                              np.zeros((50, 3)), np.zeros(3), -np.inf, np.inf, 0.0, 0.0)
    assert np.array_equal(got, ref)


def test_roi_bounds_and_median() -> None:
    rng = np.random.default_rng(4)
    for _ in range(50):
        states = np.column_stack([rng.uniform(-50, 700, 100), rng.uniform(-50, 500, 100),
                                  rng.uniform(10, 300, 100)])
        aspect, grow = float(rng.uniform(0.2, 1.5)), 1.5
        ws = states[:, 2] * aspect
        ref = (int(max(np.floor(np.min(states[:, 0] - grow * ws / 2)) - 1, 0)),
               int(max(np.floor(np.min(states[:, 1] - grow * states[:, 2] / 2)) - 1, 0)),
               int(min(np.ceil(np.max(states[:, 0] + grow * ws / 2)) + 1, 640)),
               int(min(np.ceil(np.max(states[:, 1] + grow * states[:, 2] / 2)) + 1, 480)))
        assert sk.roi_bounds(states, aspect, grow, 640, 480) == ref
    for n in (1, 2, 3, 4, 5):
        v = rng.standard_normal(n)
        assert sk.median_small(v) == float(np.median(v))
    assert np.isnan(sk.median_small(np.array([1.0, np.nan, 0.0])))


def test_patch_hists_is_the_python_loop() -> None:
    rng = np.random.default_rng(5)
    img = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    integral, used = fc.roi_integral(img, (10, 5, 150, 115), 2, 3, 10, None, 26, 51, 4.0,
                                     True)
    ri = fc.RoiIntegral(integral, used, 110, 6, (10, 5, 140, 110), (160, 120))
    rel = np.array([[0.25, 0.0, 0.75, 0.25], [0.1, 0.25, 0.9, 0.6], [0.2, 0.6, 0.8, 1.0]])
    aspect = 0.4
    for x, y, h in ((80.0, 60.0, 80.0), (20.0, 60.0, 80.0), (80.0, 60.0, 20.5)):
        # the loop view.ViewTracker._patch_hists had
        w = h * aspect
        left, top = x - w / 2.0, y - h / 2.0
        ref: np.ndarray | None = np.empty((3, 110))
        for k, r in enumerate(rel):
            bx, by, bw, bh = (left + r[0] * w, top + r[1] * h, (r[2] - r[0]) * w,
                              (r[3] - r[1]) * h)
            if bx < 0 or by < 0 or bx + bw > 160 or by + bh > 120:
                ref = None
                break
            c = np.maximum(ri.rect_counts((bx - 10, by - 5, bw, bh)), 0.0)
            assert ref is not None
            ref[k] = c / c.sum()
        out = np.empty((3, 110))
        ok = sk.patch_hists(integral, 6.0, 10.0, 5.0, 160, 120, x, y, h, rel, aspect, used,
                            110, out)
        assert ok == (ref is not None)
        if ref is not None:
            assert np.array_equal(out, ref)


def test_motion_history_on_a_channel_view_is_the_copied_frames() -> None:
    # the strided update (a colour frame's channel, every other pixel) against the cv2 steps
    # on a copy: absdiff, saturating decay, the masked set, the integral of the mask
    rng = np.random.default_rng(6)
    mh = MotionHistory(duration_frames=5, threshold=20)
    prev: np.ndarray | None = None
    ref_mhi: np.ndarray | None = None
    for t in range(8):
        bgr = (rng.integers(0, 256, (61, 81, 3), dtype=np.uint8) if t % 3 == 0 else
               np.clip(rng.normal(120, 30, (61, 81, 3)), 0, 255).astype(np.uint8))
        got = mh.update(bgr[:, :, 1], 2)
        gray = np.ascontiguousarray(bgr[::2, ::2, 1])
        if prev is None or ref_mhi is None:
            ref_mhi = np.zeros_like(gray)
        else:
            diff = cv2.absdiff(gray, prev)
            ref_mhi = u8(cv2.subtract(ref_mhi, np.array([1.0])))
            ref_mhi[diff > 20] = 5
        prev = gray
        assert np.array_equal(got, ref_mhi)
        ref_s = i32(cv2.integral((ref_mhi > 0).astype(np.uint8), sdepth=cv2.CV_32S))
        assert np.array_equal(mh.motion_integral(), ref_s)
        ref_r = i32(cv2.integral((ref_mhi > 2).astype(np.uint8), sdepth=cv2.CV_32S))
        assert np.array_equal(mh.motion_integral(3), ref_r)


def test_quantiles_are_numpys() -> None:
    rng = np.random.default_rng(7)
    for n in (1, 2, 3, 9, 10, 11, 96, 97):
        for q in (0.0, 0.1, 0.5, 0.9, 1.0):
            r = rng.standard_normal((n, 3))
            r[rng.integers(0, n)] = r[0]  # ties
            assert np.array_equal(sk.quantile_columns(r, q), np.quantile(r, q, axis=0))
            assert sk.quantile(r[:, 0], q) == float(np.quantile(r[:, 0], q))
    assert np.isnan(sk.quantile(np.array([0.0, np.nan, 1.0]), 0.5))


def test_background_boxes_are_the_numpy_selection() -> None:
    rng = np.random.default_rng(8)
    for x, y, w, h in ((320.0, 240.0, 60.0, 200.0), (40.0, 300.0, 150.0, 400.0)):
        k = rng.uniform(0.8, 1.25, 384)
        hs, ws = h * k, w * k
        lo_x, hi_x, lo_y, hi_y = sk.background_bounds(k, w, h, 640, 480)
        assert np.array_equal(lo_x, ws / 2)
        assert np.array_equal(hi_x, np.maximum(640 - ws / 2, ws / 2 + 1e-6))
        assert np.array_equal(hi_y, np.maximum(480 - hs / 2, hs / 2 + 1e-6))
        cx, cy = rng.uniform(lo_x, hi_x), rng.uniform(lo_y, hi_y)
        # the selection view.ViewTracker._background_levels made with numpy
        ix = np.clip(np.minimum(cx + ws / 2, x + w / 2) - np.maximum(cx - ws / 2, x - w / 2),
                     0, None)
        iy = np.clip(np.minimum(cy + hs / 2, y + h / 2) - np.maximum(cy - hs / 2, y - h / 2),
                     0, None)
        inter = ix * iy
        iou = inter / (ws * hs + w * h - inter)
        keep = np.flatnonzero((iou < 0.1) & (ws <= 640) & (hs <= 480))[:96]
        ref = np.stack([cx[keep], cy[keep], hs[keep]], axis=1)
        assert np.array_equal(sk.background_boxes(k, cx, cy, x, y, w, h, 640, 480, 96), ref)
