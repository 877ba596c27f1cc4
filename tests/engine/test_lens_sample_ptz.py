"""Lens-file samples from the pan-tilt calibration tools: the DLT's intrinsics and the
line-based distortion converted to the lens file's Brown-Conrady terms."""

from __future__ import annotations

import numpy as np
import pytest

from engine.errors import CalibrationError
from engine.lens import LensError, LensFile, LensSample
from engine.ptz.calibration import PtzCalibration
from engine.ptz.distortion import RadialModel, estimate_radial_from_lines
from engine.ptz.lens_sample import brown_conrady_from_radial, lens_sample_from_ptz
from engine.ptz.sim import CircleScenario

W, H = 640, 480


def _undistort_with(sample: LensSample, pts: np.ndarray) -> np.ndarray:
    import cv2

    K = np.array([[sample.fx_px, 0, sample.cx_px], [0, sample.fy_px, sample.cy_px], [0, 0, 1]])
    d = np.array([sample.k1, sample.k2, sample.p1, sample.p2, sample.k3])
    return cv2.undistortPoints(pts.reshape(-1, 1, 2), K, d, P=K).reshape(-1, 2)


def _grid() -> np.ndarray:
    gu, gv = np.meshgrid(np.linspace(0, W - 1, 21), np.linspace(0, H - 1, 16))
    return np.stack([gu.ravel(), gv.ravel()], axis=1)


def test_dlt_and_lines_make_a_sample_that_undistorts_like_the_line_model() -> None:
    """The simulator's lens (inverse radial k3 0.12, centre 6 px off the principal point):
    the sample's OpenCV model undoes the distortion within a pixel over the whole image."""
    sc = CircleScenario(distortion_k3=0.12)
    true = sc.radial()
    assert true is not None
    cal = PtzCalibration(head=sc.head(), radial=true, image_size=(W, H))
    s, rep = lens_sample_from_ptz(cal, 1200, 30, entrance_pupil_m=0.05)
    assert (s.zoom_raw, s.focus_raw, s.entrance_pupil_m) == (1200, 30, 0.05)
    assert s.fx_px == sc.head().K[0, 0]
    assert (rep["intrinsics_from"], rep["distortion_from"]) == ("DLT", "lens lines")
    assert rep["fit_rms_px"] < 0.2
    err = np.linalg.norm(_undistort_with(s, _grid()) - true.undistort_px(_grid()), axis=1)
    assert err.max() < 1.0
    # the tangential terms take up the distortion centre's offset from the principal point
    assert abs(s.p1) + abs(s.p2) > 0


def test_the_conversion_of_an_estimated_model_is_as_good_as_the_estimate() -> None:
    from engine.ptz.distortion import synthetic_distorted_grid

    true = RadialModel(k=(0.2, 0.05), centre_px=(322.0, 241.0), r_norm_px=400.0)
    fit = estimate_radial_from_lines(synthetic_distorted_grid(true, (W, H), noise_px=0.3,
                                                              seed=2), (W, H))
    K = np.array([[700.0, 0, 319.5], [0, 700.0, 239.5], [0, 0, 1]])
    b = brown_conrady_from_radial(fit.model, K, (W, H))
    s = LensSample(0, 0, 700.0, 700.0, 319.5, 239.5, b.k1, b.k2, b.k3, b.p1, b.p2)
    err = np.linalg.norm(_undistort_with(s, _grid()) - true.undistort_px(_grid()), axis=1)
    assert np.median(err) < 0.5
    assert b.rms_px < 0.5


def test_a_dlt_alone_gives_focal_length_and_principal_point_without_distortion() -> None:
    from engine.geometry import R_from_pan_tilt_roll_deg
    from engine.ptz.dlt import calibrate_dlt, compose_P, project_P
    from engine.ptz.kinematics import head_from_dlt

    rng = np.random.default_rng(3)
    K = np.array([[810.0, 0, 326.0], [0, 805.0, 244.0], [0, 0, 1]])
    R = R_from_pan_tilt_roll_deg(8.0, -5.0, 1.0).T
    c = np.array([0.2, -0.4, 1.5])
    P = compose_P(K, R, -R @ c)
    X = np.column_stack([rng.uniform(-2, 2, 30), rng.uniform(3, 7, 30), rng.uniform(0, 2.5, 30)])
    res = calibrate_dlt(X, project_P(P, X) + rng.normal(0, 0.3, (30, 2)))
    from engine.ptz.calibration import DltPose

    cal = PtzCalibration(head=head_from_dlt(res.decomposition), image_size=(W, H),
                         dlt_poses=(DltPose(0.0, 0.0, res.rmse_px, 30),))
    s, rep = lens_sample_from_ptz(cal, 500)
    assert s.fx_px == pytest.approx(810.0, rel=0.01)
    assert s.cy_px == pytest.approx(244.0, abs=3.0)
    assert (s.k1, s.k2, s.k3, s.p1, s.p2) == (0.0,) * 5
    assert rep["distortion_from"] is None
    assert s.rms_px == pytest.approx(res.rmse_px)
    assert "DLT" in s.note


def test_lens_lines_alone_take_the_focal_length_from_the_lens_file() -> None:
    sc = CircleScenario(distortion_k3=0.12)
    lens = LensFile(W, H, (LensSample(0, 0, 600.0, 600.0, 319.5, 239.5),
                           LensSample(1000, 0, 1200.0, 1200.0, 319.5, 239.5)))
    cal = PtzCalibration(head=None, radial=sc.radial(), image_size=(W, H))
    s, rep = lens_sample_from_ptz(cal, 500, lens=lens)
    assert rep["intrinsics_from"] == "lens file"
    assert s.fx_px == pytest.approx(900.0)
    assert s.k1 != 0.0
    with pytest.raises(CalibrationError, match="distortion only"):
        lens_sample_from_ptz(cal, 500)


@pytest.mark.parametrize(("cal", "lens", "match"), [
    (None, None, "no pan-tilt calibration"),
    (PtzCalibration(head=None), None, "no pan-tilt calibration"),
    (PtzCalibration(head=CircleScenario().head()), None, "no image size"),
    (PtzCalibration(head=CircleScenario().head(), image_size=(W, H)),
     LensFile(320, 240, ()), "640x480 px, the lens file is 320x240"),
])
def test_bad_input_is_one_line(cal: object, lens: object, match: str) -> None:
    with pytest.raises(CalibrationError, match=match) as e:
        lens_sample_from_ptz(cal, 0, lens=lens)  # type: ignore[arg-type]
    assert "\n" not in str(e.value)


def test_a_degenerate_head_is_refused() -> None:
    import dataclasses

    head = dataclasses.replace(CircleScenario().head(),
                               K=np.array([[-5.0, 0, 320], [0, -5.0, 240], [0, 0, 1]]))
    with pytest.raises(LensError, match="must be > 0"):
        lens_sample_from_ptz(PtzCalibration(head=head, image_size=(W, H)), 0)
    with pytest.raises(CalibrationError, match="not usable"):
        brown_conrady_from_radial(RadialModel((0.1,), (320.0, 240.0), 400.0),
                                  np.full((3, 3), np.nan), (W, H))
