"""Sparse bundle adjustment of keyframe poses and annotated points (Tykkälä 2014 sec. 6.1).

"Sparse bundle adjustment can be used to remove the small global error at the end of the
estimated camera trajectory [...] dense tracking provides a very good initial guess of the
pose configuration. To be able to execute SBA, few 3D points and their 2D correspondence are
required from the user" (sec. 6.1, Fig. 11).

Unknowns: the poses ``T_cam_world`` of every annotated keyframe except the gauge keyframe
(held fixed: it removes the 6-DOF gauge freedom) and the 3D points ``X_world``. Residuals:

- reprojection ``u_ij - pi(K, D(R_i X_j + t_i))`` in pixels with the Caltech distortion of
  eq. (2)-(4) (:func:`engine.camera.project`), per observation;
- a depth term ``(z_ij - d_i(u_ij)) / sigma_z`` where the keyframe's depth map is valid: the
  RGB-D depth fixes the metric scale, which reprojection alone leaves free (a 7th gauge
  freedom for a single fixed keyframe). ``d_i(u_ij)`` is a local plane fit evaluated at the
  sub-pixel observation (:func:`depth_plane`), ``sigma_z`` combines the sensor noise
  ``depth_sigma_rel * z`` with the fit's residual (the depth map's own local noise).

Both go through a robust loss (Cauchy by default) by iteratively reweighted least squares,
each round solved by ``scipy.optimize.least_squares`` with a block-sparse Jacobian pattern
(``jac_sparsity``): each residual depends on one pose (6 columns) and one point (3 columns).
The residuals and that pattern are :mod:`engine.keyframes.sba_residuals`; this module checks
the configuration, sets the problem up and solves it.
The loss scales are tight (0.1 px, 0.1 depth sigma): snapped annotations are mostly good to
~0.05 px, and the few off by 0.2-0.8 px (a patch matched a little off, a depth sample on a
fusion artefact) would otherwise pull the end of a long sweep by millimetres. Where the
residuals spread more (noisier clicks or depth) the scales follow their robust sigma
(``robust_k`` x the median-based sigma, 2.385: the Cauchy constant of 95 % Gaussian
efficiency), so that plain noise is not mistaken for outliers.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Protocol

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics, backproject, project
from engine.errors import StudioTrackError
from engine.geometry import invert, rotation_angle_rad
from engine.keyframes.depth_sample import depth_at, depth_plane
from engine.keyframes.sba_residuals import (
    SBAProblem,
    jacobian_sparsity,
    pixel_errors,
    residuals,
    robust_weight,
    unpack,
)
from engine.keyframes.store import KeyframeStore
from engine.params import Params, Preset, param

if TYPE_CHECKING:
    from scipy.sparse import csr_matrix

F64 = NDArray[np.float64]


class SBAError(StudioTrackError):
    """Bundle adjustment cannot run: too few points, a degenerate configuration..."""


@dataclass(frozen=True, slots=True)
class SBAParams(Params):
    """Bundle adjustment settings (one group; units in the names)."""

    min_points: int = param(6, lo=3, hi=1000, help="points seen in 2+ keyframes needed to run")
    min_points_per_keyframe: int = param(3, lo=3, hi=100,
                                         help="annotated points a refined keyframe needs")
    loss: str = param("cauchy", choices=("linear", "huber", "soft_l1", "cauchy", "arctan"),
                      help="robust loss of the reprojection residuals (cauchy ignores mis-clicks)")
    loss_scale_px: float = param(0.1, lo=0.1, hi=100.0,
                                 help="robust loss scale (px), the smallest used (see robust_k): "
                                 "larger residuals are down-weighted")
    depth_loss_scale: float = param(0.1, lo=0.1, hi=1.0e9,
                                    help="robust loss scale of the depth term (in its noise "
                                    "sigmas): depth samples disagreeing with the points are "
                                    "down-weighted")
    robust_k: float = param(2.385, lo=0.0, hi=100.0,
                            help="robust scales follow the residuals: k x their robust sigma "
                            "(median based), at least the scales above; 0: fixed scales")
    use_depth: bool = param(True,
                            help="use the keyframe depth at each observation (fixes the metric "
                            "scale)")
    depth_sigma_rel: float = param(0.002, lo=1e-4, hi=1.0,
                                   help="depth sensor noise as a fraction of the depth; the "
                                   "depth map's own local noise (plane-fit residual at the "
                                   "observation) is added to it")
    max_nfev: int = param(200, lo=5, hi=10000, help="function evaluations")
    depth_edge_rel: float = param(0.03, lo=0.0, hi=10.0,
                                  help="no depth term where the 3x3 depths spread more than this "
                                  "fraction (a depth edge)")
    pose_prior_m: float = param(0.0, lo=0.0, hi=10.0,
                                help="weak prior on each keyframe's tracked camera position (m, "
                                "1 sigma; 0: none): damps directions the points leave nearly "
                                "free (long sweeps of a flat studio)")
    pose_prior_deg: float = param(0.0, lo=0.0, hi=180.0,
                                  help="weak prior on each keyframe's tracked orientation (deg, "
                                  "1 sigma; 0: none)")
    min_spread_px: float = param(3.0, lo=0.0, hi=100.0,
                                 help="points of a keyframe spanning less than this across their "
                                 "main line count as collinear")

    PRESETS: ClassVar[Mapping[str, Preset]] = {
        "paper": Preset(
            "Tykkälä 2014 sec. 6.1 as published: sparse bundle adjustment in the manner of "
            "Lourakis' SBA [24], plain least squares of the reprojection errors (no robust "
            "loss, no pose priors). The paper does not say how the metric scale is fixed; the "
            "keyframes' RGB-D depth at the clicks is kept as a plain (non-robust) term, which "
            "is how the RGB-D keyframes' 3D points enter",
            loss="linear", robust_k=0.0, pose_prior_m=0.0, pose_prior_deg=0.0,
        ),
    }


@dataclass(frozen=True, slots=True)
class Observation:
    """Point ``point_id`` seen at pixel (u, v) of keyframe ``kf_id``."""

    point_id: int
    kf_id: int
    u: float
    v: float


@dataclass(frozen=True)
class SBAResult:
    gauge_id: int
    T_world_cam_before: dict[int, F64]
    T_world_cam_after: dict[int, F64]
    X_world_after: dict[int, F64]
    rmse_before_px: float
    rmse_after_px: float
    point_rmse_before_px: dict[int, float]
    point_rmse_after_px: dict[int, float]
    keyframe_rmse_before_px: dict[int, float]
    keyframe_rmse_after_px: dict[int, float]
    pose_change: dict[int, tuple[float, float]]  # kf id -> (centre moved m, rotated deg)
    unadjusted_ids: tuple[int, ...]  # keyframes without annotations: left as they were
    ignored_point_ids: tuple[int, ...]  # points seen in one keyframe only
    seconds: float
    nfev: int
    message: str


class AnnotatedPointLike(Protocol):
    """An annotated point (:class:`engine.project.AnnotatedPoint`): pixel per keyframe id
    and, once adjusted, its 3D position."""

    @property
    def id(self) -> int: ...
    @property
    def observations_px(self) -> Mapping[int, tuple[float, float]]: ...
    @property
    def X_world(self) -> F64 | None: ...


def collect_observations(points: Sequence[AnnotatedPointLike]) -> list[Observation]:
    """Observations of annotated points (``observations_px``)."""
    obs = []
    for p in points:
        for kf_id, (u, v) in sorted(p.observations_px.items()):
            obs.append(Observation(int(p.id), int(kf_id), float(u), float(v)))
    return obs


def check_configuration(
    obs: Sequence[Observation],
    kf_ids: Sequence[int],
    gauge_id: int,
    params: SBAParams,
    fixed_ids: Sequence[int] = (),
) -> tuple[list[Observation], list[int], list[int], list[int]]:
    """Validate; return (usable observations, adjusted kf ids, unadjusted, ignored points).

    Raises :class:`SBAError` naming what is missing.
    """
    known = set(kf_ids)
    bad = sorted({o.kf_id for o in obs if o.kf_id not in known})
    if bad:
        raise SBAError(f"SBA: annotations refer to keyframe(s) {bad} that are not in the store")
    per_point: dict[int, set[int]] = {}
    for o in obs:
        per_point.setdefault(o.point_id, set()).add(o.kf_id)
    ignored = sorted(p for p, ks in per_point.items() if len(ks) < 2)
    good_pts = {p for p, ks in per_point.items() if len(ks) >= 2}
    use = [o for o in obs if o.point_id in good_pts]
    if len(good_pts) < params.min_points:
        raise SBAError(
            f"SBA: {len(good_pts)} point(s) are annotated in 2+ keyframes, at least "
            f"{params.min_points} are needed: annotate {params.min_points - len(good_pts)} more"
        )
    per_kf: dict[int, list[Observation]] = {}
    for o in use:
        per_kf.setdefault(o.kf_id, []).append(o)
    if gauge_id not in per_kf:
        raise SBAError(
            f"SBA: the gauge keyframe {gauge_id} (held fixed) has no annotated points: "
            f"annotate at least {params.min_points_per_keyframe} points in it"
        )
    few = [
        (k, len(v))
        for k, v in sorted(per_kf.items())
        if k != gauge_id and k not in fixed_ids and len(v) < params.min_points_per_keyframe
    ]
    if few:
        desc = ", ".join(f"keyframe {k} has {n}" for k, n in few)
        raise SBAError(
            f"SBA: too few annotated points ({desc}); each refined keyframe needs at least "
            f"{params.min_points_per_keyframe}"
        )
    for k, lst in sorted(per_kf.items()):
        uv = np.array([[o.u, o.v] for o in lst])
        s = np.linalg.svd(uv - uv.mean(axis=0), compute_uv=False)
        spread = s[1] / math.sqrt(len(lst)) if len(s) > 1 else 0.0
        if spread < params.min_spread_px:
            raise SBAError(
                f"SBA: the annotated points of keyframe {k} lie (almost) on one line "
                f"(spread {spread:.1f} px): annotate a point away from that line"
            )
    # connectivity through shared points, from the gauge
    reached, frontier = {gauge_id}, [gauge_id]
    kf_of_point = {p: ks for p, ks in per_point.items() if p in good_pts}
    while frontier:
        k = frontier.pop()
        for ks in kf_of_point.values():
            if k in ks:
                for k2 in ks - reached:
                    reached.add(k2)
                    frontier.append(k2)
    cut = sorted(set(per_kf) - reached)
    if cut:
        raise SBAError(
            f"SBA: keyframe(s) {cut} share no annotated point (directly or through others) "
            f"with the gauge keyframe {gauge_id}: annotate a point seen in both"
        )
    adjusted = sorted(per_kf)
    unadjusted = sorted(set(kf_ids) - set(adjusted))
    return use, adjusted, unadjusted, ignored


def initial_points(
    intr: Intrinsics,
    T_world_cam: Mapping[int, F64],
    obs: Sequence[Observation],
    depth_maps: Mapping[int, NDArray[np.floating]] | None,
    given: Mapping[int, F64] | None = None,
) -> dict[int, F64]:
    """Starting 3D points: given ones, else the median back-projection over observations
    with depth, else a linear (DLT) triangulation."""
    by_pt: dict[int, list[Observation]] = {}
    for o in obs:
        by_pt.setdefault(o.point_id, []).append(o)
    out: dict[int, F64] = {}
    for pid, lst in by_pt.items():
        if given is not None and pid in given and given[pid] is not None:
            out[pid] = np.asarray(given[pid], dtype=np.float64)
            continue
        cands = []
        if depth_maps is not None:
            for o in lst:
                z = (
                    depth_at(depth_maps[o.kf_id], o.u, o.v, 1, 0.03)
                    if o.kf_id in depth_maps
                    else math.nan
                )
                if math.isfinite(z):
                    p_cam = backproject(intr, np.array([[o.u, o.v]]), np.array([z]))[0]
                    T = T_world_cam[o.kf_id]
                    cands.append(T[:3, :3] @ p_cam + T[:3, 3])
        if cands:
            out[pid] = np.median(np.array(cands), axis=0)
        else:
            out[pid] = _triangulate(intr, T_world_cam, lst)
    return out


def _triangulate(
    intr: Intrinsics, T_world_cam: Mapping[int, F64], lst: Sequence[Observation]
) -> F64:
    from engine.camera import pixels_to_normalized

    rows = []
    for o in lst:
        x, y = pixels_to_normalized(intr, np.array([[o.u, o.v]]))[0]
        P = invert(T_world_cam[o.kf_id])[:3, :]
        rows.append(x * P[2] - P[0])
        rows.append(y * P[2] - P[1])
    _, _, vt = np.linalg.svd(np.array(rows))
    X: F64 = vt[-1]
    w = float(X[3])
    if abs(w) < 1e-12:
        raise SBAError(f"SBA: point {lst[0].point_id} cannot be triangulated (parallel rays)")
    return X[:3] / w


def _problem(
    intr: Intrinsics,
    T_world_cam: Mapping[int, F64],
    use: Sequence[Observation],
    adjusted: Sequence[int],
    free: Sequence[int],
    depth_maps: Mapping[int, NDArray[np.floating]] | None,
    p: SBAParams,
) -> SBAProblem:
    """Arrays of the least-squares problem; the unknowns are left-multiplied deltas on each
    keyframe's fixed reference (its tracked T_cam_world)."""
    free_idx = {k: i for i, k in enumerate(free)}
    pt_ids = sorted({o.point_id for o in use})
    pt_idx = {pid: i for i, pid in enumerate(pt_ids)}
    T_cw0 = {k: invert(np.asarray(T_world_cam[k], dtype=np.float64)) for k in adjusted}
    kf_row = {k: i for i, k in enumerate(adjusted)}
    # depth term: the keyframe depth at the sub-pixel observation (local plane fit, no
    # half-pixel bias), weighted by a noise model: sensor noise depth_sigma_rel x z combined
    # with the depth map's own local noise (the plane fit's residual)
    z_obs = np.full(len(use), np.nan)
    z_noise = np.zeros(len(use))
    if p.use_depth and depth_maps is not None:
        for i, o in enumerate(use):
            if o.kf_id in depth_maps:
                z_obs[i], z_noise[i] = depth_plane(
                    depth_maps[o.kf_id], o.u, o.v, 1, p.depth_edge_rel
                )
    has_z = np.isfinite(z_obs)
    use_prior = p.pose_prior_m > 0 and p.pose_prior_deg > 0  # both or none
    return SBAProblem(
        intrinsics=intr,
        adjusted=tuple(adjusted),
        free=tuple(free),
        point_ids=tuple(pt_ids),
        R0=np.array([T_cw0[k][:3, :3] for k in adjusted]),
        t0_cw=np.array([T_cw0[k][:3, 3] for k in adjusted]),
        free_rows=np.array([kf_row[k] for k in free], dtype=np.int64),
        o_kf=np.array([kf_row[o.kf_id] for o in use]),
        o_free=np.array([free_idx.get(o.kf_id, -1) for o in use]),
        o_pt=np.array([pt_idx[o.point_id] for o in use]),
        uv=np.array([[o.u, o.v] for o in use]),
        z_idx=np.nonzero(has_z)[0],
        z_obs=z_obs,
        sigma_z=np.hypot(p.depth_sigma_rel * z_obs[has_z], z_noise[has_z]),
        prior_w=np.array(
            [1.0 / p.pose_prior_m] * 3 + [1.0 / math.radians(p.pose_prior_deg)] * 3
            if use_prior
            else [0.0] * 6
        ),
        n_prior=len(free) if use_prior else 0,
    )


def _refine_points(pb: SBAProblem, x0: F64, jac: csr_matrix, p: SBAParams) -> F64:
    """The tracked poses with the best points for them (points-only refinement): the
    "before" state of the result."""
    from scipy.optimize import least_squares

    n_f = 6 * pb.n_free
    pts_cols = np.arange(n_f, pb.n_variables)

    def res_points(xp: F64) -> F64:
        x = x0.copy()
        x[n_f:] = xp
        return residuals(pb, x)

    pre = least_squares(
        res_points,
        x0[n_f:],
        jac_sparsity=jac[:, pts_cols],
        method="trf",
        max_nfev=p.max_nfev,
    )
    x_before = x0.copy()
    x_before[n_f:] = pre.x
    return x_before


def _solve_irls(
    pb: SBAProblem, x_start: F64, jac: csr_matrix, p: SBAParams
) -> tuple[F64, int, str]:
    """Robust loss by iteratively reweighted least squares; (x, evaluations, message).

    scipy's robust losses with the sparse (lsmr) trust-region solver converge slowly here,
    while each reweighted linear problem converges in a few Gauss-Newton steps. Weights are
    per observation (pixel pair together) from the previous solution, Huber/Cauchy/soft-L1
    weight functions.
    """
    from scipy.optimize import least_squares

    n_res, n_obs, n_z = pb.n_residuals, pb.n_obs, int(pb.z_idx.size)
    w_sqrt = np.ones(n_res)
    x_cur = x_start
    nfev = 0
    sol = None
    for _ in range(1 if p.loss == "linear" else 4):

        def weighted(x: F64, w: F64 = w_sqrt) -> F64:
            return residuals(pb, x) * w

        sol = least_squares(
            weighted, x_cur, jac_sparsity=jac, method="trf", max_nfev=p.max_nfev, x_scale=1.0
        )
        x_cur, nfev = sol.x, nfev + int(sol.nfev)
        if p.loss == "linear":
            break
        r = residuals(pb, x_cur)
        e_px = np.repeat(np.linalg.norm(r[: 2 * n_obs].reshape(-1, 2), axis=1), 2)
        r_z = np.abs(r[2 * n_obs :])
        s_px, s_z = p.loss_scale_px, p.depth_loss_scale
        if p.robust_k > 0:
            # scales follow the residuals' robust spread (the median of a 2D Gaussian
            # residual's norm is 1.177 sigma, of a 1D one's magnitude 0.674 sigma)
            s_px = max(s_px, p.robust_k * float(np.median(e_px)) / 1.177)
            if n_z:
                s_z = max(s_z, p.robust_k * float(np.median(r_z[:n_z])) / 0.674)
        w_px = robust_weight(e_px, p.loss, s_px)
        w_z = robust_weight(r_z, p.loss, s_z)
        w_new = np.sqrt(np.concatenate([w_px, w_z]))
        if pb.n_prior:
            w_new[n_res - 6 * pb.n_prior :] = 1.0  # the pose prior is not an outlier candidate
        if np.allclose(w_new, w_sqrt, atol=1e-3):
            break
        w_sqrt = w_new
    assert sol is not None
    return np.asarray(sol.x), nfev, str(sol.message)


def _rms(e: F64) -> float:
    return float(np.sqrt(np.mean(e * e))) if e.size else 0.0


def _rms_by(e: F64, key: NDArray[np.int_], ids: Sequence[int]) -> dict[int, float]:
    return {k: _rms(e[key == i]) for i, k in enumerate(ids)}


def bundle_adjust(
    intr: Intrinsics,
    T_world_cam: Mapping[int, F64],
    obs: Sequence[Observation],
    *,
    depth_maps: Mapping[int, NDArray[np.floating]] | None = None,
    points_init: Mapping[int, F64] | None = None,
    gauge_id: int | None = None,
    params: SBAParams | None = None,
    fixed_ids: Sequence[int] = (),
) -> SBAResult:
    """Refine keyframe poses and 3D points; the gauge keyframe (default: lowest id) is fixed,
    and so are ``fixed_ids`` (keyframes the operator trusts, e.g. the start of the sweep: the
    paper's SBA removes "the small global error at the end of the trajectory")."""
    p = params or SBAParams()
    t0 = time.perf_counter()
    kf_ids = sorted(T_world_cam)
    if not kf_ids:
        raise SBAError("SBA: no keyframes")
    gauge = kf_ids[0] if gauge_id is None else gauge_id
    use, adjusted, unadjusted, ignored = check_configuration(
        obs, kf_ids, gauge, p, tuple(fixed_ids)
    )
    fixed = {gauge, *(int(k) for k in fixed_ids)}
    free = [k for k in adjusted if k not in fixed]
    pb = _problem(intr, T_world_cam, use, adjusted, free, depth_maps, p)
    X0 = initial_points(intr, T_world_cam, use, depth_maps, points_init)
    jac = jacobian_sparsity(pb)
    x0 = np.concatenate(
        [np.zeros(6 * pb.n_free), np.array([X0[pid] for pid in pb.point_ids]).ravel()]
    )
    x_before = _refine_points(pb, x0, jac, p)
    x_after, nfev, message = _solve_irls(pb, x_before, jac, p)

    e_b, e_a = pixel_errors(pb, x_before), pixel_errors(pb, x_after)
    R, t, X = unpack(pb, x_after)
    kf_row = {k: i for i, k in enumerate(adjusted)}
    after = {k: np.array(T_world_cam[k], dtype=np.float64) for k in kf_ids}
    change: dict[int, tuple[float, float]] = {k: (0.0, 0.0) for k in adjusted if k in fixed}
    for k in free:
        T_cw = np.eye(4)
        T_cw[:3, :3], T_cw[:3, 3] = R[kf_row[k]], t[kf_row[k]]
        after[k] = invert(T_cw)
        before = np.asarray(T_world_cam[k], dtype=np.float64)
        dR = before[:3, :3].T @ after[k][:3, :3]
        ang = math.degrees(rotation_angle_rad(dR))
        change[k] = (float(np.linalg.norm(after[k][:3, 3] - before[:3, 3])), ang)
    pt_ids = pb.point_ids
    return SBAResult(
        gauge_id=gauge,
        T_world_cam_before={k: np.array(T_world_cam[k], dtype=np.float64) for k in kf_ids},
        T_world_cam_after=after,
        X_world_after={pid: X[i].copy() for i, pid in enumerate(pt_ids)},
        rmse_before_px=_rms(e_b),
        rmse_after_px=_rms(e_a),
        point_rmse_before_px=_rms_by(e_b, pb.o_pt, pt_ids),
        point_rmse_after_px=_rms_by(e_a, pb.o_pt, pt_ids),
        keyframe_rmse_before_px=_rms_by(e_b, pb.o_kf, adjusted),
        keyframe_rmse_after_px=_rms_by(e_a, pb.o_kf, adjusted),
        pose_change=change,
        unadjusted_ids=tuple(unadjusted),
        ignored_point_ids=tuple(ignored),
        seconds=time.perf_counter() - t0,
        nfev=nfev,
        message=message,
    )


def bundle_adjust_store(
    store: KeyframeStore,
    points: Sequence[AnnotatedPointLike],
    params: SBAParams | None = None,
    gauge_id: int | None = None,
    fixed_ids: Sequence[int] = (),
) -> SBAResult:
    """:func:`bundle_adjust` on a keyframe store and annotated points (their ``X_world``
    seeds the points)."""
    kfs = store.keyframes
    T = {k.id: k.T_world_cam for k in kfs}
    depths: dict[int, NDArray[np.floating]] = {k.id: k.depth_m for k in kfs}
    given = {p.id: p.X_world for p in points if p.X_world is not None}
    return bundle_adjust(
        store.intrinsics,
        T,
        collect_observations(points),
        depth_maps=depths,
        points_init=given,
        gauge_id=gauge_id,
        params=params,
        fixed_ids=fixed_ids,
    )


def reprojection_errors(
    intr: Intrinsics,
    T_world_cam: Mapping[int, F64],
    points: Sequence[AnnotatedPointLike],
) -> dict[int, float]:
    """Per-point RMS reprojection error (px) of points with ``X_world`` (NaN without)."""
    out = {}
    for pt in points:
        X = pt.X_world
        obs = pt.observations_px
        if X is None or not obs:
            out[pt.id] = math.nan
            continue
        errs = []
        for k, (u, v) in obs.items():
            if k not in T_world_cam:
                continue
            T_cw = invert(T_world_cam[k])
            pix = project(intr, (T_cw[:3, :3] @ X + T_cw[:3, 3])[None])[0]
            errs.append(float(np.hypot(pix[0] - u, pix[1] - v)))
        out[pt.id] = float(np.sqrt(np.mean(np.square(errs)))) if errs else math.nan
    return out
