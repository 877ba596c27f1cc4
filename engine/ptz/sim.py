"""A red ball on a circular path seen by a simulated pan-tilt camera with discrete steps.

Like the paper's experiment (sec. 6.2: a red balloon on a Pioneer robot driving a circle,
period ~46 s, 2-7 m from the camera). The ball is rendered exactly: each pixel's coverage is
the fraction of 4x4 sub-pixel rays that hit the sphere, so its image is the true conic,
anti-aliased. The camera moves when its :attr:`PtzSimSource.head_port` is commanded (like a
camera driver; the pipeline's head sink does it with the tracker's
:class:`engine.ptz.head.PanTiltCommand`), in whole steps, after a ``latency_frames`` delay.
Each frame carries :class:`engine.ptz.head.PtzHeadReading` (geometry and encoder reading at
exposure) and :class:`PtzTargetTruth` (the ball's true motion).

Options for the calibration chain and a real head (``ptz-sim:key=value``):

- ``markers=1``: green reference markers at known world points (:func:`reference_markers`,
  a back wall and the floor: not one plane) for the DLT and for pan/tilt from reference
  points;
- ``distortion=K``: the lens has inverse radial distortion k3 = K (sec. 3.3; centre a few
  pixels off the image centre); :meth:`PtzSimSource.board_view` renders chessboard views
  through it for the line-based calibration;
- ``encoder=0``: the head has no encoder, frames carry no head reading (sec. 3.2: pan and
  tilt must come from the reference points);
- ``head=visca``: the head is a loopback VISCA-over-IP camera
  (:class:`engine.ptz.visca_sim.ViscaCameraSim`, finite speed) driven through the
  :class:`engine.ptz.visca_head.ViscaHead` driver; the head reading comes from the camera's
  FreeD output (``position=freed``, default) or its VISCA position inquiry
  (``position=visca``); ``visca_speed`` scales its motor speed.
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
from engine.ptz.distortion import RadialModel
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
    markers: bool = param(False, help="green reference markers at known world points")
    marker_radius_m: float = param(0.05, lo=0.005, hi=0.5, help="reference marker radius (m)")
    distortion_k3: float = param(0.0, lo=-0.5, hi=0.5,
                                 help="lens inverse radial distortion k3 (sec. 3.3), 0 = none")
    encoder: bool = param(True, help="the head reports its motor angles (else no reading)")

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

    def radial(self) -> RadialModel | None:
        """The lens's true inverse radial distortion (None when ``distortion_k3`` is 0)."""
        if self.distortion_k3 == 0.0:
            return None
        return RadialModel(k=(self.distortion_k3,),
                           centre_px=((self.width - 1) / 2 + 6.0, (self.height - 1) / 2 - 4.0),
                           r_norm_px=0.5 * math.hypot(self.width, self.height))


MARKER_BGR = (60, 200, 40)


def reference_markers() -> F64:
    """World points of the reference markers (m): a back wall at y = 9 m (three rows) and
    two rows on the floor, so that they are not one plane; placed irregularly (seeded
    jitter), as a studio's surveyed points are, so no view looks like a shifted other."""
    rng = np.random.default_rng(29)
    wall = [(x + rng.uniform(-0.45, 0.45), 9.0, z + rng.uniform(-0.3, 0.3))
            for z in (0.6, 1.6, 2.6) for x in np.arange(-10.5, 10.51, 1.5)]
    floor = [(x + rng.uniform(-0.6, 0.6), y + rng.uniform(-0.4, 0.4), 0.0)
             for y in (6.0, 7.5) for x in np.arange(-6.0, 6.01, 2.0)]
    return np.asarray(wall + floor, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class PtzTargetTruth(FramePayload):
    """The simulated target's true position, velocity, acceleration (world, m, s)."""

    xyz_world: tuple[float, float, float]
    vel_world: tuple[float, float, float]
    acc_world: tuple[float, float, float]
    omega_rad_s: float
    radius_m: float
    pan_tilt_deg: tuple[float, float] | None = None  # the head's true motor angles


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
    radial: RadialModel | None = None,
) -> tuple[float, float, float, float] | None:
    """Draw the sphere's exact anti-aliased image; returns its box (x, y, w, h) or None.

    With ``radial`` the lens distorts: each sub-pixel's ray goes through its ideal pixel
    (the inverse radial model maps distorted pixels to ideal ones, sec. 3.3)."""
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
    if radial is not None:
        if not (-0.5 * w < u < 1.5 * w and -0.5 * h < v < 1.5 * h):
            return None
        u, v = (float(c) for c in radial.distort_px(np.array([[u, v]]))[0])
        r_px = 1.3 * r_px + 2
    x0, x1 = max(0, int(u - r_px)), min(w, int(u + r_px) + 2)
    y0, y1 = max(0, int(v - r_px)), min(h, int(v + r_px) + 2)
    if x0 >= x1 or y0 >= y1:
        return None
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    xs = (np.arange(x0, x1)[:, None] + sub[None, :]).ravel()
    ys = (np.arange(y0, y1)[:, None] + sub[None, :]).ravel()
    if radial is not None:
        gx, gy = np.meshgrid(xs, ys)
        ideal = radial.undistort_px(np.stack([gx.ravel(), gy.ravel()], axis=1))
        X = ((ideal[:, 0] - cx) / fx).reshape(gx.shape)
        Y = ((ideal[:, 1] - cy) / fy).reshape(gx.shape)
    else:
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
    """Frames of :class:`CircleScenario` with a closed pan/tilt loop through ``head_port``.

    ``head``: ``"sim"`` (the simulated stepping head obeying :class:`PtzPort`) or ``"visca"``
    (a loopback VISCA camera, see the module docstring); ``position``: where a VISCA head's
    reading comes from (``"freed"`` or ``"visca"``).
    """

    def __init__(self, scenario: CircleScenario | None = None, latency_frames: int = 1,
                 head: str = "sim", position: str = "freed", visca_speed: float = 1.0
                 ) -> None:
        self.sc = scenario or CircleScenario()
        if head not in ("sim", "visca") or position not in ("freed", "visca"):
            raise ValueError(f"ptz-sim head {head!r}/position {position!r}: expected "
                             "sim|visca and freed|visca")
        self.nominal_fps = self.sc.fps
        self.head_kind = head
        self.position_kind = position
        self.visca_speed = float(visca_speed)
        self.name = (f"ptz-sim circle r={self.sc.radius_m} m T={self.sc.period_s} s"
                     + (" (VISCA head)" if head == "visca" else ""))
        self.port = PtzPort()
        self.head_port: Any = self.port  # what the pipeline's head sink commands
        self.latency_frames = max(0, int(latency_frames))
        self.limits = StepLimits(self.sc.pan_step_deg, self.sc.tilt_step_deg, max_steps=3)
        self.radial = self.sc.radial()
        self.markers = reference_markers() if self.sc.markers else np.zeros((0, 3))
        self._visca: Any = None  # (camera simulator, driver, FreeD listener)
        rng = np.random.default_rng(self.sc.seed)
        h, w = self.sc.height, self.sc.width
        grad = np.linspace(150, 90, h, dtype=np.float32)[:, None, None]
        tex = rng.normal(0, 6, (h, w, 1)).astype(np.float32)
        self._bg = np.clip(grad + tex + np.array([0, 4, 8], np.float32), 0, 255).astype(np.uint8)

    @property
    def intrinsics(self) -> Intrinsics:
        return self.sc.intrinsics()

    def _ensure_visca(self) -> Any:
        """Start the loopback VISCA camera, its FreeD listener and the driver (once)."""
        if self._visca is None:
            from engine.outputs.freed_input import FreeDListener
            from engine.ptz.visca_head import ViscaHead
            from engine.ptz.visca_sim import ViscaCameraSim

            pan, tilt = self.start_angles()
            listener = FreeDListener(0)
            cam = ViscaCameraSim(freed_to=("127.0.0.1", listener.port), pan_deg=pan,
                                 tilt_deg=tilt, speed_scale=self.visca_speed,
                                 position_m=(0.0, 0.0, self.sc.camera_height_m))
            driver = ViscaHead("127.0.0.1", cam.port, poll_hz=20.0)
            self._visca = (cam, driver, listener)
            self.head_port = driver
        return self._visca

    @property
    def visca_camera(self) -> Any:
        """The loopback VISCA camera simulator (head=visca), for tests and the GUI."""
        return self._ensure_visca()[0] if self.head_kind == "visca" else None

    def sinks(self) -> Sequence[Any]:
        """The head obeys the tracker's pan-tilt commands (closed loop)."""
        from engine.ptz.head import HeadCommandSink

        if self.head_kind == "visca":
            _, driver, _ = self._ensure_visca()
            return (HeadCommandSink(driver, "VISCA head (loopback camera)"),)
        return (HeadCommandSink(self.head_port, "ptz-sim head"),)

    def close(self) -> None:
        if self._visca is not None:
            cam, driver, listener = self._visca
            driver.close()
            cam.close()
            listener.close()
            self._visca = None
            self.head_port = self.port

    def __len__(self) -> int:
        return round(self.sc.duration_s * self.sc.fps)

    def start_angles(self) -> tuple[float, float]:
        """Motor angles of the first frame: pointed at the ball (the operator framed it)."""
        from engine.ptz.control import angles_to_centre

        p0, _, _ = self.sc.truth(0.0)
        pan, tilt = angles_to_centre(self.sc.head(), p0)
        if self.head_kind == "visca":
            return pan, tilt
        return (quantise(pan, self.limits.pan_step_deg, *self.limits.pan_range_deg),
                quantise(tilt, self.limits.tilt_step_deg, *self.limits.tilt_range_deg))

    def render(self, pan_deg: float, tilt_deg: float, t_s: float | None = None,
               ball: bool = True) -> tuple[NDArray[np.uint8], Any]:
        """The noise-free image at motor angles (with the ball at time ``t_s``) and the
        ball's box."""
        sc = self.sc
        head = sc.head()
        img = self._bg.copy()
        for m in self.markers:
            render_ball(img, head, pan_deg, tilt_deg, m, sc.marker_radius_m, MARKER_BGR,
                        ss=2, radial=self.radial)
        box = None
        if ball and t_s is not None:
            p, _, _ = sc.truth(t_s)
            box = render_ball(img, head, pan_deg, tilt_deg, p, sc.ball_radius_m, sc.ball_bgr,
                              radial=self.radial)
        return img, box

    def board_view(self, pan_deg: float, tilt_deg: float, T_cam_board: F64,
                   pattern_cols_rows: tuple[int, int] = (9, 6), square_m: float = 0.08
                   ) -> NDArray[np.uint8]:
        """A chessboard held at ``T_cam_board`` seen through this camera's lens (grey)."""
        from engine.studio.chessboard_view import pinhole_rays, render_chessboard

        cam = self.sc.intrinsics()
        rays = pinhole_rays(np.asarray(self.sc.head().K), cam.width, cam.height,
                            None if self.radial is None else self.radial.undistort_px)
        return render_chessboard(cam, T_cam_board, pattern_cols_rows, square_m, rays=rays)

    def lines_views(self, pattern_cols_rows: tuple[int, int] = (15, 11),
                    square_m: float = 0.1) -> list[NDArray[np.uint8]]:
        """Four views of a large calibration board held up to fill the image (slightly
        turned each time): long world-straight lines for the line-based distortion."""
        from engine.geometry import make_T, so3_exp

        cols, rows = pattern_cols_rows
        f = float(self.sc.head().K[0, 0])
        z = f * (cols + 3) * square_m / (0.97 * self.sc.width)
        c = np.array([(cols - 1) / 2 * square_m, (rows - 1) / 2 * square_m, 0.0])
        out = []
        for rv in ([0.0, 0.0, 0.0], [0.12, 0.0, 0.0], [0.0, 0.15, 0.0], [-0.1, -0.1, 0.05]):
            R = so3_exp(np.asarray(rv))
            out.append(self.board_view(0.0, 0.0, make_T(R, np.array([0.0, 0.0, z]) - R @ c),
                                       pattern_cols_rows, square_m))
        return out

    def frames(self) -> Iterator[Frame]:
        sc = self.sc
        head = sc.head()
        rng = np.random.default_rng(sc.seed + 1)
        noise_bank = [rng.normal(0.0, sc.noise_sigma, (sc.height, sc.width, 3)).astype(np.int16)
                      for _ in range(8)] if sc.noise_sigma > 0 else []
        pan, tilt = self.start_angles()
        visca = self._ensure_visca() if self.head_kind == "visca" else None
        seen = 0
        pending: list[tuple[int, tuple[float, float]]] = []
        cam = sc.intrinsics()
        for i in range(len(self)):
            t = i / sc.fps
            reading: tuple[float, float] | None
            if visca is not None:
                vcam, driver, listener = visca
                pan, tilt = vcam.advance(t)  # the camera moves, then reports by FreeD
                reading = None
                if self.position_kind == "freed":
                    from engine.outputs.freed_input import head_reading_of

                    r = listener.wait_beyond(seen, 0.25)
                    if r is not None:
                        seen = r.count
                        reading = head_reading_of(r)
                else:
                    pos = driver.position()
                    reading = None if pos is None else (pos.pan_deg, pos.tilt_deg)
            else:
                cmd = self.port.take()
                if cmd is not None:
                    pending.append((i + self.latency_frames - 1, cmd))
                while pending and pending[0][0] <= i:
                    _, (cp, ct) = pending.pop(0)
                    pan = quantise(cp, self.limits.pan_step_deg, *self.limits.pan_range_deg)
                    tilt = quantise(ct, self.limits.tilt_step_deg, *self.limits.tilt_range_deg)
                reading = (pan, tilt)
            p, v, a = sc.truth(t)
            img, box = self.render(pan, tilt, t)
            if noise_bank:  # sensor noise, cycled from a seeded bank (cheap)
                noisy = img.astype(np.int16) + noise_bank[int(rng.integers(len(noise_bank)))]
                img = np.clip(noisy, 0, 255).astype(np.uint8)
            payloads: list[FramePayload] = []
            if sc.encoder and reading is not None:
                payloads.append(PtzHeadReading(head=head, pan_deg=reading[0],
                                               tilt_deg=reading[1]))
            payloads.append(PtzTargetTruth(
                xyz_world=_tup(p), vel_world=_tup(v), acc_world=_tup(a),
                omega_rad_s=sc.omega_rad_s, radius_m=sc.ball_radius_m,
                pan_tilt_deg=(float(pan), float(tilt)),
            ))
            yield Frame(
                index=i,
                timestamp_s=t,
                color_bgr=img,
                intrinsics=cam,
                gt_T_world_cam=head.T_world_cam(pan, tilt),
                gt_box_xywh=box,
                payloads=tuple(payloads),
            )


def _tup(v: F64) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def open_ptz_sim(options: dict[str, str]) -> PtzSimSource:
    """``ptz-sim:duration=60,period=50,radius=2.5,fps=30,seed=3,latency=1`` -> source."""
    from engine.errors import SourceError

    keys = {"duration": "duration_s", "period": "period_s", "radius": "radius_m",
            "fps": "fps", "seed": "seed", "ball": "ball_radius_m", "noise": "noise_sigma",
            "f": "f_px", "distortion": "distortion_k3"}
    flags = {"markers": "markers", "encoder": "encoder"}
    choices = {"head": ("sim", "visca"), "position": ("freed", "visca")}
    kw: dict[str, Any] = {}
    extra: dict[str, Any] = {"latency_frames": 1}
    known = [*keys, *flags, *choices, "latency", "visca_speed"]
    for k, v in options.items():
        try:
            if k == "latency":
                extra["latency_frames"] = int(v)
            elif k == "visca_speed":
                extra["visca_speed"] = float(v)
                if not 0.05 <= extra["visca_speed"] <= 10:
                    raise SourceError(f"ptz-sim option visca_speed={v!r}: expected 0.05..10")
            elif k in keys:
                kw[keys[k]] = int(v) if k == "seed" else float(v)
            elif k in flags:
                if v not in ("0", "1"):
                    raise SourceError(f"ptz-sim option {k}={v!r}: expected 0 or 1")
                kw[flags[k]] = v == "1"
            elif k in choices:
                if v not in choices[k]:
                    raise SourceError(f"ptz-sim option {k}={v!r}: expected "
                                      f"{' or '.join(choices[k])}")
                extra[k] = v
            else:
                raise SourceError(f"ptz-sim option {k!r} unknown; known: {', '.join(known)}")
        except ValueError:
            raise SourceError(f"ptz-sim option {k}={v!r} is not a number") from None
    try:
        sc = CircleScenario(**kw)
    except (TypeError, ValueError) as exc:
        raise SourceError(f"ptz-sim: {exc}") from None
    if sc.duration_s <= 0 or sc.fps <= 0 or sc.period_s <= 0:
        raise SourceError("ptz-sim: duration, fps and period must be positive")
    if "position" in extra and extra.get("head") != "visca":
        raise SourceError("ptz-sim: option position needs head=visca")
    return PtzSimSource(sc, **extra)


SOURCES = (
    SourceSpec(
        name="ptz-sim",
        description="a ball on a circle seen by a stepping pan-tilt camera",
        opener=lambda rest: open_ptz_sim(parse_options(rest)),
        example="ptz-sim:duration=60,period=50",
    ),
)
