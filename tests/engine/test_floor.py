"""Floor calibration of the second view: homography, camera recovery, locating a person."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from engine.camera import Intrinsics, project
from engine.errors import CalibrationError
from engine.floor import (
    BODY_HALF_DEPTH_M,
    calibrate_floor,
    camera_from_homography,
    floor_calibration_from_json,
    load_floor_calibration,
    save_floor_calibration,
)
from engine.geometry import R_from_pan_tilt_roll_deg, invert, make_T
from engine.project import new_project, open_project

MARKS = [(-1.0, 2.0), (1.0, 2.0), (1.0, 4.0), (-1.0, 4.0)]


def _camera() -> tuple[Intrinsics, np.ndarray]:
    K = Intrinsics(fx=330.0, fy=330.0, cx=319.5, cy=239.5, width=640, height=480)
    T = make_T(R_from_pan_tilt_roll_deg(10.0, -45.0, 0.0), (0.3, 0.2, 3.4))
    return K, T


def _uv(K: Intrinsics, T: np.ndarray, pts: np.ndarray) -> np.ndarray:
    p = (invert(T) @ np.c_[pts, np.ones(len(pts))].T).T[:, :3]
    return project(K, p)


def test_camera_is_recovered_from_four_floor_marks() -> None:
    K, T = _camera()
    uv = _uv(K, T, np.array([[x, y, 0.0] for x, y in MARKS]))
    for f in (None, 330.0):  # focal length solved, or given
        calib = calibrate_floor(uv, MARKS, (0.0, -2.6), (640, 480), f)
        P = camera_from_homography(calib.H_floor_img, (640, 480), f)
        C = -np.linalg.solve(P[:, :3], P[:, 3])
        np.testing.assert_allclose(C, T[:3, 3], atol=1e-4)  # float32 homography
        for (u, v), (x, y) in zip(uv, MARKS, strict=True):
            assert calib.floor_point(u, v) == pytest.approx((x, y), abs=1e-4)


def test_a_standing_person_is_located_from_the_box() -> None:
    K, T = _camera()
    calib = calibrate_floor(_uv(K, T, np.array([[x, y, 0.0] for x, y in MARKS])), MARKS,
                            (0.0, -2.6), (640, 480))
    X, Y, height = 0.4, 2.8, 1.8
    # a box whose bottom centre is the foot and top centre the head of a vertical segment
    # BODY_HALF_DEPTH_M nearer the camera (the silhouette's front)
    C = T[:3, 3]
    toward = (np.array([X, Y]) - C[:2]) / np.linalg.norm(np.array([X, Y]) - C[:2])
    xs, ys = np.array([X, Y]) - BODY_HALF_DEPTH_M * toward
    foot, head = _uv(K, T, np.array([[xs, ys, 0.0], [xs, ys, height]]))
    u = 0.5 * (foot[0] + head[0])
    box = (u - 20.0, head[1], 40.0, foot[1] - head[1])
    fx, fy, h = calib.locate(box)
    assert (fx, fy) == pytest.approx((X, Y), abs=0.02)
    assert h == pytest.approx(height, abs=0.05)
    assert calib.distance_m(*foot) == pytest.approx(np.hypot(xs, ys + 2.6), abs=1e-6)


def test_a_standing_persons_box_height_and_lean_follow_from_the_calibration() -> None:
    """standing_box_px inverts the located segment: the box of a vertical segment (foot at
    the bottom, top at the top) has the height and lean it predicts at the box's centre, and
    standing_height_m gives the segment's height back; a bare homography knows no heights."""
    from engine.presenter.twoview import standing_height_m

    K, T = _camera()
    calib = calibrate_floor(_uv(K, T, np.array([[x, y, 0.0] for x, y in MARKS])), MARKS,
                            (0.0, -2.6), (640, 480))
    height = 1.8
    for X, Y in ((-1.5, 2.5), (0.4, 2.8), (1.6, 3.6)):
        foot, head = _uv(K, T, np.array([[X, Y, 0.0], [X, Y, height]]))
        u, v = 0.5 * (foot + head)
        got = calib.standing_box_px(np.array([u]), np.array([v]), height)
        assert got is not None
        h, lean = got
        assert float(h[0]) == pytest.approx(foot[1] - head[1], abs=0.05)
        assert float(lean[0]) == pytest.approx(head[0] - foot[0], abs=0.05)
        box = (u - 20.0, head[1], 40.0, foot[1] - head[1])
        assert standing_height_m(calib, box) == pytest.approx(height, abs=1e-3)
        # located with its lean: the segment itself (moved by the body's half depth)
        C = T[:3, 3]
        away = (np.array([X, Y]) - C[:2]) / np.linalg.norm(np.array([X, Y]) - C[:2])
        fx, fy, hz = calib.locate(box, lean_px=float(lean[0]))
        assert (fx, fy) == pytest.approx(tuple(np.array([X, Y]) + BODY_HALF_DEPTH_M * away),
                                         abs=1e-3)
        assert hz == pytest.approx(height, abs=1e-3)
    # off the image's middle column a vertical leans (towards the nadir's image below)
    leans = calib.standing_box_px(np.array([100.0, 540.0]), np.array([250.0, 250.0]), height)
    assert leans is not None
    assert leans[1][0] < -5.0 < 5.0 < leans[1][1]
    bare = calibrate_floor(calib.image_points_px, MARKS)  # no image size: no camera
    assert bare.standing_box_px(np.array([300.0]), np.array([250.0]), height) is None
    assert standing_height_m(bare, (280.0, 200.0, 40.0, 100.0)) is None


def test_floor_calibration_round_trips_and_lives_in_the_project(tmp_path: Path) -> None:
    K, T = _camera()
    calib = calibrate_floor(_uv(K, T, np.array([[x, y, 0.0] for x, y in MARKS])), MARKS,
                            (0.5, -2.0), (640, 480), 330.0)
    save_floor_calibration(tmp_path / "floor.json", calib)
    back = load_floor_calibration(tmp_path / "floor.json")
    np.testing.assert_allclose(back.H_floor_img, calib.H_floor_img)
    assert back.robot_floor_xy_m == (0.5, -2.0)
    assert back.f_px == 330.0
    assert back.image_wh == (640, 480)
    proj = new_project("show")
    proj.floor_calibration = calib
    proj.save(tmp_path / "proj")
    got = open_project(tmp_path / "proj").floor_calibration
    assert got is not None
    np.testing.assert_allclose(got.H_floor_img, calib.H_floor_img)


@pytest.mark.parametrize(("image", "floor", "match"), [
    ([(0, 0), (1, 1), (2, 2), (0, 5)], MARKS, "collinear"),
    ([(0, 0), (1, 1), (2, 2)], MARKS, "4 image and 4 floor points"),
    ([(0, 0), (1, 0), (1, 1), (float("nan"), 1)], MARKS, "finite"),
])
def test_bad_floor_calibration_is_one_clear_error(image: list, floor: list, match: str) -> None:
    with pytest.raises(CalibrationError, match=match):
        calibrate_floor(image, floor)


def test_malformed_floor_documents_are_rejected() -> None:
    with pytest.raises(CalibrationError, match=r"not a studiotrack\.floor_homography"):
        floor_calibration_from_json({"format": "x"})
    with pytest.raises(CalibrationError, match="newer"):
        floor_calibration_from_json({"format": "studiotrack.floor_homography", "version": 9})
    with pytest.raises(CalibrationError, match="missing"):
        floor_calibration_from_json({"format": "studiotrack.floor_homography", "version": 1})


# -------------------------------------------------------------- lens camera model (issue 13)


def _zoom_view_box(zoom_raw: int, X: float, Y: float, height: float) -> tuple[float, ...]:
    """The box of a standing person (segment at (X, Y) moved towards the camera by the
    half body depth) in the studio's second camera through its zoom lens at ``zoom_raw``."""
    from engine.studio.views import OVERHEAD
    from engine.studio.zoom import FOCUS_RAW

    cam, T = OVERHEAD.zoom_camera(640, 480, zoom_raw, FOCUS_RAW)
    C = T[:3, 3]
    toward = (np.array([X, Y]) - C[:2]) / np.linalg.norm(np.array([X, Y]) - C[:2])
    xs, ys = np.array([X, Y]) - BODY_HALF_DEPTH_M * toward
    foot, head = _uv(cam, T, np.array([[xs, ys, 0.0], [xs, ys, height]]))
    u = 0.5 * (foot[0] + head[0])  # an upright box in the distorted picture
    return (u - 20.0, head[1], 40.0, foot[1] - head[1])


def test_a_zooming_view_keeps_the_floor_position_with_the_lens_model() -> None:
    from engine.lens import LensEncoders
    from engine.studio.views import OVERHEAD
    from engine.studio.zoom import FOCUS_RAW

    calib = OVERHEAD.floor_calibration(640, 480, zoom=True)  # marks taken at the wide end
    assert calib.has_lens_model
    assert calib.encoders_raw == (0, FOCUS_RAW)
    assert calib.pnp_rms_px is not None
    assert calib.pnp_rms_px < 1e-3
    fixed = calib.without_lens()
    assert not fixed.has_lens_model
    X, Y, height = 0.3, 2.5, 1.75
    for zoom in (0, 8192, 16384):
        _, T = OVERHEAD.zoom_camera(640, 480, zoom, FOCUS_RAW)
        _cam, T_est = calib.camera_at(LensEncoders(zoom, FOCUS_RAW))
        # the pose follows the entrance pupil: T_cam_floor = T_world_cam^-1 (floor = world)
        np.testing.assert_allclose(T_est, invert(T), atol=1e-6)
        box = _zoom_view_box(zoom, X, Y, height)
        x, y, h = calib.locate(box, LensEncoders(zoom, FOCUS_RAW))
        # the box's bottom centre is not exactly the foot's image under distortion (the box
        # is upright in the distorted picture): centimetres, not decimetres
        assert np.hypot(x - X, y - Y) < 0.03, zoom
        assert h == pytest.approx(height, abs=0.05)
        hx, hy, _ = fixed.locate(box)
        if zoom == 16384:
            assert np.hypot(hx - X, hy - Y) > 0.3  # the fixed homography breaks


def test_lens_floor_calibration_round_trips_and_follows_the_project_lens(
        tmp_path: Path) -> None:
    from engine.studio.views import OVERHEAD

    calib = OVERHEAD.floor_calibration(640, 480, zoom=True)
    save_floor_calibration(tmp_path / "floor.json", calib)
    back = load_floor_calibration(tmp_path / "floor.json")
    assert back.has_lens_model
    assert back.encoders_raw == calib.encoders_raw
    np.testing.assert_allclose(back.T_cam_floor, calib.T_cam_floor, atol=1e-9)
    import json

    assert json.loads((tmp_path / "floor.json").read_text())["version"] == 2
    # made with the project's lens: a project whose lens file changes re-solves the pose
    proj = new_project("show")
    proj.lens = calib.lens
    proj.floor_calibration = calib.with_lens(calib.lens, from_project=True)
    proj.save(tmp_path / "proj")
    got = open_project(tmp_path / "proj").floor_calibration
    assert got is not None
    assert got.lens_from_project
    assert got.has_lens_model
    np.testing.assert_allclose(got.T_cam_floor, calib.T_cam_floor, atol=1e-9)


def test_lens_floor_calibration_errors_are_one_line() -> None:
    from engine.studio.views import OVERHEAD
    from engine.studio.zoom import studio_zoom_lens

    calib = OVERHEAD.floor_calibration(640, 480, zoom=True)
    with pytest.raises(CalibrationError, match=r"lens file .* is for 320x240 images, the view "
                                               r"is 640x480"):
        calibrate_floor(calib.image_points_px, calib.floor_points_m, (0.0, 0.0), (640, 480),
                        lens=studio_zoom_lens(320, 240))
    with pytest.raises(CalibrationError, match="encoders must be 2 integers"):
        calibrate_floor(calib.image_points_px, calib.floor_points_m, lens=calib.lens,
                        encoders_raw=("wide",))
