"""Depth map fusion (Tykkälä 2014 sec. 6.1, Fig. 10) on the built-in studio."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from engine.keyframes.fusion import (
    FusionParams,
    PosedFrame,
    SourceFrames,
    fuse_depth,
)
from engine.keyframes.store import KeyframeStore
from engine.sources import open_source
from engine.studio.sim import StudioLabels


@pytest.fixture(scope="module")
def sweep():  # type: ignore[no-untyped-def]
    src = open_source("synthetic:frames=24,width=160,height=120,noise=1,dropouts=1,cycle_s=3")
    frames = [src.frame(i) for i in range(24)]
    store = KeyframeStore(src.intrinsics)
    exact = {}
    for i in (0, 8, 16):
        f = frames[i]
        kf = store.add(
            f.gt_T_world_cam, cv2.cvtColor(f.color_bgr, cv2.COLOR_BGR2GRAY), np.array(f.depth_m)
        )
        exact[kf.id] = f.payload(StudioLabels).depth_exact_m
    posed = [
        PosedFrame(
            f.index, cv2.cvtColor(f.color_bgr, cv2.COLOR_BGR2GRAY), f.depth_m, f.gt_T_world_cam
        )
        for f in frames
        if f.index not in (0, 8, 16)
    ]
    return src, store, exact, posed


def _med_err(d: np.ndarray, ex: np.ndarray) -> float:
    m = (d > 0) & (ex > 0)
    return float(np.median(np.abs(d[m] - ex[m])))


def test_fusion_fills_holes_and_reduces_noise(sweep) -> None:  # type: ignore[no-untyped-def]
    _, store, exact, posed = sweep
    calls = []
    res = fuse_depth(
        store, posed, FusionParams(delta_inv_m=0.01), progress=lambda d, n: calls.append((d, n))
    )
    assert not res.cancelled
    assert res.frames_used == len(posed)
    assert calls[-1] == (len(posed), len(posed))
    assert res.hole_fraction_before > 0.02
    assert res.hole_fraction_after < 0.3 * res.hole_fraction_before
    for s in res.stats:
        kf = store.by_id(s.kf_id)
        assert s.frames > 0
        assert s.noise_after_m < 0.7 * s.noise_before_m
        assert _med_err(res.depth_m[s.kf_id], exact[s.kf_id]) < 0.7 * _med_err(
            kf.depth_m, exact[s.kf_id]
        )
    fused = res.apply_to(store)
    assert len(fused) == len(store)
    assert fused.keyframes[0].depth_m is res.depth_m[0]
    assert store.keyframes[0].depth_m is not res.depth_m[0]  # the input store is unchanged


def test_colour_deviation_rejects_wrong_samples(sweep) -> None:  # type: ignore[no-untyped-def]
    _, store, _, posed = sweep
    base = fuse_depth(store, posed)
    f = posed[0]
    # a bogus frame: right pose, depth 30 % too near, grey values off by 128: all rejected
    # by the colour test
    shifted = ((f.gray.astype(np.int16) + 128) % 256).astype(np.uint8)
    bogus = [PosedFrame(f.index, shifted, f.depth_m * 0.7, f.T_world_cam)] * 3
    res = fuse_depth(store, posed + bogus, FusionParams(color_tol=10))
    ref = fuse_depth(store, posed, FusionParams(color_tol=10))
    for k in res.depth_m:  # a colour test is statistical: a chance match may slip through
        same = np.isclose(res.depth_m[k], ref.depth_m[k], atol=2e-3)
        assert same.mean() > 0.999
    assert base.frames_used == len(posed)


def test_cancel_returns_originals(sweep) -> None:  # type: ignore[no-untyped-def]
    _, store, _, posed = sweep
    n = {"calls": 0}

    def stop() -> bool:
        n["calls"] += 1
        return n["calls"] > 3

    res = fuse_depth(store, posed, should_stop=stop)
    assert res.cancelled
    assert res.stats == ()
    for kf in store.keyframes:
        assert res.depth_m[kf.id] is kf.depth_m


def test_source_frames_and_median_window() -> None:
    src = open_source("synthetic:frames=6,width=80,height=60")
    store = KeyframeStore(src.intrinsics)
    f0 = src.frame(0)
    store.add(
        f0.gt_T_world_cam, cv2.cvtColor(f0.color_bgr, cv2.COLOR_BGR2GRAY), np.array(f0.depth_m)
    )
    poses = {i: src.frame(i).gt_T_world_cam for i in range(6)}
    res = fuse_depth(store, SourceFrames(src, poses, skip=[0]))
    assert res.frames_used == 5
    assert res.stats[0].frames == 5
    # the median window (Fig. 10): an outlier far from the median is ignored
    from engine.keyframes.fusion_kernels import robust_inverse_depth

    buf = np.zeros((3, 4), np.float32)
    buf[0] = [0.50, 0.9, 0.51, 0.49]
    buf[1, 0] = 0.3
    cnt = np.array([4, 1, 0], np.int32)
    out = np.zeros(3, np.float32)
    robust_inverse_depth(buf, cnt, 0.05, 2, out)
    np.testing.assert_allclose(out, [0.5, 0.0, 0.0], atol=1e-6)
