"""The dense tracker's rolling-shutter model (colour and depth rows exposed one after the
other while the camera moves) and the built-in studio's rolling-shutter camera."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from engine.camera import Intrinsics
from engine.dense import kernels
from engine.frames import Frame
from engine.geometry import invert, se3_exp
from engine.keyframes.store import KeyframeStore
from engine.sources import open_source
from engine.trackers import create_tracker
from engine.trackers.dense import DenseParams


def _frames(spec: str) -> list[Frame]:
    with open_source(spec) as src:
        return list(src.frames())


def test_project_rs_is_project_at_rest_and_the_row_instants_pose_when_moving() -> None:
    """``project_rs`` with no motion is ``project``; with a velocity, a point lands where the
    camera of its row's instant sees it (to first order in the readout)."""
    rng = np.random.default_rng(2)
    P = np.ascontiguousarray(np.column_stack([rng.uniform(-1, 1, 50), rng.uniform(-0.8, 0.8, 50),
                                              rng.uniform(2, 5, 50)]).T, dtype=np.float32)
    T = se3_exp(np.array([0.02, -0.01, 0.03, 0.01, -0.02, 0.005]))
    cam = np.array([525.0, 525.0, 319.5, 239.5])
    dist = np.zeros(5)
    n = P.shape[1]
    u, v, z = np.zeros(n), np.zeros(n), np.zeros(n)
    ur, vr, zr = np.zeros(n), np.zeros(n), np.zeros(n)
    kernels.project(P, T, cam, dist, u, v, z, 0, n)
    rs = np.zeros(8)
    rs[0], rs[1] = 0.02 / 480, 239.5
    kernels.project_rs(P, T, cam, dist, rs, ur, vr, zr, 0, n)
    assert np.allclose(ur, u)
    assert np.allclose(vr, v)
    xi = np.array([0.8, -0.3, 0.2, 0.1, 0.4, -0.2])  # m/s, rad/s: a fast move
    rs[2:] = xi
    kernels.project_rs(P, T, cam, dist, rs, ur, vr, zr, 0, n)
    for i in range(n):
        tau = (v[i] - 239.5) * rs[0]
        X = (T @ np.append(P[:, i].astype(np.float64), 1.0))[:3]
        X_row = (invert(se3_exp(tau * xi)) @ np.append(X, 1.0))[:3]
        want = cam[:2] * X_row[:2] / X_row[2] + cam[2:]
        assert np.allclose((ur[i], vr[i]), want, atol=0.02)  # px: first order, one pass
    assert np.max(np.hypot(ur - u, vr - v)) > 1.0  # the model moved them


def test_the_studio_renders_a_rolling_shutter_camera() -> None:
    """``rolling_shutter=S``: the middle rows are the frame instant's, the first and last
    rows the path's pose half a readout before and after; the frames carry the readout."""
    base = "synthetic:frames=12,path=pan,seed=7,width=160,height=120,ahead=0"
    still = _frames(base)[10]
    rolled = _frames(base + ",rolling_shutter=0.03")[10]
    assert rolled.intrinsics is not None
    assert rolled.intrinsics.rolling_shutter_s == 0.03
    assert still.intrinsics is not None
    assert still.intrinsics.rolling_shutter_s == 0.0
    diff = np.abs(still.color_bgr.astype(int) - rolled.color_bgr.astype(int)).mean(axis=(1, 2))
    assert diff[:10].mean() > 3.0 * diff[55:65].mean()
    assert np.array_equal(rolled.gt_T_world_cam, still.gt_T_world_cam)


@pytest.mark.parametrize("tracker", ["dense", "dense-incremental"])
def test_the_rolling_shutter_model_tracks_a_fast_pan(tracker: str) -> None:
    """A 20 ms readout on the studio's pan: modelled, the error is a third of the
    unmodelled one or less; a global-shutter camera is tracked bit for bit as before."""
    frames = _frames("synthetic:frames=60,path=pan,seed=7,width=320,height=240,"
                     "rolling_shutter=0.02")

    def err(on: bool, fr: list[Frame]) -> float:
        t = create_tracker(tracker, dataclasses.replace(DenseParams(), rolling_shutter=on))
        est = np.array([t.track(f).T_world_cam for f in fr])
        gt = np.array([f.gt_T_world_cam for f in fr])
        # started at the true pose: the plain position RMSE
        return float(np.sqrt(np.mean(np.sum((est[:, :3, 3] - gt[:, :3, 3]) ** 2, axis=1))))

    on, off = err(True, frames), err(False, frames)
    assert on < off / 3.0
    flat = [dataclasses.replace(f, intrinsics=dataclasses.replace(
        f.intrinsics, rolling_shutter_s=0.0)) for f in frames[:20] if f.intrinsics is not None]
    assert err(True, flat) == err(False, flat)


def test_keyframes_keep_the_cameras_velocity(tmp_path: Path) -> None:
    """Each online keyframe keeps the camera's velocity (the first one as soon as it is
    known), the store saves and loads it, and a malformed one is a one-line error."""
    frames = _frames("synthetic:frames=40,path=pan,seed=7,width=160,height=120,"
                     "rolling_shutter=0.02")
    t = create_tracker("dense")
    for f in frames:
        t.track(f)
    store = t.store
    assert isinstance(store, KeyframeStore)
    assert len(store) >= 2
    assert all(k.twist_per_s is not None for k in store.keyframes)
    store.save(tmp_path / "kf")
    back = KeyframeStore.load(tmp_path / "kf")
    for a, b in zip(store.keyframes, back.keyframes, strict=True):
        assert np.array_equal(a.twist_per_s, b.twist_per_s)
    assert back.intrinsics.rolling_shutter_s == 0.02
    import json

    index = tmp_path / "kf" / "keyframes.json"
    doc = json.loads(index.read_text())
    doc["keyframes"][0]["twist_per_s"] = [1, 2, 3]
    index.write_text(json.dumps(doc))
    from engine.keyframes.store import KeyframeStoreError

    with pytest.raises(KeyframeStoreError, match="twist_per_s"):
        KeyframeStore.load(tmp_path / "kf")


def test_camera_json_carries_the_readout(tmp_path: Path) -> None:
    from engine.camera import load_camera_json, save_camera_json
    from engine.errors import CalibrationError

    cam = Intrinsics(rolling_shutter_s=0.021)
    save_camera_json(cam, tmp_path / "camera.json")
    assert load_camera_json(tmp_path / "camera.json") == cam
    with pytest.raises(CalibrationError, match="rolling_shutter_s"):
        Intrinsics(rolling_shutter_s=-0.01)
