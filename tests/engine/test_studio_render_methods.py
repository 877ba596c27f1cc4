"""The studio renderer's two texture paths give the same images: ``remap`` (the default:
the kernel writes where to sample, ``cv2.remap`` samples) against ``raycast`` (the kernel
samples in floating point). Depth and labels are the same, bit for bit; colours differ by
fixed-point rounding only (a grey level, a few at the sharpest texture edges); the flat-shaded
people, ball and occluder are the same."""

from __future__ import annotations

import numpy as np
import pytest

from engine.errors import SourceError
from engine.sources import open_source
from engine.sources.synthetic import SyntheticSource
from engine.studio.presenter import body_prims, concat_prims
from engine.studio.render import Prims, Renderer, RenderOutput, _atlas_2d
from engine.studio.scene import LABEL_SET, build_scene
from engine.studio.sim import Studio, occluder_centre, occluder_prims

CASES = [
    # presenter and ball on the rail: the set, its props and the people in one picture
    ("frames=120,presenter=1,ball=1,path=rail", (0, 30, 61, 95)),
    # a distorting lens on the pan: every ray off the pinhole grid
    ("frames=120,presenter=1,path=pan,distortion=1", (10, 47)),
    # hand-held with the occluder close in front and a second person: occlusion boundaries
    ("frames=120,presenter=1,person2=cross,occluder=1,path=handheld", (20, 70)),
    # the side key light on the people (dynamic light)
    ("frames=120,presenter=1,lighting=side,path=static", (40,)),
]


def _prims(studio: Studio, i: int) -> Prims | None:
    cfg, sc = studio.config, studio.scene
    parts = []
    if cfg.presenter is not None and (st := cfg.presenter.state(i)) is not None:
        parts.append(body_prims(st, sc, cfg.presenter.look)[0])
    if cfg.person2 is not None and (st2 := cfg.person2.state(i)) is not None:
        parts.append(body_prims(st2, sc, cfg.person2.look, 6)[0])
    if cfg.ball is not None:
        parts.append(cfg.ball.prims(cfg.ball.state(i / cfg.fps)[0], sc))
    if cfg.occluder:
        parts.append(occluder_prims(occluder_centre(i / cfg.fps), sc))
    return concat_prims(*parts) if parts else None


def _edges(bgr: np.ndarray) -> np.ndarray:
    """Pixels on a sharp texture or object edge (a neighbour differs by > 40 grey levels)."""
    g = bgr.astype(np.int16).max(axis=2)
    e = np.zeros(g.shape, bool)
    e[:, 1:] |= np.abs(np.diff(g, axis=1)) > 40
    e[1:, :] |= np.abs(np.diff(g, axis=0)) > 40
    return e


@pytest.mark.parametrize(("spec", "frames"), CASES)
def test_remap_images_equal_the_ray_casters(spec: str, frames: tuple[int, ...]) -> None:
    src = open_source(f"synthetic:{spec},width=320,height=240")
    assert isinstance(src, SyntheticSource)
    studio = src.studio
    light = studio.renderer._dyn
    fast = studio.renderer
    assert fast.method == "remap"
    ref = Renderer(studio.scene, studio.intrinsics, dynamic_light=light, method="raycast")
    saw_edges = saw_people = 0
    for i in frames:
        T, prims = studio.T_world_cam(i), _prims(studio, i)
        a, b = ref.render(T, prims), fast.render(T, prims)
        assert np.array_equal(a.labels, b.labels)
        assert np.array_equal(a.depth_m, b.depth_m)
        d = np.abs(a.color_bgr.astype(np.int16) - b.color_bgr.astype(np.int16)).max(axis=2)
        assert d.max() <= 6, (i, int(d.max()))
        assert d.mean() < 0.25
        assert np.mean(d > 2) < 2e-3
        edges = _edges(a.color_bgr) & (a.labels == LABEL_SET)
        saw_edges += int(edges.sum())
        if edges.any():
            assert d[edges].mean() < 1.0
        # the flat-shaded people, ball and occluder: the same arithmetic, the same colours
        people = a.labels != LABEL_SET
        saw_people += int(people.sum())
        assert np.array_equal(a.color_bgr[people], b.color_bgr[people])
    assert saw_edges > 100
    assert saw_people > 100


def test_reused_output_buffers_give_the_same_frames() -> None:
    """remap leaves the flat-shaded pixels alone: a reused output must not keep the last
    frame's colours where the people were."""
    src = open_source("synthetic:frames=120,presenter=1,ball=1,width=320,height=240")
    assert isinstance(src, SyntheticSource)
    st = src.studio
    r = st.renderer
    h, w = r.xn.shape
    out = RenderOutput(np.zeros((h, w, 3), np.uint8), np.zeros((h, w), np.float32),
                       np.zeros((h, w), np.uint8))
    for i in (0, 50, 100):
        T, prims = st.T_world_cam(i), _prims(st, i)
        fresh = r.render(T, prims)
        r.render(T, prims, out=out)
        assert np.array_equal(fresh.color_bgr, out.color_bgr)
        assert np.array_equal(fresh.depth_m, out.depth_m)


def test_the_2d_atlas_holds_every_texture_with_its_wrap_column() -> None:
    scene = build_scene(0)
    img, xy = _atlas_2d(scene)
    assert _atlas_2d(scene)[0] is img  # one per scene
    assert img.shape[0] <= 32767
    assert img.shape[1] <= 32767
    m = scene.materials
    for k in range(len(m)):
        off, th, tw, wrap = int(m[k, 0]), int(m[k, 1]), int(m[k, 2]), bool(m[k, 4])
        if tw == 0:
            continue
        tex = scene.atlas_bgr[off:off + th * tw].reshape(th, tw, 3)
        x0, y0 = int(xy[k, 0]), int(xy[k, 1])
        assert np.array_equal(img[y0:y0 + th, x0:x0 + tw], tex)
        if wrap:
            assert np.array_equal(img[y0:y0 + th, x0 + tw], tex[:, 0])


def test_render_option_picks_the_path_and_rejects_others() -> None:
    a = open_source("synthetic:frames=5,presenter=1,width=160,height=120,render=raycast")
    b = open_source("synthetic:frames=5,presenter=1,width=160,height=120")
    assert isinstance(a, SyntheticSource)
    assert isinstance(b, SyntheticSource)
    assert a.studio.renderer.method == "raycast"
    fa, fb = a.frame(3), b.frame(3)
    assert fa.depth_m is not None
    assert fb.depth_m is not None
    assert np.array_equal(fa.depth_m, fb.depth_m)
    assert fa.gt_box_xywh == fb.gt_box_xywh
    with pytest.raises(SourceError, match="render"):
        open_source("synthetic:render=rasterize")
    with pytest.raises(ValueError, match="render method"):
        Renderer(build_scene(0), b.intrinsics, method="rasterize")


@pytest.mark.parametrize("spec", ["frames=60,presenter=1,ball=1,path=static",
                                  "frames=60,presenter=1,person2=cross,path=static,views=2"])
def test_a_still_camera_keeps_the_set_and_traces_only_the_people(spec: str) -> None:
    """The same pose twice running: the set is kept and only the tiles the people reach are
    traced again; every frame equals a fresh renderer's, bit for bit (also the second,
    overhead camera of views=2, which always stands still)."""
    src = open_source(f"synthetic:{spec},width=320,height=240")
    assert isinstance(src, SyntheticSource)
    st = src.studio
    r = st.renderer
    for i in (0, 1, 2, 9, 30, 31):
        T, prims = st.T_world_cam(i), _prims(st, i)
        kept = r.render(T, prims)
        fresh = Renderer(st.scene, st.intrinsics, dynamic_light=r._dyn).render(T, prims)
        assert np.array_equal(kept.color_bgr, fresh.color_bgr), i
        assert np.array_equal(kept.depth_m, fresh.depth_m), i
        assert np.array_equal(kept.labels, fresh.labels), i
    assert r._still is not None  # the set was kept
    # the camera moves: the kept frame is dropped, the next frames are traced whole
    T2 = st.T_world_cam(0).copy()
    T2[0, 3] += 0.1
    moved = r.render(T2, _prims(st, 5))
    assert r._still is None
    fresh = Renderer(st.scene, st.intrinsics, dynamic_light=r._dyn).render(T2, _prims(st, 5))
    assert np.array_equal(moved.color_bgr, fresh.color_bgr)
    if st.config.views == 2:
        f1, f2 = src.frame(3), src.frame(4)
        assert f1.payloads
        assert f2.payloads
