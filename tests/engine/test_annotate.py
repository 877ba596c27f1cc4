"""Prediction of a clicked point in other keyframes and sub-pixel snapping (sec. 6.1)."""

from __future__ import annotations

import cv2
import numpy as np

from engine.geometry import se3_exp
from engine.keyframes.annotate import point_from_click, predict, snap
from engine.sources import open_source


def test_prediction_and_snap_recover_true_position() -> None:
    src = open_source("synthetic:frames=40,width=320,height=240,path=rail,cycle_s=3")
    fa, fb = src.frame(5), src.frame(14)
    intr = fa.intrinsics
    ga = cv2.cvtColor(fa.color_bgr, cv2.COLOR_BGR2GRAY)
    gb = cv2.cvtColor(fb.color_bgr, cv2.COLOR_BGR2GRAY)
    corners = cv2.goodFeaturesToTrack(ga, 30, 0.05, 12, blockSize=7)[:, 0, :]
    T_b_bad = fb.gt_T_world_cam @ se3_exp(np.array([0.01, -0.005, 0.01, 0.003, -0.006, 0.002]))
    before, after = [], []
    for u, v in corners:
        if not (20 < u < 300 and 20 < v < 220):
            continue
        X = point_from_click(intr, fa.gt_T_world_cam, fa.depth_m, (float(u), float(v)))
        true = predict(intr, X, fb.gt_T_world_cam, fb.depth_m)
        guess = predict(intr, X, T_b_bad, fb.depth_m)
        if true.uv is None or guess.uv is None:
            continue
        s = snap(ga, (float(u), float(v)), gb, guess.uv)
        if not s.ok:
            continue
        before.append(np.hypot(*np.subtract(guess.uv, true.uv)))
        after.append(np.hypot(*np.subtract(s.uv, true.uv)))
    assert len(after) >= 8
    assert np.median(before) > 1.0  # the pose error moves the prediction by pixels
    assert np.median(after) < 0.35  # the snap brings it back, sub-pixel


def test_prediction_flags_invisible_points() -> None:
    from engine.camera import Intrinsics

    intr = Intrinsics(width=64, height=48, fx=50, fy=50, cx=31.5, cy=23.5)
    T = np.eye(4)
    assert predict(intr, None, T).reason == "no depth at the clicked pixel"
    assert predict(intr, np.array([0.0, 0.0, -1.0]), T).reason == "behind the camera"
    assert predict(intr, np.array([5.0, 0.0, 1.0]), T).reason == "outside the image"
    depth = np.full((48, 64), 1.0, np.float32)
    assert predict(intr, np.array([0.0, 0.0, 3.0]), T, depth).reason.startswith("occluded")
    assert predict(intr, np.array([0.0, 0.0, 1.02]), T, depth).uv is not None
    flat = np.full((48, 64), 100, np.uint8)
    assert not snap(flat, (30.0, 20.0), flat, (30.0, 20.0)).ok  # no texture: no snap
