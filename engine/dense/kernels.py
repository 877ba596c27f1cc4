"""Numba kernels of the dense RGB-D tracker (Tykkälä 2014, Algorithm 1).

Imported lazily (by :mod:`engine.dense.photometric` when a tracker is built) so that tracker
discovery stays fast. ``cache=True`` keeps the compiled code between runs; every kernel is
``nogil=True`` (it touches no Python object), so an engine thread running the tracker does not
block the GUI thread.

Conventions: a reference point ``P`` (metres, reference camera frame) is warped by
``T_cur_ref`` (the base transform T^ of eq. (1)) and projected with eq. (2)-(4) into
full-resolution pixels ``(u0, v0)``; pyramid level L (0 = 320x240 for a 640x480 input) uses
pixel-centre scaling ``u_L = (u0 + 0.5) * s_L - 0.5`` (sec. 4.6) with ``s_L = 2^-(L+1)``.
Twists are ``x = (v, w)``, translation first (engine.geometry).

Layout (for speed): point data is structure-of-arrays, ``P`` (3, n), ``J`` (6, n) per level,
so that the projection and the normal-equation loops vectorise (SIMD); the image look-ups
(bilinear intensity, nearest depth) are one scalar loop. One Gauss-Newton iteration is three
passes over the points: project (vector), sample (scalar, fills the residual histogram),
accumulate (vector).

The median of eq. (9) is read from a histogram of the signed residuals (sec. 4.2 uses a
64-bin histogram): bins are uniform in ``sign(e) sqrt(|e|)`` (fine near zero, where the median
of a good fit lies; coarse for outliers), 2 x 1024 bins over |e| < 256 grey levels, linear
inside a bin. From the one histogram come both the brightness offset (the median of e) and
the Tukey scale (the median of |e - offset|).

Point loops run over unsigned indices (``range(np.uint64(lo), np.uint64(hi))``): with a
signed index numba wraps negative indices around (``a[i]`` is ``a[i + len(a)]`` for i < 0),
and LLVM, unable to rule that out for a start it does not know, turns every contiguous load
of a vectorised loop into a gather (the projection pass was ~8x, the accumulation ~3x slower).

One specialisation per kernel: every array argument reaches :func:`minimize` and
:func:`precompute_reference` with one fixed type (dtype, layout, read-only inputs; see
``engine.dense.photometric``), and a callee is never called once with a literal and once with
a variable (``m - m``, not ``0``, starts a whole-range pass; no literal ``True``/``False``
flags). A cached caller that mixes specialisations of a cached callee (numba picks one by
casting) can segfault when a later process loads it from the cache (numba issue #6713), which
is what happened on TUM with and without the geometric term.
"""

from __future__ import annotations

import math
import os

# numba's OpenMP layer (threads > 1): idle worker threads sleep at once instead of spinning,
# which on a busy 2-core machine would take the core the tracker's own thread needs
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numpy as np
from numba import njit, prange

# Tukey constants, eq. (9)-(10).
TUKEY_C = 1.4826
TUKEY_B = 4.6851

#: histogram bins per sign of the residual, and bins per sqrt(unit) (see the module docstring)
HIST_NB = 1024
HIST_K = 64.0
#: metres -> histogram units of the geometric (point-to-plane) residual: 0.1 mm .. 6.5 m
GEO_UNIT = 1e4

#: what :func:`minimize` reports in its ``stats`` array (index by name)
STATS = (
    "median_abs_e", "valid_fraction", "inlier_fraction", "rms", "ok", "iterations",
    "last_step", "brightness_offset", "brightness_gain", "median_abs_geo_m", "n_kept",
    "weights_inlier_fraction",
)
N_STATS = len(STATS)


# ----------------------------------------------------------------------------- helpers


@njit(cache=True, inline="always", nogil=True)
def _bilinear(img: np.ndarray, u: float, v: float) -> float:
    x0 = math.floor(u)
    y0 = math.floor(v)
    ax = u - x0
    ay = v - y0
    i00: float = img[y0, x0]
    i01: float = img[y0, x0 + 1]
    i10: float = img[y0 + 1, x0]
    i11: float = img[y0 + 1, x0 + 1]
    return (1.0 - ay) * ((1.0 - ax) * i00 + ax * i01) + ay * ((1.0 - ax) * i10 + ax * i11)


@njit(cache=True, inline="always", nogil=True)
def _hist_bin(x: float) -> int:
    """Histogram bin of a signed value: uniform in sign(x) sqrt(|x|)."""
    f = min(math.sqrt(abs(x)) * HIST_K, HIST_NB - 0.5)
    b = int(f)
    return HIST_NB + b if x >= 0.0 else HIST_NB - 1 - b


@njit(cache=True, inline="always", nogil=True)
def _cdf(cum: np.ndarray, hist: np.ndarray, x: float) -> float:
    """Number of histogram samples below ``x`` (linear inside a bin)."""
    f = math.copysign(math.sqrt(abs(x)) * HIST_K, x) + HIST_NB
    if f <= 0.0:
        return 0.0
    if f >= 2 * HIST_NB:
        return float(cum[2 * HIST_NB])
    k = int(f)
    below: float = cum[k] + (f - k) * hist[k]
    return below


@njit(cache=True, nogil=True)
def _cumulate(hist: np.ndarray, cum: np.ndarray) -> int:
    """cum[k] = sum(hist[:k]); returns the total."""
    s = 0
    for k in range(2 * HIST_NB):
        cum[k] = s
        s += hist[k]
    cum[2 * HIST_NB] = s
    return s


@njit(cache=True, nogil=True)
def hist_median(cum: np.ndarray, hist: np.ndarray) -> float:
    """Median of the signed values in the histogram (``cum`` from :func:`_cumulate`)."""
    n = cum[2 * HIST_NB]
    if n == 0:
        return 0.0
    half = 0.5 * n
    k = 0
    while k < 2 * HIST_NB - 1 and cum[k + 1] < half:
        k += 1
    f = k + ((half - cum[k]) / hist[k] if hist[k] > 0 else 0.0) - HIST_NB
    return math.copysign((f / HIST_K) ** 2, f)


@njit(cache=True, nogil=True)
def hist_median_abs(cum: np.ndarray, hist: np.ndarray, centre: float) -> float:
    """Median of |x - centre| over the histogram of x (bisection on the symmetric band)."""
    n = cum[2 * HIST_NB]
    if n == 0:
        return 0.0
    half = 0.5 * n
    lo = 0.0
    hi = (HIST_NB / HIST_K) ** 2 + abs(centre)
    for _ in range(40):
        t = 0.5 * (lo + hi)
        if _cdf(cum, hist, centre + t) - _cdf(cum, hist, centre - t) < half:
            lo = t
        else:
            hi = t
    return 0.5 * (lo + hi)


@njit(cache=True, nogil=True)
def histogram_median(a: np.ndarray, mask: np.ndarray) -> float:
    """Median of ``a[mask]`` through the residual histogram (tests, diagnostics)."""
    hist = np.zeros(2 * HIST_NB, dtype=np.int64)
    cum = np.zeros(2 * HIST_NB + 1, dtype=np.int64)
    for i in range(a.shape[0]):
        if mask[i]:
            hist[_hist_bin(a[i])] += 1
    _cumulate(hist, cum)
    return hist_median(cum, hist)


@njit(cache=True, nogil=True)
def histogram_median_abs(a: np.ndarray, mask: np.ndarray, centre: float) -> float:
    """Median of ``|a[mask] - centre|`` through the residual histogram."""
    hist = np.zeros(2 * HIST_NB, dtype=np.int64)
    cum = np.zeros(2 * HIST_NB + 1, dtype=np.int64)
    for i in range(a.shape[0]):
        if mask[i]:
            hist[_hist_bin(a[i])] += 1
    _cumulate(hist, cum)
    return hist_median_abs(cum, hist, centre)


@njit(cache=True, nogil=True)
def tukey_weights(e_abs: np.ndarray, mask: np.ndarray, median: float, out: np.ndarray) -> None:
    """Eq. (9)-(10): u = |e| / (c median), w = (1 - (u/b)^2)^2 for u <= b else 0."""
    scale = TUKEY_C * max(median, 1e-6)
    for i in range(e_abs.shape[0]):
        if not mask[i]:
            out[i] = 0.0
            continue
        u = e_abs[i] / scale
        if u <= TUKEY_B:
            t = 1.0 - (u / TUKEY_B) * (u / TUKEY_B)
            out[i] = t * t
        else:
            out[i] = 0.0


@njit(cache=True, nogil=True)
def _se3_exp(x: np.ndarray) -> np.ndarray:
    """Closed-form SE(3) exponential, eq. (5), with series near zero angle."""
    v0, v1, v2 = x[0], x[1], x[2]
    w0, w1, w2 = x[3], x[4], x[5]
    th2 = w0 * w0 + w1 * w1 + w2 * w2
    th = math.sqrt(th2)
    if th < 1e-4:
        a = 1.0 - th2 / 6.0 + th2 * th2 / 120.0
        b = 0.5 - th2 / 24.0 + th2 * th2 / 720.0
        c = 1.0 / 6.0 - th2 / 120.0 + th2 * th2 / 5040.0
    else:
        a = math.sin(th) / th
        b = (1.0 - math.cos(th)) / th2
        c = (1.0 - a) / th2
    W = np.array([[0.0, -w2, w1], [w2, 0.0, -w0], [-w1, w0, 0.0]])
    W2 = W @ W
    eye = np.eye(3)
    R = eye + a * W + b * W2
    V = eye + b * W + c * W2
    T = np.eye(4)
    T[:3, :3] = R
    t = V @ np.array([v0, v1, v2])
    T[0, 3] = t[0]
    T[1, 3] = t[1]
    T[2, 3] = t[2]
    return T


@njit(cache=True, nogil=True)
def _cholesky_solve6(H: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, bool]:
    """Solve H x = g for a 6x6 symmetric positive-definite H by Cholesky (sec. 4.3)."""
    n = 6
    L = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            s = H[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                if s <= 1e-12 * max(H[i, i], 1e-300):
                    return np.zeros(n), False
                L[i, i] = math.sqrt(s)
            else:
                L[i, j] = s / L[j, j]
    y = np.zeros(n)
    for i in range(n):
        s = g[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    x = np.zeros(n)
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return x, True


# ---------------------------------------------------------------------- per-iteration passes


@njit(cache=True, fastmath=True, inline="always", nogil=True)
def _rows(T: np.ndarray) -> tuple[float, ...]:
    """The top three rows of the rigid transform ``T`` as 12 scalars (r00, r01, r02, t0,
    r10, ...): held in registers across a loop over points (:func:`_moved`)."""
    return (T[0, 0], T[0, 1], T[0, 2], T[0, 3], T[1, 0], T[1, 1], T[1, 2], T[1, 3],
            T[2, 0], T[2, 1], T[2, 2], T[2, 3])


@njit(cache=True, fastmath=True, inline="always", nogil=True)
def _moved(R: tuple[float, ...], P: np.ndarray, i: int) -> tuple[float, float, float]:
    """Point ``i`` of ``P`` ((3, n), float32 or float64) moved by the transform of
    :func:`_rows`, in float64: ``T P`` of eq. (2)."""
    x, y, z = np.float64(P[0, i]), np.float64(P[1, i]), np.float64(P[2, i])
    return (R[0] * x + R[1] * y + R[2] * z + R[3],
            R[4] * x + R[5] * y + R[6] * z + R[7],
            R[8] * x + R[9] * y + R[10] * z + R[11])


@njit(cache=True, fastmath=True, inline="always", nogil=True)
def _to_pixel(xn: float, yn: float, cam: np.ndarray, dist: np.ndarray) -> tuple[float, float]:
    """Normalised coordinates -> distorted full-resolution pixel, eq. (2)-(4)."""
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    r2 = xn * xn + yn * yn
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn)
    yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn
    return cam[0] * xd + cam[2], cam[1] * yd + cam[3]


@njit(cache=True, fastmath=True, nogil=True)
def project(
    P: np.ndarray, T: np.ndarray, cam: np.ndarray, dist: np.ndarray,
    u0: np.ndarray, v0: np.ndarray, Z: np.ndarray, lo: int, hi: int,
) -> None:
    """Warp of eq. (2)-(4) for points ``lo:hi``: full-resolution pixels ``(u0, v0)`` and the
    depth ``Z`` in the current camera (a vectorised loop; Z <= 0 is caught by the sampler).
    Whole arrays and an index range rather than slices keep numba's contiguous layout."""
    R = _rows(T)
    for i in range(np.uint64(lo), np.uint64(hi)):  # unsigned: see the module doc
        X, Y, Zi = _moved(R, P, i)
        iz = 1.0 / max(Zi, 1e-3)
        u0[i], v0[i] = _to_pixel(X * iz, Y * iz, cam, dist)
        Z[i] = Zi


@njit(cache=True, fastmath=True, nogil=True)
def project_rs(
    P: np.ndarray, T: np.ndarray, cam: np.ndarray, dist: np.ndarray, rs: np.ndarray,
    u0: np.ndarray, v0: np.ndarray, Z: np.ndarray, lo: int, hi: int,
) -> None:
    """:func:`project` for a rolling-shutter colour camera (beyond the paper): row ``v`` is
    exposed ``tau = (v - row0) t_row`` seconds after the frame's instant, when the camera has
    moved by ``tau (v, w)`` (the twist per second ``rs[2:8]``, constant over the frame), so a
    point ``X`` of the frame-instant camera is seen at ``X - tau (v + w x X)`` (first order;
    ``tau`` from the row of its global-shutter projection). ``rs = (t_row, row0, vx, vy, vz,
    wx, wy, wz)``."""
    R = _rows(T)
    t_row, row0 = rs[0], rs[1]
    vx, vy, vz, wx, wy, wz = rs[2], rs[3], rs[4], rs[5], rs[6], rs[7]
    for i in range(np.uint64(lo), np.uint64(hi)):  # unsigned: see the module doc
        X, Y, Zi = _moved(R, P, i)
        iz = 1.0 / max(Zi, 1e-3)
        _, v_gs = _to_pixel(X * iz, Y * iz, cam, dist)  # the row at the frame's instant
        tau = (v_gs - row0) * t_row
        Xr = X - tau * (vx + wy * Zi - wz * Y)
        Yr = Y - tau * (vy + wz * X - wx * Zi)
        Zr = Zi - tau * (vz + wx * Y - wy * X)
        iz = 1.0 / max(Zr, 1e-3)
        u0[i], v0[i] = _to_pixel(Xr * iz, Yr * iz, cam, dist)
        Z[i] = Zr


@njit(cache=True, nogil=True)
def rs_velocity(T_prev: np.ndarray, T: np.ndarray, dt: float, rs: np.ndarray) -> None:
    """The camera's twist per second into ``rs[2:8]`` from the previous frame's pose
    ``T_prev`` (= T_prev_ref) and this frame's current estimate ``T`` (= T_cur_ref): the motion
    ``D = T_prev_ref inv(T_cur_ref)`` (previous camera -> current camera) over ``dt``, first
    order (a frame's motion is small): ``v = t_D / dt``, ``w = vee(R_D - R_D^T) / (2 dt)``."""
    D = T_prev @ _inverse(T)
    k = 1.0 / dt
    rs[2] = D[0, 3] * k
    rs[3] = D[1, 3] * k
    rs[4] = D[2, 3] * k
    rs[5] = 0.5 * (D[2, 1] - D[1, 2]) * k
    rs[6] = 0.5 * (D[0, 2] - D[2, 0]) * k
    rs[7] = 0.5 * (D[1, 0] - D[0, 1]) * k


@njit(cache=True, nogil=True)
def sample(
    u0: np.ndarray, v0: np.ndarray, Z: np.ndarray, cstar: np.ndarray, img: np.ndarray,
    depth: np.ndarray, scale: float, inv_tau2: float, missing_depth_weight: float,
    use_depth: bool, e: np.ndarray, wz: np.ndarray, inside: np.ndarray, lo: int, hi: int,
) -> int:
    """Residual of eq. (1) and depth weight of eq. (11)-(12) at one level, for every point.

    ``e = c* - I(w(P; T^))`` (inverse-compositional form) by bilinear sampling; the current
    depth is read at the nearest full-resolution pixel (no resampling across edges). Points
    outside the level image (or behind the camera) get ``e = wz = inside = 0``. Returns the
    number inside the image.

    Branch-free (a point outside reads pixel 0 and is multiplied by 0; unsigned flat indices
    need no negative-index wrap-around): the image look-ups cannot be vectorised, but the
    loop has no unpredictable branch (about a third faster than branching per point).
    """
    h, w = img.shape
    hd, wd = depth.shape
    wmax = w - 1.0
    hmax = h - 1.0
    flat = img.ravel()  # C-contiguous inputs (photometric._ro): views, no copies
    dflat = depth.ravel()
    uw = np.uint32(w)
    uw1 = np.uint32(w + 1)
    one = np.uint32(1)
    uwd = np.uint32(wd)
    uhd = np.uint32(hd)
    nvalid = 0
    for i in range(np.uint64(lo), np.uint64(hi)):  # unsigned: see the module doc
        Zi = Z[i]
        uL = (u0[i] + 0.5) * scale - 0.5
        vL = (v0[i] + 0.5) * scale - 0.5
        ok = Zi > 1e-3 and uL >= 0.0 and vL >= 0.0 and uL < wmax and vL < hmax
        uc = uL if ok else 0.0
        vc = vL if ok else 0.0
        x0 = np.uint32(uc)
        y0 = np.uint32(vc)
        ax = uc - x0
        ay = vc - y0
        k = y0 * uw + x0
        i00 = flat[k]
        i01 = flat[k + one]
        i10 = flat[k + uw]
        i11 = flat[k + uw1]
        top = i00 + ax * (i01 - i00)
        bot = i10 + ax * (i11 - i10)
        ei = cstar[i] - (top + ay * (bot - top))  # eq. (1), inverse compositional
        wzi = 1.0
        if use_depth:  # (the same for every point: no branch misprediction)
            ui = np.uint32(u0[i] + 0.5) if ok else np.uint32(0)
            vi = np.uint32(v0[i] + 0.5) if ok else np.uint32(0)
            inb = ui < uwd and vi < uhd  # (always, when ok: a guard, not a test)
            zd = dflat[vi * uwd + ui if inb else np.uint32(0)]
            zc = zd if inb else 0.0
            ez = zc - Zi  # eq. (11)
            t = max(1.0 - ez * ez * inv_tau2, 0.0)
            wzi = t * t if zc > 0.0 else missing_depth_weight  # eq. (12)
        okf = 1.0 if ok else 0.0
        e[i] = ei * okf
        wz[i] = wzi * okf
        inside[i] = okf
        nvalid += 1 if ok else 0
    return nvalid


@njit(cache=True, fastmath=True, nogil=True)
def histogram(
    x: np.ndarray, w: np.ndarray, unit: float, bins: np.ndarray, hist: np.ndarray, lo: int,
    hi: int,
) -> int:
    """Add ``x * unit`` of points ``lo:hi`` with ``w > 0`` to the residual histogram (bin
    indices in a vectorised loop, then the counts); returns how many were added."""
    for i in range(np.uint64(lo), np.uint64(hi)):  # unsigned: see the module doc
        v = x[i] * unit
        f = min(math.sqrt(abs(v)) * HIST_K, HIST_NB - 0.5)
        b = np.int32(f)
        b = HIST_NB + b if v >= 0.0 else HIST_NB - 1 - b
        bins[i] = b if w[i] > 0.0 else 2 * HIST_NB
    cnt = 0
    for i in range(np.uint64(lo), np.uint64(hi)):  # unsigned: see the module doc
        b = bins[i]
        if b < 2 * HIST_NB:
            hist[b] += 1
            cnt += 1
    return cnt


@njit(cache=True, nogil=True)
def gather_cells(
    u0: np.ndarray, v0: np.ndarray, depth: np.ndarray, cells: np.ndarray, lo: int, hi: int
) -> None:
    """The four depths around each full-resolution position ``(u0, v0)`` into ``cells`` (4,
    n): (x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1); 0 outside the image (the
    scalar part of :func:`sample_geometric`: the look-ups)."""
    hd, wd = depth.shape
    c0 = cells[0]
    c1 = cells[1]
    c2 = cells[2]
    c3 = cells[3]
    for i in range(np.uint64(lo), np.uint64(hi)):  # unsigned: see the module doc
        u = u0[i]
        v = v0[i]
        if u >= 0.0 and v >= 0.0 and u < wd - 1 and v < hd - 1:
            x0 = int(u)
            y0 = int(v)
            c0[i] = depth[y0, x0]
            c1[i] = depth[y0, x0 + 1]
            c2[i] = depth[y0 + 1, x0]
            c3[i] = depth[y0 + 1, x0 + 1]
        else:
            c0[i] = 0.0
            c1[i] = 0.0
            c2[i] = 0.0
            c3[i] = 0.0


@njit(cache=True, fastmath=True, nogil=True)
def sample_geometric(
    u0: np.ndarray, v0: np.ndarray, Z: np.ndarray, P: np.ndarray, N: np.ndarray,
    cells: np.ndarray, T: np.ndarray, M: np.ndarray, inv_tau2: float, rg: np.ndarray,
    wg: np.ndarray, lo: int, hi: int,
) -> None:
    """Point-to-plane residual ``r = n . (M Q - P)`` in the reference frame for the geometric
    points ``P`` (warped by ``T`` to ``X = T P``, projected into ``(u0, v0)``, depth ``Z``):
    ``Q = X z / Z`` is the current surface point on the ray through ``(u0, v0)`` (projective
    association, as ICP), ``z`` the current depth there, interpolated bilinearly in inverse
    depth (exact on a plane, where 1/z is affine in the pixel) from the four depths of
    :func:`gather_cells`, ``M = T^-1 T_color_depth``.

    Sub-pixel, not the nearest pixel: with the nearest pixel Q lies up to half a pixel off the
    ray, along the surface, and ``n . (M Q - P)`` is then not zero at the true pose wherever the
    normal is not the surface's (normals from depth differences across a crease or a small
    step); a camera translation moves every point at one depth by the same sub-pixel amount,
    so those residuals share a sign: on the noise-free studio rail they pulled each alignment
    ~0.4 mm along the rail, the one direction the walls and floor leave free.

    ``wg`` is the depth weight of eq. (12) of the association (a presenter in front of the
    static scene gets 0, like in the photometric term), 0 where there is no residual (outside,
    behind the camera, no normal, a missing depth or one of the four depths beyond tau: a depth
    edge inside the interpolation cell). Branch-free, so it vectorises."""
    # M (s X) - P = s (G P - t_M) + t_M - P with G = M T, X = T P, s = z / Z
    G = M @ T
    G00, G01, G02 = G[0, 0], G[0, 1], G[0, 2]
    G10, G11, G12 = G[1, 0], G[1, 1], G[1, 2]
    G20, G21, G22 = G[2, 0], G[2, 1], G[2, 2]
    m0, m1, m2 = M[0, 3], M[1, 3], M[2, 3]
    h0, h1, h2 = G[0, 3] - m0, G[1, 3] - m1, G[2, 3] - m2
    c0 = cells[0]
    c1 = cells[1]
    c2 = cells[2]
    c3 = cells[3]
    for i in range(np.uint64(lo), np.uint64(hi)):  # unsigned: see the module doc
        Zi = max(Z[i], 1e-3)
        z00 = np.float64(c0[i])
        z01 = np.float64(c1[i])
        z10 = np.float64(c2[i])
        z11 = np.float64(c3[i])
        u = u0[i]
        v = v0[i]
        ax = u - math.floor(u)
        ay = v - math.floor(v)
        # z = 1 / (bilinear 1/z) over a common denominator: one division
        q0 = z00 * z01
        q1 = z10 * z11
        den = ((1.0 - ay) * ((1.0 - ax) * z01 + ax * z00) * q1
               + ay * ((1.0 - ax) * z11 + ax * z10) * q0)
        s = q0 * q1 / max(den * Zi, 1e-30)
        ez = Zi * (s - 1.0)
        t = 1.0 - ez * ez * inv_tau2
        dlo = min(min(z00, z01), min(z10, z11)) - Zi
        dhi = max(max(z00, z01), max(z10, z11)) - Zi
        nx = np.float64(N[0, i])
        ny = np.float64(N[1, i])
        nz = np.float64(N[2, i])
        ok = ((Z[i] > 1e-3) & (dlo + Zi > 0.0) & (max(dlo * dlo, dhi * dhi) * inv_tau2 < 1.0)
              & (nx * nx + ny * ny + nz * nz > 0.0))
        px = np.float64(P[0, i])
        py = np.float64(P[1, i])
        pz = np.float64(P[2, i])
        dx = s * (G00 * px + G01 * py + G02 * pz + h0) + m0 - px
        dy = s * (G10 * px + G11 * py + G12 * pz + h1) + m1 - py
        dz = s * (G20 * px + G21 * py + G22 * pz + h2) + m2 - pz
        r = nx * dx + ny * dy + nz * dz
        # (ok: every depth of the cell, hence z, lies within tau, so t > 0)
        rg[i] = r if ok else 0.0
        wg[i] = t * t if ok else 0.0


@njit(cache=True, fastmath=True, nogil=True)
def accumulate(
    J: np.ndarray, e: np.ndarray, cs: np.ndarray, wz: np.ndarray, a: float, b: float,
    beta: float, inv: float, out: np.ndarray, lo: int, hi: int,
) -> None:
    """Tukey weights (eq. (9)-(10)) fused with the weighted normal equations of eq. (13):
    ``out[:21]`` = upper triangle of J^T W J, ``out[21:]`` = J^T W r (sec. 4.3), with the
    residual ``r = a e + b c* - beta`` (brightness model; a = 1, b = 0: offset only),
    ``W = w_c w_z`` and ``inv = 1 / (c median b)``, over points ``lo:hi``. Branch-free, so
    it vectorises."""
    j0 = J[0]
    j1 = J[1]
    j2 = J[2]
    j3 = J[3]
    j4 = J[4]
    j5 = J[5]
    h00 = h01 = h02 = h03 = h04 = h05 = 0.0
    h11 = h12 = h13 = h14 = h15 = 0.0
    h22 = h23 = h24 = h25 = 0.0
    h33 = h34 = h35 = 0.0
    h44 = h45 = 0.0
    h55 = 0.0
    g0 = g1 = g2 = g3 = g4 = g5 = 0.0
    for i in range(np.uint64(lo), np.uint64(hi)):  # unsigned: see the module doc
        r = a * e[i] + b * cs[i] - beta
        u = r * inv  # u / b of eq. (9)-(10)
        t = max(1.0 - u * u, 0.0)
        w = t * t * wz[i]
        a0 = np.float64(j0[i])
        a1 = np.float64(j1[i])
        a2 = np.float64(j2[i])
        a3 = np.float64(j3[i])
        a4 = np.float64(j4[i])
        a5 = np.float64(j5[i])
        wr = w * r
        g0 += a0 * wr
        g1 += a1 * wr
        g2 += a2 * wr
        g3 += a3 * wr
        g4 += a4 * wr
        g5 += a5 * wr
        b0 = w * a0
        b1 = w * a1
        b2 = w * a2
        b3 = w * a3
        b4 = w * a4
        h00 += b0 * a0
        h01 += b0 * a1
        h02 += b0 * a2
        h03 += b0 * a3
        h04 += b0 * a4
        h05 += b0 * a5
        h11 += b1 * a1
        h12 += b1 * a2
        h13 += b1 * a3
        h14 += b1 * a4
        h15 += b1 * a5
        h22 += b2 * a2
        h23 += b2 * a3
        h24 += b2 * a4
        h25 += b2 * a5
        h33 += b3 * a3
        h34 += b3 * a4
        h35 += b3 * a5
        h44 += b4 * a4
        h45 += b4 * a5
        h55 += w * a5 * a5
    out[0] = h00
    out[1] = h01
    out[2] = h02
    out[3] = h03
    out[4] = h04
    out[5] = h05
    out[6] = h11
    out[7] = h12
    out[8] = h13
    out[9] = h14
    out[10] = h15
    out[11] = h22
    out[12] = h23
    out[13] = h24
    out[14] = h25
    out[15] = h33
    out[16] = h34
    out[17] = h35
    out[18] = h44
    out[19] = h45
    out[20] = h55
    out[21] = g0
    out[22] = g1
    out[23] = g2
    out[24] = g3
    out[25] = g4
    out[26] = g5


@njit(cache=True, nogil=True)
def _photometric_chunk(
    P: np.ndarray, T: np.ndarray, cam: np.ndarray, dist: np.ndarray, rs: np.ndarray,
    cs: np.ndarray, img: np.ndarray, depth: np.ndarray, scale: float, inv_tau2: float,
    mdw: float, use_depth: bool, u0: np.ndarray, v0: np.ndarray, Z: np.ndarray, e: np.ndarray,
    wz: np.ndarray, inside: np.ndarray, over_kept: bool, bins: np.ndarray, hist: np.ndarray,
    lo: int, hi: int,
) -> int:
    """Project, sample and histogram points ``lo:hi`` (one thread's share); the histogram
    counts the points the depth test keeps (``over_kept``) or all inside the image. A
    rolling-shutter camera (``rs[0]`` > 0) projects with :func:`project_rs`."""
    if rs[0] > 0.0:
        project_rs(P, T, cam, dist, rs, u0, v0, Z, lo, hi)
    else:
        project(P, T, cam, dist, u0, v0, Z, lo, hi)
    nv = sample(
        u0, v0, Z, cs, img, depth, scale, inv_tau2, mdw, use_depth, e, wz, inside, lo, hi
    )
    histogram(e, wz if over_kept else inside, 1.0, bins, hist, lo, hi)
    return nv


@njit(cache=True, nogil=True, parallel=True)
def _photometric_par(
    P: np.ndarray, T: np.ndarray, cam: np.ndarray, dist: np.ndarray, rs: np.ndarray,
    cs: np.ndarray, img: np.ndarray, depth: np.ndarray, scale: float, inv_tau2: float,
    mdw: float,
    use_depth: bool, u0: np.ndarray, v0: np.ndarray, Z: np.ndarray, e: np.ndarray,
    wz: np.ndarray, inside: np.ndarray, over_kept: bool, bins: np.ndarray, hists: np.ndarray,
    nv: np.ndarray, m: int,
) -> None:
    """:func:`_photometric_chunk` over ``hists.shape[0]`` chunks in parallel (per-chunk
    histograms, merged by the caller)."""
    nc = hists.shape[0]
    for c in prange(nc):
        hists[c, :] = 0
        nv[c] = _photometric_chunk(
            P, T, cam, dist, rs, cs, img, depth, scale, inv_tau2, mdw, use_depth, u0, v0, Z,
            e, wz, inside, over_kept, bins, hists[c], c * m // nc, (c + 1) * m // nc,
        )


@njit(cache=True, nogil=True, parallel=True)
def _accumulate_par(
    J: np.ndarray, e: np.ndarray, cs: np.ndarray, wz: np.ndarray, a: float, b: float,
    beta: float, inv: float, accs: np.ndarray, m: int,
) -> None:
    """:func:`accumulate` over ``accs.shape[0]`` chunks in parallel (summed by the caller)."""
    nc = accs.shape[0]
    for c in prange(nc):
        accumulate(J, e, cs, wz, a, b, beta, inv, accs[c], c * m // nc, (c + 1) * m // nc)


@njit(cache=True, nogil=True)
def _photometric_pass(
    P: np.ndarray, T: np.ndarray, cam: np.ndarray, dist: np.ndarray, rs: np.ndarray,
    cs: np.ndarray, img: np.ndarray, depth: np.ndarray, scale: float, inv_tau2: float,
    mdw: float,
    use_depth: bool, u0: np.ndarray, v0: np.ndarray, Z: np.ndarray, e: np.ndarray,
    wz: np.ndarray, inside: np.ndarray, over_kept: bool, bins: np.ndarray, hist: np.ndarray,
    hists: np.ndarray, nv: np.ndarray, m: int,
) -> int:
    """One photometric evaluation of the first ``m`` points into ``e``, ``wz`` and the
    histogram ``hist``: on this thread (``hists`` with one row) or split over threads."""
    nc = hists.shape[0]
    if nc <= 1:
        hist[:] = 0
        return _photometric_chunk(
            P, T, cam, dist, rs, cs, img, depth, scale, inv_tau2, mdw, use_depth, u0, v0, Z,
            e, wz, inside, over_kept, bins, hist, m - m, m,  # 0, not the literal: module doc
        )
    _photometric_par(
        P, T, cam, dist, rs, cs, img, depth, scale, inv_tau2, mdw, use_depth, u0, v0, Z, e,
        wz, inside, over_kept, bins, hists, nv, m,
    )
    for k in range(hist.shape[0]):
        s = 0
        for c in range(nc):
            s += hists[c, k]
        hist[k] = s
    return int(nv.sum())


@njit(cache=True, nogil=True)
def _accumulate_pass(
    J: np.ndarray, e: np.ndarray, cs: np.ndarray, wz: np.ndarray, a: float, b: float,
    beta: float, inv: float, acc: np.ndarray, accs: np.ndarray, m: int,
) -> None:
    """:func:`accumulate` of the first ``m`` points into ``acc``, split like
    :func:`_photometric_pass`."""
    nc = accs.shape[0]
    if nc <= 1:
        accumulate(J, e, cs, wz, a, b, beta, inv, acc, m - m, m)  # 0 as a variable (module doc)
        return
    _accumulate_par(J, e, cs, wz, a, b, beta, inv, accs, m)
    for k in range(acc.shape[0]):
        s = 0.0
        for c in range(nc):
            s += accs[c, k]
        acc[k] = s


@njit(cache=True, nogil=True)
def _unpack(acc: np.ndarray, H: np.ndarray, g: np.ndarray) -> None:
    """H, g = the normal equations packed by :func:`accumulate`."""
    k = 0
    for a in range(6):
        for b in range(a, 6):
            H[a, b] = acc[k]
            H[b, a] = acc[k]
            k += 1
    for a in range(6):
        g[a] = acc[21 + a]


@njit(cache=True, nogil=True)
def _unpack_add(acc: np.ndarray, H: np.ndarray, g: np.ndarray, s: float) -> None:
    """H, g += s * (the normal equations packed by :func:`accumulate`). (Two functions, not
    a literal ``add`` flag: one specialisation each, see the module doc.)"""
    k = 0
    for a in range(6):
        for b in range(a, 6):
            v = s * acc[k]
            H[a, b] += v
            if b != a:
                H[b, a] += v
            k += 1
    for a in range(6):
        g[a] += s * acc[21 + a]


@njit(cache=True, nogil=True)
def _fit_gain(
    cs: np.ndarray, e: np.ndarray, wz: np.ndarray, beta0: float, scale0: float, m: int
) -> tuple[float, float]:
    """Robust affine brightness model c* = alpha I + beta (auto exposure changes gain and
    offset): Tukey-weighted least squares around the median offset ``beta0`` with the robust
    scale ``scale0`` of e - beta0."""
    inv = 1.0 / (TUKEY_C * max(scale0, 1e-3) * TUKEY_B)
    sw = swx = swy = swxx = swxy = 0.0
    for i in range(m):
        if not wz[i] > 0.0:
            continue
        u = abs(e[i] - beta0) * inv
        if u >= 1.0:
            continue
        t = 1.0 - u * u
        w = t * t * wz[i]
        x = cs[i] - e[i]  # I(w(P; T))
        y = cs[i]
        sw += w
        swx += w * x
        swy += w * y
        swxx += w * x * x
        swxy += w * x * y
    det = sw * swxx - swx * swx
    if sw <= 0.0 or det <= 1e-9 * sw * sw:
        return 1.0, beta0
    alpha = (sw * swxy - swx * swy) / det
    if not (0.5 < alpha < 2.0):
        return 1.0, beta0
    return alpha, (swy - alpha * swx) / sw


@njit(cache=True, nogil=True)
def _inverse(T: np.ndarray) -> np.ndarray:
    Ti = np.eye(4)
    for a in range(3):
        for b in range(3):
            Ti[a, b] = T[b, a]
    for a in range(3):
        Ti[a, 3] = -(T[0, a] * T[0, 3] + T[1, a] * T[1, 3] + T[2, a] * T[2, 3])
    return Ti


@njit(cache=True, nogil=True)
def _pixel_step(T: np.ndarray, dT: np.ndarray, fpx: float, z_typ: float) -> float:
    """Image motion (pixels, focal length ``fpx``) of the update ``T -> T dT``: the largest
    displacement of a 3x3 grid of points at depth ``z_typ`` spanning the view (pinhole)."""
    M = T @ dT @ _inverse(T)  # current-camera points before -> after the update
    worst = 0.0
    for gx in range(3):
        for gy in range(3):
            xn = 0.5 * (gx - 1)
            yn = 0.4 * (gy - 1)
            X = xn * z_typ
            Y = yn * z_typ
            Xq = M[0, 0] * X + M[0, 1] * Y + M[0, 2] * z_typ + M[0, 3]
            Yq = M[1, 0] * X + M[1, 1] * Y + M[1, 2] * z_typ + M[1, 3]
            Zq = M[2, 0] * X + M[2, 1] * Y + M[2, 2] * z_typ + M[2, 3]
            if Zq <= 1e-6:
                return np.inf
            du = Xq / Zq - xn
            dv = Yq / Zq - yn
            worst = max(worst, math.sqrt(du * du + dv * dv))
    return fpx * worst


# ---------------------------------------------------------------------------- Algorithm 1


@njit(cache=True, nogil=True)
def minimize(
    P: np.ndarray,
    cstar: np.ndarray,
    J: np.ndarray,
    img0: np.ndarray,
    img1: np.ndarray,
    img2: np.ndarray,
    depth: np.ndarray,
    cam: np.ndarray,
    dist: np.ndarray,
    scales: np.ndarray,
    iters: np.ndarray,
    level_n: np.ndarray,
    T0: np.ndarray,
    tau_m: float,
    missing_depth_weight: float,
    use_depth: bool,
    min_median: float,
    scale_over_kept: bool,
    brightness_offset: bool,
    brightness_gain: bool,
    Pg: np.ndarray,
    N: np.ndarray,
    Jg: np.ndarray,
    geo_weight: float,
    min_geo_scale: float,
    T_cd: np.ndarray,
    T_prev: np.ndarray,
    rs_cfg: np.ndarray,
    stop_px: float,
    z_typ: float,
    quality_scale: float,
    nthreads: int,
    w_out: np.ndarray,
    uv_out: np.ndarray,
    e_out: np.ndarray,
    steps_out: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Algorithm 1: coarse-to-fine inverse-compositional Gauss-Newton.

    ``P`` (3, n), ``cstar`` (3, n) and ``J`` (3, 6, n) are the reference points, intensities
    and the Jacobian of eq. (6) per level, computed once per reference. ``iters`` are per
    level 0..2 (fine to coarse); levels run 2 -> 0. Level L uses the first ``level_n[L]``
    points (all of them in the paper; fewer at the coarse levels is an option, the points are
    stored so that any prefix is spread over the image). Returns ``(T_cur_ref, stats)``, stats
    as named in :data:`STATS`; ``w_out`` (W of eq. (13)), ``uv_out`` (full-resolution warped
    pixels) and ``e_out`` (residual) are those of the last evaluation; ``steps_out[k]`` the
    pixel size of the k-th update.

    Options beyond the paper: ``brightness_offset`` (remove the median residual once per
    level), ``brightness_gain`` (affine model), ``stop_px`` > 0 (stop a level when an update
    moves the image by less than this many pixels of that level; the counts become caps),
    ``geo_weight`` > 0 adds the point-to-plane residual of :func:`sample_geometric` over the
    geometric points ``Pg`` (3, ng) (normals ``N`` (3, ng), Jacobian ``Jg`` (6, ng),
    ``T_cd`` moving the current depth to the colour instant), each
    term in units of its own robust (Tukey) scale, the geometric one times ``geo_weight``,
    at the finest level (0) only.
    ``nthreads`` > 1 splits the photometric passes over that many threads (numba prange).
    ``rs_cfg = (t_row, row0, dt)`` with ``t_row`` > 0 and ``dt`` > 0: a rolling-shutter colour
    camera (:func:`project_rs`), the camera's velocity taken before every photometric
    evaluation from the previous frame's pose ``T_prev`` (T_prev_ref) and the current estimate
    over ``dt`` seconds (:func:`rs_velocity`): the frame's own motion, not a prediction.

    Quality report: ``w_out`` and the inlier fraction (share of points with weight > 0.1) use
    the Tukey scale ``c * quality_scale`` when ``quality_scale`` > 0 (the sequence's typical
    median residual: an honest "agrees with the model" for a bad frame, whose own adaptive
    scale of eq. (9) grows with its residuals), else the last iteration's own scale; the
    share of W > 0.1 under the optimiser's own scale is ``weights_inlier_fraction``.
    """
    n = P.shape[1]
    T = T0.copy()
    u0 = np.zeros(n)
    v0 = np.zeros(n)
    Z = np.zeros(n)
    e = np.zeros(n)
    wz = np.zeros(n)
    inside = np.zeros(n)
    hist = np.zeros(2 * HIST_NB, dtype=np.int64)
    cum = np.zeros(2 * HIST_NB + 1, dtype=np.int64)
    bins = np.zeros(n, dtype=np.int32)
    acc = np.zeros(27)
    nc = max(1, nthreads)
    hists = np.zeros((nc, 2 * HIST_NB), dtype=np.int64)
    accs = np.zeros((nc, 27))
    nv = np.zeros(nc, dtype=np.int64)
    H = np.zeros((6, 6))
    g = np.zeros(6)
    ng = Pg.shape[1]
    use_geo = geo_weight > 0.0 and ng > 0 and N.shape[1] == ng and Jg.shape[1] == ng
    ngb = ng if use_geo else 1
    rg = np.zeros(ngb)
    wg = np.zeros(ngb)
    ug = np.zeros(ngb)
    vg = np.zeros(ngb)
    Zg = np.zeros(ngb)
    bins_g = np.zeros(ngb, dtype=np.int32)
    cells = np.zeros((4, ngb), dtype=np.float32)
    inv_tau2 = 1.0 / (tau_m * tau_m)
    beta = 0.0
    alpha = 1.0
    med = 0.0
    medg = 0.0
    scale = 1.0
    nvalid = 0
    nkeep = 0
    ok = True
    total_iters = 0
    last_step = 0.0
    last_lev = 0
    m_last = n
    stats = np.zeros(N_STATS)
    rs = np.zeros(8)
    use_rs = rs_cfg[0] > 0.0 and rs_cfg[2] > 0.0
    if use_rs:
        rs[0] = rs_cfg[0]
        rs[1] = rs_cfg[1]
    for lev in range(2, -1, -1):
        img = img0 if lev == 0 else (img1 if lev == 1 else img2)
        m = min(n, max(int(level_n[lev]), 12))
        Jl = J[lev]
        csl = cstar[lev]
        for it in range(iters[lev]):
            if use_rs:
                rs_velocity(T_prev, T, rs_cfg[2], rs)
            nvalid = _photometric_pass(
                P, T, cam, dist, rs, csl, img, depth, scales[lev], inv_tau2,
                missing_depth_weight, use_depth, u0, v0, Z, e, wz, inside, scale_over_kept,
                bins, hist, hists, nv, m,
            )
            last_lev = lev
            m_last = m
            nkeep = _cumulate(hist, cum)
            if nvalid < 12 or nkeep < 12:
                ok = False
                break
            if brightness_offset and it == 0:
                # global brightness change (auto exposure): the median signed residual of the
                # points the depth test keeps, once per level (an extension; the paper
                # assumes fixed studio lighting)
                beta = hist_median(cum, hist)
                alpha = 1.0
                if brightness_gain:
                    s0 = hist_median_abs(cum, hist, beta)
                    alpha, beta = _fit_gain(csl, e, wz, beta, s0, m)
            if alpha != 1.0:
                # r = alpha e + (1 - alpha) c* - beta has its own median: histogram it
                hist[:] = 0
                hmask = wz if scale_over_kept else inside
                for i in range(m):
                    if hmask[i] > 0.0:
                        hist[_hist_bin(alpha * e[i] + (1.0 - alpha) * csl[i] - beta)] += 1
                _cumulate(hist, cum)
                med = hist_median_abs(cum, hist, 0.0)
            else:
                # the median of eq. (9) over the points the depth test keeps: a presenter
                # rejected by eq. (12) must not inflate the Tukey scale for the background
                med = hist_median_abs(cum, hist, beta)
            # noise floor of the scale: on (near) noise-free images a tiny median would make
            # the informative high-gradient points outliers after sub-pixel misalignment
            scale = TUKEY_C * max(med, min_median, 1e-6)
            _accumulate_pass(
                Jl, e, csl, wz, alpha, 1.0 - alpha, beta, 1.0 / (scale * TUKEY_B), acc, accs, m
            )
            _unpack(acc, H, g)
            if use_geo and lev == 0:
                # combined photometric + point-to-plane (ICP-like) cost, each residual in
                # units of its own robust scale (an extension; the paper is photometric), at
                # the finest level only: the coarse photometric levels bring it into the
                # narrow basin of projective association (from 5 cm off on the studio rail it
                # held the pose where the walls and floor fit, 6 cm off, with a tiny scale)
                # (the geometric points: their own set, or the photometric ones)
                mg = min(ng, max(12, (ng * m) // n))
                M = _inverse(T) @ T_cd
                if use_rs:
                    # the current depth where its rows saw the points; Zg their depth
                    # there, so Q = (z / Zg) T P lies on the instant's ray (first order)
                    project_rs(Pg, T, cam, dist, rs, ug, vg, Zg, m - m, mg)
                else:
                    project(Pg, T, cam, dist, ug, vg, Zg, m - m, mg)
                gather_cells(ug, vg, depth, cells, m - m, mg)
                sample_geometric(ug, vg, Zg, Pg, N, cells, T, M, inv_tau2, rg, wg, m - m, mg)
                hist[:] = 0
                ngk = histogram(rg, wg, GEO_UNIT, bins_g, hist, m - m, mg)
                if ngk >= 12:
                    _cumulate(hist, cum)
                    medg = hist_median_abs(cum, hist, 0.0) / GEO_UNIT
                    scale_g = TUKEY_C * max(medg, min_geo_scale, 1e-9)
                    # (a float32 row with coefficient 0 in place of c*: the same argument
                    # types as the photometric call, one specialisation)
                    _accumulate_pass(
                        Jg, rg, Jg[0], wg, 1.0, 0.0, 0.0, 1.0 / (scale_g * TUKEY_B), acc,
                        accs, mg,
                    )
                    s_c = 1.0 / (scale * scale)
                    for a in range(6):
                        g[a] *= s_c
                        for b in range(6):
                            H[a, b] *= s_c
                    _unpack_add(acc, H, g, geo_weight / (scale_g * scale_g))
            for a in range(6):
                g[a] = -g[a]
            x, solved = _cholesky_solve6(H, g)
            if not solved:
                ok = False
                break
            for a in range(6):
                if not math.isfinite(x[a]):
                    ok = False
            if not ok:
                break
            dT = _se3_exp(x)
            step = _pixel_step(T, dT, cam[0] * scales[lev], z_typ)
            T = T @ dT  # T^ <- T^ e^{A(x)}, sec. 3.1
            if total_iters < steps_out.shape[0]:
                steps_out[total_iters] = step
            last_step = step
            total_iters += 1
            if step < stop_px:
                break  # converged at this level: the counts are a cap
        if not ok:
            break
    # W = w_c w_z (eq. (13)) and the residuals of the last evaluation, full resolution pixels
    inv = 1.0 / (scale * TUKEY_B)
    qinv = 1.0 / (TUKEY_C * quality_scale * TUKEY_B) if quality_scale > 0.0 else inv
    sw = 0.0
    swe = 0.0
    ninl = 0
    nq = 0
    for i in range(n):
        if i >= m_last:
            w_out[i] = 0.0
            e_out[i] = 0.0
            uv_out[i, 0] = -1.0
            uv_out[i, 1] = -1.0
            continue
        r = alpha * e[i] + (1.0 - alpha) * cstar[last_lev, i] - beta
        u = r * inv
        t = max(1.0 - u * u, 0.0)
        wi = t * t * wz[i]
        uq = r * qinv
        tq = max(1.0 - uq * uq, 0.0)
        wq = tq * tq * wz[i]
        w_out[i] = wq
        e_out[i] = r if wz[i] > 0.0 else 0.0
        uv_out[i, 0] = u0[i]
        uv_out[i, 1] = v0[i]
        if wq > 0.1:
            nq += 1
        if wi > 0.0:
            sw += wi
            swe += wi * r * r
            if wi > 0.1:
                ninl += 1
    stats[0] = med
    stats[1] = nvalid / max(m_last, 1)
    stats[2] = nq / max(m_last, 1)
    stats[3] = math.sqrt(swe / sw) if sw > 0.0 else np.inf
    stats[4] = 1.0 if ok else 0.0
    stats[5] = total_iters
    stats[6] = last_step
    stats[7] = beta
    stats[8] = alpha
    stats[9] = medg
    stats[10] = nkeep
    stats[11] = ninl / max(m_last, 1)
    return T, stats


# ------------------------------------------------------------------ reference precomputation


@njit(cache=True, nogil=True)
def precompute_reference(
    P: np.ndarray,
    img0: np.ndarray,
    img1: np.ndarray,
    img2: np.ndarray,
    cam: np.ndarray,
    dist: np.ndarray,
    scales: np.ndarray,
    cstar: np.ndarray,
    J: np.ndarray,
) -> None:
    """Reference intensities and the Jacobian of eq. (6), once per reference and level.

    ``P`` (3, n); ``cstar`` (3, n) and ``J`` (3, 6, n) are filled. J_i = grad I*(w(P_i; I)) .
    d w(e^{-A(x)} P_i)/dx at x = 0, including the lens distortion of eq. (3)-(4) in the warp
    derivative. Image gradients are central differences of the bilinearly interpolated image.
    Points outside a level's image get c* = 0 and J = 0.
    """
    fx, fy, cx, cy = cam[0], cam[1], cam[2], cam[3]
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    for lev in range(3):
        img = img0 if lev == 0 else (img1 if lev == 1 else img2)
        s = scales[lev]
        h, w = img.shape
        for i in range(P.shape[1]):
            X, Y, Z = np.float64(P[0, i]), np.float64(P[1, i]), np.float64(P[2, i])
            xn = X / Z
            yn = Y / Z
            r2 = xn * xn + yn * yn
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn)
            yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn
            uL = (fx * xd + cx + 0.5) * s - 0.5
            vL = (fy * yd + cy + 0.5) * s - 0.5
            if not (uL >= 1.0 and vL >= 1.0 and uL < w - 2.0 and vL < h - 2.0):
                cstar[lev, i] = 0.0
                for a in range(6):
                    J[lev, a, i] = 0.0
                continue
            cstar[lev, i] = _bilinear(img, uL, vL)
            gu = 0.5 * (_bilinear(img, uL + 1.0, vL) - _bilinear(img, uL - 1.0, vL))
            gv = 0.5 * (_bilinear(img, uL, vL + 1.0) - _bilinear(img, uL, vL - 1.0))
            # d radial / d xn, yn
            dr = k1 + 2.0 * k2 * r2 + 3.0 * k3 * r2 * r2
            dxd_dx = radial + 2.0 * xn * xn * dr + 2.0 * p1 * yn + 6.0 * p2 * xn
            dxd_dy = 2.0 * xn * yn * dr + 2.0 * p1 * xn + 2.0 * p2 * yn
            dyd_dx = 2.0 * xn * yn * dr + 2.0 * p1 * xn + 2.0 * p2 * yn
            dyd_dy = radial + 2.0 * yn * yn * dr + 6.0 * p1 * yn + 2.0 * p2 * xn
            # image gradient (level px) . d uv_L / d (xn, yn)
            gx = gu * fx * s * dxd_dx + gv * fy * s * dyd_dx
            gy = gu * fx * s * dxd_dy + gv * fy * s * dyd_dy
            # d (xn, yn) / d P
            iz = 1.0 / Z
            dPx = gx * iz
            dPy = gy * iz
            dPz = -(gx * xn + gy * yn) * iz
            # d (e^{-A(x)} P)/dx at 0 = [-I | [P]x]
            J[lev, 0, i] = -dPx
            J[lev, 1, i] = -dPy
            J[lev, 2, i] = -dPz
            # [P]x w : rows (0,-Z,Y),(Z,0,-X),(-Y,X,0); gradient . ([P]x) column-wise
            J[lev, 3, i] = dPy * Z - dPz * Y
            J[lev, 4, i] = -dPx * Z + dPz * X
            J[lev, 5, i] = dPx * Y - dPy * X


# ------------------------------------------------------------------------ image pyramid


@njit(cache=True, nogil=True)
def pyramid_u8(g: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sec. 4.6 pyramid of an 8-bit grey image (``engine.dense.pyramid``): level 0 is the
    5x5 Gaussian (1 4 6 4 1 / 16, reflect-101 border) of the full image averaged over 2x2
    blocks, i.e. the 6-tap filter (1 5 10 10 5 1) / 32 at every second pixel in each
    direction, computed at level-0 resolution only; levels 1 and 2 are 2x2 block means.
    The same as OpenCV's full-resolution filter then area resize, to float round-off."""
    h, w = g.shape
    h2, w2 = h // 2, w // 2
    k0, k1, k2 = 1.0 / 32.0, 5.0 / 32.0, 10.0 / 32.0
    tmp = np.empty((h, w2), dtype=np.float32)
    for r in range(np.uint64(0), np.uint64(h)):
        row = g[r]
        # interior: columns 2x-2 .. 2x+3 inside the image
        for x in range(np.uint64(1), np.uint64(max(w2 - 1, 1))):
            c = x + x
            tmp[r, x] = (k0 * (np.float32(row[c - 2]) + np.float32(row[c + 3]))
                         + k1 * (np.float32(row[c - 1]) + np.float32(row[c + 2]))
                         + k2 * (np.float32(row[c]) + np.float32(row[c + 1])))
        for x in (0, w2 - 1):  # borders: reflect-101 (-1 -> 1, w -> w - 2)
            acc = 0.0
            for j in range(6):
                c = 2 * x - 2 + j
                c = -c if c < 0 else (2 * (w - 1) - c if c >= w else c)
                kj = k0 if (j == 0 or j == 5) else (k1 if (j == 1 or j == 4) else k2)
                acc += kj * float(row[c])
            tmp[r, x] = acc
    l0 = np.empty((h2, w2), dtype=np.float32)
    for y in range(h2):
        rows = np.empty(6, dtype=np.int64)
        for j in range(6):
            rr = 2 * y - 2 + j
            rows[j] = -rr if rr < 0 else (2 * (h - 1) - rr if rr >= h else rr)
        a0, a1, a2 = tmp[rows[0]], tmp[rows[1]], tmp[rows[2]]
        a3, a4, a5 = tmp[rows[3]], tmp[rows[4]], tmp[rows[5]]
        out = l0[y]
        for x in range(np.uint64(0), np.uint64(w2)):
            out[x] = k0 * (a0[x] + a5[x]) + k1 * (a1[x] + a4[x]) + k2 * (a2[x] + a3[x])
    return l0, _half(l0), _half(_half(l0))


@njit(cache=True, nogil=True)
def _half(a: np.ndarray) -> np.ndarray:
    """2x2 block means (an odd last row or column is dropped), OpenCV's INTER_AREA at half
    size."""
    h, w = a.shape[0] // 2, a.shape[1] // 2
    out = np.empty((h, w), dtype=np.float32)
    for y in range(h):
        r0 = a[2 * y]
        r1 = a[2 * y + 1]
        o = out[y]
        for x in range(np.uint64(0), np.uint64(w)):
            c = x + x
            o[x] = np.float32(0.25) * ((r0[c] + r0[c + 1]) + (r1[c] + r1[c + 1]))
    return out
