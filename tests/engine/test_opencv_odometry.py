"""Tracker ``opencv-odometry`` on rendered RGB-D frames with known motion, and on real TUM data."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from engine.camera import Intrinsics
from engine.errors import ParamsError
from engine.frames import Frame
from engine.geometry import invert, rotation_angle_rad, se3_exp
from engine.trackers import create_tracker, get_spec
from engine.trackers.base import TrackState
from engine.trackers.opencv_odometry import OpenCVOdometryParams, OpenCVOdometryTracker
from tests.conftest import shared_path

CAM = Intrinsics(fx=262.5, fy=262.5, cx=159.5, cy=119.5, width=320, height=240)


def _texture(seed: int = 0) -> np.ndarray:
    import cv2

    rng = np.random.default_rng(seed)
    noise = rng.uniform(0, 255, (512, 512)).astype(np.float32)
    tex = cv2.GaussianBlur(noise, (0, 0), 3.0)
    tex = (tex - tex.min()) / (tex.max() - tex.min()) * 255.0
    return tex.astype(np.float32)


TEX = _texture()

# Planes of a small room in the world frame (OpenCV axes: x right, y down, z forward):
# (axis, value, texture axes). Back wall z = 1.8 m, floor y = 0.4 m, left wall x = -0.6 m.
PLANES = ((2, 1.8, (0, 1)), (1, 0.4, (0, 2)), (0, -0.6, (2, 1)))


def render(T_world_cam: np.ndarray, cam: Intrinsics = CAM) -> tuple[np.ndarray, np.ndarray]:
    """BGR uint8 image and depth (m) of the textured room seen from ``T_world_cam``."""
    import cv2

    u, v = np.meshgrid(np.arange(cam.width), np.arange(cam.height))
    d_cam = np.stack([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, np.ones_like(u, float)], -1)
    d_w = d_cam @ T_world_cam[:3, :3].T
    c = T_world_cam[:3, 3]
    best_t = np.full(u.shape, np.inf)
    tex_uv = np.zeros((*u.shape, 2), np.float32)
    for axis, value, (ta, tb) in PLANES:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (value - c[axis]) / d_w[..., axis]
        hit = (t > 0.05) & (t < best_t)
        p = c + d_w * t[..., None]
        best_t = np.where(hit, t, best_t)
        tex_uv[hit, 0] = (p[hit, ta] * 150.0) % 512
        tex_uv[hit, 1] = (p[hit, tb] * 150.0) % 512
    grey = cv2.remap(TEX, tex_uv[..., 0], tex_uv[..., 1], cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_WRAP)
    depth = np.where(np.isfinite(best_t), best_t, 0.0).astype(np.float32)  # z of d_cam is 1
    bgr = cv2.cvtColor(np.clip(grey, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)
    return bgr, depth


def frame_at(k: int, T: np.ndarray, *, depth: bool = True, gt: bool = True) -> Frame:
    bgr, d = render(T)
    return Frame(
        index=k,
        timestamp_s=k / 30.0,
        color_bgr=bgr,
        intrinsics=CAM,
        depth_m=d if depth else None,
        gt_T_world_cam=T if gt else None,
    )


def _path(n: int) -> list[np.ndarray]:
    start = se3_exp(np.array([0.1, -0.1, 0.2, 0.02, 0.05, 0.0]))
    step = se3_exp(np.array([0.008, 0.002, 0.006, 0.0, 0.004, 0.002]))
    poses = [start]
    for _ in range(n - 1):
        poses.append(poses[-1] @ step)
    return poses


def _err(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    D = invert(T_true) @ T_est
    return float(np.linalg.norm(D[:3, 3])), float(np.degrees(rotation_angle_rad(D[:3, :3])))


def test_registered_with_depth_and_pose_output() -> None:
    spec = get_spec("opencv-odometry")
    assert spec.needs_depth
    assert spec.output == "pose"
    assert isinstance(create_tracker("opencv-odometry"), OpenCVOdometryTracker)


def test_recovers_known_motion_on_rendered_frames() -> None:
    poses = _path(6)
    tr = OpenCVOdometryTracker()
    first = tr.track(frame_at(0, poses[0]))
    assert first.state is TrackState.TRACKING
    np.testing.assert_allclose(first.T_world_cam, poses[0])  # starts at ground truth
    for k in range(1, len(poses)):
        res = tr.track(frame_at(k, poses[k]))
        assert res.state is TrackState.TRACKING, res.message
        assert {"prepare", "compute"} <= set(res.timings_ms)
    t_err, r_err = _err(res.T_world_cam, poses[-1])
    assert t_err < 0.001  # measured ~1e-5 m: the room has three planes, ICP is well posed
    assert r_err < 0.05


def test_starts_at_identity_without_ground_truth_or_when_asked() -> None:
    poses = _path(2)
    res = OpenCVOdometryTracker().track(frame_at(0, poses[0], gt=False))
    np.testing.assert_allclose(res.T_world_cam, np.eye(4))
    tr = OpenCVOdometryTracker(OpenCVOdometryParams(start_at_ground_truth=False))
    np.testing.assert_allclose(tr.track(frame_at(0, poses[0])).T_world_cam, np.eye(4))


def test_frame_without_depth_is_lost_with_a_message_and_tracking_resumes() -> None:
    poses = _path(4)
    tr = OpenCVOdometryTracker()
    res = tr.track(frame_at(0, poses[0], depth=False))
    assert res.state is TrackState.INITIALIZING
    assert res.T_world_cam is None
    assert "needs depth" in res.message
    tr.track(frame_at(1, poses[1]))
    held = tr.track(frame_at(2, poses[2], depth=False))
    assert held.state is TrackState.LOST
    np.testing.assert_allclose(held.T_world_cam, poses[1])  # holds the last good pose
    back = tr.track(frame_at(3, poses[3]))
    assert back.state is TrackState.TRACKING
    assert _err(back.T_world_cam, poses[3])[0] < 0.001


def test_failed_compute_holds_pose_then_reanchors() -> None:
    poses = _path(2)
    tr = OpenCVOdometryTracker(OpenCVOdometryParams(reanchor_after_lost=2))
    tr.track(frame_at(0, poses[0]))
    bgr, _ = render(poses[1])
    empty = Frame(1, 1 / 30, bgr, CAM, np.zeros((CAM.height, CAM.width), np.float32))
    r1 = tr.track(empty)
    assert r1.state is TrackState.LOST
    assert "compute failed" in r1.message
    np.testing.assert_allclose(r1.T_world_cam, poses[0])
    r2 = tr.track(dataclasses.replace(empty, index=2))
    assert "re-anchored" in r2.message


def test_params_validation_and_set_params_next_frame() -> None:
    with pytest.raises(ParamsError, match="algorithm 'orb'"):
        OpenCVOdometryParams(algorithm="orb")
    with pytest.raises(ParamsError, match="max_depth_m"):
        OpenCVOdometryParams(min_depth_m=3.0, max_depth_m=2.0)
    with pytest.raises(ParamsError, match="max_points_part"):
        OpenCVOdometryParams(max_points_part=1.5)
    poses = _path(3)
    tr = OpenCVOdometryTracker()
    tr.track(frame_at(0, poses[0]))
    tr.set_params(OpenCVOdometryParams(algorithm="icp"))
    assert tr.params.algorithm == "icp"
    res = tr.track(frame_at(1, poses[1]))
    assert res.state is TrackState.TRACKING
    assert _err(res.T_world_cam, poses[1])[0] < 0.001
    with pytest.raises(ParamsError):
        tr.set_params(object())


def test_tracks_the_first_tum_frames() -> None:
    from engine.sources.tum import TumSource

    folder = shared_path("tum_fr1_xyz_37")
    frames = []
    for f in TumSource(folder).frames():
        frames.append(f)
        if len(frames) == 6:
            break
    tr = OpenCVOdometryTracker()
    results = [tr.track(f) for f in frames]
    assert all(r.state is TrackState.TRACKING for r in results)
    t_err, _ = _err(results[-1].T_world_cam, frames[-1].gt_T_world_cam)
    assert t_err < 0.02  # ~7 cm travelled; drift stays at the mm level
