"""Snake, EKF/MMAE and the ``ptz`` tracker (Gaspar 2009 sec. 4-5)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from engine.ptz.ekf import ConstantTurnEkf, h_jacobian, h_measure, phi_axis
from engine.ptz.mmae import PAPER_OMEGAS_RAD_S, Mmae
from engine.ptz.sim import CircleScenario, PtzSimSource
from engine.ptz.snake import circle_points, colour_score, measure_target, run_snake


def _disc(cx: float, cy: float, r: float, bgr=(40, 40, 210), size=(200, 160)) -> np.ndarray:
    w, h = size
    ss = 4
    ys, xs = np.mgrid[0:h * ss, 0:w * ss]
    inside = ((xs + 0.5) / ss - 0.5 - cx) ** 2 + ((ys + 0.5) / ss - 0.5 - cy) ** 2 <= r * r
    cov = inside.reshape(h, ss, w, ss).mean(axis=(1, 3))[..., None]
    bg = np.full((h, w, 3), 110.0)
    return (bg * (1 - cov) + np.asarray(bgr, float) * cov + 0.5).astype(np.uint8)


@pytest.mark.parametrize("external", ["gradient", "gvf"])
def test_snake_converges_on_disc(external: str) -> None:
    img = _disc(97.3, 81.6, 24.0)
    score = colour_score(img, (0, 0, 255))
    import cv2

    sm = cv2.GaussianBlur(score, (0, 0), 1.5)
    edge = np.hypot(cv2.Sobel(sm, cv2.CV_32F, 1, 0), cv2.Sobel(sm, cv2.CV_32F, 0, 1))
    res = run_snake(edge, circle_points(100.0, 78.0, 34.0, 32), external=external)
    assert res.converged
    c = res.contour_xy
    centre = c.mean(axis=0)
    assert centre == pytest.approx((97.3, 81.6), abs=0.5)
    radii = np.linalg.norm(c - centre, axis=1)
    assert np.mean(radii) == pytest.approx(24.0, abs=1.0)
    assert np.std(radii) < 0.5


def test_measure_target_distance_from_known_size() -> None:
    f = 800.0
    r_px = 20.0
    img = _disc(101.2, 77.9, r_px, bgr=(200, 60, 40))  # a blue target: colour configurable
    m = measure_target(img, (255, 0, 0), 0.1, f)
    assert m is not None
    assert (m.u, m.v) == pytest.approx((101.2, 77.9), abs=0.05)
    assert m.radius_px == pytest.approx(r_px, abs=0.1)
    assert m.d_m == pytest.approx(0.1 / math.sin(math.atan(r_px / f)), rel=0.01)
    assert measure_target(img, (0, 255, 0), 0.1, f) is None  # no green target


def test_constant_turn_transition_is_a_rotation_of_velocity() -> None:
    w, dt = 0.3, 0.7
    F = phi_axis(w, dt)
    # x(t) = cos(w t): state (x, x', x'') maps exactly
    s = np.array([1.0, 0.0, -w * w])
    np.testing.assert_allclose(F @ s, [math.cos(w * dt), -w * math.sin(w * dt),
                                       -w * w * math.cos(w * dt)], atol=1e-12)
    np.testing.assert_allclose(phi_axis(0.0, dt), [[1, dt, dt * dt / 2], [0, 1, dt], [0, 0, 1]])


def test_measurement_jacobian_matches_numeric() -> None:
    P = np.array([[800.0, 0, 320, 10], [0, 800, 240, -50], [0, 0, 1, 2.0]])
    c = -np.linalg.inv(P[:, :3]) @ P[:, 3]
    x = np.array([0.5, 0, 0, -0.3, 0, 0, 4.0, 0, 0])
    H = h_jacobian(x, P, c)
    Hn = np.stack([(h_measure(x + 1e-6 * e, P, c) - h_measure(x - 1e-6 * e, P, c)) / 2e-6
                   for e in np.eye(9)], axis=1)
    np.testing.assert_allclose(H, Hn, atol=1e-5)


def _circle_measurements(omega: float, n: int, dt: float, seed: int = 0):
    rng = np.random.default_rng(seed)
    P = np.array([[800.0, 0, 320, 0], [0, 0, -800, 1200], [0, 1, 0, 0]])  # looks along +y
    c = -np.linalg.inv(P[:, :3]) @ P[:, 3]
    out = []
    for k in range(n):
        a = omega * k * dt
        p = np.array([2.0 * math.cos(a), 4.5 + 2.0 * math.sin(a), 1.0])
        z = h_measure(np.array([p[0], 0, 0, p[1], 0, 0, p[2], 0, 0]), P, c)
        out.append((z + rng.normal(0, [0.3, 0.3, 0.01 * z[2]]), p))
    return P, c, out


@pytest.mark.parametrize("true_j", [1, 2])
def test_mmae_picks_true_model(true_j: int) -> None:
    omega = PAPER_OMEGAS_RAD_S[true_j]
    dt = 0.1
    P, c, meas = _circle_measurements(omega, 600, dt)
    mm = Mmae(PAPER_OMEGAS_RAD_S, q_psd=1e-4)
    x0 = np.zeros(9)
    x0[[0, 3, 6]] = meas[0][1] + 0.05
    mm.init(x0, np.diag(np.tile([0.1, 1.0, 0.25], 3)))
    R = None
    for z, _ in meas[1:]:
        R = np.diag([0.09, 0.09, (0.01 * z[2]) ** 2])
        mm.predict(dt)
        assert mm.update(z, R, P, c)
    est = mm.estimate()
    assert int(np.argmax(est.probs)) == true_j
    assert est.probs[true_j] > 0.95
    assert est.omega_rad_s == pytest.approx(omega, abs=0.03)
    assert np.linalg.norm(est.x[[0, 3, 6]] - meas[-1][1]) < 0.05
    # combined covariance is symmetric positive definite
    assert np.all(np.linalg.eigvalsh(0.5 * (est.P + est.P.T)) > 0)


def test_mmae_flags_divergence() -> None:
    P, c, meas = _circle_measurements(0.2, 30, 0.1)
    mm = Mmae(nis_window=5, nis_reset=25.0)
    x0 = np.zeros(9)
    x0[[0, 3, 6]] = meas[0][1]
    mm.init(x0, np.diag(np.tile([1e-6, 1e-6, 1e-6], 3)))
    ok = True
    for z, _ in meas[1:10]:
        mm.predict(0.1)
        ok = mm.update(z + np.array([40.0, -40.0, 1.0]), np.diag([0.09, 0.09, 1e-3]), P, c)
        if not ok:
            break
    assert not ok


def test_single_ekf_runs() -> None:
    f = ConstantTurnEkf(0.0, 1e-3)
    f.init(np.zeros(9), np.eye(9))
    f.predict(0.5)
    assert np.all(np.isfinite(f.P))


def test_ptz_tracker_closed_loop_short() -> None:
    from engine.loop import run_tracking
    from engine.ptz.head import PanTiltCommand, PtzHeadReading
    from engine.ptz.sim import PtzTargetTruth
    from engine.trackers import create_tracker
    from engine.trackers.base import TrackState

    sc = CircleScenario(duration_s=2.0, fps=30.0, width=320, height=240, f_px=400.0)
    src = PtzSimSource(sc)
    tr = create_tracker("ptz", target_b=40, target_g=40, target_r=210)
    pans = set()
    last = None
    commands = 0
    # the pipeline adds the simulated head's sink: the tracker's commands move the camera
    for rec in run_tracking(src, tr):
        last = rec.result, rec.frame
        pans.add(rec.frame.payload(PtzHeadReading).pan_deg)
        commands += len(rec.result.commands_of(PanTiltCommand))
    res, frame = last
    assert res.state is TrackState.TRACKING
    err = np.linalg.norm(res.details.target_xyz - np.asarray(
        frame.payload(PtzTargetTruth).xyz_world))
    assert err < 0.1
    assert commands > 0
    assert len(pans) > 1  # the camera followed the commands in whole steps
    assert all(abs(p - round(p)) < 1e-9 for p in pans)
    assert res.details.model_probs.sum() == pytest.approx(1.0)


def test_ptz_tracker_does_no_io_the_loop_stays_open_without_the_head_sink() -> None:
    from engine.ptz.head import PtzHeadReading
    from engine.trackers import create_tracker

    sc = CircleScenario(duration_s=1.0, fps=30.0, width=320, height=240, f_px=400.0)
    src = PtzSimSource(sc)
    tr = create_tracker("ptz", target_b=40, target_g=40, target_r=210)
    pans = set()
    for f in src.frames():  # no pipeline: the commands are returned, nobody executes them
        res = tr.track(f)
        pans.add(f.payload(PtzHeadReading).pan_deg)
    assert len(pans) == 1
    assert res.commands
