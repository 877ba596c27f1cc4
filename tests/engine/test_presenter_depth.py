"""Depth agreement of the presenter hypotheses (engine.presenter.depth)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from engine.bench import presenter_scenarios as sc
from engine.frames import Frame
from engine.presenter.depth import (
    FLOOR,
    GATE,
    MAX_SPEED_M_S,
    MIXED_SPREAD,
    RESEED_FRAMES,
    DepthReference,
    depth_likelihood,
    estimate_depth,
    torso_depths,
)
from engine.presenter.params import PresenterParams
from engine.trackers import create_tracker


def _depth() -> np.ndarray:
    z = np.full((120, 160), 4.0, np.float32)  # the back wall
    z[20:110, 40:70] = 2.0  # a person
    z[20:110, 100:130] = 0.0  # a person the sensor does not see (no depth)
    return z


def test_each_hypothesis_gets_the_median_depth_of_its_body() -> None:
    xyh = np.array([[55.0, 80.0, 80.0],  # on the person
                    [20.0, 80.0, 80.0],  # on the wall
                    [115.0, 80.0, 80.0],  # on the invisible one: no opinion
                    [500.0, 80.0, 80.0],  # off the image
                    [np.nan, 80.0, 80.0]])
    z = torso_depths(_depth(), xyh, aspect=0.4)
    assert z[0] == pytest.approx(2.0)
    assert z[1] == pytest.approx(4.0)
    assert np.isnan(z[2:]).all()


def test_the_likelihood_is_neutral_without_depth_or_reference() -> None:
    z = np.array([2.0, 2.3, np.nan])
    w = depth_likelihood(z, 2.0, 0.15)
    assert w[0] == pytest.approx(1.0)
    assert w[1] == pytest.approx(FLOOR + (1.0 - FLOOR) * math.exp(-2.0))
    assert w[2] == 1.0
    assert (depth_likelihood(z, math.nan, 0.15) == 1.0).all()
    assert (depth_likelihood(z, 2.0, 0.0) == 1.0).all()


def test_a_covered_body_is_not_learned_unless_it_stays() -> None:
    ref = DepthReference(rate=0.5)
    assert ref.update(2.0, 0.15)
    assert ref.update(2.1, 0.15)
    assert ref.z_m == pytest.approx(2.05)
    jump = 2.05 - GATE * 0.15 - 0.2  # someone crossing in front
    for _ in range(RESEED_FRAMES - 1):
        assert not ref.update(jump, 0.15)
    assert ref.z_m == pytest.approx(2.05)
    assert ref.update(jump, 0.15)  # it stayed: the presenter did move
    assert ref.z_m == pytest.approx(jump)
    ref.reset()
    assert math.isnan(ref.z_m)


def test_the_paper_preset_has_no_depth_term() -> None:
    assert PresenterParams().depth_sigma_m > 0.0
    assert PresenterParams().with_preset("paper").depth_sigma_m == 0.0


def test_a_look_alike_walking_behind_does_not_take_the_track() -> None:
    """The check case the std was chosen on (320x240): colour alone follows the other
    person for a while, with depth it stays on the presenter."""
    case = "check_behind_same_look_small"

    def run(depth_sigma_m: float) -> int:
        def go(frames: list[Frame]) -> list[Any]:
            t = create_tracker("presenter", PresenterParams(depth_sigma_m=depth_sigma_m))
            return [t.track(f) for f in frames]
        return int(sc.distractor(go, case)["stolen_frames"])

    assert run(0.0) > 5
    assert run(PresenterParams().depth_sigma_m) == 0


def test_the_reference_follows_a_walk_but_not_a_slide_onto_someone_behind() -> None:
    ref = DepthReference(rate=0.5)
    assert ref.update(2.0, 0.15, frame_rate_hz=30.0)
    for k in range(1, 31):  # walking away at 1.2 m/s: followed within a few centimetres
        assert ref.update(2.0 + 0.04 * k, 0.15, frame_rate_hz=30.0)
    assert ref.z_m == pytest.approx(3.2, abs=0.06)
    ref = DepthReference(rate=0.5)
    ref.update(2.0, 0.15, frame_rate_hz=30.0)
    for z in (2.3, 2.6, 2.75, 2.75):  # each inside the gate of the last reference
        ref.update(z, 0.15, frame_rate_hz=30.0)
    assert ref.z_m <= 2.0 + 4 * MAX_SPEED_M_S / 30.0 + 1e-9


def test_a_box_over_two_depths_is_not_learned() -> None:
    z = _depth()
    z[20:110, 55:70] = 2.5  # a second person half a metre behind, overlapping
    straddle = np.array([55.0, 80.0, 80.0])
    z_est, spread = estimate_depth(z, straddle, aspect=0.4)
    assert spread > MIXED_SPREAD * 0.15
    assert z_est == pytest.approx(torso_depths(z, straddle[None, :], aspect=0.4)[0])
    assert estimate_depth(z, np.array([45.0, 80.0, 80.0]), aspect=0.4)[1] == pytest.approx(0.0)
    assert all(math.isnan(v) for v in estimate_depth(z, np.array([500.0, 80.0, 80.0]),
                                                       aspect=0.4))
    ref = DepthReference(rate=0.5)
    ref.update(2.0, 0.15)
    assert not ref.update(2.2, 0.15, spread_m=spread)
    assert ref.z_m == 2.0
