"""engine.particles: the systematic resampler shared by the presenter and beacon filters."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.particles import effective_sample_size, systematic_resample


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(0.0, 10.0), min_size=2, max_size=40), st.integers(0, 2**31 - 1),
       st.integers(1, 600))
def test_each_particle_is_drawn_floor_or_ceil_of_its_expected_count(
        raw: list[float], seed: int, n_out: int) -> None:
    w = np.asarray(raw) + 1e-3
    idx = systematic_resample(w, n_out, np.random.default_rng(seed))  # unnormalised is fine
    assert idx.shape == (n_out,)
    assert idx.dtype == np.intp
    assert idx.min() >= 0
    assert idx.max() < len(w)
    counts = np.bincount(idx, minlength=len(w))
    assert np.all(np.abs(counts - n_out * w / w.sum()) < 1.0 + 1e-9)
    assert np.all(np.diff(idx) >= 0)  # a comb through the cdf: sorted indices


def test_resampling_mean_is_unbiased_over_seeds() -> None:
    rng = np.random.default_rng(0)
    weights = rng.random(7)
    weights /= weights.sum()
    values = rng.normal(size=7)
    means = [values[systematic_resample(weights, 10, np.random.default_rng(s))].mean()
             for s in range(4000)]
    assert np.mean(means) == pytest.approx(float(weights @ values), abs=0.01)


@pytest.mark.parametrize("bad", [np.zeros(5), np.full(5, np.nan), np.array([1, 2, np.inf, 0, 1])])
def test_degenerate_weights_draw_uniformly(bad: np.ndarray) -> None:
    idx = systematic_resample(bad, 10, np.random.default_rng(3))
    assert np.array_equal(np.bincount(idx, minlength=5), np.full(5, 2))


def test_draws_exactly_one_uniform_from_the_generator() -> None:
    rng = np.random.default_rng(11)
    systematic_resample(np.array([0.2, 0.8]), 50, rng)
    ref = np.random.default_rng(11)
    ref.random()
    assert rng.random() == ref.random()


def test_effective_sample_size() -> None:
    assert effective_sample_size(np.full(8, 1 / 8)) == pytest.approx(8.0)
    assert effective_sample_size(np.array([1.0, 0.0, 0.0])) == pytest.approx(1.0)
