"""``robot-sim:``: the built-in studio filmed by a robot-mounted camera that obeys the presenter
tracker's control messages (VR-TV paper, Sec. III-D), closing the loop.

The source renders the studio (any ``synthetic:`` option) from the piggy-back tracking camera
of an :class:`engine.studio.robot.RobotRig`; the pipeline adds the source's
:class:`RobotSimSink`, which turns each :class:`engine.presenter.control.RobotCameraCommand`
into the arm's Cartesian velocity the way a Cartesian controller would (image velocity x
working depth / focal length along the camera's x and y; the depth command as a zoom rate of
the TV lens, v_d / d*), under the arm's own speed and acceleration limits. Each frame carries a
:class:`RobotCameraTruth`: the TV camera's pose and zoom, and where the presenter really is in
the TV picture (for the framing error).

Options: those of ``synthetic:`` (the camera path is replaced by the robot; the presenter is
on) plus ``robot_depth_m`` (2.4: the controller's working depth), ``robot_speed`` (1.5 m/s),
``robot_accel`` (2 m/s^2), ``robot_x`` (start x, m; default: where the presenter starts).
The tracking camera is a wide lens (f = 330 px at 640 px wide), the TV camera the studio's
(f = 525 px at 640) times its zoom.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics, project
from engine.errors import SourceError
from engine.frames import Frame, FramePayload
from engine.geometry import invert
from engine.loop import FrameRecord
from engine.pipeline import SinkBase, SinkHealth, SinkLevel
from engine.presenter.control import RobotCameraCommand
from engine.sources.base import Source, SourceSpec, parse_options
from engine.studio.robot import RobotLimits, RobotRig

F64 = NDArray[np.float64]
ROBOT_OPTIONS = ("robot_depth_m", "robot_speed", "robot_accel", "robot_x")
TRACKING_F_AT_640 = 330.0  # px: about 88 x 72 degrees


@dataclass(frozen=True, slots=True)
class RobotCameraTruth(FramePayload):
    """The TV camera at this frame and the presenter's true place in its picture."""

    T_world_tv: tuple[tuple[float, ...], ...]
    zoom: float
    velocity_world_m_s: tuple[float, float, float]
    f_tv_px: float
    tv_image_wh: tuple[int, int]
    presenter_tv_px: tuple[float, float] | None  # body centre (between feet and head)


class RobotSimSink(SinkBase):
    """Carries out the tracker's robot-camera corrections on the simulated arm."""

    name = "robot-sim arm"

    def __init__(self, rig: RobotRig, f_px: float, depth_m: float) -> None:
        self.rig = rig
        self.f_px = float(f_px)
        self.depth_m = float(depth_m)
        self.commands = 0

    def on_record(self, record: FrameRecord) -> None:
        for cmd in record.result.commands_of(RobotCameraCommand):
            m = cmd.message
            # image velocity (px/s) -> camera-frame velocity (m/s) at the working depth
            k = self.depth_m / self.f_px
            v_cam = np.array([m.v_x_px_s * k, m.v_y_px_s * k, 0.0])
            zoom_rate = m.v_d_m_s / m.target_d_m if m.target_d_m > 0 else 0.0
            self.rig.command_velocity(self.rig.R_world_tv @ v_cam, zoom_rate)
            self.commands += 1

    def health(self) -> SinkHealth:
        p = self.rig.p_world
        return SinkHealth(self.name, SinkLevel.OK,
                          f"at x {p[0]:+.2f} z {p[2]:.2f} m, zoom {self.rig.zoom:.2f}",
                          counters={"commands": self.commands})


class RobotSimSource(Source):
    """The studio from the robot's tracking camera; the arm moves between frames."""

    live = False

    def __init__(self, config: Any, depth_m: float = 2.4, limits: RobotLimits | None = None,
                 start_x_m: float | None = None) -> None:
        from engine.studio.sim import Studio

        if config.presenter is None:
            raise SourceError("robot-sim: needs presenter=1 (the robot frames the presenter)")
        self.config = config
        self.studio = Studio(config)
        # the tracking camera: a wide lens that keeps the presenter in sight (the paper:
        # "the tracking camera has no zoom ... but keeps always a large FOV")
        self.studio.intrinsics = Intrinsics(
            fx=TRACKING_F_AT_640 * config.width / 640.0,
            fy=TRACKING_F_AT_640 * config.width / 640.0,
            cx=(config.width - 1) / 2.0, cy=(config.height - 1) / 2.0,
            width=config.width, height=config.height)
        self.nominal_fps = config.fps
        self.depth_m = float(depth_m)
        T0 = config.path.T_world_cam(0.0).copy()
        if start_x_m is None:  # start framing the presenter
            st = config.presenter.state(config.presenter.start_frame)
            start_x_m = float(st.x_m) if st is not None else 0.0
        T0[0, 3] = start_x_m
        self.rig = RobotRig(T0, limits)
        self._sink = RobotSimSink(self.rig, self.studio.intrinsics.fx, self.depth_m)
        self.name = f"robot-sim ({config.frames} frames, presenter {config.presenter.mode})"

    @property
    def intrinsics(self) -> Intrinsics:
        return self.studio.intrinsics

    def __len__(self) -> int:
        return int(self.config.frames)

    def sinks(self) -> Sequence[Any]:
        """The simulated arm obeys the tracker's corrections (closed loop)."""
        return (self._sink,)

    def _truth(self) -> RobotCameraTruth:
        from engine.studio.sim import studio_intrinsics

        rig = self.rig
        cfg = self.config
        base = studio_intrinsics(cfg.width, cfg.height)
        f_tv = base.fx * rig.zoom
        T = rig.T_world_tv()
        return RobotCameraTruth(
            T_world_tv=tuple(tuple(float(v) for v in row) for row in T),
            zoom=float(rig.zoom),
            velocity_world_m_s=(float(rig.v_world[0]), float(rig.v_world[1]),
                                float(rig.v_world[2])),
            f_tv_px=float(f_tv), tv_image_wh=(cfg.width, cfg.height),
            presenter_tv_px=None)

    def frames(self) -> Iterator[Frame]:
        from engine.studio.sim import StudioTruth

        dt = 1.0 / self.config.fps
        for i in range(len(self)):
            if i > 0:
                self.rig.advance(dt)
            f = self.studio.frame(i, self.rig.T_world_tracking())
            truth = self._truth()
            st = f.payload(StudioTruth)
            if st is not None and st.presenter_pos_world is not None \
                    and st.presenter_head_world is not None:
                centre = 0.5 * (np.asarray(st.presenter_pos_world)
                                + np.asarray(st.presenter_head_world))
                truth = replace(truth, presenter_tv_px=self._tv_px(centre, truth))
            yield replace(f, payloads=(*f.payloads, truth))

    @staticmethod
    def _tv_px(p_world: F64, truth: RobotCameraTruth) -> tuple[float, float] | None:
        W, H = truth.tv_image_wh
        K = Intrinsics(fx=truth.f_tv_px, fy=truth.f_tv_px, cx=(W - 1) / 2.0, cy=(H - 1) / 2.0,
                       width=W, height=H)
        p_cam = (invert(np.asarray(truth.T_world_tv)) @ np.append(p_world, 1.0))[:3]
        if p_cam[2] <= 0:
            return None
        uv = project(K, p_cam[None, :])[0]
        return (float(uv[0]), float(uv[1]))


def open_robot_sim(rest: str) -> RobotSimSource:
    from engine.sources.synthetic import config_from_options

    opts = parse_options(rest)
    robot = {k: opts.pop(k) for k in list(opts) if k in ROBOT_OPTIONS}
    opts.setdefault("presenter", "1")
    opts.setdefault("path", "static")
    # the robot follows: the presenter walks wider than a static camera would see
    opts.setdefault("presenter_xmin", "-2.2")
    opts.setdefault("presenter_xmax", "2.2")
    if opts["path"] != "static":
        raise SourceError("robot-sim: the robot moves the camera; leave out path= (or static)")
    try:
        depth = float(robot.get("robot_depth_m", 2.4))
        speed = float(robot.get("robot_speed", 1.5))
        accel = float(robot.get("robot_accel", 2.0))
        x0 = float(robot["robot_x"]) if "robot_x" in robot else None
    except ValueError as exc:
        raise SourceError(f"robot-sim: robot options must be numbers ({exc})") from None
    if not (depth > 0 and speed > 0 and accel > 0 and (x0 is None or abs(x0) <= 3.0)):
        raise SourceError("robot-sim: robot_depth_m, robot_speed, robot_accel must be > 0 and "
                          "|robot_x| <= 3 m")
    cfg = config_from_options(opts)
    return RobotSimSource(cfg, depth, RobotLimits(max_speed_m_s=speed, max_accel_m_s2=accel),
                          x0)


SOURCES = (
    SourceSpec(
        name="robot-sim",
        description="the built-in studio seen by a robot-mounted camera that obeys the "
        "presenter tracker's control messages",
        opener=open_robot_sim,
        example="robot-sim:frames=300,presenter_xmin=-2,presenter_xmax=2",
    ),
)
