"""The beacon SLAM filter (Yang 2007): observation model, Map Adjustment, resampling, seeds."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from engine.beacons.cloud import liu_west_roughen, weighted_mean_cov
from engine.beacons.filter import BeaconSlamFilter
from engine.beacons.likelihood import (
    marginal_range_sigma,
    normalise_log_weights,
    predicted_ranges,
    range_log_likelihood,
)
from engine.beacons.map_adjustment import map_adjustment
from engine.beacons.params import BeaconFilterParams
from engine.beacons.simulator import PAPER_LAYOUT, SimConfig, paper_camera_path, simulate
from engine.beacons.startup import trilaterate
from engine.errors import ParamsError


def _run(params: BeaconFilterParams, sim_cfg: SimConfig, seed: int = 0) -> tuple[np.ndarray, ...]:
    sim = simulate(PAPER_LAYOUT, sim_cfg)
    f = BeaconSlamFilter(sim.ids, params, layout_xy=PAPER_LAYOUT, seed=seed)
    path = np.array([f.step(sim.ranges_m[t]).cam_xy for t in range(len(sim.path_xy))])
    assert f.last is not None
    return path, sim.path_xy, f.last.beacons_xy, sim.beacons_xy


# ---------------------------------------------------------------- observation model, eq. (8)
def test_predicted_ranges_are_euclidean_distances() -> None:
    cam = np.array([[0.0, 0.0], [3.0, 4.0]])
    beacons = np.array([[[3.0, 4.0], [10.0, 0.0]], [[3.0, 4.0], [0.0, 0.0]]])
    d = predicted_ranges(cam, beacons)
    np.testing.assert_allclose(d, [[5.0, 10.0], [0.0, 5.0]])


def test_range_likelihood_is_gaussian_and_robust_mixture_bounded() -> None:
    r = np.array([0.0, 0.3, 1.0, 30.0])
    sigma = 0.3
    expected = -0.5 * (r / sigma) ** 2 - math.log(math.sqrt(2 * math.pi) * sigma)
    np.testing.assert_allclose(range_log_likelihood(r, sigma), expected)
    robust = range_log_likelihood(r, sigma, outlier_prob=0.05, max_range_m=60.0)
    assert robust[-1] >= math.log(0.05 / 60.0) - 1e-9  # a wild reading cannot zero a weight
    assert robust[0] == pytest.approx(expected[0] + math.log(0.95), abs=1e-3)


# ---------------------------------------------------------------- Map Adjustment, eq. (12)
def test_map_adjustment_moves_along_line_by_p_times_residual() -> None:
    cam = np.array([[1.0, 1.0]])
    beacon = np.array([[[4.0, 5.0]]])  # d' = 5
    for p in (0.0, 0.3, 1.0):
        out = map_adjustment(cam, beacon, np.array([7.0]), p)
        new_r = float(np.linalg.norm(out[0, 0] - cam[0]))
        assert new_r == pytest.approx(5.0 + p * (7.0 - 5.0))  # |d - d'| shrinks by (1 - p)
        direction = (out[0, 0] - cam[0]) / new_r
        np.testing.assert_allclose(direction, [0.6, 0.8])  # along the camera->beacon line


def test_map_adjustment_moves_estimates_toward_consistency_in_the_filter() -> None:
    """With the camera held at the truth, repeated MA steps make the map agree with ranges."""
    rng = np.random.default_rng(3)
    truth = np.array(list(PAPER_LAYOUT.values()))
    path = paper_camera_path(60)
    beacons = truth[None] + rng.normal(0.0, 3.0, (50, 4, 2))
    first = None
    for s in path:
        cam = np.tile(s, (50, 1))
        d = np.linalg.norm(truth - s, axis=1)
        resid = np.abs(d[None] - predicted_ranges(cam, beacons))
        first = resid.mean() if first is None else first
        beacons = map_adjustment(cam, beacons, d, 0.3)
    final_resid = np.abs(
        np.linalg.norm(truth - path[-1], axis=1)[None] - predicted_ranges(
            np.tile(path[-1], (50, 1)), beacons)
    ).mean()
    assert final_resid < 0.05 * first
    err_before = np.linalg.norm(truth[None] + 0 - truth[None], axis=2)  # noqa: F841 - shape only
    assert float(np.mean(np.linalg.norm(beacons - truth[None], axis=2))) < 3.0 * math.sqrt(2)


# ---------------------------------------------------------------- weights
def test_normalised_weights_sum_to_one_even_for_tiny_likelihoods() -> None:
    w = normalise_log_weights(np.array([-1e5, -1e5 - 1.0, -1e5 - 50.0]))
    assert w.sum() == pytest.approx(1.0)
    assert w[0] > w[1] > w[2] > 0.0


def test_weighted_mean_cov() -> None:
    x = np.array([[0.0, 0.0], [2.0, 0.0]])
    mean, cov = weighted_mean_cov(x, np.array([0.5, 0.5]))
    np.testing.assert_allclose(mean, [1.0, 0.0])
    np.testing.assert_allclose(cov, [[1.0, 0.0], [0.0, 0.0]])


# ---------------------------------------------------------------- whole filter
def test_particles_hold_2_n_plus_1_states() -> None:
    f = BeaconSlamFilter(list(PAPER_LAYOUT), BeaconFilterParams(n_particles=30),
                         layout_xy=PAPER_LAYOUT)
    f.step([14.1, 22.0, 20.0, 15.8])
    assert f.cam.shape == (30, 2)
    assert f.beacons.shape == (30, 4, 2)
    # sec. III.B: after the first measurement each beacon lies on its range circle
    np.testing.assert_allclose(np.linalg.norm(f.beacons[:, 0], axis=1), 14.1, atol=1.5)


def test_seeded_runs_are_reproducible() -> None:
    cfg = SimConfig(n_steps=40, seed=5, dropout_prob=0.1, outlier_prob=0.05)
    p = BeaconFilterParams(n_particles=100)
    a = _run(p, cfg, seed=11)
    b = _run(p, cfg, seed=11)
    c = _run(p, cfg, seed=12)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[2], b[2])
    assert not np.array_equal(a[0], c[0])


def test_known_beacon_mode_localises_accurately() -> None:
    path, truth, _, _ = _run(BeaconFilterParams(n_particles=100, known_beacons=True),
                             SimConfig(seed=2))
    assert float(np.sqrt(np.mean(np.sum((path - truth) ** 2, axis=1)))) < 0.3


def test_slam_tracks_the_paper_path() -> None:
    path, truth, b_est, b_true = _run(BeaconFilterParams(), SimConfig(seed=1))
    rmse = float(np.sqrt(np.mean(np.sum((path - truth) ** 2, axis=1))))
    assert rmse < 1.5
    assert float(np.mean(np.linalg.norm(b_est - b_true, axis=1))) < 4.0


def test_missing_readings_and_outliers_are_handled() -> None:
    cfg = SimConfig(seed=4, dropout_prob=0.3, outlier_prob=0.1)
    sim = simulate(PAPER_LAYOUT, cfg)
    f = BeaconSlamFilter(sim.ids, BeaconFilterParams(), layout_xy=PAPER_LAYOUT)
    flagged = 0
    for t in range(len(sim.path_xy)):
        est = f.step(sim.ranges_m[t])
        assert np.all(np.isfinite(est.cam_xy))
        assert not np.any(est.used & ~np.isfinite(sim.ranges_m[t]))  # missing never used
        flagged += int(np.count_nonzero(est.outliers & sim.outlier_mask[t]))
    assert flagged >= 0.5 * int(np.count_nonzero(sim.outlier_mask[1:]))


def test_gross_outlier_is_rejected_and_not_adjusted_into_the_map() -> None:
    # roughening off: it moves every beacon after resampling, which would hide what MA did
    f = BeaconSlamFilter(list(PAPER_LAYOUT), BeaconFilterParams(roughen_h=0.0),
                         layout_xy=PAPER_LAYOUT, seed=0)
    truth = np.array(list(PAPER_LAYOUT.values()))
    for s in paper_camera_path(10)[:10]:
        f.step(np.linalg.norm(truth - s, axis=1))
    before = f.beacons[:, 1].copy()
    r = np.linalg.norm(truth - paper_camera_path(10)[10], axis=1)
    r[1] += 15.0
    est = f.step(r)
    assert est.outliers[1]
    assert not est.used[1]
    np.testing.assert_array_equal(est.outliers[[0, 2, 3]], False)
    # the rejected beacon was not pulled by Map Adjustment (only resampled)
    assert np.all(np.isin(f.beacons[:, 1, 0], before[:, 0]))


def test_particle_count_change_applies_next_step() -> None:
    f = BeaconSlamFilter(list(PAPER_LAYOUT), BeaconFilterParams(n_particles=50),
                         layout_xy=PAPER_LAYOUT)
    truth = np.array(list(PAPER_LAYOUT.values()))
    f.step(np.linalg.norm(truth, axis=1))
    f.set_params(dataclasses.replace(f.params, n_particles=120))
    assert f.n_particles == 50
    f.step(np.linalg.norm(truth - [0.1, 0.1], axis=1))
    assert f.n_particles == 120
    assert f.beacons.shape == (120, 4, 2)


def test_params_validation() -> None:
    with pytest.raises(ParamsError, match="map_adjust_p"):
        BeaconFilterParams(map_adjust_p=1.5)
    with pytest.raises(ParamsError, match="n_particles"):
        BeaconFilterParams(n_particles=1)
    with pytest.raises(ParamsError, match="unique"):
        BeaconSlamFilter(["A", "A"])


def test_trilaterate() -> None:
    b = np.array(list(PAPER_LAYOUT.values()))
    x = trilaterate(b, np.linalg.norm(b - [2.0, -1.0], axis=1), np.zeros(2))
    assert x is not None
    np.testing.assert_allclose(x, [2.0, -1.0], atol=1e-6)


def test_steps_without_any_reading_do_not_start_the_filter() -> None:
    f = BeaconSlamFilter(["A", "B"], BeaconFilterParams(n_particles=20))
    est = f.step([math.nan, math.nan])
    assert est.step == -1
    assert f.t == 0
    assert f.step([5.0, 6.0]).step == 0  # the first measurement initialises (sec. III.B)


# ---------------------------------------------------------------- against particle collapse
def test_marginal_sigma_adds_map_spread_along_the_line_of_sight_only() -> None:
    """Eq. (10) integrates over the beacon: spread along the line of sight widens the
    likelihood, spread across it (which does not change the range) does not."""
    m = 400
    rng = np.random.default_rng(0)
    cam = np.zeros((m, 2))
    w = np.full(m, 1.0 / m)
    point = np.tile([[10.0, 0.0]], (m, 1, 1))
    np.testing.assert_allclose(marginal_range_sigma(cam, point, w, 0.3), 0.3)
    along = point + np.stack([rng.normal(0.0, 0.4, m), np.zeros(m)], axis=1)[:, None, :]
    across = point + np.stack([np.zeros(m), rng.normal(0.0, 0.4, m)], axis=1)[:, None, :]
    s_along = marginal_range_sigma(cam, along, w, 0.3)
    s_across = marginal_range_sigma(cam, across, w, 0.3)
    assert float(np.median(s_along)) == pytest.approx(0.5, abs=0.03)  # sqrt(0.3^2 + 0.4^2)
    assert float(np.median(s_across)) < 0.32


def test_roughening_keeps_the_map_cloud_and_splits_duplicates() -> None:
    rng = np.random.default_rng(1)
    m = 4000
    base = rng.normal([[5.0, -2.0], [0.0, 12.0]], [[0.5, 0.2], [1.0, 1.0]], (40, 2, 2))
    x = base[rng.integers(0, 40, m)]  # after resampling: 40 distinct maps, many copies each
    w = np.full(m, 1.0 / m)
    out = liu_west_roughen(x, w, 0.3, rng)
    assert len(np.unique(out[:, 0, 0])) == m
    mean0, cov0 = weighted_mean_cov(x, w)
    mean1, cov1 = weighted_mean_cov(out, w)
    np.testing.assert_allclose(mean1, mean0, atol=0.05)
    np.testing.assert_allclose(np.diagonal(cov1, axis1=1, axis2=2),
                               np.diagonal(cov0, axis1=1, axis2=2), rtol=0.1)


def test_map_converges_over_the_run() -> None:
    """The beacon map gets better as the camera moves (paper, sec. IV: errors "get smaller
    and converge"); without roughening and the eq. (10) spread the map collapses early."""

    def beacon_err(params: BeaconFilterParams, seed: int) -> tuple[float, float]:
        sim = simulate(PAPER_LAYOUT, SimConfig(seed=seed))
        f = BeaconSlamFilter(sim.ids, params, layout_xy=PAPER_LAYOUT, seed=100 + seed)
        errs = []
        for t in range(len(sim.path_xy)):
            est = f.step(sim.ranges_m[t])
            errs.append(float(np.mean(np.linalg.norm(est.beacons_xy - sim.beacons_xy, axis=1))))
        return errs[30], errs[-1]

    new = np.array([beacon_err(BeaconFilterParams(), s) for s in range(12)])
    t30, final = np.mean(new, axis=0)
    assert final < 0.85 * t30  # the old filter (collapsed map) got worse: 1.7 m -> 2.0 m
    assert final < 1.0


# ---------------------------------------------------------------- start-up ambiguity (setting A)
def _ring_mass_relative(f: BeaconSlamFilter, i: int, rel_deg: float, tol_deg: float) -> float:
    """Weight of beacon i's start-up hypotheses at bearing ``rel_deg`` relative to each
    particle's own heading from the start (the map frame itself is not fixed in setting A)."""
    ring = f.rings[i]
    h = f.cam - ring.centre
    head = np.degrees(np.arctan2(h[:, 1], h[:, 0]))
    rel = ring.hyp - ring.centre[:, None, :]
    ang = np.degrees(np.arctan2(rel[..., 1], rel[..., 0])) - head[:, None]
    near = np.abs((ang - rel_deg + 180.0) % 360.0 - 180.0) < tol_deg
    return float(np.sum(f.weights[:, None] * np.exp(ring.log_w) * near))


@pytest.mark.parametrize("seed", [0, 3])
def test_ring_start_up_keeps_the_mirror_image_until_the_path_turns(seed: int) -> None:
    """Along the straight first leg (heading 40 deg, turn at step 20) beacon B(22, 0), 40 deg
    right of the path, and its mirror image 40 deg left of it fit the ranges equally well: the
    start-up mixture keeps both sides (the old point start-up had settled all particles on
    the middle by step 10) and resolves them after the turn."""
    sim = simulate(PAPER_LAYOUT, SimConfig(seed=seed))
    f = BeaconSlamFilter(sim.ids, BeaconFilterParams(hint_sigma_m=0.0), layout_xy=PAPER_LAYOUT,
                         seed=7)
    b = sim.ids.index("B")
    for t in range(21):
        f.step(sim.ranges_m[t])
    assert b in f.rings
    right = _ring_mass_relative(f, b, -40.0, 20.0)
    left = _ring_mass_relative(f, b, 40.0, 20.0)
    assert right > 0.15, (right, left)
    assert left > 0.15, (right, left)
    for t in range(21, len(sim.path_xy)):
        f.step(sim.ranges_m[t])
    assert not f.rings  # resolved after the turn: one point per particle again


def test_ring_start_up_finds_the_map_shape_the_point_start_up_misses() -> None:
    """Setting A (quadrants only, sec. III.B): the old one-point-per-beacon start-up settled on
    a wrong middle solution (beacon error ~6 m after the best rotation/mirror)."""
    from engine.bench.beacon import run_once

    def err(params: BeaconFilterParams) -> float:
        return float(np.median([run_once(params, s, SimConfig(), dict(PAPER_LAYOUT))
                                ["beacon_err_final_aligned"] for s in range(6)]))

    ring = err(BeaconFilterParams(hint_sigma_m=0.0))
    point = err(BeaconFilterParams(hint_sigma_m=0.0, ring_hypotheses=0))
    assert ring < 2.0
    assert point > 2.0 * ring


# ---------------------------------------------------------------- extension switches
def test_every_extension_switch_is_live_and_its_off_value_valid() -> None:
    """Each entry of EXTENSIONS turns a live part of the filter off (the ablation's switches):
    on a run where the extension is on, switching it off changes the estimate."""
    from engine.beacons.params import EXTENSIONS

    on_values: dict[str, dict[str, object]] = {  # where an extension is off by default
        # the annealed gain is a variant of eq. (12)'s fixed one
        "annealed_map_adjustment": {"map_adjust_anneal": True, "map_adjust_gain": "fixed"},
        "beacon_jitter": {"beacon_jitter_m": 0.05},
        "ess_resampling": {"resample_ess_fraction": 0.5},
        "ring_startup": {"hint_sigma_m": 0.0},  # the ring and the gauge act without a hint
        "gauge_alignment": {"hint_sigma_m": 0.0},
    }
    sim = simulate(PAPER_LAYOUT, SimConfig(n_steps=40, outlier_prob=0.1, seed=2))
    assert set(on_values) <= set(EXTENSIONS)

    def final(params: BeaconFilterParams) -> np.ndarray:
        f = BeaconSlamFilter(sim.ids, params, layout_xy=PAPER_LAYOUT)
        for t in range(len(sim.ranges_m)):
            est = f.step(sim.ranges_m[t])
        return np.concatenate([est.cam_xy, est.beacons_xy.ravel()])

    for name, ext in EXTENSIONS.items():
        on = dataclasses.replace(BeaconFilterParams(n_particles=60, seed=4),
                                 **on_values.get(name, {}))  # type: ignore[arg-type]
        off = dataclasses.replace(on, **ext.values)  # type: ignore[arg-type]
        assert off != on, name
        assert not np.allclose(final(on), final(off)), f"switching off {name} changed nothing"


def test_kalman_map_adjustment_is_the_kalman_update_and_eq12_for_a_round_kernel() -> None:
    """The 'kalman' gain: each particle's beacon kernel N(f, P) updated by a range as the
    textbook Kalman step with h = u^T (checked with matrices), which for an isotropic P is
    eq. (12) with p = s_b^2 / (s_b^2 + s_r^2); the kernel narrows along the line of sight
    only, and the weighting's std integrates the kernel."""
    from engine.beacons.map_adjustment import (
        kalman_map_adjustment,
        kernel_range_sigma,
        map_adjustment,
    )

    rng = np.random.default_rng(3)
    cam = rng.normal(0.0, 2.0, (5, 2))
    f = rng.normal(6.0, 3.0, (5, 2, 2))
    a = rng.normal(0.0, 1.0, (5, 2, 2, 2))
    P = a @ np.swapaxes(a, -1, -2) + 0.1 * np.eye(2)
    d = np.array([7.0, 9.0])
    sr = 0.3
    f2, P2 = kalman_map_adjustment(cam, f, P, d, sr)
    for m in range(5):
        for k in range(2):
            diff = f[m, k] - cam[m]
            r = np.linalg.norm(diff)
            h = (diff / r)[None, :]
            s = float((h @ P[m, k] @ h.T)[0, 0]) + sr**2
            K = P[m, k] @ h.T / s
            assert np.allclose(f2[m, k], f[m, k] + K[:, 0] * (d[k] - r))
            assert np.allclose(P2[m, k], (np.eye(2) - K @ h) @ P[m, k])
    assert np.allclose(kernel_range_sigma(cam, f, P, sr)[0, 0],
                       np.sqrt(float((f[0, 0] - cam[0]) @ P[0, 0] @ (f[0, 0] - cam[0]))
                               / np.sum((f[0, 0] - cam[0]) ** 2) + sr**2))
    sb = 0.8
    round_P = np.broadcast_to(sb**2 * np.eye(2), P.shape)
    f3, P3 = kalman_map_adjustment(cam, f, round_P, d, sr)
    assert np.allclose(f3, map_adjustment(cam, f, d, sb**2 / (sb**2 + sr**2)))
    u = (f[0, 0] - cam[0]) / np.linalg.norm(f[0, 0] - cam[0])
    t = np.array([-u[1], u[0]])
    assert u @ P3[0, 0] @ u < sb**2
    assert np.isclose(t @ P3[0, 0] @ t, sb**2)
