"""Rigid-body geometry as short pure functions.

Conventions (carried in the names):
- ``T_a_b`` is a 4x4 homogeneous transform mapping points in frame *b* into frame *a*
  (``p_a = T_a_b @ p_b``); ``T_world_cam`` is therefore the camera pose in the world.
- Twists are ``xi = (v, w)``: translational part first, rotational part second (3+3).
- Quaternions are ``quat_xyzw`` (scalar last), as in TUM trajectory files.
- Camera frames are OpenCV's: x right, y down, z forward (optical axis).
- ``*_batch`` functions (and :func:`invert`) take stacks: a leading (N,) axis (or any
  leading axes) over the single-element shapes.

The SE(3) exponential and logarithm follow the closed forms (e.g. Tykkälä 2014 eq. (5)
uses this parameterisation) with Taylor expansions near zero angle so that they stay
accurate for the tiny increments Gauss-Newton produces.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

_SMALL_ANGLE = 1e-4


def hat(w: F64) -> F64:
    """Skew-symmetric matrix [w]x so that hat(w) @ p == cross(w, p)."""
    return np.array(
        [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]], dtype=np.float64
    )


def vee(W: F64) -> F64:
    """Inverse of :func:`hat`."""
    return np.array([W[2, 1], W[0, 2], W[1, 0]], dtype=np.float64)


def _so3_coeffs(theta: float) -> tuple[float, float, float]:
    """A = sin(t)/t, B = (1-cos t)/t^2, C = (1 - A)/t^2 with series near 0."""
    if theta < _SMALL_ANGLE:
        t2 = theta * theta
        a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
        b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
        c = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0
        return a, b, c
    a = np.sin(theta) / theta
    # 1 - cos t = 2 sin^2(t/2): no cancellation (1 - cos t loses 8 digits at t = 1e-4)
    b = 2.0 * np.sin(0.5 * theta) ** 2 / (theta * theta)
    c = (1.0 - a) / (theta * theta)
    return float(a), float(b), float(c)


def so3_exp(w: F64) -> F64:
    """Rodrigues' formula R = I + A[w]x + B[w]x^2, stable at small angles."""
    w = np.asarray(w, dtype=np.float64)
    theta = float(np.linalg.norm(w))
    a, b, _ = _so3_coeffs(theta)
    W = hat(w)
    return np.eye(3) + a * W + b * (W @ W)


def hat_batch(w: F64) -> F64:
    """(N, 3) vectors -> (N, 3, 3) skew-symmetric matrices (see :func:`hat`)."""
    w = np.asarray(w, dtype=np.float64)
    W = np.zeros((*w.shape[:-1], 3, 3))
    W[..., 0, 1], W[..., 0, 2] = -w[..., 2], w[..., 1]
    W[..., 1, 0], W[..., 1, 2] = w[..., 2], -w[..., 0]
    W[..., 2, 0], W[..., 2, 1] = -w[..., 1], w[..., 0]
    return W


def so3_exp_batch(w: F64) -> F64:
    """Rodrigues' formula for (N, 3) rotation vectors -> (N, 3, 3), as :func:`so3_exp` row by
    row (same series below the small angle, same cancellation-free B)."""
    w = np.asarray(w, dtype=np.float64)
    theta = np.linalg.norm(w, axis=-1)
    small = theta < _SMALL_ANGLE
    t2 = theta * theta
    safe = np.where(small, 1.0, theta)
    a: F64 = np.where(small, 1.0 - t2 / 6.0 + t2 * t2 / 120.0, np.sin(safe) / safe)
    b: F64 = np.where(
        small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, 2.0 * np.sin(0.5 * safe) ** 2 / (safe * safe)
    )
    W = hat_batch(w)
    return np.eye(3) + a[..., None, None] * W + b[..., None, None] * (W @ W)


def so3_log(R: F64) -> F64:
    """Rotation vector of R, stable near 0 and near pi.

    The angle comes from atan2(sin, cos), accurate over [0, pi] (arccos of the trace loses
    half the digits near 0 and pi). Near pi, where sin(theta) n = vee(R - R^T)/2 vanishes,
    the axis is read from the symmetric part of Rodrigues' formula instead:
    (R + R^T)/2 = cos(theta) I + (1 - cos(theta)) n n^T.
    """
    R = np.asarray(R, dtype=np.float64)
    s = vee(R - R.T) * 0.5  # sin(theta) n
    sin_t = float(np.linalg.norm(s))
    cos_t = float((np.trace(R) - 1.0) * 0.5)
    theta = float(np.arctan2(sin_t, cos_t))
    if theta < _SMALL_ANGLE:
        # theta / sin(theta) = 1 + theta^2/6 + O(theta^4)
        return s * (1.0 + theta * theta / 6.0)
    if np.pi - theta < 1e-3:
        nnT = (0.5 * (R + R.T) - cos_t * np.eye(3)) / (1.0 - cos_t)
        k = int(np.argmax(np.diag(nnT)))
        n: F64 = nnT[:, k] / np.sqrt(max(nnT[k, k], 1e-15))
        n /= np.linalg.norm(n)
        # n and -n give the same n n^T; the antisymmetric part (while not exactly 0) decides.
        if float(np.dot(s, n)) < 0.0:
            n = -n
        return n * theta
    return s * (theta / sin_t)


def se3_exp(xi: F64) -> F64:
    """Exponential map of a twist xi = (v, w) to a 4x4 transform (closed form, eq. (5))."""
    xi = np.asarray(xi, dtype=np.float64)
    v, w = xi[:3], xi[3:]
    theta = float(np.linalg.norm(w))
    a, b, c = _so3_coeffs(theta)
    W = hat(w)
    W2 = W @ W
    R = np.eye(3) + a * W + b * W2
    V = np.eye(3) + b * W + c * W2
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = V @ v
    return T


def se3_log(T: F64) -> F64:
    """Logarithm of a 4x4 transform to a twist (v, w)."""
    T = np.asarray(T, dtype=np.float64)
    w = so3_log(T[:3, :3])
    theta = float(np.linalg.norm(w))
    W = hat(w)
    if theta < _SMALL_ANGLE:
        V_inv = np.eye(3) - 0.5 * W + (W @ W) / 12.0
    else:
        a, b, _ = _so3_coeffs(theta)
        V_inv = np.eye(3) - 0.5 * W + (1.0 / (theta * theta)) * (1.0 - a / (2.0 * b)) * (W @ W)
    return np.concatenate([V_inv @ T[:3, 3], w])


def make_T(R: F64, t: F64 | Sequence[float]) -> F64:
    """4x4 transform from rotation and translation (an array or three numbers)."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(t, dtype=np.float64).reshape(3)
    return T


def invert(T: F64) -> F64:
    """Inverse of a rigid transform (4, 4), or of each in a stack (..., 4, 4), without a
    general matrix inverse: [R | t]^-1 = [R^T | -R^T t]."""
    if T.ndim == 2:
        R = T[:3, :3]
        Ti = np.eye(4)
        Ti[:3, :3] = R.T
        Ti[:3, 3] = -R.T @ T[:3, 3]
        return Ti
    Ri = np.swapaxes(T[..., :3, :3], -1, -2)
    out = np.zeros(T.shape, dtype=np.float64)
    out[..., :3, :3] = Ri
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Ri, T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def compose(*Ts: F64) -> F64:
    """Product T1 @ T2 @ ... of rigid transforms."""
    out = np.eye(4)
    for T in Ts:
        out = out @ T
    return out


def transform_points(T_a_b: F64, p_b: F64) -> F64:
    """Apply T_a_b to an (N, 3) array of points in frame b."""
    return p_b @ T_a_b[:3, :3].T + T_a_b[:3, 3]


def quat_xyzw_from_R(R: F64) -> F64:
    """Unit quaternion (x, y, z, w) with w >= 0 from a rotation matrix (Shepperd's method)."""
    R = np.asarray(R, dtype=np.float64)
    tr = np.trace(R)
    if tr > 0.0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = np.array(
            [(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, 0.25 * s]
        )
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = np.array(
            [0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s, (R[2, 1] - R[1, 2]) / s]
        )
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = np.array(
            [(R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s, (R[0, 2] - R[2, 0]) / s]
        )
    else:
        s = 2.0 * np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = np.array(
            [(R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s, (R[1, 0] - R[0, 1]) / s]
        )
    q /= np.linalg.norm(q)
    return -q if q[3] < 0.0 else q


def R_from_quat_xyzw(q: F64) -> F64:
    """Rotation matrix from a (not necessarily unit) quaternion (x, y, z, w)."""
    q = np.asarray(q, dtype=np.float64)
    n = np.linalg.norm(q)
    if not np.isfinite(n) or n < 1e-12:
        raise ValueError(f"quaternion {q.tolist()} has zero or non-finite norm")
    x, y, z, w = q / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def T_from_tum(txyz_quat_xyzw: F64) -> F64:
    """4x4 pose from a TUM row (tx, ty, tz, qx, qy, qz, qw)."""
    row = np.asarray(txyz_quat_xyzw, dtype=np.float64)
    return make_T(R_from_quat_xyzw(row[3:7]), row[:3])


def tum_from_T(T: F64) -> F64:
    """TUM row (tx, ty, tz, qx, qy, qz, qw) of a 4x4 pose."""
    return np.concatenate([T[:3, 3], quat_xyzw_from_R(T[:3, :3])])


def rotation_angle_rad(R: F64) -> float:
    """Angle of a rotation matrix in radians, in [0, pi]."""
    return float(np.arccos(np.clip((np.trace(R) - 1.0) * 0.5, -1.0, 1.0)))


def rotation_angle_rad_batch(R: F64) -> F64:
    """Angle of each rotation of an (N, 3, 3) stack: arccos((trace - 1) / 2), clipped (as
    TUM's evaluation script)."""
    tr: F64 = np.trace(R, axis1=-2, axis2=-1)
    return np.arccos(np.clip((tr - 1.0) * 0.5, -1.0, 1.0))


def pan_tilt_roll_deg(R_world_cam: F64) -> tuple[float, float, float]:
    """Pan, tilt, roll (degrees) of a camera orientation in a z-up world.

    The world is right-handed with z up; at pan = tilt = roll = 0 the camera (OpenCV axes)
    looks along world +y with its image x along world +x. Pan turns about world z
    (positive to the left, counter-clockwise seen from above), tilt raises the optical axis
    (positive up), roll turns about the optical axis (positive clockwise in the image).
    R_world_cam = Rz(pan) @ Rx(tilt) @ Ry_view(roll) @ R_base.
    """
    R_base = _R_BASE_ZUP
    M = R_world_cam @ R_base.T  # = Rz(pan) Rx(tilt) Ry(roll) in world axes
    # M = Rz(p) Rx(t) Ry(r): M[2,1] = sin t, M[0,1] = -sin p cos t, M[1,1] = cos p cos t,
    # M[2,0] = -cos t sin r, M[2,2] = cos t cos r.
    tilt = np.arcsin(np.clip(M[2, 1], -1.0, 1.0))
    pan = np.arctan2(-M[0, 1], M[1, 1])
    roll = np.arctan2(-M[2, 0], M[2, 2])
    return float(np.degrees(pan)), float(np.degrees(tilt)), float(np.degrees(roll))


def R_from_pan_tilt_roll_deg(pan_deg: float, tilt_deg: float, roll_deg: float) -> F64:
    """Inverse of :func:`pan_tilt_roll_deg`."""
    p, t, r = np.radians([pan_deg, tilt_deg, roll_deg])
    Rz: F64 = np.array([[np.cos(p), -np.sin(p), 0], [np.sin(p), np.cos(p), 0], [0, 0, 1]])
    Rx: F64 = np.array([[1, 0, 0], [0, np.cos(t), -np.sin(t)], [0, np.sin(t), np.cos(t)]])
    Ry: F64 = np.array([[np.cos(r), 0, np.sin(r)], [0, 1, 0], [-np.sin(r), 0, np.cos(r)]])
    return Rz @ Rx @ Ry @ _R_BASE_ZUP


# Columns are the camera axes (x right, y down, z forward) expressed in a z-up world when the
# camera looks along +y: x_cam = +x_world, y_cam = -z_world, z_cam = +y_world.
_R_BASE_ZUP: F64 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
