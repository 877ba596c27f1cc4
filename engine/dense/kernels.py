"""Numba kernels of the dense RGB-D tracker (Tykkälä 2014, Algorithm 1).

Imported lazily (by :mod:`engine.dense.photometric` when a tracker is built) so that tracker
discovery stays fast. ``cache=True`` keeps the compiled code between runs.

Conventions: a reference point ``P`` (metres, reference camera frame) is warped by
``T_cur_ref`` (the base transform T^ of eq. (1)) and projected with eq. (2)-(4) into
full-resolution pixels ``(u0, v0)``; pyramid level L (0 = 320x240 for a 640x480 input) uses
pixel-centre scaling ``u_L = (u0 + 0.5) * s_L - 0.5`` (sec. 4.6) with ``s_L = 2^-(L+1)``.
Twists are ``x = (v, w)``, translation first (engine.geometry).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Tukey constants, eq. (9)-(10).
TUKEY_C = 1.4826
TUKEY_B = 4.6851
N_HIST_BINS = 64  # sec. 4.2: 64-bin histogram median


@njit(cache=True, inline="always")
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


@njit(cache=True, inline="always")
def _project_full(
    X: float, Y: float, Z: float, fx: float, fy: float, cx: float, cy: float, dist: np.ndarray
) -> tuple[float, float]:
    """Eq. (2)-(4): u = K D(N(p), alpha) at full resolution."""
    xn = X / Z
    yn = Y / Z
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    r2 = xn * xn + yn * yn
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn)
    yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn
    return fx * xd + cx, fy * yd + cy


@njit(cache=True, nogil=True)
def histogram_median(a: np.ndarray, mask: np.ndarray, nbins: int) -> float:
    """Approximate median of ``a[mask]`` (non-negative) with two ``nbins`` histograms.

    Sec. 4.2: the median of eq. (9) from a 64-bin histogram (the GPU's histogram64); a second
    64-bin histogram inside the median bin refines it to 1/4096 of the range.
    """
    n = 0
    hi = 0.0
    for i in range(a.shape[0]):
        if mask[i]:
            n += 1
            if a[i] > hi:
                hi = a[i]
    return _histogram_median_known(a, mask, n, hi, nbins)


@njit(cache=True, nogil=True)
def _histogram_median_known(
    a: np.ndarray, mask: np.ndarray, n: int, hi: float, nbins: int
) -> float:
    """:func:`histogram_median` with the count ``n`` and maximum ``hi`` of ``a[mask]`` known."""
    if n == 0:
        return 0.0
    if hi <= 0.0:
        return 0.0
    half = (n + 1) // 2  # rank of the (lower) median
    lo = 0.0
    width = hi / nbins
    below = 0
    for _pass in range(2):
        h = np.zeros(nbins, dtype=np.int64)
        for i in range(a.shape[0]):
            if mask[i]:
                b = int((a[i] - lo) / width)
                if b < 0:
                    continue
                if b >= nbins:
                    if _pass == 0:
                        b = nbins - 1
                    else:
                        continue
                h[b] += 1
        cum = below
        k = nbins - 1
        for j in range(nbins):
            if cum + h[j] >= half:
                k = j
                break
            cum += h[j]
        below = cum
        lo = lo + k * width
        if _pass == 0:
            width = width / nbins
        else:
            return lo + 0.5 * width
    return lo


@njit(cache=True, inline="always")
def _abs_and_keep(
    r: np.ndarray, valid: np.ndarray, wz: np.ndarray, r_abs: np.ndarray, keep: np.ndarray
) -> tuple[int, float]:
    """|r| into ``r_abs``; ``keep`` = valid and depth weight > 0 (eq. 12).

    Returns the kept count and the largest kept |r| (the histogram range of eq. 9).
    """
    n_keep = 0
    hi = 0.0
    for i in range(r.shape[0]):
        a_i = abs(r[i])
        r_abs[i] = a_i
        k_i = valid[i] and wz[i] > 0.0
        keep[i] = k_i
        if k_i:
            n_keep += 1
            if a_i > hi:
                hi = a_i
    return n_keep, hi


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


@njit(cache=True, fastmath=True, nogil=True)
def _accumulate(
    Jl: np.ndarray, e: np.ndarray, e_abs: np.ndarray, wz: np.ndarray, keep: np.ndarray,
    scale: float, wc: np.ndarray, H: np.ndarray, g: np.ndarray,
) -> None:
    """Tukey weights (eq. (9)-(10)) fused with the weighted normal equations of eq. (13):
    H = J^T W J (upper triangle, mirrored), g = J^T W e (sec. 4.3)."""
    h00 = h01 = h02 = h03 = h04 = h05 = 0.0
    h11 = h12 = h13 = h14 = h15 = 0.0
    h22 = h23 = h24 = h25 = 0.0
    h33 = h34 = h35 = 0.0
    h44 = h45 = 0.0
    h55 = 0.0
    g0 = g1 = g2 = g3 = g4 = g5 = 0.0
    inv = 1.0 / (scale * TUKEY_B)
    for i in range(e.shape[0]):
        w = 0.0
        if keep[i]:
            u = e_abs[i] * inv  # u / b of eq. (9)-(10)
            if u < 1.0:
                t = 1.0 - u * u
                w = t * t * wz[i]
        wc[i] = w
        if w == 0.0:
            continue
        j0 = Jl[i, 0]
        j1 = Jl[i, 1]
        j2 = Jl[i, 2]
        j3 = Jl[i, 3]
        j4 = Jl[i, 4]
        j5 = Jl[i, 5]
        we = w * e[i]
        g0 += j0 * we
        g1 += j1 * we
        g2 += j2 * we
        g3 += j3 * we
        g4 += j4 * we
        g5 += j5 * we
        w0 = w * j0
        w1 = w * j1
        w2 = w * j2
        w3 = w * j3
        w4 = w * j4
        h00 += w0 * j0
        h01 += w0 * j1
        h02 += w0 * j2
        h03 += w0 * j3
        h04 += w0 * j4
        h05 += w0 * j5
        h11 += w1 * j1
        h12 += w1 * j2
        h13 += w1 * j3
        h14 += w1 * j4
        h15 += w1 * j5
        h22 += w2 * j2
        h23 += w2 * j3
        h24 += w2 * j4
        h25 += w2 * j5
        h33 += w3 * j3
        h34 += w3 * j4
        h35 += w3 * j5
        h44 += w4 * j4
        h45 += w4 * j5
        h55 += w * j5 * j5
    vals = (h00, h01, h02, h03, h04, h05, h11, h12, h13, h14, h15, h22, h23, h24, h25,
            h33, h34, h35, h44, h45, h55)
    k = 0
    for a in range(6):
        for b in range(a, 6):
            H[a, b] = vals[k]
            H[b, a] = vals[k]
            k += 1
    g[0] = g0
    g[1] = g1
    g[2] = g2
    g[3] = g3
    g[4] = g4
    g[5] = g5


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
                if s <= 1e-12:
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


@njit(cache=True, nogil=True)
def evaluate(
    P: np.ndarray,
    cstar: np.ndarray,
    img: np.ndarray,
    depth: np.ndarray,
    T: np.ndarray,
    cam: np.ndarray,
    dist: np.ndarray,
    scale: float,
    tau_m: float,
    missing_depth_weight: float,
    use_depth: bool,
    e: np.ndarray,
    wz: np.ndarray,
    valid: np.ndarray,
    uv: np.ndarray,
) -> int:
    """Residual of eq. (1) and depth weights of eq. (11)-(12) for every point at one level.

    ``cam`` = (fx, fy, cx, cy) at full resolution; ``depth`` is the full-resolution depth
    map (metres, 0 invalid) sampled at the nearest pixel (no resampling across edges).
    Returns the number of valid (projected inside the image) points.
    """
    fx, fy, cx, cy = cam[0], cam[1], cam[2], cam[3]
    h, w = img.shape
    hd, wd = depth.shape
    nvalid = 0
    for i in range(P.shape[0]):
        X = T[0, 0] * P[i, 0] + T[0, 1] * P[i, 1] + T[0, 2] * P[i, 2] + T[0, 3]
        Y = T[1, 0] * P[i, 0] + T[1, 1] * P[i, 1] + T[1, 2] * P[i, 2] + T[1, 3]
        Z = T[2, 0] * P[i, 0] + T[2, 1] * P[i, 1] + T[2, 2] * P[i, 2] + T[2, 3]
        if Z <= 1e-3:
            valid[i] = False
            e[i] = 0.0
            wz[i] = 0.0
            uv[i, 0] = -1.0
            uv[i, 1] = -1.0
            continue
        u0, v0 = _project_full(X, Y, Z, fx, fy, cx, cy, dist)
        uv[i, 0] = u0
        uv[i, 1] = v0
        uL = (u0 + 0.5) * scale - 0.5
        vL = (v0 + 0.5) * scale - 0.5
        if not (uL >= 0.0 and vL >= 0.0 and uL < w - 1.0 and vL < h - 1.0):
            valid[i] = False
            e[i] = 0.0
            wz[i] = 0.0
            continue
        valid[i] = True
        nvalid += 1
        # eq. (1) in inverse-compositional form: e = c*(0) - I(w(P; T^))
        e[i] = cstar[i] - _bilinear(img, uL, vL)
        if use_depth:
            ui = int(u0 + 0.5)
            vi = int(v0 + 0.5)
            zc = 0.0
            if ui >= 0 and vi >= 0 and ui < wd and vi < hd:
                zc = depth[vi, ui]
            if zc > 0.0:
                ez = zc - Z  # eq. (11)
                t = 1.0 - ez * ez / (tau_m * tau_m)
                wz[i] = t * t if t > 0.0 else 0.0  # eq. (12)
            else:
                wz[i] = missing_depth_weight
        else:
            wz[i] = 1.0
    return nvalid


@njit(cache=True, nogil=True)
def _fit_gain(
    cs: np.ndarray, e: np.ndarray, valid: np.ndarray, wz: np.ndarray, beta0: float,
    tmp: np.ndarray,
) -> tuple[float, float]:
    """Robust affine brightness model c* = alpha I + beta (auto exposure changes gain and
    offset): Tukey-weighted least squares around the median offset ``beta0``."""
    cnt = 0
    for i in range(e.shape[0]):
        if valid[i] and wz[i] > 0.0:
            tmp[cnt] = abs(e[i] - beta0)
            cnt += 1
    med = np.median(tmp[:cnt])
    inv = 1.0 / (TUKEY_C * max(med, 1e-3) * TUKEY_B)
    sw = swx = swy = swxx = swxy = 0.0
    for i in range(e.shape[0]):
        if not (valid[i] and wz[i] > 0.0):
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
def evaluate_geometric(
    P: np.ndarray,
    N: np.ndarray,
    depth: np.ndarray,
    rays: np.ndarray,
    T: np.ndarray,
    T_cd: np.ndarray,
    valid: np.ndarray,
    uv: np.ndarray,
    r: np.ndarray,
    gvalid: np.ndarray,
) -> int:
    """Point-to-plane residual r = n . (T^-1 Q - P) in the reference frame, Q the current
    depth point at the nearest full-resolution pixel of the warped point (projective
    association, as ICP). Returns the number of points with a residual."""
    hd, wd = depth.shape
    # M = T^-1 T_cd: current depth-camera points (depth instant) into the reference frame
    Ti = np.eye(4)
    for a in range(3):
        for b in range(3):
            Ti[a, b] = T[b, a]
    for a in range(3):
        Ti[a, 3] = -(T[0, a] * T[0, 3] + T[1, a] * T[1, 3] + T[2, a] * T[2, 3])
    M = Ti @ T_cd
    R00, R01, R02, t0 = M[0, 0], M[0, 1], M[0, 2], M[0, 3]
    R10, R11, R12, t1 = M[1, 0], M[1, 1], M[1, 2], M[1, 3]
    R20, R21, R22, t2 = M[2, 0], M[2, 1], M[2, 2], M[2, 3]
    cnt = 0
    for i in range(P.shape[0]):
        gvalid[i] = False
        r[i] = 0.0
        if not valid[i]:
            continue
        if N[i, 0] == 0.0 and N[i, 1] == 0.0 and N[i, 2] == 0.0:
            continue
        ui = int(uv[i, 0] + 0.5)
        vi = int(uv[i, 1] + 0.5)
        if ui < 0 or vi < 0 or ui >= wd or vi >= hd:
            continue
        z = depth[vi, ui]
        if not z > 0.0:
            continue
        X = rays[vi, ui, 0] * z
        Y = rays[vi, ui, 1] * z
        qx = R00 * X + R01 * Y + R02 * z + t0
        qy = R10 * X + R11 * Y + R12 * z + t1
        qz = R20 * X + R21 * Y + R22 * z + t2
        r[i] = N[i, 0] * (qx - P[i, 0]) + N[i, 1] * (qy - P[i, 1]) + N[i, 2] * (qz - P[i, 2])
        gvalid[i] = True
        cnt += 1
    return cnt


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
    T0: np.ndarray,
    tau_m: float,
    missing_depth_weight: float,
    use_depth: bool,
    min_median: float,
    brightness_offset: bool,
    w_out: np.ndarray,
    uv_out: np.ndarray,
    e_out: np.ndarray,
    N: np.ndarray,
    Jg: np.ndarray,
    rays: np.ndarray,
    geo_weight: float,
    min_geo_scale: float,
    T_cd: np.ndarray,
    brightness_gain: bool,
    step_tol: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Algorithm 1: coarse-to-fine inverse-compositional Gauss-Newton.

    ``cstar`` (3, n) and ``J`` (3, n, 6) are the reference intensities and the Jacobian of
    eq. (6) per level, computed once per reference. ``iters`` are per level 0..2 (fine to
    coarse); levels run 2 -> 0. Returns ``(T_cur_ref, stats)`` with stats =
    (median |e|, valid fraction, inlier fraction, weighted RMS, ok, iterations, step norm,
    brightness offset, brightness gain). Options beyond the paper: ``brightness_gain``
    (affine model), ``step_tol`` (stop a level when |x| falls below it), ``geo_weight`` > 0
    adds the point-to-plane residual of :func:`evaluate_geometric` (normals ``N``, Jacobian
    ``Jg``, full-resolution rays, ``T_cd`` moving the current depth to the colour instant),
    each residual scaled by its own robust (Tukey) scale.
    """
    n = P.shape[0]
    T = T0.copy()
    e = np.zeros(n)
    e_abs = np.zeros(n)
    wz = np.zeros(n)
    wc = np.zeros(n)
    valid = np.zeros(n, dtype=np.bool_)
    keep = np.zeros(n, dtype=np.bool_)
    tmp = np.zeros(n)
    beta = 0.0
    alpha = 1.0
    stats = np.zeros(9)
    ok = True
    total_iters = 0
    med = 0.0
    nvalid = 0
    last_step = 0.0
    H = np.zeros((6, 6))
    g = np.zeros(6)
    Hg = np.zeros((6, 6))
    gg = np.zeros(6)
    rg = np.zeros(n)
    rg_abs = np.zeros(n)
    gvalid = np.zeros(n, dtype=np.bool_)
    gkeep = np.zeros(n, dtype=np.bool_)
    wg = np.zeros(n)
    use_geo = geo_weight > 0.0 and N.shape[0] == n
    for lev in range(2, -1, -1):
        img = img0 if lev == 0 else (img1 if lev == 1 else img2)
        for _it in range(iters[lev]):
            nvalid = evaluate(
                P, cstar[lev], img, depth, T, cam, dist, scales[lev], tau_m,
                missing_depth_weight, use_depth, e, wz, valid, uv_out,
            )
            if nvalid < 12:
                ok = False
                break
            if brightness_offset:
                # global brightness change (auto exposure): remove the median signed residual
                # of the points the depth test keeps, estimated once per level (an extension;
                # the paper assumes fixed studio lighting)
                if _it == 0:
                    cnt = 0
                    for i in range(n):
                        if valid[i] and wz[i] > 0.0:
                            tmp[cnt] = e[i]
                            cnt += 1
                    beta = np.median(tmp[:cnt]) if cnt >= 12 else 0.0
                    alpha = 1.0
                    if brightness_gain and cnt >= 12:
                        alpha, beta = _fit_gain(cstar[lev], e, valid, wz, beta, tmp)
                if alpha != 1.0:
                    cs = cstar[lev]
                    for i in range(n):
                        e[i] = cs[i] - alpha * (cs[i] - e[i]) - beta
                else:
                    for i in range(n):
                        e[i] -= beta
            # The median of eq. (9) over the points the depth test keeps: a presenter
            # rejected by eq. (12) must not inflate the Tukey scale for the background.
            nkeep, hi = _abs_and_keep(e, valid, wz, e_abs, keep)
            if nkeep < 12:
                ok = False
                break
            med = _histogram_median_known(e_abs, keep, nkeep, hi, N_HIST_BINS)
            # noise floor of the scale: on (near) noise-free images a tiny median would make
            # the informative high-gradient points outliers after sub-pixel misalignment
            scale = TUKEY_C * max(med, min_median, 1e-6)
            _accumulate(J[lev], e, e_abs, wz, keep, scale, wc, H, g)
            if use_geo:
                # combined photometric + point-to-plane (ICP-like) cost, each residual in
                # units of its own robust scale (an extension; the paper is photometric)
                evaluate_geometric(P, N, depth, rays, T, T_cd, valid, uv_out, rg, gvalid)
                ngk, hig = _abs_and_keep(rg, gvalid, wz, rg_abs, gkeep)
                if ngk >= 12:
                    medg = _histogram_median_known(rg_abs, gkeep, ngk, hig, N_HIST_BINS)
                    scale_g = TUKEY_C * max(medg, min_geo_scale, 1e-9)
                    _accumulate(Jg, rg, rg_abs, wz, gkeep, scale_g, wg, Hg, gg)
                    a_c = 1.0 / (scale * scale)
                    a_g = geo_weight / (scale_g * scale_g)
                    for a in range(6):
                        g[a] = a_c * g[a] + a_g * gg[a]
                        for b in range(6):
                            H[a, b] = a_c * H[a, b] + a_g * Hg[a, b]
            x, solved = _cholesky_solve6(H, -g)
            if not solved:
                ok = False
                break
            for a in range(6):
                if not math.isfinite(x[a]):
                    ok = False
            if not ok:
                break
            T = T @ _se3_exp(x)  # T^ <- T^ e^{A(x)}, sec. 3.1
            last_step = math.sqrt(np.sum(x * x))
            total_iters += 1
            if last_step < step_tol:
                break  # converged at this level: the counts are a cap
        if not ok:
            break
    sw = 0.0
    swe = 0.0
    ninl = 0
    for i in range(n):
        wi = wc[i] if keep[i] else 0.0  # W = w_c w_z (eq. (13)), from _accumulate
        w_out[i] = wi
        e_out[i] = e[i]
        if wi > 0.0:
            sw += wi
            swe += wi * e[i] * e[i]
            if wi > 0.1:
                ninl += 1
    stats[0] = med
    stats[1] = nvalid / max(n, 1)
    stats[2] = ninl / max(n, 1)
    stats[3] = math.sqrt(swe / sw) if sw > 0.0 else np.inf
    stats[4] = 1.0 if ok else 0.0
    stats[5] = total_iters
    stats[6] = last_step
    stats[7] = beta
    stats[8] = alpha
    return T, stats


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

    J_i = grad I*(w(P_i; I)) . d w(e^{-A(x)} P_i)/dx at x = 0, including the lens distortion
    of eq. (3)-(4) in the warp derivative. Image gradients are central differences of the
    bilinearly interpolated image. Points outside a level's image get c* = 0 and J = 0.
    """
    fx, fy, cx, cy = cam[0], cam[1], cam[2], cam[3]
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    for lev in range(3):
        img = img0 if lev == 0 else (img1 if lev == 1 else img2)
        s = scales[lev]
        h, w = img.shape
        for i in range(P.shape[0]):
            X, Y, Z = P[i, 0], P[i, 1], P[i, 2]
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
                    J[lev, i, a] = 0.0
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
            J[lev, i, 0] = -dPx
            J[lev, i, 1] = -dPy
            J[lev, i, 2] = -dPz
            # [P]x w : rows (0,-Z,Y),(Z,0,-X),(-Y,X,0); gradient . ([P]x) column-wise
            J[lev, i, 3] = dPy * Z - dPz * Y
            J[lev, i, 4] = -dPx * Z + dPz * X
            J[lev, i, 5] = dPx * Y - dPy * X
