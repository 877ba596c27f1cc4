"""Yang 2007 as published (``preset=paper``), the studio simulation and the bench statistics."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from engine.beacons.params import EXTENSIONS, PAPER_MAP_ADJUST_P, BeaconFilterParams
from engine.beacons.studio_sim import (
    STUDIO_BEACONS_XYZ,
    StudioRangingConfig,
    project_to_floor,
    simulate_studio,
    studio_camera_path,
    studio_layout_xy,
)
from engine.bench.stats import bootstrap_ci, first_crossing, paired_difference


def test_paper_preset_switches_every_extension_off() -> None:
    p = BeaconFilterParams().with_preset("paper")
    for name, ext in EXTENSIONS.items():
        for key, value in ext.values.items():
            assert getattr(p, key) == value, f"{name}: {key}"
    assert p.n_particles == 200  # fig. 8
    assert p.map_adjustment
    assert p.map_adjust_p == PAPER_MAP_ADJUST_P
    assert p.quadrant_init
    assert not p.known_beacons
    assert p.matching_presets() == ("paper",)
    assert BeaconFilterParams().matching_presets() == ()


def test_studio_path_is_a_smooth_crane_move() -> None:
    path = studio_camera_path(10.0)
    assert np.allclose(path[0], (0.0, 0.0, 1.6))  # the start mark
    speed = np.linalg.norm(np.diff(path, axis=0), axis=1) * 10.0
    assert speed.max() < 1.6  # m/s: a dolly / crane, not a jump
    assert 3.0 < path[:, 2].max() < 4.0  # the crane goes up
    acc = np.linalg.norm(np.diff(path, n=2, axis=0), axis=1) * 100.0
    assert acc.max() < 2.0  # m/s^2


def test_floor_projection_undoes_the_height_difference() -> None:
    d = project_to_floor(np.array([5.0, 3.0, np.nan]), np.array([3.0, 4.0, 1.0]))
    assert d[0] == pytest.approx(4.0)
    assert d[1] == 0.0  # a range shorter than the height: directly overhead
    assert math.isnan(d[2])


def test_studio_ranges_noise_free_equal_floor_distances() -> None:
    cfg = StudioRangingConfig(noise_sigma_m=0.0, nlos_enter_prob=0.0, burst_enter_prob=0.0,
                              dropout_prob=0.0, height_sigma_m=0.0, max_range_m=1000.0)
    run = simulate_studio(cfg)
    fl = run.floor
    assert fl.ids == tuple(STUDIO_BEACONS_XYZ)
    assert fl.ranges_m.shape == (len(fl.path_xy), len(fl.ids))
    true = np.linalg.norm(fl.beacons_xy[None] - fl.path_xy[:, None], axis=2)
    assert np.allclose(fl.ranges_m, true, atol=1e-9)
    assert not fl.ranges_m.flags.writeable


def test_studio_ranging_is_biased_long_when_blocked_and_drops_in_bursts() -> None:
    cfg = StudioRangingConfig(noise_sigma_m=0.0, height_sigma_m=0.0, seed=4,
                              nlos_enter_prob=0.05, burst_enter_prob=0.05, dropout_prob=0.0,
                              max_range_m=1000.0)
    run = simulate_studio(cfg)
    true3 = np.linalg.norm(run.beacons_xyz[None] - run.path_xyz[:, None], axis=2)
    ok = np.isfinite(run.ranges_3d_m)
    extra = run.ranges_3d_m[ok] - true3[ok]
    assert np.all(extra >= -1e-9)  # multipath is never shorter than the direct path
    assert np.all(np.abs(extra[~run.nlos[ok]]) < 1e-9)
    assert np.mean(extra[run.nlos[ok]]) > 0.1
    lost = ~ok
    runs = np.diff(np.flatnonzero(np.diff(np.concatenate([[0], lost[:, 0], [0]]))))[::2]
    assert lost.mean() > 0.05
    assert np.mean(runs) > 1.5  # bursts, not independent losses
    far = simulate_studio(dataclasses.replace(cfg, max_range_m=15.0, burst_enter_prob=0.0))
    true_far = np.linalg.norm(far.beacons_xyz[None] - far.path_xyz[:, None], axis=2) > 15.0
    assert np.all(np.isnan(far.ranges_3d_m[true_far]))


def test_studio_source_option() -> None:
    from engine.errors import SourceError
    from engine.sources import open_source
    from engine.sources.beacons import RangeReadings

    src = open_source("beacons:scene=studio,seed=1")
    frames = list(src.frames())
    assert len(frames) == len(studio_camera_path())
    readings = frames[0].payload(RangeReadings)
    assert readings is not None
    assert readings.layout is not None
    assert set(readings.layout) == set(studio_layout_xy())
    with pytest.raises(SourceError, match="sensor"):
        open_source("beacons:scene=studio,sensor=laser")
    with pytest.raises(SourceError, match="scene"):
        open_source("beacons:scene=moon")


def test_first_crossing_interpolates_in_log_particles() -> None:
    grid = (10, 100, 1000)
    assert first_crossing(grid, [5.0, 3.0, 1.0], 3.0) == pytest.approx(100.0)
    assert first_crossing(grid, [5.0, 3.0, 1.0], 4.0) == pytest.approx(math.sqrt(10 * 100))
    assert first_crossing(grid, [5.0, 3.0, 1.0], 9.0) == 10.0
    assert first_crossing(grid, [5.0, 3.0, 2.0], 1.0) == math.inf


def test_bootstrap_interval_and_paired_difference() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(1.0, 0.1, 40)
    lo, hi = bootstrap_ci(a)
    assert lo < float(np.mean(a)) < hi
    assert hi - lo < 0.1
    d = paired_difference(a - 0.5, a)
    assert d["mean_diff"] == pytest.approx(-0.5)
    assert d["fraction_a_lower"] == 1.0


def test_particles_needed_finds_the_shifted_curve() -> None:
    """A with-MA curve that equals the without-MA curve at 4x fewer particles needs 4x fewer
    particles for the same accuracy (the definition the bench reports)."""
    from engine.bench.beacon_paper import Runs, particles_needed

    grid = (25, 50, 100, 200, 400, 800)
    rng = np.random.default_rng(1)
    noise = rng.random(30)

    def runs(n_eff: float) -> Runs:
        v = (3.0 / math.sqrt(n_eff)) * (1.0 + noise)
        z = np.zeros(30)
        return Runs(path_rmse=v, beacon_err_final=v, path_rmse_abs=v, beacon_err_final_abs=v,
                    err_t=np.zeros((30, 2)), examples=({"x": z},))

    sweep = {"paper.with_ma": {n: runs(4 * n) for n in grid},
             "paper.without_ma": {n: runs(n) for n in grid}}
    out = particles_needed(grid, sweep, "beacon_err_final", "paper", ("paper",))
    assert out["paper"]["without_ma"] == pytest.approx(200.0)
    assert out["paper"]["with_ma"] == pytest.approx(50.0)
    assert out["paper"]["ratio_without_over_with"] == pytest.approx(4.0)
    lo, hi = out["paper"]["ci95"]["ratio"]
    assert lo <= 4.0 + 1e-9
    assert hi >= 4.0 - 1e-9
