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
