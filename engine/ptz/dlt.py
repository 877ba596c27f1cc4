"""Direct linear transform calibration (Gaspar 2009 sec. 3.1, after Faugeras & Luong 2001).

``lambda m = P M`` (eq. (1)); each world<->image correspondence gives two rows of ``L p = 0``
with ``p = (p11 .. p34)``; ``p`` is the right singular vector of ``L`` with the smallest
singular value. ``P`` is then decomposed into intrinsics (alpha_u, alpha_v, u0, v0) and
extrinsics (R, t) with the closed forms of sec. 3.1 (zero skew assumed, as in the paper).

Conventions: ``P`` maps world points to pixels; ``R_cam_world``/``t_cam_world`` map world
points into the camera frame (OpenCV axes: x right, y down, z forward).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from engine.errors import CalibrationError

F64 = NDArray[np.float64]

MIN_POINTS = 6
#: smallest/largest spread of the world points below which they count as coplanar
COPLANAR_RATIO = 1e-3


@dataclass(frozen=True, slots=True)
class DltDecomposition:
    """Intrinsic and extrinsic parameters read from P (sec. 3.1)."""

    alpha_u: float
    alpha_v: float
    u0: float
    v0: float
    R_cam_world: F64  # orthonormalised (nearest rotation); the raw rows are in R_raw
    t_cam_world: F64
    R_raw: F64
    skew_deg: float  # angle between r1 and r2 minus 90 deg: 0 for a skew-free camera

    @property
    def K(self) -> F64:
        return np.array([[self.alpha_u, 0.0, self.u0], [0.0, self.alpha_v, self.v0], [0, 0, 1.0]])

    @property
    def camera_centre_world(self) -> F64:
        return -self.R_cam_world.T @ self.t_cam_world


@dataclass(frozen=True, slots=True)
class DltResult:
    """P, its decomposition and the per-point reprojection residuals (px)."""

    P: F64
    decomposition: DltDecomposition
    residuals_px: F64  # (N,) reprojection distance of each point
    rmse_px: float
    singular_values: F64


def project_P(P: F64, X_world: F64) -> F64:
    """Pixels (N, 2) of world points (N, 3) through a 3x4 projection matrix, eq. (1)."""
    X = np.asarray(X_world, dtype=np.float64)
    Xh = np.hstack([X, np.ones((len(X), 1))])
    m = Xh @ np.asarray(P, dtype=np.float64).T
    return m[:, :2] / m[:, 2:3]


def check_correspondences(X_world: F64, uv: F64) -> tuple[F64, F64]:
    """Validate shapes, count and non-coplanarity; raises CalibrationError with one line."""
    X = np.asarray(X_world, dtype=np.float64)
    m = np.asarray(uv, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 3 or m.ndim != 2 or m.shape[1] != 2 or len(X) != len(m):
        raise CalibrationError(
            f"DLT needs matching (N, 3) world and (N, 2) image points, got {X.shape} and {m.shape}"
        )
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(m))):
        raise CalibrationError("DLT points contain a non-finite value")
    if len(X) < MIN_POINTS:
        raise CalibrationError(
            f"DLT needs at least {MIN_POINTS} points (12 unknowns, 2 equations per point), "
            f"got {len(X)}"
        )
    s = np.linalg.svd(X - X.mean(axis=0), compute_uv=False)
    if s[0] <= 0 or s[2] / s[0] < COPLANAR_RATIO:
        raise CalibrationError(
            f"the {len(X)} world points are coplanar (or collinear): DLT needs points off one "
            "plane; add points at another depth/height or use chessboard calibration"
        )
    return X, m


def _normaliser_2d(m: F64) -> F64:
    c = m.mean(axis=0)
    s = np.sqrt(2.0) / max(float(np.mean(np.linalg.norm(m - c, axis=1))), 1e-12)
    return np.array([[s, 0, -s * c[0]], [0, s, -s * c[1]], [0, 0, 1.0]])


def _normaliser_3d(X: F64) -> F64:
    c = X.mean(axis=0)
    s = np.sqrt(3.0) / max(float(np.mean(np.linalg.norm(X - c, axis=1))), 1e-12)
    T: F64 = np.eye(4) * s
    T[3, 3] = 1.0
    T[:3, 3] = -s * c
    return T


def build_L(X_world: F64, uv: F64) -> F64:
    """The 2n x 12 matrix L of sec. 3.1 (two rows per correspondence)."""
    n = len(X_world)
    L = np.zeros((2 * n, 12))
    Xh = np.hstack([X_world, np.ones((n, 1))])
    L[0::2, 0:4] = Xh
    L[0::2, 8:12] = -uv[:, 0:1] * Xh
    L[1::2, 4:8] = Xh
    L[1::2, 8:12] = -uv[:, 1:2] * Xh
    return L


def estimate_P(X_world: F64, uv: F64) -> tuple[F64, F64]:
    """P from >= 6 non-coplanar correspondences: smallest right singular vector of L.

    Hartley normalisation of both point sets conditions L (the paper solves the raw system;
    normalising changes nothing in exact arithmetic and keeps 0.5 px noise from being
    amplified). Returns P (scaled so that ||p3|| = 1 and points lie in front) and the
    singular values of the normalised L.
    """
    X, m = check_correspondences(X_world, uv)
    Tm = _normaliser_2d(m)
    TX = _normaliser_3d(X)
    mn = (np.hstack([m, np.ones((len(m), 1))]) @ Tm.T)[:, :2]
    Xn = (np.hstack([X, np.ones((len(X), 1))]) @ TX.T)[:, :3]
    L = build_L(Xn, mn)
    _, s, Vt = np.linalg.svd(L)
    if s[-2] <= 1e-9 * s[0]:
        raise CalibrationError(
            "DLT system is degenerate (several null directions): points too few or badly spread"
        )
    Pn = Vt[-1].reshape(3, 4)
    P = np.linalg.inv(Tm) @ Pn @ TX
    P = P / np.linalg.norm(P[2, :3])
    # the sign that puts the points in front of the camera (lambda > 0 in eq. (1))
    depth = np.hstack([X, np.ones((len(X), 1))]) @ P[2]
    if np.median(depth) < 0:
        P = -P
    return P, s


def decompose_P(P: F64) -> DltDecomposition:
    """Intrinsics and extrinsics of P with the closed forms of sec. 3.1.

    With p1, p2, p3 the first three entries of the rows of P scaled so that ||p3|| = 1:
    u0 = p1.p3, v0 = p2.p3, alpha_u = ||p1 - u0 p3||, alpha_v = ||p2 - v0 p3||,
    r3 = p3, r1 = (p1 - u0 r3)/alpha_u, r2 = (p2 - v0 r3)/alpha_v,
    tz = p34, tx = (p14 - u0 tz)/alpha_u, ty = (p24 - v0 tz)/alpha_v.
    (The paper prints r1 = (p3 - u0 r3)/alpha_u: a typo for p1.)
    """
    P = np.asarray(P, dtype=np.float64)
    scale = np.linalg.norm(P[2, :3])
    if scale <= 0 or not np.isfinite(scale):
        raise CalibrationError("projection matrix has a zero third row")
    P = P / scale
    p1, p2, p3 = P[0, :3], P[1, :3], P[2, :3]
    u0 = float(p1 @ p3)
    v0 = float(p2 @ p3)
    alpha_u = float(np.linalg.norm(p1 - u0 * p3))
    alpha_v = float(np.linalg.norm(p2 - v0 * p3))
    r3 = p3
    r1 = (p1 - u0 * r3) / alpha_u
    r2 = (p2 - v0 * r3) / alpha_v
    tz = P[2, 3]
    tx = (P[0, 3] - u0 * tz) / alpha_u
    ty = (P[1, 3] - v0 * tz) / alpha_v
    R_raw = np.stack([r1, r2, r3])
    if np.linalg.det(R_raw) < 0:  # a left-handed image frame: flip the camera y axis
        raise CalibrationError(
            "decomposed rotation is a reflection: image v axis and world handedness disagree"
        )
    U, _, Vt = np.linalg.svd(R_raw)
    R = U @ Vt
    skew = float(np.degrees(np.arccos(np.clip(r1 @ r2, -1.0, 1.0))) - 90.0)
    return DltDecomposition(
        alpha_u=alpha_u,
        alpha_v=alpha_v,
        u0=u0,
        v0=v0,
        R_cam_world=R,
        t_cam_world=np.array([tx, ty, tz]),
        R_raw=R_raw,
        skew_deg=skew,
    )


def compose_P(K: F64, R_cam_world: F64, t_cam_world: F64) -> F64:
    """P = A . pi . g (sec. 3.1): K [R | t]."""
    return np.asarray(K, dtype=np.float64) @ np.hstack(
        [np.asarray(R_cam_world, dtype=np.float64), np.asarray(t_cam_world).reshape(3, 1)]
    )


def calibrate_dlt(X_world: F64, uv: F64) -> DltResult:
    """Estimate P, decompose it and report per-point reprojection residuals."""
    X, m = check_correspondences(X_world, uv)
    P, s = estimate_P(X, m)
    dec = decompose_P(P)
    res = np.linalg.norm(project_P(P, X) - m, axis=1)
    return DltResult(
        P=P,
        decomposition=dec,
        residuals_px=res,
        rmse_px=float(np.sqrt(np.mean(res**2))),
        singular_values=s,
    )


def outlier_mask(residuals_px: F64, threshold_px: float = 3.0) -> NDArray[np.bool_]:
    """Points whose residual exceeds both ``threshold_px`` and 3 robust sigmas (MAD)."""
    r = np.asarray(residuals_px, dtype=np.float64)
    if len(r) == 0:
        return np.zeros(0, dtype=bool)
    sigma = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    return r > max(threshold_px, float(np.median(r)) + 3.0 * sigma)


def load_points_csv(path: str | Path) -> tuple[F64, F64]:
    """Read ``x,y,z,u,v`` rows (header optional, '#' comments) -> (N, 3) world, (N, 2) pixels."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CalibrationError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"{path}: cannot read ({exc})") from None
    rows: list[list[float]] = []
    for lineno, row in enumerate(csv.reader(text.splitlines()), start=1):
        cells = [c.strip() for c in row]
        if not cells or not cells[0] or cells[0].startswith("#"):
            continue
        try:
            vals = [float(c) for c in cells[:5]]
        except ValueError:
            if not rows and lineno == 1:  # header
                continue
            raise CalibrationError(f"{path}:{lineno}: expected numbers x,y,z,u,v") from None
        if len(vals) != 5:
            raise CalibrationError(
                f"{path}:{lineno}: expected 5 columns x,y,z,u,v, got {len(vals)}"
            )
        rows.append(vals)
    if not rows:
        raise CalibrationError(f"{path}: no x,y,z,u,v rows")
    a = np.asarray(rows, dtype=np.float64)
    return a[:, :3], a[:, 3:5]


def save_points_csv(path: str | Path, X_world: F64, uv: F64) -> None:
    """Write ``x,y,z,u,v`` rows with a header (atomically)."""
    from engine.persist import atomic_write_text

    lines = ["x,y,z,u,v"]
    for (x, y, z), (u, v) in zip(np.asarray(X_world), np.asarray(uv), strict=True):
        lines.append(f"{x:.6f},{y:.6f},{z:.6f},{u:.3f},{v:.3f}")
    atomic_write_text(Path(path), "\n".join(lines) + "\n")
