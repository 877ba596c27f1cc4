"""Calibration pieces of the pan-tilt tracker (Gaspar 2009 sec. 3)."""

from __future__ import annotations

import glob

import numpy as np
import pytest

from engine.errors import CalibrationError
from engine.geometry import R_from_pan_tilt_roll_deg
from engine.ptz.distortion import (
    RadialModel,
    estimate_radial_from_lines,
    propose_lines_chessboard,
    synthetic_distorted_grid,
)
from engine.ptz.dlt import (
    calibrate_dlt,
    compose_P,
    decompose_P,
    load_points_csv,
    outlier_mask,
    project_P,
    save_points_csv,
)
from engine.ptz.kinematics import estimate_pan_tilt, head_from_dlt
from tests.conftest import shared_path

K_TRUE = np.array([[810.0, 0, 322.0], [0, 795.0, 241.0], [0, 0, 1]])
R_WC = R_from_pan_tilt_roll_deg(12.0, -7.0, 1.5)
C_TRUE = np.array([0.4, -0.6, 1.7])


def _P_true() -> np.ndarray:
    R = R_WC.T
    return compose_P(K_TRUE, R, -R @ C_TRUE)


def _points(n: int = 20, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-2, 2, n), rng.uniform(3, 7, n), rng.uniform(0, 2.5, n)])


def test_dlt_recovers_known_P() -> None:
    P = _P_true()
    X = _points()
    res = calibrate_dlt(X, project_P(P, X))
    Pn = P / np.linalg.norm(P[2, :3])
    np.testing.assert_allclose(res.P, Pn, rtol=1e-7, atol=1e-6)
    assert res.rmse_px < 1e-6


def test_decomposition_matches() -> None:
    dec = decompose_P(_P_true() * 2.5)  # any positive scale
    assert dec.alpha_u == pytest.approx(810.0, rel=1e-9)
    assert dec.alpha_v == pytest.approx(795.0, rel=1e-9)
    assert (dec.u0, dec.v0) == pytest.approx((322.0, 241.0), abs=1e-6)
    np.testing.assert_allclose(dec.R_cam_world, R_WC.T, atol=1e-9)
    np.testing.assert_allclose(dec.camera_centre_world, C_TRUE, atol=1e-9)
    assert abs(dec.skew_deg) < 1e-6


def test_dlt_with_noise_and_outlier_flagged() -> None:
    rng = np.random.default_rng(1)
    X = _points(25, seed=2)
    uv = project_P(_P_true(), X) + rng.normal(0, 0.5, (25, 2))
    uv[4] += (15.0, -10.0)
    res = calibrate_dlt(X, uv)
    mask = outlier_mask(res.residuals_px)
    assert mask[4]
    assert mask.sum() <= 2


def test_dlt_rejects_coplanar_and_too_few() -> None:
    X = _points(10)
    X[:, 2] = 0.0
    with pytest.raises(CalibrationError, match="coplanar"):
        calibrate_dlt(X, project_P(_P_true(), X))
    X = _points(5)
    with pytest.raises(CalibrationError, match="at least 6"):
        calibrate_dlt(X, project_P(_P_true(), X))


def test_points_csv_roundtrip(tmp_path) -> None:  # type: ignore[no-untyped-def]
    X = _points(7)
    uv = project_P(_P_true(), X)
    save_points_csv(tmp_path / "p.csv", X, uv)
    X2, uv2 = load_points_csv(tmp_path / "p.csv")
    np.testing.assert_allclose(X2, X, atol=1e-6)
    np.testing.assert_allclose(uv2, uv, atol=1e-3)
    (tmp_path / "bad.csv").write_text("x,y,z,u,v\n1,2,3,oops,5\n")
    with pytest.raises(CalibrationError, match=r"bad\.csv:2"):
        load_points_csv(tmp_path / "bad.csv")


def test_distortion_recovers_known_k() -> None:
    true = RadialModel(k=(0.22, 0.04), centre_px=(328.0, 236.0), r_norm_px=400.0)
    lines = synthetic_distorted_grid(true, (640, 480), noise_px=0.0)
    fit = estimate_radial_from_lines(lines, (640, 480))
    assert fit.model.k[0] == pytest.approx(0.22, rel=1e-3)
    assert fit.model.k[1] == pytest.approx(0.04, rel=2e-2)
    assert fit.model.centre_px == pytest.approx((328.0, 236.0), abs=0.5)
    assert fit.rms_after_px < 0.01 < fit.rms_before_px
    p = np.array([[10.0, 20.0], [600.0, 400.0]])
    np.testing.assert_allclose(true.undistort_px(true.distort_px(p)), p, atol=1e-9)


def test_distortion_on_real_chessboard_matches_opencv_centre() -> None:
    import cv2

    files = sorted(glob.glob(str(shared_path("opencv_samples", "chessboard_stereo")
                                 / "left0*.jpg")))[:4]
    lines = []
    for f in files:
        lines += propose_lines_chessboard(cv2.imread(f, cv2.IMREAD_GRAYSCALE), (9, 6))
    assert len(lines) >= 45
    fit = estimate_radial_from_lines(lines, (640, 480))
    assert fit.rms_after_px < 0.3 * fit.rms_before_px
    # OpenCV's reference principal point: (342.3, 235.6)
    assert fit.model.centre_px == pytest.approx((342.3, 235.6), abs=10.0)


def test_chessboard_matches_opencv_reference() -> None:
    from engine.ptz.chessboard import calibrate_chessboard

    files = sorted(glob.glob(str(shared_path("opencv_samples", "chessboard_stereo")
                                 / "left*.jpg")))
    res = calibrate_chessboard(files, (9, 6), 0.025)
    assert res.intrinsics.fx == pytest.approx(535.9, rel=0.01)
    assert res.intrinsics.dist_k1k2p1p2k3[0] == pytest.approx(-0.266, abs=0.01)
    assert res.rms_px < 0.5


def test_head_from_dlt_and_pan_tilt_from_reference_points() -> None:
    X = _points(12, seed=4)
    dec = calibrate_dlt(X, project_P(_P_true(), X)).decomposition
    off = np.array([0.0, 0.0, 0.05])
    head = head_from_dlt(dec, off)
    np.testing.assert_allclose(head.P(0.0, 0.0) / np.linalg.norm(head.P(0, 0)[2, :3]),
                               _P_true() / np.linalg.norm(_P_true()[2, :3]), atol=1e-6)
    # rotation centre stays fixed while the optical centre swings with the offset
    c1, c2 = head.optical_centre_world(0, 0), head.optical_centre_world(30, 10)
    assert np.linalg.norm(c1 - c2) > 0.01
    assert np.linalg.norm(c1 - head.rotation_centre_world_m) == pytest.approx(0.05)
    pan, tilt = 17.0, -6.0
    ref = _points(6, seed=8)
    Pm = head.P(pan, tilt)
    vis = (np.hstack([ref, np.ones((6, 1))]) @ Pm[2]) > 0
    uv = project_P(Pm, ref[vis])
    pe, te, rms = estimate_pan_tilt(head, ref[vis], uv, (10.0, 0.0))
    assert (pe, te) == pytest.approx((pan, tilt), abs=1e-5)
    assert rms < 1e-6
