"""Gaspar 2009 as published: ``preset=paper`` and the published experiment's scenarios."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from engine.ptz.paper_sim import (
    PAPER_OMEGA_RAD_S,
    LineScenario,
    paper_circle,
    paper_range,
)
from engine.trackers.ptz import PAPER_OMEGAS, PAPER_Q_JERK_PSD, PtzParams


def test_paper_preset_is_the_published_bank_and_noise() -> None:
    p = PtzParams().with_preset("paper")
    assert p.omegas == pytest.approx(PAPER_OMEGAS)  # 2 pi / 50 [0, 1, 2, 3], sec. 6.1
    assert p.q_jerk_psd == PAPER_Q_JERK_PSD
    assert (p.snake_alpha, p.snake_beta) == (0.5, 0.05)
    assert p.centre_method == "contour"
    assert p.min_model_prob == 0.0
    assert "paper" in p.matching_presets()


def test_paper_turn_rate_lies_between_two_models() -> None:
    w = np.asarray(PAPER_OMEGAS)
    assert w[1] < PAPER_OMEGA_RAD_S < w[2]
    assert abs(PAPER_OMEGA_RAD_S - w[1]) < abs(PAPER_OMEGA_RAD_S - w[2])


def test_paper_scenarios_match_the_published_experiment() -> None:
    c = paper_circle()
    assert c.omega_rad_s == pytest.approx(PAPER_OMEGA_RAD_S)
    assert 1.0 / c.fps == pytest.approx(0.5)
    assert c.duration_s == 140.0
    r = paper_range()
    head = r.head()
    d = [float(np.linalg.norm(r.truth(t)[0] - head.T_world_cam(0.0, 0.0)[:3, 3]))
         for t in np.linspace(0.0, 140.0, 2801)]
    assert min(d) == pytest.approx(0.40, abs=0.01)
    assert max(d) == pytest.approx(7.0, abs=0.01)


def test_line_scenario_velocity_and_acceleration_are_derivatives() -> None:
    sc = LineScenario(radius_m=2.0, period_s=20.0, direction_world=(1.0, 1.0, 0.0))
    h = 1e-4
    p0, v0, a0 = sc.truth(3.0)
    p1, v1, _ = sc.truth(3.0 + h)
    assert np.allclose((p1 - p0) / h, v0, atol=1e-3)
    assert np.allclose((v1 - v0) / h, a0, atol=1e-3)
    # the constant-turn model per axis: a''' = -w^2 a'
    _, _, a1 = sc.truth(3.0 + h)
    assert np.allclose((a1 - a0) / h, -sc.omega_rad_s**2 * v0, atol=1e-3)


def test_paper_set_picks_the_model_closest_to_the_true_turn_rate() -> None:
    """Fig. 6: on the paper's circle (shortened), the closest model's probability rises to
    the top and the estimated turn rate approaches it."""
    from engine.bench.ptz_paper import summary, track

    sc = dataclasses.replace(paper_circle(), duration_s=50.0)
    p = PtzParams(target_b=sc.ball_bgr[0], target_g=sc.ball_bgr[1], target_r=sc.ball_bgr[2],
                  target_radius_m=sc.ball_radius_m).with_preset("paper")
    s = summary(track(sc, p), p.omegas, PAPER_OMEGA_RAD_S)
    assert s["true_model"] == 1
    assert s["true_model_prob_final"] > 0.9
    assert abs(s["omega_est_final_rad_s"] - PAPER_OMEGAS[1]) < 0.02
    assert s["pos_err_m_steady"] < 0.2  # fig. 5: beneath 20 cm
    assert math.isfinite(s["vel_err_m_s_steady"])


def test_paper_lens_distorts_and_the_line_based_fit_corrects_it() -> None:
    """Sec. 3.3 in the published experiment: the simulated lens distorts and the line-based
    model fitted to straight lines seen through it undoes the distortion to a pixel."""
    from engine.ptz.paper_sim import PAPER_LENS_K3, lens_calibration
    from engine.ptz.sim import PtzSimSource

    sc = paper_circle()
    assert sc.distortion_k3 == PAPER_LENS_K3 != 0.0
    cal, rep = lens_calibration(PtzSimSource(sc))
    assert cal.radial is not None
    assert rep["straightness_after_px"] < 0.25 * rep["straightness_before_px"]
    assert rep["max_correction_err_px"] < 1.0
    assert rep["k_est"][0] == pytest.approx(PAPER_LENS_K3, abs=0.03)
