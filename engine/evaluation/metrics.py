"""ATE and RPE as the TUM RGB-D benchmark defines them (Sturm et al., IROS 2012).

ATE - absolute trajectory error, as TUM's ``evaluate_ate.py`` (defaults ``--offset 0
--scale 1 --max_difference 0.02``): associate the stamps one-to-one (greedy by time
difference, < 0.02 s), find the rigid motion S (rotation + translation, no scale) that best
maps the estimated positions onto the ground-truth positions (Horn's closed form, as the
script's ``align()``; Umeyama 1991 without scale), and report the RMSE of the remaining
position differences, ``sqrt(mean ||p_gt_i - S p_est_i||^2)`` (paper eq. (3)-(4), translation
part). Only positions enter; orientations are ignored. This equals
``evo_ape tum GT EST --align --t_max_diff 0.02`` (translation part, RMSE).

RPE - relative pose error over a fixed time delta, as TUM's ``evaluate_rpe.py --fixed_delta
--delta 1 --delta_unit s`` chooses its pairs, with the error of the paper's eq. (1):

- pairs: for every estimated pose i, j is the estimated pose whose stamp is closest to
  ``t_i + delta`` (the script's binary search ``find_closest_index``); the pair is skipped when j
  is the last estimated pose (that is how the script drops pairs running past the end - so a
  pose exactly ``delta`` before the last one is dropped too);
- ground truth: the pose nearest in time to ``t_i`` and to ``t_j``; the pair is skipped when
  either is further than twice the median ground-truth interval;
- error: ``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`` with Q ground truth and P the estimate (paper
  eq. (1), the same as evo's ``RPE.rpe_base``); translational error ``||trans(E)||``,
  rotational error ``angle(rot(E))``;
- result: RMSE over the pairs. The errors are *not* divided by the actual time between the
  poses of a pair: with ``delta = 1 s`` the RMSE of drift per (about) one second is reported
  as m/s and deg/s, exactly as the script reports its numbers.

Two documented differences from the script: (a) it composes the error the other way round,
``E' = (P_i^-1 P_j) (Q_i^-1 Q_j)^-1`` - the rotation angle is identical, the translation
differs at second order (rotation error times motion); pass ``script_error_order=True`` to
get the script's numbers bit for bit; (b) it draws a random subset when there are more than
10000 pairs (the default ``--max_pairs``); we always use all pairs (deterministic).
evo 1.38 has no time unit for ``--delta`` (frames, metres, degrees, radians only), so the
pairing by seconds above is TUM's; evo gives the same per-pair errors and statistics when
handed the same pose pairs (the tests check this to 1e-9 on evo's own test trajectories).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.errors import EvaluationError
from engine.evaluation.trajectory import TUM_MAX_DIFF_S, Trajectory, associate
from engine.geometry import invert, rotation_angle_rad_batch

F64 = NDArray[np.float64]

#: fewest associated poses for a meaningful SE(3) alignment (3 non-collinear points)
MIN_ATE_POSES = 3
#: TUM's evaluate_rpe.py refuses fewer than 2 pose pairs
MIN_RPE_PAIRS = 2


def align_rigid(model_xyz: F64, data_xyz: F64) -> tuple[F64, F64]:
    """Rotation R and translation t minimising sum ||data - (R model + t)||^2 (no scale).

    Horn's closed form via SVD, as in TUM's ``evaluate_ate.align(model, data)``:
    ``W = sum model_c data_c^T``, ``U D V^T = svd(W^T)``, ``R = U S V^T`` with
    ``S = diag(1, 1, det(U) det(V^T))`` to exclude reflections (Umeyama 1991, eq. (39)-(41)).
    """
    model = np.asarray(model_xyz, dtype=np.float64)
    data = np.asarray(data_xyz, dtype=np.float64)
    mu_m = model.mean(axis=0)
    mu_d = data.mean(axis=0)
    W = (model - mu_m).T @ (data - mu_d)  # sum of outer(model_c, data_c)
    U, _, Vh = np.linalg.svd(W.T)
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vh) < 0:
        S[2, 2] = -1.0
    R = U @ S @ Vh
    t = mu_d - R @ mu_m
    return R, t


@dataclass(frozen=True, slots=True)
class AteResult:
    """Absolute trajectory error after rigid alignment of the estimate onto the ground truth."""

    rmse_m: float
    mean_m: float
    median_m: float
    max_m: float
    n_associated: int
    R_gt_est: F64  # alignment rotation applied to the estimate
    t_gt_est: F64  # alignment translation
    errors_m: F64  # per associated pose
    stamps_est_s: F64  # stamps of the associated estimated poses


def ate(
    gt: Trajectory,
    est: Trajectory,
    *,
    max_diff_s: float = TUM_MAX_DIFF_S,
    offset_s: float = 0.0,
) -> AteResult:
    """ATE of ``est`` against ``gt`` exactly as TUM's evaluate_ate.py (see module doc)."""
    ig, ie = associate(gt.timestamps_s, est.timestamps_s, max_diff_s, offset_s)
    if ig.size < MIN_ATE_POSES:
        raise EvaluationError(
            f"{est.name}: only {ig.size} pose(s) match {gt.name} within {max_diff_s} s "
            f"(need >= {MIN_ATE_POSES}); do the files cover the same time span?"
        )
    p_gt = gt.positions_xyz[ig]
    p_est = est.positions_xyz[ie]
    R, t = align_rigid(p_est, p_gt)
    err = np.linalg.norm(p_est @ R.T + t - p_gt, axis=1)
    return AteResult(
        rmse_m=float(np.sqrt(np.mean(err * err))),
        mean_m=float(np.mean(err)),
        median_m=float(np.median(err)),
        max_m=float(np.max(err)),
        n_associated=int(ig.size),
        R_gt_est=R,
        t_gt_est=t,
        errors_m=err,
        stamps_est_s=est.timestamps_s[ie],
    )


def find_closest_index(stamps: F64, t: float) -> int:
    """Index of the stamp closest to ``t`` - TUM's binary search, ties resolved as it does."""
    beginning = 0
    difference = abs(stamps[0] - t)
    best = 0
    end = len(stamps)
    while beginning < end:
        middle = (end + beginning) // 2
        d = abs(stamps[middle] - t)
        if d < difference:
            difference = d
            best = middle
        if t == stamps[middle]:
            return middle
        if stamps[middle] > t:
            end = middle
        else:
            beginning = middle + 1
    return best


@dataclass(frozen=True, slots=True)
class RpePairs:
    """Pose pairs chosen for the RPE: indices into the estimate and the ground truth."""

    est_i: NDArray[np.int64]
    est_j: NDArray[np.int64]
    gt_i: NDArray[np.int64]
    gt_j: NDArray[np.int64]


def rpe_pairs(
    gt: Trajectory, est: Trajectory, *, delta_s: float = 1.0, offset_s: float = 0.0
) -> RpePairs:
    """The pairs TUM's ``evaluate_rpe.py --fixed_delta --delta_unit s`` evaluates."""
    if len(gt) < 2:
        raise EvaluationError(f"{gt.name}: needs at least 2 ground-truth poses for the RPE")
    if len(est) < 2:
        raise EvaluationError(f"{est.name}: needs at least 2 poses for the RPE")
    t_est = est.timestamps_s
    t_gt = gt.timestamps_s
    max_gt_gap = 2.0 * float(np.median(np.diff(t_gt)))
    out: list[tuple[int, int, int, int]] = []
    last = len(est) - 1
    for i in range(len(est)):
        j = find_closest_index(t_est, float(t_est[i]) + delta_s)
        if j == last:
            continue
        gi = find_closest_index(t_gt, float(t_est[i]) + offset_s)
        gj = find_closest_index(t_gt, float(t_est[j]) + offset_s)
        if (
            abs(t_gt[gi] - (t_est[i] + offset_s)) > max_gt_gap
            or abs(t_gt[gj] - (t_est[j] + offset_s)) > max_gt_gap
        ):
            continue
        out.append((i, j, gi, gj))
    arr = np.asarray(out, dtype=np.int64).reshape(-1, 4)
    return RpePairs(arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3])


@dataclass(frozen=True, slots=True)
class RpeResult:
    """Relative pose error over a fixed time delta (RMSE and per-pair values)."""

    trans_rmse_m_per_s: float  # RMSE of ||trans(E)|| over pairs ~delta_s apart (not divided)
    rot_rmse_deg_per_s: float  # RMSE of angle(rot(E)) in degrees
    trans_mean_m: float
    rot_mean_deg: float
    n_pairs: int
    delta_s: float
    trans_errors_m: F64
    rot_errors_deg: F64
    stamps_est_s: F64  # start stamp of each pair


def rpe(
    gt: Trajectory,
    est: Trajectory,
    *,
    delta_s: float = 1.0,
    offset_s: float = 0.0,
    script_error_order: bool = False,
) -> RpeResult:
    """RPE with a fixed time delta, TUM's pairing and the paper's error (see module doc).

    Raises EvaluationError when fewer than 2 pairs ``delta_s`` apart match the ground truth
    (e.g. a trajectory shorter than ``delta_s`` plus a frame).
    """
    if not (delta_s > 0 and math.isfinite(delta_s)):
        raise EvaluationError(f"RPE delta must be a positive number of seconds, got {delta_s}")
    pairs = rpe_pairs(gt, est, delta_s=delta_s, offset_s=offset_s)
    n = int(pairs.est_i.size)
    if n < MIN_RPE_PAIRS:
        raise EvaluationError(
            f"{est.name}: only {n} pose pair(s) {delta_s:g} s apart match {gt.name} "
            f"(need >= {MIN_RPE_PAIRS}); the estimate spans {est.duration_s:.3f} s"
        )
    Q_i, Q_j = gt.T_world_cam[pairs.gt_i], gt.T_world_cam[pairs.gt_j]
    P_i, P_j = est.T_world_cam[pairs.est_i], est.T_world_cam[pairs.est_j]
    Q_rel = invert(Q_i) @ Q_j
    P_rel = invert(P_i) @ P_j
    # Sturm 2012 eq. (1): E_i = (Q_i^-1 Q_{i+delta})^-1 (P_i^-1 P_{i+delta}).
    E = P_rel @ invert(Q_rel) if script_error_order else invert(Q_rel) @ P_rel
    trans = np.linalg.norm(E[:, :3, 3], axis=1)
    rot_deg = np.degrees(rotation_angle_rad_batch(E[:, :3, :3]))
    return RpeResult(
        trans_rmse_m_per_s=float(np.sqrt(np.mean(trans * trans))),
        rot_rmse_deg_per_s=float(np.sqrt(np.mean(rot_deg * rot_deg))),
        trans_mean_m=float(np.mean(trans)),
        rot_mean_deg=float(np.mean(rot_deg)),
        n_pairs=n,
        delta_s=float(delta_s),
        trans_errors_m=trans,
        rot_errors_deg=rot_deg,
        stamps_est_s=est.timestamps_s[pairs.est_i],
    )
