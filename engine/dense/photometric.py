"""Reference model and inverse-compositional minimisation (Tykkälä 2014 sec. 3, Algorithm 1).

A :class:`Reference` holds the selected 3D points P* (reference camera frame, metres) and, per
pyramid level, their intensities c* and the Jacobian of eq. (6), computed once. :func:`align`
runs Algorithm 1 against a current frame and returns the base transform T^ = T_cur_ref.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics, undistort_normalized
from engine.dense import pyramid as pyr
from engine.dense.selection import gradient_magnitude, select_points

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]


@dataclass(frozen=True, slots=True)
class Preprocessed:
    """A frame after pre-processing: grey pyramid (3 levels) and full-resolution depth."""

    levels: tuple[F32, F32, F32]
    depth_m: F32
    intrinsics: Intrinsics


def preprocess(
    gray_full: NDArray[np.floating] | NDArray[np.uint8],
    depth_m: NDArray[np.floating],
    intr: Intrinsics,
) -> Preprocessed:
    """Sec. 4.6 pre-processing of one RGB-D frame (grey uint8 or float; depth is kept at
    full resolution)."""
    if gray_full.shape != (intr.height, intr.width):
        raise ValueError(
            f"image is {gray_full.shape[1]}x{gray_full.shape[0]} but the intrinsics say "
            f"{intr.width}x{intr.height}"
        )
    l0, l1, l2 = pyr.build_pyramid(gray_full)
    f32 = np.float32
    # read-only views: the kernels take them as they are (no per-call view, see _ro)
    return Preprocessed((_ro(l0, f32), _ro(l1, f32), _ro(l2, f32)), _ro(depth_m, f32), intr)


@functools.lru_cache(maxsize=8)
def _level0_rays(intr: Intrinsics) -> tuple[F64, NDArray[np.int64], NDArray[np.int64]]:
    """Undistorted normalised rays of the full-resolution pixels under the level-0 grid.

    Level-0 pixel (u1, v1) samples full-resolution pixel (2 u1, 2 v1), where the depth was
    measured; the 3D point is back-projected there (the inverse of eq. (2)-(4)).
    """
    h0, w0 = intr.height // 2, intr.width // 2
    u1, v1 = np.meshgrid(np.arange(w0), np.arange(h0))
    uf = (2 * u1).ravel().astype(np.float64)
    vf = (2 * v1).ravel().astype(np.float64)
    xy = np.stack([(uf - intr.cx) / intr.fx, (vf - intr.cy) / intr.fy], axis=1)
    if intr.has_distortion:
        xy = undistort_normalized(xy, intr.dist)
    return xy, (2 * u1).ravel(), (2 * v1).ravel()


@functools.lru_cache(maxsize=8)
def full_rays(intr: Intrinsics) -> F64:
    """(h, w, 2) undistorted normalised rays of every full-resolution pixel (read-only)."""
    u, v = np.meshgrid(np.arange(intr.width), np.arange(intr.height))
    xy = np.stack([(u.ravel() - intr.cx) / intr.fx, (v.ravel() - intr.cy) / intr.fy], axis=1)
    if intr.has_distortion:
        xy = undistort_normalized(xy.astype(np.float64), intr.dist)
    out = np.ascontiguousarray(xy.reshape(intr.height, intr.width, 2))
    out.setflags(write=False)
    return out


def depth_sigma_m(z_m: F64) -> F64:
    """Axial depth noise std (m) of a disparity-based depth sensor at depth ``z_m``: the
    Kinect v1 model sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2 (Nguyen, Izadi, Lovell 2012,
    "Modeling Kinect sensor noise", eq. 3; quadratic in z as for any sensor measuring
    disparity, Khoshelham and Elberink 2012)."""
    return 0.0012 + 0.0019 * (np.asarray(z_m, dtype=np.float64) - 0.4) ** 2


def geometric_noise_weights(z_m: F64) -> F64:
    """Per point factor 1 / sigma(z) of :func:`depth_sigma_m`, relative to the points'
    median depth (1 there): multiplying a point-to-plane residual by it makes every residual
    of the geometric term one of the same noise (the depth noise along the ray, which the
    normal projects; the reference and the current depth of a point lie at about the same
    distance, so one factor serves both). The term's robust scale is then the median over
    these normalised residuals."""
    z = np.asarray(z_m, dtype=np.float64)
    if z.size == 0:
        return z
    return depth_sigma_m(np.median(z, keepdims=True)) / depth_sigma_m(z)


def _normals(depth: F32, intr: Intrinsics, uf: NDArray[np.int64], vf: NDArray[np.int64],
             P: F64, step: int = 2, max_jump: float = 0.05, planarity: float = 3.0) -> F64:
    """Unit surface normals (pointing at the camera) at full-resolution pixels ``(uf, vf)``
    from the cross product of central depth differences ``step`` pixels away; zero where a
    neighbour is missing or beyond a depth jump (``max_jump`` of the depth), and where the
    point is not on a plane with its neighbours: its offset along the normal from the midpoint
    of a neighbour pair beyond ``planarity`` times the robust spread of that offset over all
    the points (the depth noise; 2 % of the pair's span on noise-free depth). A normal across a
    crease or a small step is the average of two surfaces, neither's: on the studio rail those
    few points, being the only ones with a normal along the rail, set the alignment there."""
    rays = full_rays(intr)
    h, w = depth.shape
    def point(du: int, dv: int) -> tuple[F64, NDArray[np.bool_]]:
        uu = np.clip(uf + du, 0, w - 1)
        vv = np.clip(vf + dv, 0, h - 1)
        z = depth[vv, uu].astype(np.float64)
        r = rays[vv, uu]
        ok = (z > 0) & (np.abs(z - P[:, 2]) < max_jump * P[:, 2])
        return np.stack([r[:, 0] * z, r[:, 1] * z, z], axis=1), ok
    pr, okr = point(step, 0)
    pl, okl = point(-step, 0)
    pd, okd = point(0, step)
    pu, oku = point(0, -step)
    n = np.cross(pr - pl, pd - pu)
    norm = np.linalg.norm(n, axis=1)
    ok = okr & okl & okd & oku & (norm > 1e-12)
    n = np.where(ok[:, None], n / np.where(norm > 0, norm, 1.0)[:, None], 0.0)
    if planarity > 0.0 and np.any(ok):
        # n is orthogonal to both chords: the centre's offset from each chord's midpoint
        off = np.abs(np.stack([np.sum(n * (0.5 * (pr + pl) - P), axis=1),
                               np.sum(n * (0.5 * (pd + pu) - P), axis=1)], axis=1))
        span = np.stack([np.linalg.norm(pr - pl, axis=1), np.linalg.norm(pd - pu, axis=1)],
                        axis=1)
        spread = 1.4826 * float(np.median(off[ok]))
        ok &= np.all(off <= planarity * spread + 0.02 * span, axis=1)
        n[~ok] = 0.0
    flip = np.sum(n * P, axis=1) > 0  # towards the camera
    n[flip] = -n[flip]
    return n


def _ro(a: NDArray[Any], dtype: type[np.generic]) -> NDArray[Any]:
    """A read-only, C-contiguous view of ``a`` as ``dtype`` (a copy only if needed).

    Every kernel input goes through this, so each numba kernel sees one type per argument
    whatever the caller's arrays were (read-only frame depth, writable keyframe depth, ...):
    one specialisation per kernel, see :mod:`engine.dense.kernels`. An array that already
    is one (a cached constant, an earlier result of this) is returned as it is."""
    if (isinstance(a, np.ndarray) and a.dtype == dtype and not a.flags.writeable
            and a.flags.c_contiguous):
        return a
    v = np.ascontiguousarray(a, dtype=dtype).view()
    v.setflags(write=False)
    return v


_NO_N = _ro(np.zeros((3, 0)), np.float32)
_NO_JG = _ro(np.zeros((6, 0)), np.float32)
_NO_TCD = _ro(np.eye(4), np.float64)


def cam_vector(intr: Intrinsics) -> F64:
    return np.array([intr.fx, intr.fy, intr.cx, intr.cy], dtype=np.float64)


def _camera_inputs(intr: Intrinsics) -> tuple[F64, F64, F64]:
    """The per-camera kernel inputs (fx fy cx cy, distortion, level scales), read-only, made
    once per calibration rather than once per frame (keyed by value: an Intrinsics built
    with a list for the distortion is not hashable)."""
    return _camera_inputs_of(
        (float(intr.fx), float(intr.fy), float(intr.cx), float(intr.cy)),
        tuple(float(v) for v in intr.dist_k1k2p1p2k3),
    )


@functools.lru_cache(maxsize=8)
def _camera_inputs_of(
    fxfycxcy: tuple[float, ...], dist: tuple[float, ...]
) -> tuple[F64, F64, F64]:
    return (_ro(np.array(fxfycxcy), np.float64), _ro(np.array(dist), np.float64),
            _ro(pyr.level_scales(), np.float64))


def _at_frame_instant(P: F64, rows: NDArray[np.int64], rs: F64) -> F64:
    """Points ``P`` (n, 3) seen at full-resolution ``rows`` by a rolling-shutter camera
    moving with ``rs[2:8]``, moved to the frame's instant (first order)."""
    tau = (rows.astype(np.float64) - rs[1]) * rs[0]
    v = np.asarray(rs[2:5], dtype=np.float64)
    w = np.asarray(rs[5:8], dtype=np.float64)
    return np.asarray(P + tau[:, None] * (v[None, :] + np.cross(w[None, :], P)),
                      dtype=np.float64)


def rs_rows(intr: Intrinsics, readout_s: float) -> tuple[float, float]:
    """``(t_row, row0)`` of a rolling-shutter frame read out in ``readout_s``: seconds per
    full-resolution row, and the row exposed at the frame's instant (the middle one)."""
    return readout_s / max(intr.height, 1), 0.5 * (intr.height - 1)


def _rs_config(intr: Intrinsics, readout_s: float, dt_s: float) -> F64:
    """``(t_row, row0, dt)`` for :func:`engine.dense.kernels.minimize` (:func:`rs_rows` and
    the time since the previous frame; zeros: no rolling-shutter model)."""
    on = readout_s > 0.0 and dt_s > 0.0 and math.isfinite(readout_s) and math.isfinite(dt_s)
    cfg = np.array([*rs_rows(intr, readout_s), dt_s] if on else [0.0, 0.0, 0.0],
                   dtype=np.float64)
    return _ro(cfg, np.float64)


def spread_order(n: int) -> NDArray[np.int64]:
    """A permutation of ``range(n)`` whose prefixes of length n/4 and n/2 are every 4th and
    every 2nd index: on points sorted in image order, any such prefix covers the image."""
    idx = np.arange(n)
    return np.concatenate([idx[0::4], idx[2::4], idx[1::2]])


@dataclass(frozen=True, slots=True)
class Reference:
    """Selected points P* with c* and J per level (eq. (6)), computed once per reference.

    Structure-of-arrays, float32 (the kernels compute in float64): ``P`` (3, n) in the
    reference camera frame, ``cstar`` (3, n) per level, ``J`` (3, 6, n) per level. The points
    are in :func:`spread_order` so that a prefix serves as a thinner spread-out set.
    """

    P: F32  # (3, n) reference camera frame, metres
    cstar: F32  # (3 levels, n)
    J: F32  # (3 levels, 6, n)
    uv_full: F32  # (n, 2) pixels of the points in the reference image
    intrinsics: Intrinsics
    n_requested: int
    z_median_m: float = 1.0  # median depth of the points (convergence test scale)
    normals: F32 | None = None  # (3, ng) unit normals (0: none; times the point's
    # noise weight with geometric_noise_model), for the geometric term
    Jg: F32 | None = None  # (6, ng) Jacobian of the point-to-plane residual (inverse comp.)
    Pg: F32 | None = None  # (3, ng) points of the geometric term (with ``normals``)

    @property
    def n(self) -> int:
        return int(self.P.shape[1])

    @property
    def nbytes(self) -> int:
        """Memory held by the arrays (bytes)."""
        arrs = (self.P, self.cstar, self.J, self.uv_full, self.normals, self.Jg, self.Pg)
        return int(sum(a.nbytes for a in arrs if a is not None))


def build_reference(
    pre: Preprocessed,
    n_points: int,
    *,
    min_depth_m: float = 0.3,
    max_depth_m: float = 8.0,
    border_px: int = 4,
    max_edge_depth_ratio: float = 0.05,
    T_color_depth: F64 | None = None,
    with_normals: bool = False,
    geometric_points: int = 0,
    geometric_noise_model: bool = False,
    rs_ref: F64 | None = None,
) -> Reference:
    """Select the ``n_points`` strongest-gradient points with valid depth (sec. 4.5, eq. (14))
    and precompute c* and the Jacobian of eq. (6) at every level.

    ``with_normals``: also the points of the optional geometric term with their surface
    normals and point-to-plane Jacobian: ``geometric_points`` > 0 of their own, spread evenly
    over every pixel with valid, non-edge depth and a normal (flat walls and floors constrain
    the geometry as much as textured edges do), else the photometric points themselves.
    ``geometric_noise_model``: each normal is scaled by :func:`geometric_noise_weights` of its
    point's depth (the residual in units of its depth noise; ``normals`` are then not unit).
    ``rs_ref`` (``(t_row, row0, vx, vy, vz, wx, wy, wz)``, the reference frame's readout per
    row and velocity, :func:`engine.dense.kernels.project_rs`): a rolling-shutter frame's
    points, each measured at its own row's instant, are moved to the frame's instant (c* and
    the Jacobian stay those of the pixels where they were seen)."""
    from engine.dense import kernels

    intr = pre.intrinsics
    l0 = pre.levels[0]
    h0, w0 = l0.shape
    xy, uf, vf = _level0_rays(intr)
    z = pre.depth_m[vf, uf].astype(np.float64)

    cand = (z > min_depth_m) & (z < max_depth_m)
    if max_edge_depth_ratio > 0.0:
        # points on depth discontinuities have unreliable 3D positions (mixed foreground and
        # background depth, sensor/colour misregistration): keep points whose 5x5
        # neighbourhood spans less than ``max_edge_depth_ratio`` of their depth
        import cv2

        d = pre.depth_m
        kernel = np.ones((5, 5), np.uint8)
        dmax = cv2.dilate(d, kernel)[vf, uf]
        dmin = cv2.erode(np.where(d > 0, d, np.float32(1e6)).astype(np.float32), kernel)[vf, uf]
        cand &= (dmax - dmin) < max_edge_depth_ratio * z
    cand = cand.reshape(h0, w0)
    b = max(border_px, 2)
    cand[:b, :] = False
    cand[-b:, :] = False
    cand[:, :b] = False
    cand[:, -b:] = False
    g = gradient_magnitude(l0)
    cand &= g > 0.0
    idx = select_points(g, cand, n_points)
    idx = idx[spread_order(idx.size)]
    zi = z[idx]
    P = np.stack([xy[idx, 0] * zi, xy[idx, 1] * zi, zi], axis=1)
    Pg = N = None
    if with_normals and geometric_points > 0:
        cg = np.flatnonzero(cand.ravel())
        if cg.size > geometric_points:  # evenly over the image (a few lose their normal)
            cg = cg[np.linspace(0, cg.size - 1, geometric_points).astype(np.int64)]
        cg = cg[spread_order(cg.size)]  # prefixes stay spread
        zg = z[cg]
        Pc = np.stack([xy[cg, 0] * zg, xy[cg, 1] * zg, zg], axis=1)
        Nc = _normals(pre.depth_m, intr, uf[cg], vf[cg], Pc)
        has_n = np.any(Nc != 0.0, axis=1)
        Pg, N = Pc[has_n], Nc[has_n]
    elif with_normals:
        Pg, N = P, _normals(pre.depth_m, intr, uf[idx], vf[idx], P)
    if T_color_depth is not None:
        # depth captured at another instant than the colour image: move the photometric points
        # into the colour camera's pose (time-offset compensation, not in the paper). The
        # geometric points stay at the depth instant: depth against depth, their relative
        # pose is the colour images' one at constant velocity, and no velocity estimate of the
        # tracker's own feeds back into them
        P = P @ T_color_depth[:3, :3].T + T_color_depth[:3, 3]
    P32 = np.ascontiguousarray(P.T, dtype=np.float32)
    N32 = Jg = Pg32 = None
    if Pg is not None and N is not None and geometric_noise_model:
        # inverse-noise weighting of the point-to-plane residual (an extension): the residual
        # r = n . (T^-1 Q - P) and its Jacobian are linear in n, so scaling n by the point's
        # 1 / sigma(z) scales both (the kernels need no other input)
        N = N * geometric_noise_weights(Pg[:, 2])[:, None]
    # the reference frame's rolling-shutter motion, where there is one
    rs_moving = rs_ref if rs_ref is not None and rs_ref[0] > 0.0 else None
    if Pg is not None and N is not None:
        if rs_moving is not None:
            # the depth image's rows too (a depth sensor scanning in step with the colour
            # one, as a Kinect's; see below for the photometric points); the current depth is
            # read at the rows the points are seen in (kernels.minimize), so both sides of the
            # point-to-plane residual are at the frames' instants
            vg = vf[cg][has_n] if with_normals and geometric_points > 0 else vf[idx]
            Pg = _at_frame_instant(Pg, vg, rs_moving)
        N32 = np.ascontiguousarray(N.T, dtype=np.float32)
        Pg32 = np.ascontiguousarray(Pg.T, dtype=np.float32)
        # point-to-plane residual r = n . (T^-1 Q - P) (Q: current depth point); the inverse
        # compositional increment gives the constant Jacobian [-n, -(P x n)] at x = 0
        Jg = np.ascontiguousarray(
            np.concatenate([-N, -np.cross(Pg, N)], axis=1).T, dtype=np.float32
        )
    n = P.shape[0]
    cstar = np.zeros((3, n), dtype=np.float32)
    J = np.zeros((3, 6, n), dtype=np.float32)
    f32, f64 = np.float32, np.float64
    kernels.precompute_reference(
        _ro(P32, f32), _ro(pre.levels[0], f32), _ro(pre.levels[1], f32),
        _ro(pre.levels[2], f32), _ro(cam_vector(intr), f64), _ro(intr.dist, f64),
        _ro(pyr.level_scales(), f64), cstar, J,
    )
    if rs_moving is not None:
        # seen at X_row = X - tau (v + w x X) (kernels.project_rs): X = X_row + tau (v + w x
        # X_row) to first order, tau from the row the point was seen in
        P = _at_frame_instant(P, vf[idx], rs_moving)
        P32 = np.ascontiguousarray(P.T, dtype=np.float32)
    uv = np.stack([uf[idx], vf[idx]], axis=1).astype(np.float32)
    zmed = float(np.median(P[:, 2])) if n else 1.0
    # read-only from here on (the kernels then take them without a per-frame view, _ro)
    return Reference(_ro(P32, f32), _ro(cstar, f32), _ro(J, f32), _ro(uv, f32), intr,
                     n_points, zmed, normals=None if N32 is None else _ro(N32, f32),
                     Jg=None if Jg is None else _ro(Jg, f32),
                     Pg=None if Pg32 is None else _ro(Pg32, f32))


def orthonormalize(T: F64) -> F64:
    """Project the rotation of a rigid transform back onto SO(3) (nearest).

    Poses are composed with ``invert`` (which uses R^T); without this, float round-off in
    chained compositions is amplified about threefold per reference update. A rotation that
    is orthonormal to round-off takes one Newton step of the polar decomposition,
    R <- R (3 I - R^T R) / 2 (quadratic convergence); anything further off the SVD.
    """
    out = np.array(T, dtype=np.float64)
    R = out[:3, :3]
    E = R.T @ R
    E[0, 0] -= 1.0
    E[1, 1] -= 1.0
    E[2, 2] -= 1.0
    if float(np.abs(E).max()) < 1e-6:
        out[:3, :3] = R - 0.5 * (R @ E)
    else:
        U, _, Vt = np.linalg.svd(R)
        Rn = U @ Vt
        if np.linalg.det(Rn) < 0:
            U[:, -1] = -U[:, -1]
            Rn = U @ Vt
        out[:3, :3] = Rn
    out[3] = (0.0, 0.0, 0.0, 1.0)
    return out


@dataclass(frozen=True, slots=True)
class AlignResult:
    """Result of Algorithm 1 for one frame."""

    T_cur_ref: F64
    median_abs_e: float  # grey levels (0-255), finest level evaluated
    valid_fraction: float  # points projecting inside the image
    inlier_fraction: float  # points with weight > 0.1 (``weights``, see quality_scale)
    rms: float  # weighted RMS residual (grey levels)
    ok: bool  # linear system solvable, finite
    iterations: int
    weights: F32  # (n,) w_c w_z in [0, 1] (Tukey scale: quality_scale, else eq. (9)'s own)
    uv_full: F32  # (n, 2) warped points in the current full-resolution image
    residuals: F32  # (n,)
    brightness_offset: float = 0.0  # removed global offset (grey levels), finest level
    brightness_gain: float = 1.0  # fitted gain of the affine brightness model, finest level
    median_abs_geo_m: float = 0.0  # median |point-to-plane residual| (geometric term only)
    steps_px: tuple[float, ...] = ()  # image motion of each update (pixels of its level)
    weights_inlier_fraction: float = 0.0  # share of W > 0.1 under the optimiser's own scale


#: longest iteration log kept in AlignResult.steps_px
_MAX_STEPS = 64


def align(
    ref: Reference,
    pre: Preprocessed,
    T0_cur_ref: F64,
    iterations_fine_to_coarse: tuple[int, int, int],
    *,
    tau_m: float = 0.05,
    missing_depth_weight: float = 1.0,
    use_depth: bool = True,
    min_residual_scale: float = 0.0,
    scale_over_kept: bool = True,
    brightness_offset: bool = False,
    geo_weight: float = 0.0,
    min_geo_scale_m: float = 0.001,
    T_color_depth: F64 | None = None,
    brightness_gain: bool = False,
    stop_px: float = 0.0,
    level_fraction: tuple[float, float, float] = (1.0, 1.0, 1.0),
    threads: int = 1,
    quality_scale: float = 0.0,
    rolling_shutter_s: float = 0.0,
    T_prev_ref: F64 | None = None,
    dt_prev_s: float = 0.0,
) -> AlignResult:
    """Minimise eq. (1) from the initial base transform ``T0_cur_ref`` (Algorithm 1).

    ``scale_over_kept``: the median of eq. (9) over the points the depth test keeps (else over
    all that project into the image, the paper); ``level_fraction`` (fine to coarse): the
    share of the points used at each level (the paper: all at every level); ``stop_px``: stop
    a level once an update moves the image by less than this many pixels of that level (0:
    the fixed counts of the paper); ``threads`` > 1 splits the passes over the points between
    that many threads. ``quality_scale`` (grey levels, > 0): report ``weights`` and
    ``inlier_fraction`` against this typical median residual instead of the frame's own (a
    frame that went wrong cannot make its residuals look normal by inflating its scale).
    ``rolling_shutter_s`` (> 0, the colour camera's readout time, first to last row) with the
    previous frame's pose ``T_prev_ref`` ``dt_prev_s`` seconds before: each point is warped
    as seen by its own row (``kernels.project_rs``), the camera's velocity being the motion
    from the previous frame to this frame's current estimate (beyond the paper).
    """
    from engine.dense import kernels

    intr = pre.intrinsics
    n = ref.n
    w = np.empty(n, dtype=np.float32)
    uv = np.empty((n, 2), dtype=np.float32)
    e = np.empty(n, dtype=np.float32)
    steps = np.zeros(_MAX_STEPS)
    Pg, normals, Jg = ref.Pg, ref.normals, ref.Jg
    use_geo = geo_weight > 0 and Pg is not None and normals is not None and Jg is not None
    level_n = np.array([max(1, round(f * n)) for f in level_fraction], dtype=np.int64)
    f32, f64, i64 = np.float32, np.float64, np.int64
    cam, dist, scales = _camera_inputs(intr)
    T, st = kernels.minimize(
        _ro(ref.P, f32), _ro(ref.cstar, f32), _ro(ref.J, f32), _ro(pre.levels[0], f32),
        _ro(pre.levels[1], f32), _ro(pre.levels[2], f32), _ro(pre.depth_m, f32),
        cam, dist, scales,
        _ro(np.asarray(iterations_fine_to_coarse), i64), _ro(level_n, i64),
        _ro(T0_cur_ref, f64), float(tau_m),
        float(missing_depth_weight), bool(use_depth), float(min_residual_scale),
        bool(scale_over_kept), bool(brightness_offset),
        bool(brightness_gain and brightness_offset),
        _ro(Pg, f32) if use_geo and Pg is not None else _NO_N,
        _ro(normals, f32) if use_geo and normals is not None else _NO_N,
        _ro(Jg, f32) if use_geo and Jg is not None else _NO_JG,
        float(geo_weight) if use_geo else 0.0, float(min_geo_scale_m),
        _NO_TCD if T_color_depth is None else _ro(T_color_depth, f64),
        _NO_TCD if T_prev_ref is None else _ro(T_prev_ref, f64),
        _rs_config(intr, rolling_shutter_s, dt_prev_s if T_prev_ref is not None else 0.0),
        float(stop_px), float(ref.z_median_m), float(quality_scale), int(threads), w, uv, e,
        steps,
    )
    ok = bool(st[4] > 0.5) and bool(np.all(np.isfinite(T)))
    if ok:
        T = orthonormalize(T)
    its = int(st[5])
    return AlignResult(
        T_cur_ref=T,
        median_abs_e=float(st[0]),
        valid_fraction=float(st[1]),
        inlier_fraction=float(st[2]),
        rms=float(st[3]),
        ok=ok,
        iterations=its,
        weights=w,
        uv_full=uv,
        residuals=e,
        brightness_offset=float(st[7]),
        brightness_gain=float(st[8]),
        median_abs_geo_m=float(st[9]),
        steps_px=tuple(float(v) for v in steps[: min(its, _MAX_STEPS)]),
        weights_inlier_fraction=float(st[11]),
    )
