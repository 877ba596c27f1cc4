"""The least-squares model of the keyframe bundle adjustment (Tykkälä 2014 sec. 6.1, Fig. 11).

:class:`SBAProblem` holds the observations as arrays; :func:`residuals` evaluates, for a
parameter vector ``x`` (6 pose deltas per free keyframe, then 3 coordinates per point):

- reprojection ``u_ij - pi(K, D(R_i X_j + t_i))`` in pixels with the Caltech distortion of
  eq. (2)-(4) (:func:`engine.camera.project`), two rows per observation;
- the depth term ``(z_ij - d_i(u_ij)) / sigma_z`` where the keyframe's depth map is valid
  (the RGB-D depth fixes the metric scale);
- an optional weak prior on the free keyframes' pose deltas.

Each pose is a left-multiplied delta on its tracked ``T_cam_world``: ``T_cw = [dR | dt]
T_cw0`` with ``dR`` from a rotation vector. :func:`jacobian_sparsity` gives the block pattern
(each residual row depends on one pose's 6 columns and one point's 3); :func:`robust_weight`
the IRLS weights of the robust losses. The solve is :func:`engine.keyframes.sba.bundle_adjust`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics, project
from engine.geometry import so3_exp_batch

if TYPE_CHECKING:
    from scipy.sparse import csr_matrix

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


@dataclass(frozen=True)
class SBAProblem:
    """Observations, fixed references and noise model of one bundle adjustment."""

    intrinsics: Intrinsics
    adjusted: tuple[int, ...]  # keyframe ids with observations (row order of R0, t0_cw)
    free: tuple[int, ...]  # adjusted keyframes whose pose is refined (the others are fixed)
    point_ids: tuple[int, ...]
    R0: F64  # (K, 3, 3) tracked T_cam_world rotation of each adjusted keyframe
    t0_cw: F64  # (K, 3) its translation
    free_rows: I64  # row in ``adjusted`` of each free keyframe
    o_kf: I64  # per observation: row of its keyframe in ``adjusted``
    o_free: I64  # per observation: index of its keyframe in ``free`` (-1: fixed)
    o_pt: I64  # per observation: index of its point in ``point_ids``
    uv: F64  # (N, 2) observed pixels
    z_idx: I64  # observations with a depth term
    z_obs: F64  # (N,) keyframe depth at each observation (NaN: none)
    sigma_z: F64  # noise (m) of each depth term, aligned with ``z_idx``
    prior_w: F64  # (6,) 1/sigma of the pose prior (position m, rotation rad)
    n_prior: int  # free keyframes with a pose prior (all of them, or 0)

    @property
    def n_obs(self) -> int:
        return int(self.uv.shape[0])

    @property
    def n_free(self) -> int:
        return len(self.free)

    @property
    def n_residuals(self) -> int:
        return 2 * self.n_obs + int(self.z_idx.size) + 6 * self.n_prior

    @property
    def n_variables(self) -> int:
        return 6 * self.n_free + 3 * len(self.point_ids)


def unpack(pb: SBAProblem, x: F64) -> tuple[F64, F64, F64]:
    """(R_cw (K, 3, 3), t_cw (K, 3), X_world (P, 3)) of every adjusted keyframe and point."""
    n_f = pb.n_free
    poses = x[: 6 * n_f].reshape(n_f, 6)
    X = x[6 * n_f :].reshape(len(pb.point_ids), 3)
    dR = np.repeat(np.eye(3)[None], len(pb.adjusted), axis=0)
    dt = np.zeros((len(pb.adjusted), 3))
    if n_f:
        dR[pb.free_rows] = so3_exp_batch(poses[:, 3:])
        dt[pb.free_rows] = poses[:, :3]
    R = dR @ pb.R0  # T_cw = [dR | dt] T_cw0
    t = np.einsum("nij,nj->ni", dR, pb.t0_cw) + dt
    return R, t, X


def residuals(pb: SBAProblem, x: F64) -> F64:
    """All residual rows: pixels (2 per observation), depth terms, pose prior."""
    R, t, X = unpack(pb, x)
    p_cam = np.einsum("nij,nj->ni", R[pb.o_kf], X[pb.o_pt]) + t[pb.o_kf]
    with np.errstate(invalid="ignore", divide="ignore"):
        pix = project(pb.intrinsics, p_cam)  # eq. (2)-(4)
    r_px = np.nan_to_num(pix - pb.uv, nan=1e3).ravel()
    parts = [r_px]
    if pb.z_idx.size:
        parts.append((p_cam[pb.z_idx, 2] - pb.z_obs[pb.z_idx]) / pb.sigma_z)
    if pb.n_prior:
        # dt of T_cw = [dR | dt] T_cw0 is the camera-centre change (C = C0 - R^T dt)
        poses = x[: 6 * pb.n_free].reshape(pb.n_free, 6)
        parts.append((poses[:, :3] * pb.prior_w[:3]).ravel())
        parts.append((poses[:, 3:] * pb.prior_w[3:]).ravel())
    return np.concatenate(parts)


def pixel_errors(pb: SBAProblem, x: F64) -> F64:
    """Reprojection error (px) of each observation."""
    return np.asarray(
        np.linalg.norm(residuals(pb, x)[: 2 * pb.n_obs].reshape(-1, 2), axis=1)
    )


def jacobian_sparsity(pb: SBAProblem) -> csr_matrix:
    """Block pattern: residual row -> its keyframe's 6 pose columns and its point's 3."""
    from scipy.sparse import coo_matrix

    n_obs, n_f, n_prior = pb.n_obs, pb.n_free, pb.n_prior
    z_idx = pb.z_idx
    row_obs = np.concatenate([np.repeat(np.arange(n_obs), 2), z_idx])
    rows_all = np.arange(row_obs.size)
    rr, cc = [], []
    pf = pb.o_free[row_obs]
    has_pose = pf >= 0
    for j in range(6):
        rr.append(rows_all[has_pose])
        cc.append(6 * pf[has_pose] + j)
    for j in range(3):
        rr.append(rows_all)
        cc.append(6 * n_f + 3 * pb.o_pt[row_obs] + j)
    r0 = 2 * n_obs + int(z_idx.size)
    for j in range(3):  # prior rows: position block then rotation block, per free keyframe
        rr.append(r0 + 3 * np.arange(n_prior) + j)
        cc.append(6 * np.arange(n_prior) + j)
        rr.append(r0 + 3 * n_prior + 3 * np.arange(n_prior) + j)
        cc.append(6 * np.arange(n_prior) + 3 + j)
    A = coo_matrix(
        (np.ones(sum(len(r) for r in rr), np.int8), (np.concatenate(rr), np.concatenate(cc))),
        shape=(pb.n_residuals, pb.n_variables),
    )
    return A.tocsr()


def robust_weight(e: F64, loss: str, scale: float) -> F64:
    """IRLS weight w(e) = rho'(e^2) of scipy's loss functions at scale ``scale``."""
    z = (e / scale) ** 2
    if loss == "huber":
        return np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1e-300)))
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + z)
    if loss == "cauchy":
        return 1.0 / (1.0 + z)
    if loss == "arctan":
        return 1.0 / (1.0 + z * z)
    return np.ones_like(e)
