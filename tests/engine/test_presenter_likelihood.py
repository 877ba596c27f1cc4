"""Equation-level checks of the presenter likelihoods (VR-TV paper eq. 2-4)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from engine.presenter.likelihood import (
    MotionHistory,
    bhattacharyya,
    bin_map,
    binned_integral,
    colour_likelihood,
    colour_residuals,
    direct_histogram,
    motion_likelihood,
    motion_residuals,
    n_bins_total,
    rect_histogram,
)


def _random_hsv(rng: np.random.Generator, h: int = 40, w: int = 50) -> np.ndarray:
    bgr = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)


def test_bhattacharyya_matches_direct_formula() -> None:
    rng = np.random.default_rng(1)
    for _ in range(20):
        q = rng.random(110)
        r = rng.random(110)
        qn, rn = q / q.sum(), r / r.sum()
        direct = math.sqrt(1.0 - sum(math.sqrt(a * b) for a, b in zip(qn, rn, strict=True)))
        assert bhattacharyya(q, r) == pytest.approx(direct, abs=1e-12)
    assert bhattacharyya(q, q) == pytest.approx(0.0, abs=1e-7)
    one_hot = np.eye(110)
    assert bhattacharyya(one_hot[0], one_hot[5]) == pytest.approx(1.0)


def test_colour_and_motion_likelihoods_are_eq_3_and_4() -> None:
    assert colour_likelihood(0.3, 0.15) == pytest.approx(math.exp(-0.3 / 0.15))
    assert motion_likelihood(0.5, 2.0) == pytest.approx(math.exp(-0.25 / 2.0))


def test_bin_map_puts_grey_pixels_in_brightness_bins() -> None:
    hsv = np.array([[[0, 0, 255], [60, 200, 200], [179, 255, 255]]], np.uint8)
    b = bin_map(hsv, 10)
    assert b[0, 0] == 100 + 9  # grey, brightest bin
    assert b[0, 1] == (60 * 10 // 180) * 10 + 200 * 10 // 256
    assert b[0, 2] == 9 * 10 + 9
    assert n_bins_total(10) == 110


def test_integral_histogram_equals_direct_histogram() -> None:
    rng = np.random.default_rng(2)
    hsv = _random_hsv(rng)
    integral = binned_integral(hsv, 10, cell=1)
    for _ in range(30):
        x, y = int(rng.integers(0, 40)), int(rng.integers(0, 30))
        w, h = int(rng.integers(1, 50 - x)), int(rng.integers(1, 40 - y))
        direct = direct_histogram(hsv, (x, y, w, h), 10)
        fast = rect_histogram(integral, 1, (x, y, w, h))
        np.testing.assert_allclose(fast, direct, atol=1e-3)


def test_integral_histogram_on_a_cell_grid_is_exact_on_cell_boundaries() -> None:
    rng = np.random.default_rng(3)
    hsv = _random_hsv(rng, 48, 64)
    integral = binned_integral(hsv, 10, cell=4)
    for x, y, w, h in ((0, 0, 64, 48), (8, 4, 16, 20), (12, 40, 40, 8)):
        np.testing.assert_allclose(rect_histogram(integral, 4, (x, y, w, h)),
                                   direct_histogram(hsv, (x, y, w, h), 10), atol=1e-3)


def test_colour_residuals_equal_sum_of_squared_bhattacharyya() -> None:
    rng = np.random.default_rng(4)
    hsv = _random_hsv(rng, 60, 80)
    rel = np.array([[0.0, 0.0, 1.0, 0.5], [0.0, 0.5, 1.0, 1.0]])
    ref = np.stack([rng.random(110), rng.random(110)])
    ref /= ref.sum(axis=1, keepdims=True)
    states = np.array([[40.0, 30.0, 20.0], [25.0, 22.0, 16.0]])  # (x, y, h), aspect 1
    got = colour_residuals(binned_integral(hsv, 10, 1, soft=False), 1, (0, 0, 80, 60),
                           (80, 60), states, rel, 1.0, np.sqrt(ref))
    for k, (x, y, h) in enumerate(states):
        want = 0.0
        for p in range(2):
            box = (int(x - h / 2 + rel[p, 0] * h), int(y - h / 2 + rel[p, 1] * h),
                   int((rel[p, 2] - rel[p, 0]) * h), int((rel[p, 3] - rel[p, 1]) * h))
            want += bhattacharyya(direct_histogram(hsv, box, 10, soft=False), ref[p]) ** 2
        assert got[k] == pytest.approx(want, abs=1e-6)


def test_soft_votes_keep_counts_and_soften_a_hue_shift() -> None:
    hsv = np.zeros((10, 10, 3), np.uint8)
    hsv[..., 0], hsv[..., 1], hsv[..., 2] = 17, 200, 200  # hue just below a bin edge (18)
    shifted = hsv.copy()
    shifted[..., 0] = 19  # just above it
    for soft in (False, True):
        assert direct_histogram(hsv, (0, 0, 10, 10), 10, soft=soft).sum() == pytest.approx(100)
    hard = bhattacharyya(direct_histogram(hsv, (0, 0, 10, 10), 10, soft=False),
                         direct_histogram(shifted, (0, 0, 10, 10), 10, soft=False))
    soft_b = bhattacharyya(direct_histogram(hsv, (0, 0, 10, 10), 10, soft=True),
                           direct_histogram(shifted, (0, 0, 10, 10), 10, soft=True))
    assert hard == pytest.approx(1.0)
    assert soft_b < 0.2


def test_motion_history_of_a_moving_square() -> None:
    mh = MotionHistory(duration_frames=5, threshold=20)
    frames = []
    for t in range(6):
        img = np.zeros((60, 100), np.uint8)
        img[20:40, 10 + 10 * t: 30 + 10 * t] = 200  # moves 10 px right per frame
        frames.append(img)
        mhi = mh.update(img)
    # newest motion (leading and trailing edges of the last step) holds the full duration
    assert mhi[30, 10 + 10 * 5 + 15] == 5
    # the square's path decays with age: older positions have lower values, far left is 0
    assert mhi[30, 12] < mhi[30, 35] <= 5
    assert mhi[5, 50] == 0  # never moved there
    assert mhi[30, 99] == 0
    # E is the fraction of non-motion pixels under the patches (eq. 4)
    S = mh.motion_integral()
    rel = np.array([[0.0, 0.0, 1.0, 1.0]])
    on = motion_residuals(S, np.array([[60.0, 30.0, 20.0]]), rel, 1.0)[0]
    off = motion_residuals(S, np.array([[85.0, 8.0, 10.0]]), rel, 1.0)[0]
    assert on < 0.5
    assert off == pytest.approx(1.0)
