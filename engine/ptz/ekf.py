"""Extended Kalman filter with the 3D planar constant-turn model (Gaspar 2009 sec. 5.1).

State x = [x, x', x'', y, y', y'', z, z', z''] (position, velocity, acceleration in the world,
metres). The constant-turn model of Li & Jilkov 2003 with known turn rate omega gives, per
axis, a''' = -omega^2 a' (a uniform circle of angular speed omega in any plane satisfies it),
driven by white jerk noise of power spectral density q. Its exact discretisation over T:

    Phi(omega, T) = [[1, sin(wT)/w, (1 - cos wT)/w^2],
                     [0, cos wT,    sin(wT)/w       ],
                     [0, -w sin wT, cos wT          ]]

(omega = 0 is the constant-acceleration model). Measurements z = [u, v, d] (sec. 5.1):
u = (p1 . X) / (p3 . X), v = (p2 . X) / (p3 . X) with X = [x, y, z, 1], and d the distance
to the target. The paper's d = sqrt(x^2 + y^2 + z^2) is the distance to the world origin,
where its camera sat; here d = ||X - c|| to the camera's optical centre c (the two agree when
the world origin is the camera), since that is what the target's apparent size measures.

Predict/update follow the paper's notation (Gelb 2001): x- = f(x), P- = A P A^T + Q;
K = P- H^T (H P- H^T + R)^-1, x = x- + K (z - h(x-)), P = (I - K H) P- (Joseph form here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.arrays import f64

F64 = NDArray[np.float64]

POS = np.array([0, 3, 6])
VEL = np.array([1, 4, 7])
ACC = np.array([2, 5, 8])


def phi_axis(omega: float, dt: float) -> F64:
    """Per-axis transition of the constant-turn model (exact, omega = 0 -> const. accel.)."""
    w = float(omega)
    if abs(w) < 1e-9:
        return np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    s, c = math.sin(w * dt), math.cos(w * dt)
    return np.array([[1.0, s / w, (1.0 - c) / (w * w)], [0.0, c, s / w], [0.0, -w * s, c]])


def q_axis(omega: float, dt: float, q_psd: float) -> F64:
    """Discrete process noise of white jerk with PSD q (Van Loan's method)."""
    from scipy.linalg import expm

    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, -omega * omega, 0.0]])
    Qc = np.zeros((3, 3))
    Qc[2, 2] = q_psd
    M = np.zeros((6, 6))
    M[:3, :3] = -A
    M[:3, 3:] = Qc
    M[3:, 3:] = A.T
    E = expm(M * dt)
    Phi: F64 = E[3:, 3:].T
    return Phi @ E[:3, 3:]


def block3(m: F64) -> F64:
    """The 9x9 matrix acting as ``m`` on each of the x, y, z axis blocks."""
    return f64(np.kron(np.eye(3), m))


def h_measure(x: F64, P: F64, c_world: F64) -> F64:
    """z = [u, v, d] of state x through projection matrix P (sec. 5.1)."""
    X = np.array([x[0], x[3], x[6], 1.0])
    m = P @ X
    d = float(np.linalg.norm(X[:3] - c_world))
    return np.array([m[0] / m[2], m[1] / m[2], d])


def h_jacobian(x: F64, P: F64, c_world: F64) -> F64:
    """3x9 Jacobian H of h at x (non-zero only on the position entries)."""
    X = np.array([x[0], x[3], x[6], 1.0])
    m = P @ X
    H = np.zeros((3, 9))
    H[0, POS] = (P[0, :3] * m[2] - m[0] * P[2, :3]) / (m[2] * m[2])
    H[1, POS] = (P[1, :3] * m[2] - m[1] * P[2, :3]) / (m[2] * m[2])
    r = X[:3] - c_world
    H[2, POS] = r / max(float(np.linalg.norm(r)), 1e-9)
    return H


@dataclass(frozen=True, slots=True)
class EkfStep:
    """One EKF update: innovation, its covariance, NIS and log-likelihood."""

    innovation: F64
    S: F64
    nis: float
    log_likelihood: float


class ConstantTurnEkf:
    """EKF for one turn-rate hypothesis omega (rad/s)."""

    def __init__(self, omega_rad_s: float, q_psd: float) -> None:
        self.omega = float(omega_rad_s)
        self.q_psd = float(q_psd)
        self.x = np.zeros(9)
        self.P = np.eye(9)
        self._cache: dict[float, tuple[F64, F64]] = {}

    def init(self, x0: F64, P0: F64) -> None:
        self.x = np.asarray(x0, dtype=np.float64).copy()
        self.P = np.asarray(P0, dtype=np.float64).copy()

    def transition(self, dt: float) -> tuple[F64, F64]:
        key = round(dt, 6)
        if key not in self._cache:
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = (
                block3(phi_axis(self.omega, dt)), block3(q_axis(self.omega, dt, self.q_psd))
            )
        return self._cache[key]

    def predict(self, dt: float) -> None:
        A, Q = self.transition(dt)
        self.x = A @ self.x
        self.P = A @ self.P @ A.T + Q

    def update(self, z: F64, R: F64, P_cam: F64, c_world: F64) -> EkfStep:
        H = h_jacobian(self.x, P_cam, c_world)
        nu = np.asarray(z, dtype=np.float64) - h_measure(self.x, P_cam, c_world)
        S = H @ self.P @ H.T + R
        S = 0.5 * (S + S.T)
        Sinv = np.linalg.inv(S)
        K = self.P @ H.T @ Sinv
        self.x = self.x + K @ nu
        IKH = np.eye(9) - K @ H
        self.P = IKH @ self.P @ IKH.T + K @ R @ K.T  # Joseph form: stays symmetric PSD
        nis = float(nu @ Sinv @ nu)
        sign, logdet = np.linalg.slogdet(S)
        ll = -0.5 * (nis + logdet + 3.0 * math.log(2.0 * math.pi)) if sign > 0 else -np.inf
        return EkfStep(innovation=nu, S=S, nis=nis, log_likelihood=float(ll))
