"""Property tests of engine.camera: agreement with cv2.projectPoints/undistortPoints, the
project/backproject round trip with distortion, camera.json round trip and validation."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine import camera as c
from engine.camera import TUM_DEFAULTS, Intrinsics
from engine.errors import CalibrationError

FR1 = TUM_DEFAULTS["freiburg1"]
FR2 = TUM_DEFAULTS["freiburg2"]
PINHOLE = Intrinsics()

coord = st.floats(-1.0, 1.0, allow_nan=False)
depth = st.floats(0.2, 20.0, allow_nan=False)


def points(n_min: int = 1, n_max: int = 30, xy_max: float = 0.6) -> st.SearchStrategy[np.ndarray]:
    """(N, 3) camera-frame points in front of the camera, |x/z| and |y/z| <= xy_max."""
    row = st.tuples(st.floats(-xy_max, xy_max), st.floats(-xy_max, xy_max), depth).map(
        lambda t: [t[0] * t[2], t[1] * t[2], t[2]]
    )
    return st.lists(row, min_size=n_min, max_size=n_max).map(
        lambda r: np.array(r, dtype=np.float64)
    )


@settings(max_examples=200, deadline=None)
@given(points(), st.sampled_from([FR1, FR2, PINHOLE]))
def test_project_matches_cv2_project_points(p_cam: np.ndarray, cam: Intrinsics) -> None:
    uv = c.project(cam, p_cam)
    uv_cv, _ = cv2.projectPoints(
        p_cam.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, cam.dist
    )
    np.testing.assert_allclose(uv, uv_cv.reshape(-1, 2), atol=1e-6)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-0.2, 0.2), min_size=5, max_size=5),
    points(xy_max=0.5),
)
def test_distortion_model_matches_cv2_for_random_coefficients(
    dist: list[float], p_cam: np.ndarray
) -> None:
    cam = Intrinsics(fx=600.0, fy=590.0, cx=330.0, cy=250.0, dist_k1k2p1p2k3=tuple(dist))  # type: ignore[arg-type]
    uv_cv, _ = cv2.projectPoints(
        p_cam.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, cam.dist
    )
    np.testing.assert_allclose(c.project(cam, p_cam), uv_cv.reshape(-1, 2), atol=1e-6)


def image_pixels(cam: Intrinsics) -> st.SearchStrategy[np.ndarray]:
    px = st.tuples(st.floats(0.0, cam.width - 1.0), st.floats(0.0, cam.height - 1.0))
    return st.lists(px, min_size=1, max_size=30).map(lambda r: np.array(r, dtype=np.float64))


@settings(max_examples=200, deadline=None)
@given(st.data(), st.sampled_from([FR1, FR2, PINHOLE]))
def test_backproject_then_project_returns_the_pixel(data: st.DataObject, cam: Intrinsics) -> None:
    uv = data.draw(image_pixels(cam))
    z = data.draw(st.lists(depth, min_size=len(uv), max_size=len(uv)).map(np.array))
    p_cam = c.backproject(cam, uv, z)
    np.testing.assert_allclose(p_cam[:, 2], z)
    np.testing.assert_allclose(c.project(cam, p_cam), uv, atol=1e-6)


@settings(max_examples=200, deadline=None)
@given(points(xy_max=0.55), st.sampled_from([FR1, FR2]))
def test_project_then_backproject_returns_the_point(p_cam: np.ndarray, cam: Intrinsics) -> None:
    back = c.backproject(cam, c.project(cam, p_cam), p_cam[:, 2])
    np.testing.assert_allclose(back, p_cam, atol=1e-7 * p_cam[:, 2:].max())


@settings(max_examples=100, deadline=None)
@given(st.data())
def test_undistort_matches_cv2_undistort_points(data: st.DataObject) -> None:
    uv = data.draw(image_pixels(FR1))
    xy = c.pixels_to_normalized(FR1, uv)
    # OpenCV stops its own fixed-point iteration by count/eps; ask it for plenty
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-15)
    xy_cv = cv2.undistortPoints(uv.reshape(-1, 1, 2), FR1.K, FR1.dist, criteria=crit)
    np.testing.assert_allclose(xy, xy_cv.reshape(-1, 2), atol=1e-8)


@pytest.mark.parametrize("cam", [FR1, FR2], ids=["fr1", "fr2"])
def test_round_trip_at_image_corners(cam: Intrinsics) -> None:
    # the corners are where the fixed-point undistortion converges slowest
    w, h = cam.width - 1.0, cam.height - 1.0
    uv = np.array([[0, 0], [w, 0], [0, h], [w, h], [w / 2, 0], [0, h / 2]], dtype=np.float64)
    np.testing.assert_allclose(c.project(cam, c.backproject(cam, uv, np.ones(6))), uv, atol=1e-6)


def test_points_behind_the_camera_are_nan() -> None:
    uv = c.project(FR1, np.array([[0.1, 0.2, -1.0], [0.0, 0.0, 0.0], [0.1, 0.1, 1.0]]))
    assert np.all(np.isnan(uv[:2]))
    assert np.all(np.isfinite(uv[2]))


def test_principal_point_and_pinhole_values() -> None:
    uv = c.project(FR1, np.array([[0.0, 0.0, 2.0], [0.2, -0.1, 1.0]]))
    np.testing.assert_allclose(uv[0], [FR1.cx, FR1.cy])
    # the pinhole camera has no distortion: u = fx x/z + cx
    uv_p = c.project(PINHOLE, np.array([[0.2, -0.1, 1.0]]))
    np.testing.assert_allclose(uv_p[0], [525 * 0.2 + 319.5, -525 * 0.1 + 239.5])
    assert not np.allclose(uv[1], uv_p[0])


@settings(max_examples=100, deadline=None)
@given(points(), st.sampled_from([0.25, 0.5, 2.0]))
def test_scaled_intrinsics_scale_pixels(p_cam: np.ndarray, factor: float) -> None:
    # pixel-centre convention: u' + 0.5 = factor (u + 0.5)
    uv = c.project(FR1, p_cam)
    uv_s = c.project(FR1.scaled(factor), p_cam)
    np.testing.assert_allclose(uv_s + 0.5, factor * (uv + 0.5), atol=1e-9)


def test_backproject_depth_image() -> None:
    cam = FR1.scaled(0.125)  # 80 x 60
    rng = np.random.default_rng(4)
    depth_m = rng.uniform(0.5, 3.0, (cam.height, cam.width)).astype(np.float32)
    depth_m[3, 5] = 0.0
    pts = c.backproject_depth_image(cam, depth_m)
    assert pts.shape == (cam.height, cam.width, 3)
    assert np.all(np.isnan(pts[3, 5]))
    valid = ~np.isnan(pts[..., 2])
    assert valid.sum() == cam.width * cam.height - 1
    uv = c.project(cam, pts[valid])
    v, u = np.nonzero(valid)
    np.testing.assert_allclose(uv, np.stack([u, v], axis=1), atol=1e-6)
    np.testing.assert_allclose(pts[valid][:, 2], depth_m[valid], rtol=1e-7)


intrinsics = st.builds(
    Intrinsics,
    fx=st.floats(1.0, 5000.0),
    fy=st.floats(1.0, 5000.0),
    cx=st.floats(-100.0, 3000.0),
    cy=st.floats(-100.0, 3000.0),
    width=st.integers(1, 8000),
    height=st.integers(1, 8000),
    dist_k1k2p1p2k3=st.tuples(*[st.floats(-5.0, 5.0)] * 5),
    depth_scale=st.floats(1.0, 1e5),
)


@settings(max_examples=100, deadline=None)
@given(intrinsics)
def test_camera_json_round_trip(cam: Intrinsics) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "camera.json"
        c.save_camera_json(cam, path)
        assert c.load_camera_json(path) == cam  # exact: JSON floats round-trip bit for bit
        raw = json.loads(path.read_text())
        assert raw["distortion"] == list(cam.dist_k1k2p1p2k3)


def test_shared_fr1_camera_json_is_the_tum_default() -> None:
    """The shared camera.json is TUM's fr1 calibration; it says nothing of the shutter, which
    the TUM source takes from the default (the Kinect v1's readout)."""
    import dataclasses

    from engine.sources import open_source
    from tests.conftest import shared_path

    got = c.load_camera_json(shared_path("tum_fr1_xyz_37", "camera.json"))
    assert got.rolling_shutter_s == 0.0
    assert dataclasses.replace(got, rolling_shutter_s=FR1.rolling_shutter_s) == FR1
    assert FR1.rolling_shutter_s == c.KINECT_V1_READOUT_S
    with open_source(str(shared_path("tum_fr1_xyz_37"))) as src:
        frame = next(iter(src.frames()))
    assert frame.intrinsics == FR1


def test_camera_json_optional_keys_default(tmp_path: Path) -> None:
    path = tmp_path / "camera.json"
    path.write_text('{"fx": 500, "fy": 500, "cx": 320, "cy": 240, "width": 640, "height": 480}')
    cam = c.load_camera_json(path)
    assert cam.dist_k1k2p1p2k3 == (0.0,) * 5
    assert cam.depth_scale == 5000.0


def _cam_text(**changes: object) -> str:
    """camera.json text: a valid base with keys changed (None removes a key)."""
    d: dict[str, object] = {"fx": 500, "fy": 500, "cx": 320, "cy": 240, "width": 640}
    d["height"] = 480
    d.update(changes)
    return json.dumps({k: v for k, v in d.items() if v is not None})


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("", "malformed JSON at line 1"),
        ('{"fx": 1,\n "fy": }', "malformed JSON at line 2"),
        ('"just a string"', "expected a JSON object, got str"),
        (_cam_text(cy=None, height=None), "missing key(s) cy, height"),
        (_cam_text(fx=True), "'fx' must be a number"),
        (_cam_text(width="640"), "'width' must be an integer"),
        (_cam_text(distortion=[0, 0]), "'distortion' must be a list of 5"),
        (_cam_text(distortion=[0, 0, 0, "x", 0]), "'distortion'[3] must be a number"),
        (_cam_text(height=0), "'height' must be in [1, 100000], got 0"),
        (_cam_text(depth_scale=0), "'depth_scale' must be > 0"),
        (_cam_text(cx=float("nan")), "'cx' must be finite, got nan"),
        # issue 18: no OverflowError, no absurd or fractional values accepted
        (_cam_text(fx=10**400), "'fx' must be > 0 and <= 1e+07, got 100000000000... (401 digits)"),
        (_cam_text(width=10**400), "'width' must be in [1, 100000]"),
        ('{"fx": 500, "fy": 500, "cx": 320, "cy": 240, "width": 1e400, "height": 480}',
         "'width' must be an integer, got inf"),
        (_cam_text(fx=1e308), "'fx' must be > 0 and <= 1e+07, got 1e+308"),
        (_cam_text(width=160.5), "'width' must be an integer, got 160.5"),
    ],
)
def test_malformed_camera_json_one_line_errors(tmp_path: Path, text: str, problem: str) -> None:
    path = tmp_path / "camera.json"
    path.write_text(text)
    with pytest.raises(CalibrationError) as exc:
        c.load_camera_json(path)
    msg = str(exc.value)
    assert msg.startswith(f"{path}: ")
    assert problem in msg
    assert "\n" not in msg


def test_missing_camera_json(tmp_path: Path) -> None:
    with pytest.raises(CalibrationError, match=r"camera.json: file not found"):
        c.load_camera_json(tmp_path / "camera.json")


@pytest.mark.parametrize(
    "kwargs",
    [
        {"fx": 0.0},
        {"fy": -1.0},
        {"fx": math.inf},
        {"width": 0},
        {"dist_k1k2p1p2k3": (0.0, 0.0)},
        {"depth_scale": -5.0},
    ],
)
def test_intrinsics_validation(kwargs: dict[str, object]) -> None:
    with pytest.raises(CalibrationError):
        Intrinsics(**kwargs)  # type: ignore[arg-type]


def test_tum_default_for_names() -> None:
    assert c.tum_default_for("rgbd_dataset_freiburg1_xyz") is FR1
    assert c.tum_default_for("TUM_FR2_desk") is FR2
    assert c.tum_default_for("fr3_office") is TUM_DEFAULTS["freiburg3"]
    assert c.tum_default_for("studio") is None
