"""A red ball on a circular path seen by a simulated pan-tilt camera with discrete steps.

Like the paper's experiment (sec. 6.2: a red balloon on a Pioneer robot driving a circle,
period ~46 s, 2-7 m from the camera). The ball is rendered exactly: each pixel's coverage is
the fraction of 4x4 sub-pixel rays that hit the sphere, so its image is the true conic,
anti-aliased. The camera moves when its :attr:`PtzSimSource.head_port` is commanded (like a
camera driver; the pipeline's head sink does it with the tracker's
:class:`engine.ptz.head.PanTiltCommand`), in whole steps, after a ``latency_frames`` delay.
Each frame carries :class:`engine.ptz.head.PtzHeadReading` (geometry and encoder reading at
exposure) and :class:`PtzTargetTruth` (the ball's true motion).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics
from engine.frames import Frame, FramePayload
from engine.params import Params, param
from engine.ptz.control import StepLimits, quantise
from engine.ptz.head import PtzHeadReading
from engine.ptz.kinematics import PtzHead
from engine.sources.base import Source, SourceSpec, parse_options

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class CircleScenario(Params):
    """Ball on a horizontal circle; defaults put it 2-7 m from the camera."""

    centre_world_m: tuple[float, float, float] = param(
        (0.0, 4.5, 1.0), help="centre of the ball's circle, world frame (m)")
    radius_m: float = param(2.5, lo=0.0, help="radius of the ball's circle (m)")
    period_s: float = param(50.0, help="time of one circle (s); omega = 2 pi / 50 is model 1 "
                            "of the paper's bank")
    ball_radius_m: float = param(0.1, lo=0.0, help="ball radius (m)")
    ball_bgr: tuple[int, int, int] = param((40, 40, 210), lo=0, hi=255,
                                           help="ball colour (blue, green, red)")
    fps: float = param(30.0, help="frame rate (Hz)")
    duration_s: float = param(60.0, help="length of the run (s)")
    phase0_rad: float = param(-math.pi / 2, help="start angle on the circle (rad): -pi/2 "
                              "starts nearest the camera")
    width: int = param(640, lo=1, help="image width (px)")
    height: int = param(480, lo=1, help="image height (px)")
    f_px: float = param(800.0, lo=1.0, help="focal length (px)")
    camera_height_m: float = param(1.5, help="height of the head's rotation centre (m)")
    optical_offset_m: float = param(0.04, help="optical centre ahead of the rotation centre "
                                    "(m)")
    pan_step_deg: float = param(1.0, lo=1e-3, help="pan motor step (deg)")
    tilt_step_deg: float = param(1.0, lo=1e-3, help="tilt motor step (deg)")
    noise_sigma: float = param(2.0, lo=0.0, help="image noise std (grey levels)")
    seed: int = param(3, help="random seed of the image noise")

    @property
    def omega_rad_s(self) -> float:
        return 2.0 * math.pi / self.period_s

    def truth(self, t: float) -> tuple[F64, F64, F64]:
        """Position, velocity, acceleration (world, m) at time t."""
        w = self.omega_rad_s
        a = self.phase0_rad + w * t
        c = np.asarray(self.centre_world_m)
        r = self.radius_m
        p = c + r * np.array([math.cos(a), math.sin(a), 0.0])
        v = r * w * np.array([-math.sin(a), math.cos(a), 0.0])
        acc = -r * w * w * np.array([math.cos(a), math.sin(a), 0.0])
        return p, v, acc

    def head(self) -> PtzHead:
        K = np.array([[self.f_px, 0, (self.width - 1) / 2], [0, self.f_px, (self.height - 1) / 2],
                      [0, 0, 1.0]])
        return PtzHead(
            K=K,
            rotation_centre_world_m=np.array([0.0, 0.0, self.camera_height_m]),
            optical_offset_cam_m=np.array([0.0, 0.0, self.optical_offset_m]),
        )

    def intrinsics(self) -> Intrinsics:
        return Intrinsics(fx=self.f_px, fy=self.f_px, cx=(self.width - 1) / 2,
                          cy=(self.height - 1) / 2, width=self.width, height=self.height)


@dataclass(frozen=True, slots=True)
class PtzTargetTruth(FramePayload):
    """The simulated target's true position, velocity, acceleration (world, m, s)."""

    xyz_world: tuple[float, float, float]
    vel_world: tuple[float, float, float]
    acc_world: tuple[float, float, float]
    omega_rad_s: float
    radius_m: float


class PtzPort:
    """Thread-safe command port of the simulated head (what a camera driver would expose)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._cmd: tuple[float, float] | None = None

    def command(self, pan_deg: float, tilt_deg: float) -> None:
        with self._lock:
            self._cmd = (float(pan_deg), float(tilt_deg))

    def take(self) -> tuple[float, float] | None:
        with self._lock:
            cmd, self._cmd = self._cmd, None
            return cmd


def render_ball(
    image: NDArray[np.uint8], head: PtzHead, pan_deg: float, tilt_deg: float,
    p_world: F64, radius_m: float, bgr: tuple[int, int, int], ss: int = 4,
) -> tuple[float, float, float, float] | None:
    """Draw the sphere's exact anti-aliased image; returns its box (x, y, w, h) or None."""
    T = head.T_world_cam(pan_deg, tilt_deg)
    p_cam = T[:3, :3].T @ (np.asarray(p_world) - T[:3, 3])
    D = float(np.linalg.norm(p_cam))
    if p_cam[2] <= radius_m or radius_m >= D:
        return None
    K = np.asarray(head.K)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    u = fx * p_cam[0] / p_cam[2] + cx
    v = fy * p_cam[1] / p_cam[2] + cy
    ang = math.asin(radius_m / D)
    r_px = 1.3 * fx * math.tan(ang) * D / p_cam[2] + 2
    h, w = image.shape[:2]
    x0, x1 = max(0, int(u - r_px)), min(w, int(u + r_px) + 2)
    y0, y1 = max(0, int(v - r_px)), min(h, int(v + r_px) + 2)
    if x0 >= x1 or y0 >= y1:
        return None
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    xs = (np.arange(x0, x1)[:, None] + sub[None, :]).ravel()
    ys = (np.arange(y0, y1)[:, None] + sub[None, :]).ravel()
    X, Y = np.meshgrid((xs - cx) / fx, (ys - cy) / fy)
    dirs_dot = (X * p_cam[0] + Y * p_cam[1] + p_cam[2]) / (np.sqrt(X * X + Y * Y + 1.0) * D)
    hit = (dirs_dot >= math.cos(ang)).astype(np.float32)
    cov = hit.reshape(y1 - y0, ss, x1 - x0, ss).mean(axis=(1, 3))
    if cov.max() <= 0:
        return None
    roi = image[y0:y1, x0:x1].astype(np.float32)
    col = np.asarray(bgr, dtype=np.float32)
    image[y0:y1, x0:x1] = np.clip(roi * (1 - cov[..., None]) + col * cov[..., None] + 0.5,
                                  0, 255).astype(np.uint8)
    ys_, xs_ = np.nonzero(cov > 0.5)
    if len(xs_) == 0:
        return None
    return (float(x0 + xs_.min()), float(y0 + ys_.min()),
            float(xs_.max() - xs_.min() + 1), float(ys_.max() - ys_.min() + 1))


class PtzSimSource(Source):
    """Frames of :class:`CircleScenario` with a closed pan/tilt loop through ``PtzPort``."""

    def __init__(self, scenario: CircleScenario | None = None, latency_frames: int = 1) -> None:
        self.sc = scenario or CircleScenario()
        self.nominal_fps = self.sc.fps
        self.name = f"ptz-sim circle r={self.sc.radius_m} m T={self.sc.period_s} s"
        self.port = PtzPort()
        self.head_port = self.port  # what the pipeline's head sink commands
        self.latency_frames = max(0, int(latency_frames))
        self.limits = StepLimits(self.sc.pan_step_deg, self.sc.tilt_step_deg, max_steps=3)
        rng = np.random.default_rng(self.sc.seed)
        h, w = self.sc.height, self.sc.width
        grad = np.linspace(150, 90, h, dtype=np.float32)[:, None, None]
        tex = rng.normal(0, 6, (h, w, 1)).astype(np.float32)
        self._bg = np.clip(grad + tex + np.array([0, 4, 8], np.float32), 0, 255).astype(np.uint8)

    @property
    def intrinsics(self) -> Intrinsics:
        return self.sc.intrinsics()

    def sinks(self) -> Sequence[Any]:
        """The simulated head obeys the tracker's pan-tilt commands (closed loop)."""
        from engine.ptz.head import HeadCommandSink

        return (HeadCommandSink(self.head_port, "ptz-sim head"),)

    def __len__(self) -> int:
        return round(self.sc.duration_s * self.sc.fps)

    def frames(self) -> Iterator[Frame]:
        sc = self.sc
        head = sc.head()
        rng = np.random.default_rng(sc.seed + 1)
        noise_bank = [rng.normal(0.0, sc.noise_sigma, (sc.height, sc.width, 3)).astype(np.int16)
                      for _ in range(8)] if sc.noise_sigma > 0 else []
        # start pointed at the ball (the operator framed it)
        from engine.ptz.control import angles_to_centre

        p0, _, _ = sc.truth(0.0)
        pan, tilt = angles_to_centre(head, p0)
        pan = quantise(pan, self.limits.pan_step_deg, *self.limits.pan_range_deg)
        tilt = quantise(tilt, self.limits.tilt_step_deg, *self.limits.tilt_range_deg)
        pending: list[tuple[int, tuple[float, float]]] = []
        cam = sc.intrinsics()
        for i in range(len(self)):
            cmd = self.port.take()
            if cmd is not None:
                pending.append((i + self.latency_frames - 1, cmd))
            while pending and pending[0][0] <= i:
                _, (cp, ct) = pending.pop(0)
                pan = quantise(cp, self.limits.pan_step_deg, *self.limits.pan_range_deg)
                tilt = quantise(ct, self.limits.tilt_step_deg, *self.limits.tilt_range_deg)
            t = i / sc.fps
            p, v, a = sc.truth(t)
            img = self._bg.copy()
            box = render_ball(img, head, pan, tilt, p, sc.ball_radius_m, sc.ball_bgr)
            if noise_bank:  # sensor noise, cycled from a seeded bank (cheap)
                noisy = img.astype(np.int16) + noise_bank[int(rng.integers(len(noise_bank)))]
                img = np.clip(noisy, 0, 255).astype(np.uint8)
            yield Frame(
                index=i,
                timestamp_s=t,
                color_bgr=img,
                intrinsics=cam,
                gt_T_world_cam=head.T_world_cam(pan, tilt),
                gt_box_xywh=box,
                payloads=(
                    PtzHeadReading(head=head, pan_deg=pan, tilt_deg=tilt),
                    PtzTargetTruth(
                        xyz_world=_tup(p), vel_world=_tup(v), acc_world=_tup(a),
                        omega_rad_s=sc.omega_rad_s, radius_m=sc.ball_radius_m,
                    ),
                ),
            )


def _tup(v: F64) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def open_ptz_sim(options: dict[str, str]) -> PtzSimSource:
    """``ptz-sim:duration=60,period=50,radius=2.5,fps=30,seed=3,latency=1`` -> source."""
    from engine.errors import SourceError

    keys = {"duration": "duration_s", "period": "period_s", "radius": "radius_m",
            "fps": "fps", "seed": "seed", "ball": "ball_radius_m", "noise": "noise_sigma",
            "f": "f_px"}
    kw: dict[str, Any] = {}
    latency = 1
    for k, v in options.items():
        try:
            if k == "latency":
                latency = int(v)
            elif k in keys:
                kw[keys[k]] = int(v) if k == "seed" else float(v)
            else:
                raise SourceError(
                    f"ptz-sim option {k!r} unknown; known: {', '.join([*keys, 'latency'])}"
                )
        except ValueError:
            raise SourceError(f"ptz-sim option {k}={v!r} is not a number") from None
    try:
        sc = CircleScenario(**kw)
    except (TypeError, ValueError) as exc:
        raise SourceError(f"ptz-sim: {exc}") from None
    if sc.duration_s <= 0 or sc.fps <= 0 or sc.period_s <= 0:
        raise SourceError("ptz-sim: duration, fps and period must be positive")
    return PtzSimSource(sc, latency_frames=latency)


SOURCES = (
    SourceSpec(
        name="ptz-sim",
        description="a ball on a circle seen by a stepping pan-tilt camera",
        opener=lambda rest: open_ptz_sim(parse_options(rest)),
        example="ptz-sim:duration=60,period=50",
    ),
)
