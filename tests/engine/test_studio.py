"""The built-in virtual studio: exact RGB-D truth, presenter, ball, options, determinism."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from engine.camera import backproject, project
from engine.errors import SourceError
from engine.geometry import invert, transform_points
from engine.sources import open_source
from engine.sources.synthetic import SyntheticSource
from engine.studio.sim import StudioLabels, StudioTruth

SMALL = "width=160,height=120"


def _src(opts: str) -> SyntheticSource:
    src = open_source(f"synthetic:{opts}")
    assert isinstance(src, SyntheticSource)
    return src


def _world_points(frame, uv):  # type: ignore[no-untyped-def]
    z = frame.depth_m[uv[:, 1].astype(int), uv[:, 0].astype(int)]
    return transform_points(frame.gt_T_world_cam, backproject(frame.intrinsics, uv, z))


@pytest.mark.parametrize("distortion", [0, 1])
def test_static_points_agree_across_frames_to_a_millimetre(distortion: int) -> None:
    """Backproject a static pixel with the true pose in frame i; re-render frame j with the
    principal point shifted so that the same world point falls exactly on a pixel centre;
    backprojecting that pixel gives the same world point (< 1 mm): exact RGB-D truth."""
    from engine.studio.render import Renderer

    src = _src(f"frames=90,cycles=1,{SMALL},distortion={distortion}")
    fi, fj = src.frame(5), src.frame(16)
    rng = np.random.default_rng(0)
    uv_i = np.stack([rng.integers(20, 140, 12), rng.integers(15, 105, 12)], axis=1).astype(float)
    P = _world_points(fi, uv_i)
    cam = src.intrinsics
    p_cam_j = transform_points(invert(fj.gt_T_world_cam), P)
    uv_j = project(cam, p_cam_j)
    errs = []
    for k in range(len(P)):
        du, dv = uv_j[k] - np.round(uv_j[k])
        cam_k = dataclasses.replace(cam, cx=cam.cx - du, cy=cam.cy - dv)
        out = Renderer(src.studio.scene, cam_k).render(fj.gt_T_world_cam)
        u, v = (int(c) for c in np.round(uv_j[k]))
        if not (0 <= u < cam.width and 0 <= v < cam.height):
            continue
        z = out.depth_m[v, u]
        if z < p_cam_j[k, 2] - 0.01:
            continue  # occluded in frame j by something nearer
        Q = transform_points(
            fj.gt_T_world_cam, backproject(cam_k, np.array([[u, v]], float), np.array([z]))
        )[0]
        errs.append(np.linalg.norm(Q - P[k]))
    assert len(errs) >= 8
    assert max(errs) < 1e-3, errs


def test_warped_colours_agree_between_frames() -> None:
    """Colour is a property of the surface (Lambertian, baked lighting): warping frame i
    into frame j with depth and true poses reproduces frame j's colours."""
    src = _src(f"frames=90,cycles=1,{SMALL}")
    fi, fj = src.frame(10), src.frame(14)
    cam = src.intrinsics
    h, w = fi.depth_m.shape
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    P = transform_points(fi.gt_T_world_cam, backproject(cam, uv, fi.depth_m.ravel()))
    pj = transform_points(invert(fj.gt_T_world_cam), P)
    uvj = project(cam, pj).astype(np.float32)
    gray_j = fj.gray_f32
    warped = cv2.remap(gray_j, uvj[:, 0].reshape(h, w), uvj[:, 1].reshape(h, w), cv2.INTER_LINEAR)
    zj = cv2.remap(fj.depth_m, uvj[:, 0].reshape(h, w), uvj[:, 1].reshape(h, w), cv2.INTER_NEAREST)
    inside = (uvj[:, 0] > 1) & (uvj[:, 0] < w - 2) & (uvj[:, 1] > 1) & (uvj[:, 1] < h - 2)
    visible = inside.reshape(h, w) & (np.abs(zj - pj[:, 2].reshape(h, w)) < 0.01)
    diff = np.abs(warped - fi.gray_f32)[visible]
    assert visible.mean() > 0.6
    assert np.median(diff) < 2.0
    assert np.mean(diff) < 6.0


def test_presenter_occludes_the_set_and_box_matches_labels() -> None:
    from engine.studio.render import Renderer

    src = _src(f"frames=60,presenter=1,path=static,{SMALL}")
    f = src.frame(20)
    assert f.gt_box_xywh is not None
    labels = f.payload(StudioLabels).labels
    mask = (labels >= 1) & (labels <= 3)
    x, y, bw, bh = f.gt_box_xywh
    ys, xs = np.nonzero(mask)
    assert (xs.min(), ys.min(), xs.max() - xs.min() + 1, ys.max() - ys.min() + 1) == (x, y, bw, bh)
    empty = Renderer(src.studio.scene, src.intrinsics).render(f.gt_T_world_cam)
    assert np.all(f.depth_m[mask] < empty.depth_m[mask] - 0.05)
    assert np.array_equal(f.depth_m[~mask], empty.depth_m[~mask])
    parts = f.payload(StudioTruth).presenter_part_boxes
    assert set(parts) == {"head", "torso", "legs"}
    head, legs = parts["head"], parts["legs"]
    assert head is not None
    assert legs is not None
    assert head[1] < legs[1]  # head above legs in the image
    # distinct colours: skin head, blue torso, dark legs
    bgr = f.color_bgr.astype(float)
    torso = bgr[labels == 2].mean(axis=0)
    assert torso[0] > torso[2] + 30  # blue
    assert bgr[labels == 3].mean() < bgr[labels == 1].mean() - 40
    feet = f.payload(StudioTruth).presenter_pos_world
    assert feet[2] == 0.0
    assert abs(feet[1] - 2.4) < 1e-9


def test_presenter_leaves_the_frame_and_returns() -> None:
    src = _src(f"frames=240,presenter=1,presenter_mode=leave,path=static,{SMALL}")
    vis = [src.frame(i).gt_box_xywh is not None for i in range(0, 240, 6)]
    assert vis[0]
    assert vis[-1]
    gone = [i for i, v in enumerate(vis) if not v]
    assert gone, "the presenter never left the frame"
    assert gone[0] > 80 // 6
    assert gone[-1] < 240 // 6 - 1
    assert all(not vis[i] for i in range(gone[0], gone[-1] + 1))  # one absence, then back


def test_still_presenter_does_not_move() -> None:
    src = _src(f"frames=40,presenter=1,presenter_mode=still,path=static,{SMALL}")
    a, b = src.frame(3), src.frame(37)
    assert a.gt_box_xywh == b.gt_box_xywh
    assert np.array_equal(a.color_bgr, b.color_bgr)


def test_presenter_start_and_last_cycles() -> None:
    src = _src(f"cycles=3,cycle_s=1,presenter=1,presenter_last_cycles=1,{SMALL}")
    assert len(src) == 90
    assert src.config.presenter is not None
    assert src.config.presenter.start_frame == 60
    assert src.frame(59).payload(StudioTruth).presenter_in_scene is False
    assert src.frame(59).gt_box_xywh is None
    assert src.frame(60).payload(StudioTruth).presenter_in_scene is True


def test_ball_truth_projects_into_its_pixels() -> None:
    src = _src(f"frames=30,ball=1,path=static,{SMALL}")
    f = src.frame(0)
    assert f.payload(StudioTruth).ball_pixels > 10
    x, y, bw, bh = f.payload(StudioTruth).ball_box_xywh
    u, v = f.payload(StudioTruth).ball_center_px
    assert x <= u <= x + bw
    assert y <= v <= y + bh
    red = f.color_bgr[f.payload(StudioLabels).labels == 4].astype(float).mean(axis=0)
    assert red[2] > 2 * red[1]
    assert red[2] > 2 * red[0]
    p0 = np.array(f.payload(StudioTruth).ball_pos_world)
    c = np.array(src.config.ball.centre_m)
    assert abs(np.linalg.norm(p0 - c) - 1.0) < 1e-9
    assert 2 * np.pi / f.payload(StudioTruth).ball_omega_rad_s == pytest.approx(30.0)


def test_rail_path_travels_3_3_m_back_and_forth_with_fixed_orientation() -> None:
    src = _src(f"frames=180,cycles=2,{SMALL}")
    Ts = [src.studio.T_world_cam(i) for i in (0, 45, 90, 135)]
    xs = [T[0, 3] for T in Ts]
    assert xs[0] == pytest.approx(-1.65)
    assert xs[1] == pytest.approx(1.65)
    assert xs[2] == pytest.approx(-1.65)
    assert xs[3] == pytest.approx(1.65)
    for T in Ts:
        np.testing.assert_allclose(T[:3, :3], Ts[0][:3, :3], atol=1e-12)
        assert T[1, 3] == 0.0
        assert T[2, 3] == 1.5
    # camera looks towards +y (the set) and the image's "down" is world -z-ish
    assert Ts[0][1, 2] > 0.9
    assert Ts[0][2, 1] < -0.9


@pytest.mark.parametrize("path", ["pan", "handheld"])
def test_other_paths_move_smoothly(path: str) -> None:
    src = _src(f"frames=60,path={path},{SMALL}")
    Ts = [src.studio.T_world_cam(i) for i in range(60)]
    steps = [np.linalg.norm(Ts[i + 1][:3, 2] - Ts[i][:3, 2]) for i in range(59)]
    assert max(steps) < 0.05  # < ~3 degrees per frame
    assert max(steps) > 1e-4
    f = src.frame(30)
    assert f.depth_m.min() > 0.2


def test_frames_timestamps_intrinsics() -> None:
    src = _src(f"frames=4,{SMALL}")
    frames = list(src)
    assert [f.index for f in frames] == [0, 1, 2, 3]
    assert [f.timestamp_s for f in frames] == pytest.approx([0, 1 / 30, 2 / 30, 3 / 30])
    cam = src.intrinsics
    assert (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy) == (
        160,
        120,
        131.25,
        131.25,
        79.5,
        59.5,
    )
    f = frames[0]
    assert f.color_bgr.shape == (120, 160, 3)
    assert f.color_bgr.dtype == np.uint8
    assert f.depth_m.dtype == np.float32
    assert f.depth_m.min() > 0
    assert not f.color_bgr.flags.writeable
    full = SyntheticSource.from_options({}).intrinsics
    assert (full.fx, full.cx, full.cy, full.width, full.height) == (525.0, 319.5, 239.5, 640, 480)


def test_same_seed_same_arrays_other_seed_other_textures() -> None:
    opts = (
        f"frames=10,seed=3,presenter=1,ball=1,noise=1,dropouts=1,color_noise=2,blur=0.7,"
        f"vignette=0.5,{SMALL}"
    )
    a, b = _src(opts).frame(7), _src(opts).frame(7)
    assert np.array_equal(a.color_bgr, b.color_bgr)
    assert np.array_equal(a.depth_m, b.depth_m)
    assert a.gt_box_xywh == b.gt_box_xywh
    c = _src(opts.replace("seed=3", "seed=4")).frame(7)
    assert not np.array_equal(a.color_bgr, c.color_bgr)


def test_depth_noise_grows_with_distance_and_dropouts_make_holes() -> None:
    f = _src(f"frames=2,noise=1,dropouts=0.05,{SMALL}").frame(1)
    exact = f.payload(StudioLabels).depth_exact_m
    valid = f.depth_m > 0
    hole_frac = 1.0 - valid.mean()
    assert 0.05 < hole_frac < 0.3  # blobs plus edge dropouts
    err = (f.depth_m - exact)[valid]
    z = exact[valid]
    near, far = np.std(err[z < 2.6]), np.std(err[z > 3.8])
    assert far > near > 0
    assert np.std(err[z > 3.8]) == pytest.approx(0.0012 + 0.0019 * (4.2 - 0.4) ** 2, rel=0.4)


@pytest.mark.parametrize(
    ("spec", "name"),
    [
        ("synthetic:frobnicate=1", "frobnicate"),
        ("synthetic:frames=abc", "frames"),
        ("synthetic:frames=0", "frames"),
        ("synthetic:path=orbit", "path"),
        ("synthetic:presenter=2", "presenter"),
        ("synthetic:width=3", "width"),
        ("synthetic:noise=-1", "noise"),
        ("synthetic:presenter_mode=dance,presenter=1", "presenter_mode"),
        ("synthetic:presenter_mode=still", "presenter_mode"),
        ("synthetic:cycles=0", "cycles"),
        ("synthetic:frames=10,cycles=1,cycle_s=3", "cycle_s"),
        ("synthetic:ball_period_s=nan", "ball_period_s"),
    ],
)
def test_bad_options_name_the_option(spec: str, name: str) -> None:
    with pytest.raises(SourceError, match=name):
        open_source(spec)


def test_random_access_range_is_checked() -> None:
    src = _src(f"frames=3,{SMALL}")
    with pytest.raises(SourceError, match="out of range"):
        src.frame(3)


def test_pose_override_renders_the_same_instant_from_another_camera() -> None:
    src = _src(f"frames=30,presenter=1,ball=1,path=static,{SMALL}")
    T = src.studio.T_world_cam(0).copy()
    T[0, 3] += 0.5
    a, b = src.frame(12), src.frame(12, T)
    np.testing.assert_allclose(b.gt_T_world_cam, T)
    assert b.payload(StudioTruth).ball_pos_world == a.payload(StudioTruth).ball_pos_world
    assert b.payload(StudioTruth).presenter_pos_world == a.payload(StudioTruth).presenter_pos_world
    assert a.gt_box_xywh is not None
    assert b.gt_box_xywh is not None
    assert b.gt_box_xywh[0] < a.gt_box_xywh[0]  # camera moved right: presenter moves left


@pytest.mark.parametrize("spec", ["synthetic:ball_period_s=20", "synthetic:presenter_x=1"])
def test_dependent_options_need_their_switch(spec: str) -> None:
    with pytest.raises(SourceError, match="needs"):
        open_source(spec)


def test_occluder_covers_about_a_third_of_a_static_view() -> None:
    src = _src(f"frames=200,path=static,occluder=1,{SMALL}")
    f = src.frame(90)
    assert 0.25 < f.payload(StudioTruth).occluder_fraction < 0.4
    mask = f.payload(StudioLabels).labels == 5
    x, y, w, h = f.payload(StudioTruth).occluder_box_xywh
    assert mask[int(y) : int(y + h), int(x) : int(x + w)].mean() > 0.9
    assert f.depth_m[mask].max() < 1.8  # 1.6 m in front of the rail, nearer than the set


def test_covered_lens_gives_dark_frames_without_depth_but_keeps_the_truth() -> None:
    src = _src(f"frames=40,cover_start=10,cover_frames=5,{SMALL}")
    covered = [src.frame(i).payload(StudioTruth).covered for i in range(8, 17)]
    assert covered == [False, False, True, True, True, True, True, False, False]
    f = src.frame(12)
    assert f.color_bgr.max() < 10
    assert not np.any(f.depth_m)
    np.testing.assert_array_equal(f.gt_T_world_cam, src.studio.T_world_cam(12))
