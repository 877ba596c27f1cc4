"""Equation-level tests of the dense tracker (Tykkälä 2014 sec. 3-4)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from engine.camera import project
from engine.dense import kernels, robust
from engine.dense import photometric as ph
from engine.dense.pyramid import build_pyramid, level_scales
from engine.dense.selection import N_BINS, gradient_magnitude, select_points, threshold_bin
from engine.dense.testscene import PlaneScene, Quad, small_intrinsics
from engine.geometry import hat, invert, rotation_angle_rad, se3_exp


def test_histogram_median_matches_direct_median() -> None:
    """The residual histogram (uniform in sign(e) sqrt|e|) gives the median of e, the median
    of |e - offset| (the scale of eq. (9)) and survives gross outliers."""
    rng = np.random.default_rng(1)
    for scale in (0.05, 3.0, 30.0):
        e = rng.laplace(1.5 * scale, scale, 4001)
        e[:40] = 250.0  # gross outliers
        e[40:60] = -300.0  # beyond the histogram range: counted in the last bin
        mask = np.ones(e.size, dtype=bool)
        mask[60:80] = False
        med = float(np.median(e[mask]))
        assert abs(kernels.histogram_median(e, mask) - med) < 0.02 * abs(med) + 1e-3
        mad = float(np.median(np.abs(e[mask] - med)))
        got = kernels.histogram_median_abs(e, mask, med)
        assert abs(got - mad) < 0.02 * mad + 1e-3, (scale, got, mad)
    assert kernels.histogram_median(e, np.zeros(e.size, dtype=bool)) == 0.0


def test_tukey_weights_with_histogram_median_match_direct_median() -> None:
    """Eq. (9)-(10) with the histogram median vs NumPy's exact median."""
    rng = np.random.default_rng(2)
    e = rng.normal(0.0, 4.0, 8192)
    e[::10] += rng.uniform(-120, 120, e[::10].size)  # 10 % outliers
    mask = np.ones(e.size, dtype=bool)
    w = np.zeros(e.size)
    med_h = kernels.histogram_median_abs(e, mask, 0.0)
    kernels.tukey_weights(np.abs(e), mask, med_h, w)
    w_ref = robust.tukey_weights(e)
    assert np.max(np.abs(w - w_ref)) < 0.02
    # the Tukey shape itself: weight 1 at zero, 0 beyond b * c * median
    med = float(np.median(np.abs(e)))
    w0 = robust.tukey_weights(np.array([0.0, 4.6851 * 1.4826 * med * 1.0001]), med)
    np.testing.assert_allclose(w0, [1.0, 0.0])
    # masked points get zero weight
    mask[:5] = False
    kernels.tukey_weights(np.abs(e), mask, med_h, w)
    assert np.all(w[:5] == 0.0)
    # the tracker's fused kernel (Tukey x depth weight, then eq. (13)) gives the same
    # normal equations; wz = 0 is how the kernels mark points the depth test drops
    J = np.zeros((6, e.size), dtype=np.float32)
    J[0] = 1.0
    J[3] = rng.normal(size=e.size)
    wz = np.where(mask, 0.5, 0.0)
    beta = 0.7
    acc = np.zeros(27)
    scale = kernels.TUKEY_C * med_h
    kernels.accumulate(J, e + beta, np.zeros(e.size), wz, 1.0, 0.0, beta,
                       1.0 / (scale * kernels.TUKEY_B), acc, 0, e.size)
    w_ref = 0.5 * robust.tukey_weights(e, med_h) * mask
    assert acc[0] == pytest.approx(w_ref.sum())  # H[0, 0]
    assert acc[3] == pytest.approx(float(np.sum(w_ref * J[3])))  # H[0, 3]
    assert acc[15] == pytest.approx(float(np.sum(w_ref * J[3] ** 2)))  # H[3, 3]
    assert acc[21] == pytest.approx(float(np.sum(w_ref * e)))  # g[0]
    assert acc[24] == pytest.approx(float(np.sum(w_ref * J[3] * e)))  # g[3]


def test_depth_weights_eq12() -> None:
    w = robust.depth_weights(np.array([1.0, 1.02, 1.2]), np.array([1.0, 1.0, 1.0]), 0.05)
    np.testing.assert_allclose(w, [1.0, (1 - 0.16) ** 2, 0.0])


@pytest.mark.parametrize("n", [1, 100, 1000, 1024, 3000])
def test_histogram_selection_returns_exactly_n(n: int) -> None:
    rng = np.random.default_rng(n)
    img = rng.uniform(0, 255, (60, 80)).astype(np.float32)
    img = (img + np.roll(img, 1, 0) + np.roll(img, 1, 1)) / 3  # ties in many bins
    g = gradient_magnitude(img)
    cand = rng.uniform(size=g.shape) > 0.2
    idx = select_points(g, cand, n)
    assert idx.size == n
    assert np.unique(idx).size == n
    assert cand.ravel()[idx].all()
    # eq. (15): every candidate in a bin above B_t is selected (P_good)
    bins = np.clip((g.ravel() * 0.5).astype(int), 0, N_BINS - 1)
    h = np.bincount(bins[cand.ravel()], minlength=N_BINS)
    bt = threshold_bin(h, n)
    good = np.flatnonzero(cand.ravel() & (bins > bt))
    assert np.isin(good, idx).all()
    assert h[bt + 1 :].sum() < n <= h[bt:].sum()


def test_selection_with_fewer_candidates_returns_all() -> None:
    g = np.ones((10, 10), np.float32)
    cand = np.zeros((10, 10), bool)
    cand[2, 3:7] = True
    assert select_points(g, cand, 50).size == 4


@pytest.mark.parametrize(
    "xi",
    [
        [0.1, -0.2, 0.3, 1e-9, -2e-9, 1e-9],
        [0.01, 0.02, -0.03, 1e-5, 3e-5, -2e-5],
        [0.5, -0.1, 0.2, 0.3, -0.2, 0.1],
        [1.0, 2.0, -1.0, 2.0, 1.0, -1.5],
    ],
)
def test_se3_exp_matches_scipy_expm(xi: list[float]) -> None:
    x = np.array(xi)
    A = np.zeros((4, 4))
    A[:3, :3] = hat(x[3:])
    A[:3, 3] = x[:3]
    ref = scipy.linalg.expm(A)
    np.testing.assert_allclose(se3_exp(x), ref, atol=1e-12, rtol=1e-10)
    np.testing.assert_allclose(kernels._se3_exp(x), ref, atol=1e-12, rtol=1e-10)


def _bilinear_np(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    u, v = uv[:, 0], uv[:, 1]
    x0, y0 = np.floor(u).astype(int), np.floor(v).astype(int)
    ax, ay = u - x0, v - y0
    return (1 - ay) * ((1 - ax) * img[y0, x0] + ax * img[y0, x0 + 1]) + ay * (
        (1 - ax) * img[y0 + 1, x0] + ax * img[y0 + 1, x0 + 1]
    )


@pytest.mark.parametrize("texture", ["ramp", "sinusoid"])
def test_jacobian_matches_finite_differences(texture: str) -> None:
    """Eq. (6) with distortion in the warp vs central differences of c*(x) = I*(w(e^{-A(x)}P)).

    On an intensity ramp, bilinear sampling and central differences are exact, so J must
    match to numerical precision at every level; on a sinusoid the image-gradient
    approximation adds a small error (checked at the finest level).
    """
    intr = small_intrinsics(distorted=True)
    h, w = intr.height, intr.width
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    if texture == "ramp":
        gray = (20 + 0.4 * u + 0.25 * v).astype(np.float32)
        levels, tol = (0, 1, 2), 1e-4
    else:
        gray = (110 + 60 * np.sin(u / 9.0) * np.cos(v / 11.0)).astype(np.float32)
        levels, tol = (0,), 0.03
    depth = (1.2 + 0.3 * u / w).astype(np.float32)  # a slanted plane
    pre = ph.Preprocessed(build_pyramid(gray), depth, intr)
    ref = ph.build_reference(pre, 300)
    scales = level_scales()
    P = ref.P.T.astype(np.float64)  # (n, 3)
    for lev in levels:
        img = pre.levels[lev].astype(np.float64)
        Jl = ref.J[lev].T.astype(np.float64)  # (n, 6)
        ok = np.abs(Jl).sum(axis=1) > 0
        assert ok.mean() > 0.9
        eps = 1e-6
        num = np.zeros((ref.n, 6))
        for a in range(6):
            dx = np.zeros(6)
            dx[a] = eps
            vals = []
            for sgn in (1.0, -1.0):
                T = se3_exp(-sgn * dx)  # e^{-A(x)}
                q = P @ T[:3, :3].T + T[:3, 3]
                uv0 = project(intr, q)
                vals.append(_bilinear_np(img, (uv0 + 0.5) * scales[lev] - 0.5))
            num[:, a] = (vals[0] - vals[1]) / (2 * eps)
        err = np.linalg.norm(Jl[ok] - num[ok], axis=1)
        scale = np.linalg.norm(num[ok], axis=1)
        assert np.median(err / scale) < tol, lev
        # c*(0) is the bilinear sample at the projection
        uv0 = project(intr, P)
        c0 = _bilinear_np(img, (uv0 + 0.5) * scales[lev] - 0.5)
        np.testing.assert_allclose(ref.cstar[lev][ok], c0[ok], atol=2e-3)


def test_pyramid_sizes_and_geometry_not_downsampled() -> None:
    gray = np.random.default_rng(0).uniform(0, 255, (480, 640)).astype(np.float32)
    levels = build_pyramid(gray)
    assert [lv.shape for lv in levels] == [(240, 320), (120, 160), (60, 80)]
    # 2x2 averaging between levels 0 -> 1 -> 2
    np.testing.assert_allclose(levels[1][0, 0], levels[0][:2, :2].mean(), rtol=1e-6)
    depth = np.ones((480, 640), np.float32)
    intr = small_intrinsics().scaled(2.0)
    pre = ph.preprocess(gray, depth, intr)
    assert pre.depth_m.shape == (480, 640)


def test_pyramid_of_8bit_images_is_the_opencv_pyramid() -> None:
    """The numba pyramid of 8-bit frames (level-0 resolution only) against the OpenCV path
    (full-resolution Gaussian, then area resizing) that float images take, odd sizes too."""
    rng = np.random.default_rng(3)
    for shape in ((480, 640), (61, 87), (8, 9)):
        g = rng.integers(0, 256, shape).astype(np.uint8)
        fast = build_pyramid(g)
        ref = build_pyramid(g.astype(np.float32))
        for a, b in zip(fast, ref, strict=True):
            assert a.shape == b.shape
            assert a.dtype == np.float32
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-4)


def test_two_frame_alignment_recovers_known_motion() -> None:
    """Algorithm 1 on two rendered frames: < 0.5 mm and < 0.05 deg."""
    intr = small_intrinsics(distorted=True)
    scene = PlaneScene(intr, room_scale=0.45)
    T_world_ref = np.eye(4)
    T_world_cur = se3_exp(np.array([0.012, -0.006, 0.01, 0.012, -0.01, 0.006]))
    g0, d0 = scene.render(T_world_ref)
    g1, d1 = scene.render(T_world_cur)
    ref = ph.build_reference(ph.preprocess(g0.astype(np.float32), d0, intr), 4096)
    assert ref.n == 4096
    res = ph.align(ref, ph.preprocess(g1.astype(np.float32), d1, intr), np.eye(4), (10, 3, 2))
    assert res.ok
    T_true = invert(T_world_cur) @ T_world_ref  # T_cur_ref
    D = invert(T_true) @ res.T_cur_ref
    assert np.linalg.norm(D[:3, 3]) < 0.5e-3
    assert np.degrees(rotation_angle_rad(D[:3, :3])) < 0.05
    assert res.inlier_fraction > 0.8
    assert res.weights.shape == (4096,)
    assert res.uv_full.shape == (4096, 2)


def test_point_to_plane_jacobian_matches_finite_differences() -> None:
    """Geometric term: r(x) = n . (e^{-A(x)} q - P) has the constant Jacobian [-n, -(P x n)]
    at q = P (inverse compositional)."""
    rng = np.random.default_rng(4)
    P = rng.uniform(-0.5, 0.5, (20, 3)) + np.array([0.0, 0.0, 2.0])
    N = rng.normal(size=(20, 3))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    Jg = np.concatenate([-N, -np.cross(P, N)], axis=1)
    h = 1e-6
    for a in range(6):
        x = np.zeros(6)
        x[a] = h
        Tm = se3_exp(-x)
        r = np.sum(N * (P @ Tm[:3, :3].T + Tm[:3, 3] - P), axis=1)
        np.testing.assert_allclose(r / h, Jg[:, a], atol=1e-5)


def test_combined_photometric_geometric_alignment_and_gain() -> None:
    """The optional point-to-plane term, affine gain and convergence stop keep the synthetic
    two-frame accuracy (< 0.5 mm, < 0.05 deg), also under a brightness gain change."""
    intr = small_intrinsics(distorted=True)
    scene = PlaneScene(intr, room_scale=0.45)
    T_world_cur = se3_exp(np.array([0.012, -0.006, 0.01, 0.012, -0.01, 0.006]))
    g0, d0 = scene.render(np.eye(4))
    g1, d1 = scene.render(T_world_cur)
    ref = ph.build_reference(
        ph.preprocess(g0.astype(np.float32), d0, intr), 4096, with_normals=True
    )
    assert ref.normals is not None
    assert ref.Jg is not None
    assert np.mean(np.linalg.norm(ref.normals, axis=0) > 0.5) > 0.8
    g1b = np.clip(1.1 * g1.astype(np.float32) + 3.0, 0, 255).astype(np.float32)
    res = ph.align(
        ref, ph.preprocess(g1b, d1, intr), np.eye(4), (10, 3, 2), brightness_offset=True,
        brightness_gain=True, geo_weight=1.0, stop_px=1e-4,
    )
    assert res.ok
    D = invert(invert(T_world_cur) @ np.eye(4)) @ res.T_cur_ref
    assert np.linalg.norm(D[:3, 3]) < 0.5e-3
    assert np.degrees(rotation_angle_rad(D[:3, :3])) < 0.05
    assert abs(res.brightness_gain - 1.0 / 1.1) < 0.05


def test_separate_geometric_points_spread_over_the_depth_and_align() -> None:
    """``geometric_points``: the geometric term's own points, spread over all valid depth (not
    only the photometric edges), each with a unit normal; with the geometric term weighted
    strongly the two-frame accuracy holds (< 0.5 mm, < 0.05 deg)."""
    intr = small_intrinsics(distorted=True)
    scene = PlaneScene(intr, room_scale=0.45)
    T_world_cur = se3_exp(np.array([0.012, -0.006, 0.01, 0.012, -0.01, 0.006]))
    g0, d0 = scene.render(np.eye(4))
    g1, d1 = scene.render(T_world_cur)
    pre0 = ph.preprocess(g0.astype(np.float32), d0, intr)
    ref = ph.build_reference(pre0, 2048, with_normals=True, geometric_points=3000)
    same = ph.build_reference(pre0, 2048, with_normals=True)
    assert ref.Pg is not None
    assert ref.normals is not None
    assert ref.Jg is not None
    ng = ref.Pg.shape[1]
    assert 0.9 * 3000 <= ng <= 3000  # (points without a normal dropped)
    assert ref.normals.shape == (3, ng)
    assert ref.Jg.shape == (6, ng)
    np.testing.assert_allclose(np.linalg.norm(ref.normals, axis=0), 1.0, atol=1e-5)
    assert same.Pg is not None
    assert np.array_equal(same.Pg, same.P)
    # spread: the geometric points cover the image more evenly than the gradient points
    def cover(P: np.ndarray) -> int:
        u = intr.fx * P[0] / P[2] + intr.cx
        v = intr.fy * P[1] / P[2] + intr.cy
        h, _, _ = np.histogram2d(u, v, bins=8, range=[[0, intr.width], [0, intr.height]])
        return int(np.count_nonzero(h))
    assert cover(ref.Pg) >= cover(ref.P)
    assert cover(ref.Pg[:, : ng // 4]) > 0.8 * cover(ref.Pg)  # a prefix is spread too
    res = ph.align(ref, ph.preprocess(g1.astype(np.float32), d1, intr), np.eye(4), (10, 3, 2),
                   brightness_offset=True, geo_weight=10.0)
    assert res.ok
    assert res.median_abs_geo_m < 1e-3
    D = invert(invert(T_world_cur)) @ res.T_cur_ref
    assert np.linalg.norm(D[:3, 3]) < 0.5e-3
    assert np.degrees(rotation_angle_rad(D[:3, :3])) < 0.05


def test_geometric_noise_model_weights_residuals_by_the_depth_noise() -> None:
    """``geometric_noise_model``: each point-to-plane normal (so its residual and Jacobian)
    is scaled by sigma(z_median) / sigma(z) of the Kinect model: 1 at the median depth, lower
    for farther (noisier) points; the alignment on exact depth keeps its accuracy."""
    z = np.array([0.8, 1.2, 2.5, 4.0])
    w = ph.geometric_noise_weights(z)
    sig = ph.depth_sigma_m(z)
    np.testing.assert_allclose(w * sig, w[0] * sig[0])  # w ~ 1 / sigma(z)
    assert np.all(np.diff(w) < 0)
    assert ph.geometric_noise_weights(np.array([1.0, 1.0, 1.0]))[0] == 1.0
    assert ph.depth_sigma_m(np.array([0.4]))[0] == 0.0012  # Nguyen 2012 eq. 3 at 0.4 m
    intr = small_intrinsics(distorted=True)
    scene = PlaneScene(intr, room_scale=0.45)
    T_world_cur = se3_exp(np.array([0.012, -0.006, 0.01, 0.012, -0.01, 0.006]))
    g0, d0 = scene.render(np.eye(4))
    g1, d1 = scene.render(T_world_cur)
    pre0 = ph.preprocess(g0.astype(np.float32), d0, intr)
    plain = ph.build_reference(pre0, 2048, with_normals=True, geometric_points=3000)
    ref = ph.build_reference(pre0, 2048, with_normals=True, geometric_points=3000,
                             geometric_noise_model=True)
    assert ref.Pg is not None
    assert ref.normals is not None
    assert plain.normals is not None
    assert np.array_equal(ref.Pg, plain.Pg)
    np.testing.assert_allclose(np.linalg.norm(ref.normals, axis=0),
                               ph.geometric_noise_weights(ref.Pg[2].astype(np.float64)),
                               rtol=1e-5)
    res = ph.align(ref, ph.preprocess(g1.astype(np.float32), d1, intr), np.eye(4), (10, 3, 2),
                   brightness_offset=True, geo_weight=3.0)
    assert res.ok
    D = invert(invert(T_world_cur)) @ res.T_cur_ref
    assert np.linalg.norm(D[:3, 3]) < 0.5e-3
    assert np.degrees(rotation_angle_rad(D[:3, :3])) < 0.05


def test_depth_delay_compensation_moves_by_the_velocity_over_the_gap() -> None:
    """Depth-delay compensation: T_color_depth = exp(xi (t_depth - t_colour)) with the body
    twist per second of the last good frames; off, or without a depth time: none."""
    from engine.dense.params import DenseParams
    from engine.dense.tracking import DenseIncrementalTracker
    from engine.frames import Frame

    xi = np.array([0.3, 0.0, 0.1, 0.0, 0.2, 0.0])  # body twist per second
    frame = Frame(index=0, timestamp_s=10.0, color_bgr=None, depth_timestamp_s=9.985)
    tr = DenseIncrementalTracker(DenseParams())
    tr._velocity = xi
    T = tr._depth_delay_transform(frame)
    assert T is not None
    np.testing.assert_allclose(T, se3_exp(xi * -0.015), atol=1e-12)
    assert tr._depth_delay_transform(Frame(index=0, timestamp_s=10.0, color_bgr=None)) is None
    off = DenseIncrementalTracker(DenseParams(compensate_depth_delay=False))
    off._velocity = xi
    assert off._depth_delay_transform(frame) is None


def _two_frames() -> tuple[ph.Reference, ph.Preprocessed, np.ndarray]:
    intr = small_intrinsics(distorted=True)
    scene = PlaneScene(intr, room_scale=0.45)
    T_world_cur = se3_exp(np.array([0.012, -0.006, 0.01, 0.012, -0.01, 0.006]))
    g0, d0 = scene.render(np.eye(4))
    g1, d1 = scene.render(T_world_cur)
    ref = ph.build_reference(ph.preprocess(g0.astype(np.float32), d0, intr), 4096)
    return ref, ph.preprocess(g1.astype(np.float32), d1, intr), invert(T_world_cur)


def test_split_over_threads_gives_the_same_alignment() -> None:
    """threads=2 splits the point passes (per-chunk histograms and normal equations summed):
    the same minimum as one thread, to float round-off of the reordered sums."""
    ref, cur, _ = _two_frames()
    one = ph.align(ref, cur, np.eye(4), (10, 3, 2), brightness_offset=True, threads=1)
    two = ph.align(ref, cur, np.eye(4), (10, 3, 2), brightness_offset=True, threads=2)
    np.testing.assert_allclose(two.T_cur_ref, one.T_cur_ref, atol=1e-9)
    assert two.iterations == one.iterations == 15
    np.testing.assert_allclose(two.weights, one.weights, atol=1e-6)


def test_coarse_subsets_and_convergence_stop_keep_the_minimum() -> None:
    """Fewer points at the coarse levels (a spread-out prefix) and the pixel-step stop reach
    the same two-frame accuracy; the stop runs fewer iterations than the fixed counts."""
    ref, cur, T_true = _two_frames()
    # the point order: any prefix of n/4 or n/2 covers the image
    uv = ref.uv_full
    for m in (ref.n // 4, ref.n // 2):
        assert np.ptp(uv[:m, 0]) > 0.8 * np.ptp(uv[:, 0])
        assert np.ptp(uv[:m, 1]) > 0.8 * np.ptp(uv[:, 1])
    for kw in ({"level_fraction": (1.0, 0.5, 0.25)}, {"stop_px": 0.01}):
        res = ph.align(ref, cur, np.eye(4), (10, 3, 2), brightness_offset=True, **kw)
        D = invert(T_true) @ res.T_cur_ref
        assert np.linalg.norm(D[:3, 3]) < 0.5e-3, kw
        assert np.degrees(rotation_angle_rad(D[:3, :3])) < 0.05, kw
        assert len(res.steps_px) == res.iterations
    stopped = ph.align(ref, cur, np.eye(4), (10, 3, 2), stop_px=0.01)
    assert stopped.iterations < 15
    assert min(stopped.steps_px) < 0.01


def test_paper_preset_is_the_published_method() -> None:
    from engine.dense.params import DenseParams

    p = DenseParams().with_preset("paper")
    assert p.iterations_fine_to_coarse == (10, 3, 2)
    assert p.n_points == 8192
    assert p.level_fraction_fine_to_coarse == (1.0, 1.0, 1.0)
    assert (p.brightness_offset, p.compensate_depth_delay, p.scale_over_kept) == (
        False, False, False)
    assert (p.stop_px, p.geometric_weight, p.edge_depth_ratio) == (0.0, 0.0, 0.0)
    assert "paper" in p.matching_presets()
    assert "paper" not in DenseParams().matching_presets()  # the defaults go beyond it


def test_kernels_see_one_type_per_argument() -> None:
    """Writable or read-only frame arrays (a camera frame's depth is read-only, a keyframe's
    is not), float64 or float32 inputs, with or without the geometric term, one or two
    threads: each kernel entry point keeps a single numba specialisation. A cached caller
    compiled against several specialisations of its callees can segfault when a later process
    loads it from numba's cache (numba issue #6713; it did on TUM)."""
    intr = small_intrinsics(distorted=True)
    scene = PlaneScene(intr, room_scale=0.45)
    g0, d0 = scene.render(np.eye(4))
    g1, d1 = scene.render(se3_exp(np.array([0.01, 0.0, 0.005, 0.0, 0.01, 0.0])))
    d1_ro = np.asarray(d1, dtype=np.float32).view()
    d1_ro.setflags(write=False)
    for with_normals, depth, gray, n_geo in ((False, d1, g1.astype(np.float32), 0),
                                             (True, d1_ro, g1.astype(np.float64), 0),
                                             (True, d1, g1.astype(np.float32), 1500)):
        pre0 = ph.preprocess(g0.astype(np.float32), d0.astype(np.float64), intr)
        ref = ph.build_reference(pre0, 1024, with_normals=with_normals, geometric_points=n_geo)
        cur = ph.preprocess(gray, depth, intr)
        for threads in (1, 2):
            res = ph.align(ref, cur, np.eye(4), (3, 2, 1), geo_weight=1.0 if with_normals else 0.0,
                           T_color_depth=np.eye(4) if with_normals else None,
                           brightness_offset=True, brightness_gain=with_normals,
                           threads=threads)
            assert res.ok
    assert len(kernels.minimize.signatures) == 1, kernels.minimize.signatures
    assert len(kernels.precompute_reference.signatures) == 1
    # the callees only minimize calls (compiled here on a fresh cache, empty when minimize
    # came from the cache): no literal-argument twin specialisations
    for callee in (kernels._photometric_pass, kernels._accumulate_pass, kernels.sample,
                   kernels.sample_geometric, kernels.gather_cells, kernels._unpack,
                   kernels._unpack_add,
                   kernels._photometric_chunk, kernels.project, kernels.histogram):
        assert len(callee.signatures) <= 1, (callee.py_func.__name__, callee.signatures)


def test_geometric_term_alone_converges_to_the_true_pose_on_noise_free_depth() -> None:
    """The point-to-plane term alone (photometric weight ~0) of a frame against the same room
    seen from a pose shifted along the back wall (sub-pixel fractions that every point at one
    depth shares) converges to that pose on exact depth, from the truth and from the
    identity: the residual is zero at the true pose whatever the points' normals. With
    nearest-pixel association and normals taken across the room's creases and the quads'
    steps it settled 50 um / 0.0015 deg off."""
    for distorted in (False, True):
        intr = small_intrinsics(distorted=distorted)
        scene = PlaneScene(intr, room_scale=0.45)
        quads = (Quad(-0.3, 0.1, -0.2, 0.25, 1.2), Quad(0.25, 0.6, -0.1, 0.3, 1.45))
        T_w_ref = se3_exp(np.array([0.0, 0.0, 0.0, 0.0, 0.35, 0.0]))  # a corner in view
        g0, d0 = scene.render(T_w_ref, quads)
        ref = ph.build_reference(ph.preprocess(g0.astype(np.float32), d0, intr), 2048,
                                 with_normals=True, geometric_points=4096)
        for dx in (0.0037, 0.0113, -0.0071):
            T_w_cur = T_w_ref @ se3_exp(np.array([dx, 0.0, 0.0, 0.0, 0.0, 0.0]))
            g1, d1 = scene.render(T_w_cur, quads)
            pre1 = ph.preprocess(g1.astype(np.float32), d1, intr)
            T_true = invert(T_w_cur) @ T_w_ref
            for T0 in (T_true, np.eye(4)):
                res = ph.align(ref, pre1, T0, (30, 0, 0), geo_weight=1e6)
                assert res.ok
                D = T_true @ invert(res.T_cur_ref)
                assert np.linalg.norm(D[:3, 3]) < 2e-6, (distorted, dx, D[:3, 3])
                assert np.degrees(rotation_angle_rad(D[:3, :3])) < 2e-5
