"""Property tests of engine.geometry: exp/log round trips (tiny angles, near pi), agreement
with the matrix exponential, composition/inversion, quaternions, pan/tilt/roll."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from engine import geometry as g

finite = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)
vec3 = st.tuples(finite, finite, finite).map(np.array)
unit3 = vec3.filter(lambda v: np.linalg.norm(v) > 1e-3).map(lambda v: v / np.linalg.norm(v))
# angles from 1e-12 to pi, log-uniform at the small end so that the series branches are hit
angle = st.one_of(
    st.floats(-12.0, 0.0).map(lambda e: 10.0**e * np.pi),
    st.floats(1e-6, np.pi, allow_nan=False),
)
rotvec = st.builds(lambda n, a: n * a, unit3, angle)
twist = st.builds(lambda v, w: np.concatenate([v, w]), vec3, rotvec)


def rot_err(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return g.rotation_angle_rad(R_a.T @ R_b)


def se3_matrix_exp(xi: np.ndarray) -> np.ndarray:
    """Reference: expm of the 4x4 twist matrix [[hat(w), v], [0, 0]]."""
    X = np.zeros((4, 4))
    X[:3, :3] = g.hat(xi[3:])
    X[:3, 3] = xi[:3]
    return scipy.linalg.expm(X)


@settings(max_examples=300, deadline=None)
@given(rotvec)
def test_so3_exp_matches_expm_of_hat(w: np.ndarray) -> None:
    R = g.so3_exp(w)
    np.testing.assert_allclose(R, scipy.linalg.expm(g.hat(w)), atol=1e-13)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-13)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-13)


@settings(max_examples=300, deadline=None)
@given(rotvec)
def test_so3_log_inverts_exp(w: np.ndarray) -> None:
    theta = np.linalg.norm(w)
    assume(theta < np.pi - 1e-9)  # at exactly pi both +w and -w are valid logs
    w_back = g.so3_log(g.so3_exp(w))
    # relative accuracy: rotation vectors of 1e-12 rad must come back, not just "near zero"
    assert np.linalg.norm(w_back - w) <= 1e-9 * theta


@pytest.mark.parametrize("eps", [0.0, 1e-12, 1e-9, 1e-7, 1e-5, 1e-4, 5e-4, 1e-3, 2e-3, 1e-2])
@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 0, 1), (1, 2, 3), (-0.3, 0.9, 0.1)])
def test_so3_log_near_pi(eps: float, axis: tuple[float, float, float]) -> None:
    n = np.array(axis, dtype=float) / np.linalg.norm(axis)
    w = n * (np.pi - eps)
    R = g.so3_exp(w)
    w_back = g.so3_log(R)
    np.testing.assert_allclose(g.so3_exp(w_back), R, atol=1e-12)
    if eps > 0:
        np.testing.assert_allclose(w_back, w, atol=1e-9)
    else:
        assert min(np.linalg.norm(w_back - w), np.linalg.norm(w_back + w)) < 1e-9


@settings(max_examples=300, deadline=None)
@given(twist)
def test_se3_exp_matches_matrix_exponential(xi: np.ndarray) -> None:
    np.testing.assert_allclose(g.se3_exp(xi), se3_matrix_exp(xi), atol=1e-11)


@settings(max_examples=300, deadline=None)
@given(twist)
def test_se3_log_inverts_exp(xi: np.ndarray) -> None:
    assume(np.linalg.norm(xi[3:]) < np.pi - 1e-6)  # the log is the principal one (|w| < pi)
    xi_back = g.se3_log(g.se3_exp(xi))
    assert np.linalg.norm(xi_back[3:] - xi[3:]) <= 1e-9 * np.linalg.norm(xi[3:])
    # the translation part is conditioned by 1 / sin near pi: absolute tolerance scaled by it
    theta = np.linalg.norm(xi[3:])
    cond = 1.0 / max(np.sin(theta / 2), 1e-6) if theta > 2.5 else 1.0
    np.testing.assert_allclose(xi_back[:3], xi[:3], atol=1e-10 * cond * (1 + np.linalg.norm(xi)))


@pytest.mark.parametrize("theta", [1e-9, 1e-7, 1e-5, 1e-4 * 0.999, 1e-4 * 1.001])
def test_se3_tiny_increments(theta: float) -> None:
    xi = np.array([1e-3, -2e-3, 5e-4, 0.0, 0.0, 0.0])
    xi[3:] = np.array([0.6, -0.8, 0.0]) * theta
    T = g.se3_exp(xi)
    np.testing.assert_allclose(T, se3_matrix_exp(xi), atol=1e-17 + 1e-15)
    np.testing.assert_allclose(g.se3_log(T), xi, rtol=1e-8, atol=1e-18)


@pytest.mark.parametrize("theta", [0.999e-4, 1.001e-4, 3e-4, 1e-3, 1e-2])
def test_se3_log_translation_near_series_switch(theta: float) -> None:
    # regression: (1 - cos t) / t^2 lost 8 digits at t ~ 1e-4 and with it the translation
    xi = np.array([0.0, 0.0, 1.0, 0.0, theta / np.sqrt(2), theta / np.sqrt(2)])
    T = g.se3_exp(xi)
    np.testing.assert_allclose(T, se3_matrix_exp(xi), atol=1e-15)
    np.testing.assert_allclose(g.se3_log(T), xi, atol=1e-14)


def test_exp_of_zero_is_identity() -> None:
    np.testing.assert_array_equal(g.se3_exp(np.zeros(6)), np.eye(4))
    np.testing.assert_array_equal(g.se3_log(np.eye(4)), np.zeros(6))


def random_T(seed_xi: np.ndarray) -> np.ndarray:
    return g.se3_exp(seed_xi)


@settings(max_examples=200, deadline=None)
@given(twist, twist, st.tuples(finite, finite, finite).map(np.array))
def test_compose_invert_transform_points(
    xi_a: np.ndarray, xi_b: np.ndarray, p: np.ndarray
) -> None:
    T_a, T_b = g.se3_exp(xi_a), g.se3_exp(xi_b)
    np.testing.assert_allclose(g.compose(T_a, g.invert(T_a)), np.eye(4), atol=1e-12)
    np.testing.assert_allclose(g.invert(T_a), np.linalg.inv(T_a), atol=1e-10)
    np.testing.assert_allclose(
        g.invert(g.compose(T_a, T_b)), g.compose(g.invert(T_b), g.invert(T_a)), atol=1e-10
    )
    # T_a_c = T_a_b @ T_b_c maps points of c into a in two steps
    pts = np.stack([p, 2 * p, -p])
    two_steps = g.transform_points(T_a, g.transform_points(T_b, pts))
    np.testing.assert_allclose(g.transform_points(g.compose(T_a, T_b), pts), two_steps, atol=1e-9)
    homog = (g.compose(T_a, T_b) @ np.c_[pts, np.ones(3)].T).T[:, :3]
    np.testing.assert_allclose(two_steps, homog, atol=1e-9)


def test_compose_of_nothing_is_identity() -> None:
    np.testing.assert_array_equal(g.compose(), np.eye(4))


@settings(max_examples=300, deadline=None)
@given(rotvec)
def test_quaternion_round_trip_and_scipy_agreement(w: np.ndarray) -> None:
    R = g.so3_exp(w)
    q = g.quat_xyzw_from_R(R)
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-14)
    assert q[3] >= 0.0  # sign convention: scalar part non-negative
    np.testing.assert_allclose(g.R_from_quat_xyzw(q), R, atol=1e-13)
    # scipy uses the same (x, y, z, w) order; q and -q are the same rotation
    q_ref = Rotation.from_matrix(R).as_quat()
    assert min(np.abs(q - q_ref).max(), np.abs(q + q_ref).max()) < 1e-12
    np.testing.assert_allclose(g.R_from_quat_xyzw(q_ref), R, atol=1e-13)


@settings(max_examples=100, deadline=None)
@given(rotvec, st.floats(0.01, 100.0))
def test_quaternion_scale_and_sign_do_not_matter(w: np.ndarray, s: float) -> None:
    R = g.so3_exp(w)
    q = g.quat_xyzw_from_R(R)
    np.testing.assert_allclose(g.R_from_quat_xyzw(s * q), R, atol=1e-12)
    np.testing.assert_allclose(g.R_from_quat_xyzw(-q), R, atol=1e-12)


def test_quaternion_known_values() -> None:
    # 90 deg about z: (0, 0, sin 45, cos 45); identity: (0, 0, 0, 1)
    Rz = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(g.quat_xyzw_from_R(Rz), [0, 0, np.sqrt(0.5), np.sqrt(0.5)])
    np.testing.assert_allclose(g.quat_xyzw_from_R(np.eye(3)), [0, 0, 0, 1])
    with pytest.raises(ValueError, match="zero or non-finite norm"):
        g.R_from_quat_xyzw(np.zeros(4))


@settings(max_examples=200, deadline=None)
@given(twist)
def test_tum_row_round_trip(xi: np.ndarray) -> None:
    T = g.se3_exp(xi)
    row = g.tum_from_T(T)
    assert row.shape == (7,)
    np.testing.assert_allclose(g.T_from_tum(row), T, atol=1e-12)


@settings(max_examples=300, deadline=None)
@given(st.floats(-179.9, 179.9), st.floats(-89.0, 89.0), st.floats(-179.9, 179.9))
def test_pan_tilt_roll_round_trip(pan: float, tilt: float, roll: float) -> None:
    R = g.R_from_pan_tilt_roll_deg(pan, tilt, roll)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-13)
    p, t, r = g.pan_tilt_roll_deg(R)
    np.testing.assert_allclose([p, t, r], [pan, tilt, roll], atol=1e-8)


def test_pan_tilt_roll_conventions() -> None:
    # zero: camera looks along world +y, image x along world +x, image down = world -z
    R0 = g.R_from_pan_tilt_roll_deg(0, 0, 0)
    np.testing.assert_allclose(R0[:, 2], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(R0[:, 0], [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(R0[:, 1], [0, 0, -1], atol=1e-15)
    # pan +90: turned left (counter-clockwise from above): looks along world -x
    np.testing.assert_allclose(g.R_from_pan_tilt_roll_deg(90, 0, 0)[:, 2], [-1, 0, 0], atol=1e-15)
    # tilt +30: optical axis rises
    axis = g.R_from_pan_tilt_roll_deg(0, 30, 0)[:, 2]
    np.testing.assert_allclose(
        axis, [0, np.cos(np.radians(30)), np.sin(np.radians(30))], atol=1e-15
    )
    # roll keeps the optical axis
    np.testing.assert_allclose(g.R_from_pan_tilt_roll_deg(0, 0, 40)[:, 2], [0, 1, 0], atol=1e-15)


# ---------------------------------------------------------------- batched helpers


def _rotvecs(rng: np.random.Generator, n: int) -> np.ndarray:
    """Rotation vectors from tiny (series branch) to near pi."""
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([[0.0, 1e-9, 5e-5, 2e-4], rng.uniform(0, np.pi - 1e-3, n - 4)])
    return axes * angles[:, None]


def test_so3_exp_batch_matches_so3_exp_row_by_row() -> None:
    w = _rotvecs(np.random.default_rng(0), 64)
    batch = g.so3_exp_batch(w)
    assert batch.shape == (64, 3, 3)
    for wi, Ri in zip(w, batch, strict=True):
        np.testing.assert_allclose(Ri, g.so3_exp(wi), rtol=0, atol=1e-15)
    np.testing.assert_array_equal(g.hat_batch(w[:3]), np.stack([g.hat(x) for x in w[:3]]))


def test_invert_and_rotation_angle_take_stacks() -> None:
    rng = np.random.default_rng(1)
    w = _rotvecs(rng, 32)
    T = np.stack([g.make_T(g.so3_exp(wi), rng.normal(size=3)) for wi in w])
    Ti = g.invert(T)
    assert Ti.shape == (32, 4, 4)
    for a, b in zip(Ti, T, strict=True):
        np.testing.assert_allclose(a, g.invert(b), atol=1e-14)
    np.testing.assert_allclose(Ti @ T, np.broadcast_to(np.eye(4), T.shape), atol=1e-12)
    angles = g.rotation_angle_rad_batch(T[:, :3, :3])
    np.testing.assert_allclose(angles, [g.rotation_angle_rad(R) for R in T[:, :3, :3]],
                               rtol=0, atol=0)
    np.testing.assert_allclose(angles[4:], np.linalg.norm(w[4:], axis=1), atol=1e-6)
