"""``synthetic:key=value,...`` - the built-in virtual studio as a frame source.

Example: ``synthetic:frames=600,seed=3,presenter=1,path=rail``. Options (defaults):

=====================  ==========================================================================
frames (300)           number of frames; default with ``cycles``: cycles x cycle_s x fps
seed (0)               textures, hand-held wobble and sensor noise
path (rail)            rail | pan | handheld | static (see :mod:`engine.studio.paths`)
cycles                 number of path cycles (rail: there and back) in ``frames``
cycle_s (6)            seconds per cycle (give at most two of frames, cycles, cycle_s)
fps (30)               frame rate (timestamps are index / fps)
width, height          image size (640x480); f = 525 px is scaled with it
distortion (0)         1: a real Kinect's lens distortion (TUM freiburg1 coefficients)
presenter (0)          1: the walking presenter
presenter_mode (walk)  walk | still | leave (walks out of view and back)
presenter_start (0)    first frame with the presenter in the studio (walks in from x = -4.6)
presenter_last_cycles  presenter only during the last N cycles (sets presenter_start)
presenter_leave        leave mode: frame the presenter starts walking out (frames/3)
presenter_return       leave mode: frame the presenter starts walking back (2 frames/3)
presenter_speed (0.9)  walking speed, m/s
presenter_xmin/xmax    walk mode range along x, m (-2.6, 2.6; static camera -1.1, 1.1)
presenter_x (0)        still/leave mode standing position along x, m
presenter_out          leave mode: where the presenter waits out of view, m (x + 2.6; left
                       of the standing position = walks out to the left)
presenter_y (2.4)      distance of the presenter's line from the rail (world y), m
presenter_dy (0)       walk mode: the line goes from presenter_y (at xmin) to presenter_y + dy
                       (at xmax): the presenter walks towards / away from the camera, m
presenter_look (0)     who presents: 0..6 (engine.studio.presenter.LOOKS: clothes, skin, height)
person2 (none)         a second person: cross (walks to and fro 0.8 m in front of the
                       presenter's line), behind (0.5 m behind it), beside (stands 0.7 m to
                       the presenter's right)
person2_look (1)       the second person's look (0 = dressed like the presenter)
person2_speed (0.7)    the second person's walking speed, m/s
person2_start (0)      first frame with the second person in the studio
lighting (default)     default | warm | cool | dim | bright | ramp (dark to light) | side
views (1)              2: also the overhead camera (engine.studio.views) with its floor
                       calibration, as a second view of every frame
ball (0)               1: the red target ball on a circle
ball_period_s (30)     ball circle period, s
ball_circle_m (1.0)    ball circle radius, m
ball_radius_m (0.1)    ball radius, m
ball_cx/cy/cz          centre of the ball's circle, m (0.6, 2.6, 1.2)
noise (0)              depth noise as a multiple of the Kinect model (1 = Kinect v1)
dropouts (0)           1: depth holes (2 % of the image + edge dropouts); or a fraction < 1
color_noise (0)        colour noise std (grey levels)
vignette (0)           vignetting strength 0..1 (cos^4 law)
blur (0)               Gaussian lens blur of the colour image, sigma in pixels (e.g. 0.6)
rolling_shutter (0)    the camera's readout time, s (e.g. 0.02): rows of colour and depth
                       exposed one after the other while the camera moves (as a Kinect's);
                       the frames' intrinsics carry it (0 = global shutter)
occluder (0)           1: a grey panel (0.7 x 1.3 m) moving 1.6 m in front of the rail
cover_start            lens covered (dark image, no depth) from this frame ...
cover_frames (20)      ... for this many frames (loss-and-relock tests)
threads (1)            renderer threads per frame (0: all cores; 1 is steadier on a busy CPU)
render (remap)         remap: textures sampled by cv2.remap from the ray caster's maps (fast);
                       raycast: sampled in the ray caster itself (same depth and labels,
                       colours within a few grey levels; ``engine.studio.render``)
ahead (1)              frames rendered ahead on a worker thread while the consumer tracks, as a
                       camera exposes the next frame meanwhile (``engine.sources.ahead``; every
                       frame is rendered, capture time = when it is handed out); 0: rendered
                       on the consumer's thread when asked for
zoom                   sweep: a 3x zoom lens swept wide -> tele -> wide (``engine.studio.zoom``:
                       a known lens file, frames carry the zoom/focus encoders); N: held at
                       encoder value N (0..65535)
zoom_cycle_s           seconds of one sweep cycle (default: the whole shot)
over_zoom              views=2: the second camera gets the same zoom lens (its floor
                       calibration a camera model from the lens file, marks taken at the wide
                       end); sweep: wide -> about 1.3x -> wide over the shot; N: held at N
=====================  ==========================================================================
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any

from engine.camera import Intrinsics
from engine.errors import SourceError
from engine.frames import Frame
from engine.sources.base import Source, SourceSpec, parse_options

PATHS = ("rail", "pan", "handheld", "static")
PRESENTER_MODES = ("walk", "still", "leave")
PERSON2_MODES = ("none", "cross", "behind", "beside")
LIGHTING_NAMES = ("default", "warm", "cool", "dim", "bright", "ramp", "side")


#: frames the studio renders ahead of the consumer (the ``ahead`` option)
DEFAULT_AHEAD = 1

#: the largest integer option accepted (frame counts, seeds): beyond it len() overflows
_INT_MAX = 10**9


def _int(lo: int, hi: int = _INT_MAX) -> Callable[[str], int]:
    def parse(s: str) -> int:
        v = int(s)
        if v < lo or v > hi:
            raise ValueError(f"expected an integer in [{lo}, {hi}]")
        return v

    return parse


def _float(lo: float, hi: float | None = None, open_lo: bool = False) -> Callable[[str], float]:
    def parse(s: str) -> float:
        v = float(s)
        bad = not math.isfinite(v) or (v <= lo if open_lo else v < lo)
        if bad or (hi is not None and v > hi):
            lo_b = "(" if open_lo else "["
            raise ValueError(
                f"expected a number in {lo_b}{lo}, {hi if hi is not None else 'inf'}]"
            )
        return v

    return parse


def _choice(*names: str) -> Callable[[str], str]:
    def parse(s: str) -> str:
        if s not in names:
            raise ValueError(f"expected one of {', '.join(names)}")
        return s

    return parse


def _bool(s: str) -> bool:
    if s.lower() in ("1", "true", "yes", "on"):
        return True
    if s.lower() in ("0", "false", "no", "off"):
        return False
    raise ValueError("expected 0 or 1")


def _dropouts(s: str) -> float:
    v = float(s)
    if not math.isfinite(v) or v < 0 or v > 1:
        raise ValueError("expected 0, 1 or a fraction in (0, 1)")
    return 0.02 if v == 1.0 else v


def _zoom(s: str) -> str | int:
    if s == "sweep":
        return s
    try:
        v = int(s)
    except ValueError:
        raise ValueError("expected sweep or an encoder value 0..65535") from None
    if not 0 <= v <= 65535:
        raise ValueError("expected sweep or an encoder value 0..65535")
    return v


OPTIONS: dict[str, Callable[[str], Any]] = {
    "frames": _int(1),
    "seed": _int(0),
    "path": _choice(*PATHS),
    "cycles": _float(0.0, open_lo=True),
    "cycle_s": _float(0.0, open_lo=True),
    "fps": _float(0.0, 1000.0, open_lo=True),
    "width": _int(16, 4096),
    "height": _int(16, 4096),
    "distortion": _bool,
    "presenter": _bool,
    "presenter_mode": _choice(*PRESENTER_MODES),
    "presenter_start": _int(0),
    "presenter_last_cycles": _float(0.0, open_lo=True),
    "presenter_leave": _int(0),
    "presenter_return": _int(0),
    "presenter_speed": _float(0.0, 10.0, open_lo=True),
    "presenter_xmin": _float(-4.5, 4.5),
    "presenter_xmax": _float(-4.5, 4.5),
    "presenter_x": _float(-4.5, 4.5),
    "presenter_out": _float(-4.6, 4.6),
    "presenter_y": _float(0.5, 4.2),
    "presenter_look": _int(0, 6),
    "presenter_dy": _float(-3.5, 3.5),
    "person2": _choice(*PERSON2_MODES),
    "person2_look": _int(0, 6),
    "person2_speed": _float(0.0, 10.0, open_lo=True),
    "person2_start": _int(0),
    "lighting": _choice(*LIGHTING_NAMES),
    "views": _int(1, 2),
    "ball": _bool,
    "ball_period_s": _float(0.0, open_lo=True),
    "ball_circle_m": _float(0.0, 3.0),
    "ball_radius_m": _float(0.0, 1.0, open_lo=True),
    "ball_cx": _float(-4.5, 4.5),
    "ball_cy": _float(-2.5, 4.2),
    "ball_cz": _float(0.0, 3.5),
    "noise": _float(0.0, 100.0),
    "dropouts": _dropouts,
    "color_noise": _float(0.0, 100.0),
    "vignette": _float(0.0, 1.0),
    "blur": _float(0.0, 10.0),
    "occluder": _bool,
    "cover_start": _int(0),
    "cover_frames": _int(0),
    "threads": _int(0, 256),
    "render": _choice("remap", "raycast"),
    "ahead": _int(0, 8),
    "zoom": _zoom,
    "zoom_cycle_s": _float(0.0, open_lo=True),
    "over_zoom": _zoom,
    "rolling_shutter": _float(0.0, 0.999),
}


def parse_synthetic_options(opts: dict[str, str]) -> dict[str, Any]:
    """Validate and convert option strings; SourceError names the bad option."""
    out: dict[str, Any] = {}
    for key, raw in opts.items():
        if key not in OPTIONS:
            raise SourceError(
                f"synthetic: unknown option {key!r} (known: {', '.join(sorted(OPTIONS))})"
            )
        try:
            out[key] = OPTIONS[key](raw)
        except ValueError as exc:
            msg = str(exc)
            if msg.startswith(("invalid literal", "could not convert")):
                msg = "not a number"
            raise SourceError(f"synthetic: option {key}={raw!r}: {msg}") from None
    return out


def config_from_options(opts: dict[str, str]) -> Any:
    """Build a :class:`engine.studio.sim.StudioConfig` from ``key=value`` strings."""
    from engine.studio.ball import BallPath
    from engine.studio.paths import CameraPath
    from engine.studio.presenter import PresenterScript
    from engine.studio.sim import StudioConfig

    o = parse_synthetic_options(opts)
    fps = o.get("fps", 30.0)
    given = [k for k in ("frames", "cycles", "cycle_s") if k in o]
    if len(given) == 3:
        raise SourceError("synthetic: give at most two of frames, cycles, cycle_s")
    if "frames" in o and "cycles" in o:
        cycle_s = o["frames"] / fps / o["cycles"]
        frames = o["frames"]
    else:
        cycle_s = o.get("cycle_s", 6.0)
        frames = (
            o["frames"]
            if "frames" in o
            else (max(1, round(o["cycles"] * cycle_s * fps)) if "cycles" in o else 300)
        )
    path_kind = o.get("path", "rail")
    presenter = None
    if o.get("presenter", False):
        start = o.get("presenter_start", 0)
        if "presenter_last_cycles" in o:
            start = max(0, frames - round(o["presenter_last_cycles"] * cycle_s * fps))
        wide = path_kind != "static"
        try:
            presenter = PresenterScript(
                mode=o.get("presenter_mode", "walk"),
                fps=fps,
                start_frame=start,
                speed_mps=o.get("presenter_speed", 0.9),
                x_min_m=o.get("presenter_xmin", -2.6 if wide else -1.1),
                x_max_m=o.get("presenter_xmax", 2.6 if wide else 1.1),
                x_still_m=o.get("presenter_x", 0.0),
                y_m=o.get("presenter_y", 2.4),
                leave_frame=o.get("presenter_leave", frames // 3),
                return_frame=o.get("presenter_return", (2 * frames) // 3),
                # the static camera sees x within +-1.5 m at y = 2.4: 2.6 m is well outside
                x_out_m=o["presenter_out"] if "presenter_out" in o else
                (min(4.6, o.get("presenter_x", 0.0) + 2.6) if not wide else 4.6),
                # appearing mid-sequence: walk in from the left wall rather than pop up
                enter_from_m=-4.6 if start > 0 else None,
                look=o.get("presenter_look", 0),
                dy_m=o.get("presenter_dy", 0.0),
            )
        except ValueError as exc:
            raise SourceError(f"synthetic: presenter options: {exc}") from None
    else:
        stray = [k for k in o if k.startswith(("presenter_", "person2"))]
        if stray:
            raise SourceError(f"synthetic: option {stray[0]} needs presenter=1")
    person2 = _person2(o, presenter, fps, path_kind != "static")
    ball = None
    stray = [k for k in o if k.startswith("ball_")]
    if stray and not o.get("ball", False):
        raise SourceError(f"synthetic: option {stray[0]} needs ball=1")
    if o.get("ball", False):
        ball = BallPath(
            centre_m=(o.get("ball_cx", 0.6), o.get("ball_cy", 2.6), o.get("ball_cz", 1.2)),
            circle_radius_m=o.get("ball_circle_m", 1.0),
            period_s=o.get("ball_period_s", 30.0),
            ball_radius_m=o.get("ball_radius_m", 0.1),
        )
    zoom = None
    if "zoom_cycle_s" in o and "zoom" not in o:
        raise SourceError("synthetic: option zoom_cycle_s needs zoom=sweep")
    if "zoom" in o:
        from engine.studio.zoom import ZoomScript

        z = o["zoom"]
        cycle = max(2, round(o.get("zoom_cycle_s", frames / fps) * fps))
        zoom = (ZoomScript("sweep", cycle_frames=cycle) if z == "sweep"
                else ZoomScript("fixed", value_raw=int(z)))
    over_zoom = None
    if "over_zoom" in o:
        from engine.studio.views import OVER_ZOOM_SWEEP_MAX_RAW
        from engine.studio.zoom import ZoomScript

        if o.get("views", 1) != 2:
            raise SourceError("synthetic: option over_zoom needs views=2")
        z = o["over_zoom"]
        over_zoom = (ZoomScript("sweep", cycle_frames=max(2, frames),
                                sweep_max_raw=OVER_ZOOM_SWEEP_MAX_RAW) if z == "sweep"
                     else ZoomScript("fixed", value_raw=int(z)))
    if zoom is not None and o.get("distortion", False):
        raise SourceError("synthetic: zoom has its own lens distortion; drop distortion=1")
    return StudioConfig(
        frames=frames,
        seed=o.get("seed", 0),
        fps=fps,
        width=o.get("width", 640),
        height=o.get("height", 480),
        distortion=o.get("distortion", False),
        path=CameraPath(path_kind, cycle_s, o.get("seed", 0)),
        presenter=presenter,
        ball=ball,
        depth_noise=o.get("noise", 0.0),
        dropouts=o.get("dropouts", 0.0),
        color_noise=o.get("color_noise", 0.0),
        vignette=o.get("vignette", 0.0),
        blur_px=o.get("blur", 0.0),
        occluder=o.get("occluder", False),
        cover_start=o.get("cover_start", -1),
        cover_frames=o.get("cover_frames", 20 if "cover_start" in o else 0),
        threads=o.get("threads", 1),
        render=o.get("render", "remap"),
        person2=person2,
        lighting=o.get("lighting", "default"),
        views=o.get("views", 1),
        zoom=zoom,
        over_zoom=over_zoom,
        rolling_shutter_s=o.get("rolling_shutter", 0.0),
    )


def _person2(o: dict[str, Any], presenter: Any, fps: float, wide: bool) -> Any:
    """The second person's script: walking to and fro in front of or behind the presenter's
    line, or standing beside the presenter's (standing) position."""
    from engine.studio.presenter import PresenterScript

    mode = o.get("person2", "none")
    stray = [k for k in o if k.startswith("person2_")]
    if mode == "none":
        if stray:
            raise SourceError(f"synthetic: option {stray[0]} needs person2=cross|behind|beside")
        return None
    assert presenter is not None
    look = o.get("person2_look", 1)
    start = o.get("person2_start", 0)
    speed = o.get("person2_speed", 0.7)
    if mode == "beside":
        return PresenterScript(mode="still", fps=fps, start_frame=start,
                               x_still_m=min(presenter.x_still_m + 0.7, 4.4),
                               y_m=presenter.y_m, look=look)
    dy = -0.8 if mode == "cross" else 0.5
    span = 2.6 if wide else 1.6
    return PresenterScript(mode="walk", fps=fps, start_frame=start, speed_mps=speed,
                           x_min_m=-span, x_max_m=span, y_m=min(max(presenter.y_m + dy, 0.6), 4.2),
                           look=look, enter_from_m=4.6 - 9.2 if start > 0 else None)


#: the built-in studio stands in for a camera, whose frames cost the computer nothing: its
#: render-ahead thread is a background one (``SCHED_IDLE`` on Linux,
#: :func:`engine.realtime.background_priority`), so the air path's threads (engine, output
#: sender, window) get a core at once whenever they want one. At nice +10 (before) a 2-core
#: run still left the engine waiting for a core 2.4 ms of its 6.6 ms median frame (the
#: render, ~10 ms per frame, keeps the core to the end of its slice); rendered in the idle
#: time it is as fast as before
RENDER_BACKGROUND = True


class SyntheticSource(Source):
    """The built-in virtual studio: RGB-D frames with exact pose, presenter and ball truth."""

    nominal_fps = 30.0
    live = False

    def __init__(self, config: Any = None, *, ahead: int = DEFAULT_AHEAD) -> None:
        from engine.studio.sim import Studio, StudioConfig

        self.config = config if config is not None else StudioConfig()
        self.ahead = int(ahead)
        self.studio = Studio(self.config)
        self.nominal_fps = self.config.fps
        extras = []
        if self.config.presenter is not None:
            extras.append(f"presenter {self.config.presenter.mode}")
        if self.config.ball is not None:
            extras.append("ball")
        self.name = (
            f"built-in studio ({self.config.path.kind}, {self.config.frames} frames"
            + "".join(f", {e}" for e in extras)
            + ")"
        )

    @classmethod
    def from_options(cls, opts: dict[str, str]) -> SyntheticSource:
        ahead = parse_synthetic_options(opts).get("ahead", DEFAULT_AHEAD)
        return cls(config_from_options(opts), ahead=ahead)

    def with_config(self, **changes: Any) -> SyntheticSource:
        return SyntheticSource(replace(self.config, **changes), ahead=self.ahead)

    @property
    def intrinsics(self) -> Intrinsics:
        return self.studio.intrinsics

    def __len__(self) -> int:
        return int(self.config.frames)

    def frame(self, index: int, T_world_cam: Any = None) -> Frame:
        """Random access: frame ``index`` (a pure function of the config and the index);
        ``T_world_cam`` (4x4) renders it from another camera pose instead of the path's."""
        if not 0 <= index < len(self):
            raise SourceError(f"synthetic: frame {index} out of range [0, {len(self)})")
        return self.studio.frame(index, T_world_cam)

    def frames(self) -> Iterator[Frame]:
        """Every frame in order; with ``ahead`` the next ones render on a worker thread
        while the consumer works (:func:`engine.sources.ahead.read_ahead`)."""
        from engine.sources.ahead import read_ahead

        return read_ahead(self.studio.frame, len(self), depth=self.ahead,
                          name="studio-render-ahead", background=RENDER_BACKGROUND)


SOURCES = (
    SourceSpec(
        name="synthetic",
        description="the built-in virtual studio",
        opener=lambda rest: SyntheticSource.from_options(parse_options(rest)),
        example="synthetic:frames=300,presenter=1,path=rail",
    ),
)
