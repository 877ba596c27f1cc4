"""The presenter's trajectory (identity by motion): it coasts on motion no person makes."""

from __future__ import annotations

import numpy as np

from engine.presenter import trajectory as tj
from engine.presenter.params import PresenterParams
from engine.presenter.trajectory import Trajectory

H = 390.0  # presenter height, px


def _walk(t: Trajectory, x0: float, v: float, n: int) -> float:
    """Feed n frames of a presenter walking at v px/frame from x0 (velocity as the view's
    smoothed estimate gives it); returns the last x."""
    x = x0
    for _ in range(n):
        x += v
        t.update(np.array([x, 200.0]), np.array([v, 0.0]), H)
    return x


def test_a_steady_walk_never_coasts_and_the_track_learns_its_speed() -> None:
    t = Trajectory()
    _walk(t, 100.0, 6.0, 40)
    assert t.coasting == 0
    assert abs(t.vel[0] - 6.0) < 0.2
    pred = t.predicted()
    assert pred is not None
    assert abs(pred[0] - (100.0 + 41 * 6.0)) < 2.0


def test_an_estimate_dragged_the_other_way_coasts_on_the_presenters_motion() -> None:
    t = Trajectory()
    x = _walk(t, 100.0, 6.0, 30)
    # the estimate slides onto someone walking the other way: -4 px/frame at once
    est = x
    for _ in range(5):
        est -= 4.0
        t.update(np.array([est, 200.0]), np.array([-4.0, 0.0]), H)
    assert t.coasting > 0
    pred = t.predicted()
    assert pred is not None
    # the prediction went on where the presenter walks, not with the estimate
    assert pred[0] > x + 5 * 6.0 - 3.0
    assert abs(t.vel[0] - 6.0) < 0.5


def test_coasting_ends_when_the_estimate_is_back_on_the_path_or_after_a_while() -> None:
    t = Trajectory()
    x = _walk(t, 100.0, 6.0, 30)
    t.update(np.array([x - 4.0, 200.0]), np.array([-4.0, 0.0]), H)
    assert t.coasting == 1
    pred = t.predicted()
    assert pred is not None
    t.update(np.array([pred[0], 200.0]), np.array([6.0, 0.0]), H)  # the cloud found it
    assert t.coasting == 0
    # a lone presenter who stopped: nothing where the old motion led; the track gives up
    # after COAST_FRAMES and follows the estimate again
    stop = float(pred[0])
    t.update(np.array([stop, 200.0]), np.array([-4.0, 0.0]), H)
    assert t.coasting == 1
    for _ in range(tj.COAST_FRAMES + 1):
        t.update(np.array([stop, 200.0]), np.array([0.0, 0.0]), H)
    assert t.coasting == 0
    p2 = t.predicted()
    assert p2 is not None
    assert abs(p2[0] - stop) < 1.0


def test_no_coasting_before_the_track_is_trusted() -> None:
    t = Trajectory()
    _walk(t, 100.0, 6.0, tj.WARM_FRAMES - 2)
    t.update(np.array([100.0, 200.0]), np.array([-6.0, 0.0]), H)
    assert t.coasting == 0


def test_paper_preset_and_default_off_switch() -> None:
    p = PresenterParams()
    assert PresenterParams().with_preset("paper").trajectory_share == 0.0
    assert 0.0 <= p.trajectory_share <= 0.5


def test_tracker_draws_particles_at_the_coasting_prediction() -> None:
    from dataclasses import replace

    from engine.presenter.model import model_from_box
    from engine.presenter.view import ViewTracker

    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)
    img[60:200, 100:140] = (200, 40, 40)
    model = model_from_box(img, (100.0, 60.0, 40.0, 140.0), 3, 10, grey_world=False)
    p = replace(PresenterParams(), trajectory_share=0.2, use_motion=False)
    v = ViewTracker(model, p, 30.0)
    v.step(img)
    # force a coasting track far from the cloud: a fifth of the particles go there
    v.trajectory.reset(np.array([250.0, 130.0]))
    v.trajectory.coasting = 1
    v.step(img)
    near = np.abs(v.particles[:, 0] - 250.0) < 40.0
    assert int(near.sum()) >= round(0.2 * p.n_particles) - 2
