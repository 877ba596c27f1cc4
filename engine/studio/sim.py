"""One studio "shoot": scene + camera path + presenter + ball + sensor -> Frames with truth.

Frames are rendered on demand and are a pure function of (config, index): random access,
deterministic by seed. Each frame carries the truth as two payloads:

- :class:`StudioTruth` (small): ``path`` and ``cycle`` (time / cycle period); ``covered``
  (True while the lens is covered: dark image, depth 0, pose truth unchanged); with the
  presenter on, ``presenter_in_scene``, ``presenter_box_xywh`` (box of the presenter's
  visible pixels, also ``Frame.gt_box_xywh``; None when fewer than 0.1 % of the image shows
  the presenter), ``presenter_part_boxes`` {head, torso, legs: box or None},
  ``presenter_pixels``, ``presenter_pos_world`` (feet centre on the floor, m),
  ``presenter_head_world``; with the ball on, ``ball_pos_world``, ``ball_vel_world``,
  ``ball_acc_world``, ``ball_radius_m``, ``ball_omega_rad_s``, ``ball_center_px``
  (projection of the centre, may be outside), ``ball_box_xywh`` (visible pixels) and
  ``ball_pixels``; with the occluder on, ``occluder_pos_world``, ``occluder_box_xywh``,
  ``occluder_pixels``, ``occluder_fraction``; with a second person, ``person2_box_xywh``,
  ``person2_pixels``, ``person2_pos_world`` (label 6, never part of the presenter's box).
  Fields of parts that are off are None.
- :class:`StudioLabels` (images, not kept in the run history): ``labels``, a uint8 (H, W)
  map (0 set, 1 head, 2 torso (+arms), 3 legs (+shoes), 4 ball, 5 occluder, 6 second
  person) and
  ``depth_exact_m``, the noise-free depth (only when noise or dropouts are on, else None).
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from engine.camera import TUM_DEFAULTS, Intrinsics, project
from engine.frames import Frame, FramePayload, readonly
from engine.geometry import invert
from engine.studio import sensor
from engine.studio.ball import BallPath
from engine.studio.lighting import LIGHTINGS, apply_gain
from engine.studio.paths import CameraPath
from engine.studio.presenter import PresenterScript, body_prims, concat_prims
from engine.studio.render import (
    RENDER_METHODS,
    Prims,
    Renderer,
    core_boxes_from_labels,
    label_boxes,
)
from engine.studio.scene import (
    BOX,
    LABEL_BALL,
    LABEL_HEAD,
    LABEL_LEGS,
    LABEL_OCCLUDER,
    LABEL_PERSON2,
    LABEL_TORSO,
    StudioScene,
    build_scene,
)
from engine.studio.zoom import ZoomScript, studio_zoom_lens

F64 = NDArray[np.float64]
Box = tuple[float, float, float, float]
Vec3 = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class StudioTruth(FramePayload):
    """The built-in studio's per-frame truth (see the module docstring)."""

    path: str
    cycle: float
    covered: bool = False
    presenter_in_scene: bool | None = None
    presenter_pixels: int | None = None
    presenter_box_xywh: Box | None = None
    presenter_part_boxes: Mapping[str, Box | None] | None = None
    presenter_pos_world: Vec3 | None = None
    presenter_head_world: Vec3 | None = None
    ball_pos_world: Vec3 | None = None
    ball_vel_world: Vec3 | None = None
    ball_acc_world: Vec3 | None = None
    ball_radius_m: float | None = None
    ball_omega_rad_s: float | None = None
    ball_center_px: tuple[float, float] | None = None
    ball_pixels: int | None = None
    ball_box_xywh: Box | None = None
    occluder_pos_world: Vec3 | None = None
    occluder_pixels: int | None = None
    occluder_fraction: float | None = None
    occluder_box_xywh: Box | None = None
    person2_pixels: int | None = None
    person2_box_xywh: Box | None = None
    person2_pos_world: Vec3 | None = None


@dataclass(frozen=True, slots=True)
class StudioLabels(FramePayload):
    """The studio's label map and noise-free depth (images: not kept in run histories)."""

    light: ClassVar[bool] = False
    labels: NDArray[np.uint8]
    depth_exact_m: NDArray[np.float32] | None = None

    def __post_init__(self) -> None:
        readonly(self.labels)
        readonly(self.depth_exact_m)

#: row bands of a rolling-shutter colour image, each rendered at its own instant
RS_BANDS = 24

#: Kinect-like camera of the studio at 640x480 (TUM's default ROS calibration)
KINECT_FX = 525.0
#: the optional lens distortion: TUM freiburg1's (a real Kinect's) Caltech coefficients
KINECT_DISTORTION = TUM_DEFAULTS["freiburg1"].dist_k1k2p1p2k3


def studio_intrinsics(width: int = 640, height: int = 480, distortion: bool = False) -> Intrinsics:
    """f = 525 px at 640x480, scaled with the image size; principal point at the centre."""
    return Intrinsics(
        fx=KINECT_FX * width / 640.0,
        fy=KINECT_FX * height / 480.0,
        cx=(width - 1) / 2.0,
        cy=(height - 1) / 2.0,
        width=width,
        height=height,
        dist_k1k2p1p2k3=KINECT_DISTORTION if distortion else (0.0, 0.0, 0.0, 0.0, 0.0),
        depth_scale=5000.0,
    )


@dataclass(frozen=True, slots=True)
class StudioConfig:
    frames: int = 300
    seed: int = 0
    fps: float = 30.0
    width: int = 640
    height: int = 480
    distortion: bool = False
    path: CameraPath = field(default_factory=CameraPath)
    presenter: PresenterScript | None = None
    ball: BallPath | None = None
    depth_noise: float = 0.0  # multiple of the Kinect noise model
    dropouts: float = 0.0  # fraction of the image in holes (edge dropouts when > 0)
    color_noise: float = 0.0  # std in grey levels
    vignette: float = 0.0  # 0..1
    blur_px: float = 0.0  # Gaussian lens blur sigma (pixels), softens aliased edges
    occluder: bool = False  # a grey panel moving close in front of the camera
    cover_start: int = -1  # lens covered from this frame (dark image, no depth) ...
    cover_frames: int = 0  # ... for this many frames
    threads: int = 1  # renderer threads (0: all cores)
    person2: PresenterScript | None = None  # a second person (another look, label 6)
    lighting: str = "default"  # a variant of ``engine.studio.lighting.LIGHTINGS``
    views: int = 1  # 2: also the overhead camera (engine.studio.views), an OverheadView payload
    zoom: ZoomScript | None = None  # a zoom lens (engine.studio.zoom): None = the fixed lens
    #: the second camera's zoom (views=2; engine.studio.views): None = its fixed wide lens
    over_zoom: ZoomScript | None = None
    #: how textures are sampled (``engine.studio.render.RENDER_METHODS``): remap (fast) or
    #: raycast (the kernel's own floating-point fetch; colours within a few grey levels)
    render: str = "remap"
    #: the camera's rolling shutter: readout time first row to last (s); 0 = global shutter.
    #: Row bands of the colour and depth images are rendered at the path's pose of their
    #: instant (both sensors scanning in step, as a Kinect's)
    rolling_shutter_s: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.rolling_shutter_s < 1.0:
            raise ValueError(f"rolling_shutter_s must be in [0, 1) s, got "
                             f"{self.rolling_shutter_s}")
        if self.lighting not in LIGHTINGS:
            raise ValueError(f"lighting {self.lighting!r} is not one of {', '.join(LIGHTINGS)}")
        if self.views not in (1, 2):
            raise ValueError(f"views must be 1 or 2, got {self.views}")
        if self.render not in RENDER_METHODS:
            raise ValueError(f"render {self.render!r} is not one of {', '.join(RENDER_METHODS)}")
        if self.over_zoom is not None and self.views != 2:
            raise ValueError("over_zoom needs views=2 (it zooms the second camera)")


class Studio:
    """Renders the frames of a :class:`StudioConfig`."""

    def __init__(self, config: StudioConfig) -> None:
        self.config = config
        self.scene = build_scene(config.seed)
        self.intrinsics = studio_intrinsics(config.width, config.height, config.distortion)
        self._zoom_renderers: dict[int, tuple[Intrinsics, Renderer]] = {}
        self._over_renderers: dict[int, tuple[F64, Renderer]] = {}
        if config.zoom is not None:
            self.intrinsics = studio_zoom_lens(config.width, config.height).intrinsics_at(
                config.zoom.encoders(0).zoom_raw)

    @cached_property
    def renderer(self) -> Renderer:
        light = LIGHTINGS[self.config.lighting]
        return Renderer(self.scene, self.intrinsics, self.config.threads,
                        None if light.name == "default" else light.dynamic_light(),
                        method=self.config.render)

    @cached_property
    def renderer2(self) -> Renderer:
        """The second (overhead) camera's renderer (``views=2``)."""
        from engine.studio.views import OVERHEAD

        light = LIGHTINGS[self.config.lighting]
        return Renderer(self.scene, OVERHEAD.intrinsics(self.config.width, self.config.height),
                        self.config.threads,
                        None if light.name == "default" else light.dynamic_light(),
                        method=self.config.render)

    @cached_property
    def floor_calibration(self) -> Any:
        """The overhead camera's exact floor calibration (``views=2``)."""
        from engine.studio.views import OVERHEAD

        return OVERHEAD.floor_calibration(self.config.width, self.config.height,
                                          zoom=self.config.over_zoom is not None)

    def _second_camera(self, index: int) -> tuple[F64, Renderer, Any]:
        """Pose, renderer and lens encoders of the second camera at frame ``index`` (zoom:
        renderers kept for recent encoder values)."""
        from engine.studio.views import OVERHEAD

        cfg = self.config
        if cfg.over_zoom is None:
            return OVERHEAD.T_world_cam(), self.renderer2, None
        enc = cfg.over_zoom.encoders(index)
        cached = self._over_renderers.get(enc.zoom_raw)
        if cached is None:
            cam, T = OVERHEAD.zoom_camera(cfg.width, cfg.height, enc.zoom_raw, enc.focus_raw)
            light = LIGHTINGS[cfg.lighting]
            cached = (T, Renderer(self.scene, cam, cfg.threads,
                                  None if light.name == "default" else light.dynamic_light(),
                                  method=cfg.render))
            if len(self._over_renderers) >= 4:
                self._over_renderers.pop(next(iter(self._over_renderers)))
            self._over_renderers[enc.zoom_raw] = cached
        return cached[0], cached[1], enc

    def _second_view(self, index: int, prims: Prims | None, feet: F64 | None) -> Any:
        """The overhead camera's frame of the same instant, as an ``OverheadView`` payload."""
        from engine.floor import OverheadView

        cfg = self.config
        T_over, renderer2, enc = self._second_camera(index)
        out = renderer2.render(T_over, prims)
        color = out.color_bgr
        light = LIGHTINGS[cfg.lighting]
        if not light.is_identity:
            color = apply_gain(color, light.gain_bgr(index / max(cfg.frames - 1, 1)))
        if cfg.color_noise > 0:
            color = sensor.add_color_noise(color, cfg.color_noise,
                                           np.random.default_rng([cfg.seed, index, 23]))
        boxes = label_boxes(out.labels, 7)
        sel = boxes[[LABEL_HEAD, LABEL_TORSO, LABEL_LEGS]]
        box = None
        if int(sel[:, 4].sum()) >= max(1, round(1e-3 * cfg.width * cfg.height)):
            vis = sel[sel[:, 4] > 0]
            box = _xywh(vis[:, 0].min(), vis[:, 1].min(), vis[:, 2].max(), vis[:, 3].max())
        parts: tuple[tuple[str, tuple[float, float, float, float]], ...] = ()
        if box is not None:
            # the operator's patches of the second view's model (every frame: the tracker
            # initialises on the first whose box is wholly inside the image)
            cores = core_boxes_from_labels(
                out.labels, {"head": LABEL_HEAD, "torso": LABEL_TORSO, "legs": LABEL_LEGS})
            parts = tuple((k, (float(b[0]), float(b[1]), float(b[2]), float(b[3])))
                          for k, b in cores.items())
        return OverheadView(color_bgr=color, box_xywh=box, part_boxes=parts,
                            floor_calibration=self.floor_calibration,
                            timestamp_s=index / cfg.fps, lens_encoders=enc,
                            floor_xy_m_true=None if feet is None
                            else (float(feet[0]), float(feet[1])))

    @cached_property
    def _vignette(self) -> NDArray[np.float32] | None:
        if self.config.vignette <= 0:
            return None
        r = self.renderer
        return sensor.vignette_gain(r.xn, r.yn, self.config.vignette)[..., None]

    def T_world_cam(self, index: int) -> F64:
        return self.config.path.T_world_cam(index / self.config.fps)

    def lens_at(self, index: int) -> tuple[Intrinsics, Renderer, tuple[FramePayload, ...]]:
        """Intrinsics, renderer and lens payloads of frame ``index`` (zoom lens: the known
        lens file at the frame's zoom encoder, renderers kept for recent encoder values)."""
        zoom = self.config.zoom
        if zoom is None:
            return self.intrinsics, self.renderer, ()
        enc = zoom.encoders(index)
        cached = self._zoom_renderers.get(enc.zoom_raw)
        if cached is None:
            lens = studio_zoom_lens(self.config.width, self.config.height)
            cam = lens.intrinsics_at(enc.zoom_raw, enc.focus_raw)
            light = LIGHTINGS[self.config.lighting]
            cached = (cam, Renderer(self.scene, cam, self.config.threads,
                                    None if light.name == "default" else light.dynamic_light(),
                                    method=self.config.render))
            if len(self._zoom_renderers) >= 4:
                self._zoom_renderers.pop(next(iter(self._zoom_renderers)))
            self._zoom_renderers[enc.zoom_raw] = cached
        return cached[0], cached[1], (enc,)

    def _rolling_shutter(self, renderer: Renderer, t_s: float, prims: Prims | None,
                         colour: NDArray[np.uint8], depth: NDArray[np.float32]
                         ) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
        """Colour and depth of a rolling-shutter RGB-D camera whose two sensors scan in step
        (as a Kinect's): each band of :data:`RS_BANDS` rows rendered at the path's pose at
        the band's mid-row instant, ``(row - (H - 1) / 2) / H * readout`` after the frame's
        (the people stand still over the readout; labels stay the frame instant's)."""
        h = colour.shape[0]
        out_c = np.array(colour, copy=True)
        out_d = np.array(depth, copy=True)
        readout = self.config.rolling_shutter_s
        edges = np.linspace(0, h, RS_BANDS + 1).round().astype(int)
        for r0, r1 in itertools.pairwise(edges):
            if r1 <= r0:
                continue
            tau = (0.5 * (r0 + r1 - 1) - 0.5 * (h - 1)) / h * readout
            band = renderer.render(self.config.path.T_world_cam(t_s + tau), prims)
            out_c[r0:r1] = band.color_bgr[r0:r1]
            out_d[r0:r1] = band.depth_m[r0:r1]
        return out_c, out_d

    def frame(self, index: int, T_world_cam: F64 | None = None) -> Frame:
        """Frame ``index``; ``T_world_cam`` overrides the path's pose (closed-loop cameras,
        e.g. a simulated pan-tilt head driven by a tracker) - the presenter, ball and noise
        still follow the index."""
        cfg = self.config
        t_s = index / cfg.fps
        moving = T_world_cam is None  # on its path (an override is one instant's pose)
        if T_world_cam is None:
            T_world_cam = self.T_world_cam(index)
        else:
            T_world_cam = np.array(T_world_cam, dtype=np.float64, copy=True)
            if T_world_cam.shape != (4, 4):
                raise ValueError(f"T_world_cam must be 4x4, got {T_world_cam.shape}")
        parts: list[Prims] = []
        truth: dict[str, Any] = {"path": cfg.path.kind, "cycle": t_s / cfg.path.period_s}
        keypoints: dict[str, F64] | None = None
        state = cfg.presenter.state(index) if cfg.presenter is not None else None
        if state is not None and cfg.presenter is not None:
            body, keypoints = body_prims(state, self.scene, cfg.presenter.look)
            parts.append(body)
        state2 = cfg.person2.state(index) if cfg.person2 is not None else None
        keypoints2: dict[str, F64] | None = None
        if state2 is not None and cfg.person2 is not None:
            body2, keypoints2 = body_prims(state2, self.scene, cfg.person2.look, LABEL_PERSON2)
            parts.append(body2)
        ball_truth = None
        if cfg.ball is not None:
            ball_truth = cfg.ball.state(t_s)
            parts.append(cfg.ball.prims(ball_truth[0], self.scene))
        if cfg.occluder:
            occ_centre = occluder_centre(t_s)
            parts.append(occluder_prims(occ_centre, self.scene))
            truth["occluder_pos_world"] = _tup(occ_centre)
        prims = concat_prims(*parts) if parts else None
        cam, renderer, lens_payloads = self.lens_at(index)
        out = renderer.render(T_world_cam, prims)
        color, depth, labels = out.color_bgr, out.depth_m, out.labels
        if cfg.rolling_shutter_s > 0.0 and moving:
            color, depth = self._rolling_shutter(renderer, t_s, prims, color, depth)
        if cfg.rolling_shutter_s > 0.0:
            cam = dataclasses.replace(cam, rolling_shutter_s=cfg.rolling_shutter_s)
        # exposure and white balance of the lighting variant (before the sensor noise)
        light = LIGHTINGS[cfg.lighting]
        if not light.is_identity:
            color = apply_gain(color, light.gain_bgr(index / max(cfg.frames - 1, 1)))

        boxes = label_boxes(labels, 7)
        if cfg.person2 is not None:
            n_p2 = int(boxes[LABEL_PERSON2, 4])
            truth["person2_pixels"] = n_p2
            truth["person2_box_xywh"] = _xywh(*boxes[LABEL_PERSON2, :4]) if n_p2 else None
            truth["person2_pos_world"] = None if keypoints2 is None else _tup(keypoints2["feet"])
        if cfg.occluder:
            n_occ = int(boxes[LABEL_OCCLUDER, 4])
            truth["occluder_pixels"] = n_occ
            truth["occluder_fraction"] = n_occ / float(cfg.width * cfg.height)
            truth["occluder_box_xywh"] = _xywh(*boxes[LABEL_OCCLUDER, :4]) if n_occ else None
        min_px = max(1, round(1e-3 * cfg.width * cfg.height))
        presenter_box: Box | None = None
        if cfg.presenter is not None:
            sel = boxes[[LABEL_HEAD, LABEL_TORSO, LABEL_LEGS]]
            n_px = int(sel[:, 4].sum())
            if n_px >= min_px:
                vis = sel[sel[:, 4] > 0]
                presenter_box = _xywh(
                    vis[:, 0].min(), vis[:, 1].min(), vis[:, 2].max(), vis[:, 3].max()
                )
            truth["presenter_in_scene"] = state is not None
            truth["presenter_pixels"] = n_px
            truth["presenter_box_xywh"] = presenter_box
            truth["presenter_part_boxes"] = MappingProxyType({
                name: (_xywh(*boxes[k, :4]) if boxes[k, 4] > 0 else None)
                for name, k in (("head", LABEL_HEAD), ("torso", LABEL_TORSO), ("legs", LABEL_LEGS))
            })
            truth["presenter_pos_world"] = None if keypoints is None else _tup(keypoints["feet"])
            truth["presenter_head_world"] = None if keypoints is None else _tup(keypoints["head"])
        if ball_truth is not None and cfg.ball is not None:
            pos, vel, acc = ball_truth
            p_cam = (invert(T_world_cam) @ np.append(pos, 1.0))[:3]
            uv = project(cam, p_cam[None, :])[0]
            truth["ball_pos_world"] = _tup(pos)
            truth["ball_vel_world"] = _tup(vel)
            truth["ball_acc_world"] = _tup(acc)
            truth["ball_radius_m"] = cfg.ball.ball_radius_m
            truth["ball_omega_rad_s"] = cfg.ball.omega_rad_s
            truth["ball_center_px"] = (float(uv[0]), float(uv[1]))
            truth["ball_pixels"] = int(boxes[LABEL_BALL, 4])
            truth["ball_box_xywh"] = (
                _xywh(*boxes[LABEL_BALL, :4]) if boxes[LABEL_BALL, 4] > 0 else None
            )

        if cfg.depth_noise > 0 or cfg.dropouts > 0 or cfg.color_noise > 0:
            rng = np.random.default_rng([cfg.seed, index, 11])
            exact = depth
            if cfg.depth_noise > 0 or cfg.dropouts > 0:
                truth["depth_exact_m"] = readonly(exact)
            if cfg.depth_noise > 0:
                depth = sensor.add_depth_noise(depth, cfg.depth_noise, rng)
            if cfg.dropouts > 0:
                depth = sensor.add_dropouts(depth, exact, cfg.dropouts, rng)
            if cfg.color_noise > 0:
                color = sensor.add_color_noise(color, cfg.color_noise, rng)
        covered = cfg.cover_start <= index < cfg.cover_start + cfg.cover_frames
        truth["covered"] = covered
        if covered:
            # lens cap: a dark, slightly noisy image and no depth; the truth stays valid
            rng_c = np.random.default_rng([cfg.seed, index, 13])
            color = rng_c.integers(0, 6, size=color.shape, dtype=np.uint8)
            depth = np.zeros_like(depth)
        if cfg.blur_px > 0:
            color = sensor.lens_blur(color, cfg.blur_px)
        if self._vignette is not None:
            color = np.clip(color * self._vignette + 0.5, 0, 255).astype(np.uint8)
        truth["labels"] = readonly(labels)
        exact_depth = truth.pop("depth_exact_m", None)
        labels_payload = StudioLabels(labels=truth.pop("labels"), depth_exact_m=exact_depth)
        payloads: tuple[Any, ...] = (StudioTruth(**truth), labels_payload)
        if cfg.views == 2:
            payloads = (*payloads, self._second_view(
                index, prims, None if keypoints is None else keypoints["feet"]))
        return Frame(
            index=index,
            timestamp_s=t_s,
            color_bgr=color,
            intrinsics=cam,
            depth_m=depth,
            gt_T_world_cam=T_world_cam,
            gt_box_xywh=presenter_box,
            payloads=(*payloads, *lens_payloads),
        )


def _xywh(x0: float, y0: float, x1: float, y1: float) -> Box:
    """Pixel-index extremes -> (x, y, w, h) covering whole pixels."""
    return (float(x0), float(y0), float(x1 - x0 + 1), float(y1 - y0 + 1))


def _tup(v: F64) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


#: the occluder: a grey panel 0.7 m wide and 1.3 m tall, 1.6 m in front of the rail, moving
#: back and forth across the view at 0.5 m/s (about 30 % of a static 640x480 view)
OCCLUDER_HALF_M = (0.35, 0.05, 0.65)
OCCLUDER_Y_M = 1.6
OCCLUDER_Z_M = 1.05


def occluder_centre(t_s: float) -> F64:
    """Triangle wave in x between -1.6 and 1.6 m at 0.5 m/s, starting at the left."""
    span, speed = 3.2, 0.5
    s = (speed * t_s) % (2.0 * span)
    x = -1.6 + (s if s < span else 2.0 * span - s)
    return np.array([x, OCCLUDER_Y_M, OCCLUDER_Z_M])


def occluder_prims(centre: F64, scene: StudioScene) -> Prims:
    hx, hy, hz = OCCLUDER_HALF_M
    geom = np.zeros((1, 9))
    geom[0, :8] = (*centre, hx, hy, hz, 1.0, 0.0)
    mat = np.full((1, 6), scene.flat_mat["occluder"], np.int32)
    signs = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
    corners = (centre + signs * np.array(OCCLUDER_HALF_M))[None]
    return Prims(
        np.array([BOX], np.int32), geom, mat, np.array([LABEL_OCCLUDER], np.uint8), corners
    )
