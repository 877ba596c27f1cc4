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
    RESEED_FRAMES,
    DepthReference,
    depth_likelihood,
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
