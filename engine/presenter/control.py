"""Robot-camera control errors and the UDP control message (VR-TV paper, Sec. III-D).

Errors
    eq. (7)  e_f = [x - x*, y - y*]   image error against the operator's framing target
             (x*, y*) - any point of the frame, not only its centre;
    eq. (8)  e_d = d - d*             depth error against the target distance d*.

Commands
    A proportional-integral velocity command v = gain * e + ki * integral(e dt) per axis,
    limited to ``max_speed`` and changed by at most ``max_accel * dt`` per update (no abrupt
    accelerations). The integral removes the steady lag of a P controller behind a presenter
    walking at constant speed (a P controller lags by v / gain); it stops growing while the
    command is at its speed limit (anti-windup). While the tracker is LOST the target
    velocity is zero and the integral is cleared: the robot brakes within its acceleration
    limit and holds the last position (the paper: "the robot does not drift").

Message (one UDP datagram per frame, UTF-8 JSON, to 127.0.0.1:9870 by default)::

    {"type": "studiotrack.presenter.control", "version": 1,
     "seq": 42,                     # increasing per sender
     "t_s": 1.40,                   # source timestamp of the frame (s)
     "state": "TRACKING",           # or "LOST" / "INITIALIZING"
     "x_px": 321.5, "y_px": 240.2,  # filtered frontal position (x1, y1)
     "d_m": 3.2,                    # floor distance from the robot, null without overhead view
     "target": {"x_px": 320.0, "y_px": 240.0, "d_m": 3.0},
     "e_f_px": [1.5, 0.2],          # eq. (7)
     "e_d_m": 0.2,                  # eq. (8), null without d
     "v_cmd": {"x_px_s": 1.5, "y_px_s": 0.2, "d_m_s": 0.2}}  # limited velocity command
"""

from __future__ import annotations

import json
import math
import socket
from dataclasses import dataclass

from engine.presenter import PresenterError
from engine.results import TrackerCommand

MESSAGE_TYPE = "studiotrack.presenter.control"
MESSAGE_VERSION = 1
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 9870


@dataclass(frozen=True, slots=True)
class ControlLimits:
    gain: float = 1.0
    ki: float = 0.0  # integral gain (1/s^2)
    max_speed_px_s: float = 200.0
    max_accel_px_s2: float = 400.0
    max_speed_m_s: float = 0.5
    max_accel_m_s2: float = 1.0


@dataclass(frozen=True, slots=True)
class ControlCommand:
    seq: int
    t_s: float
    state: str
    x_px: float
    y_px: float
    d_m: float | None
    target_x_px: float
    target_y_px: float
    target_d_m: float
    e_f_px: tuple[float, float]
    e_d_m: float | None
    v_x_px_s: float
    v_y_px_s: float
    v_d_m_s: float

    def to_json(self) -> str:
        return json.dumps({
            "type": MESSAGE_TYPE, "version": MESSAGE_VERSION, "seq": self.seq,
            "t_s": self.t_s, "state": self.state, "x_px": self.x_px, "y_px": self.y_px,
            "d_m": self.d_m,
            "target": {"x_px": self.target_x_px, "y_px": self.target_y_px,
                       "d_m": self.target_d_m},
            "e_f_px": list(self.e_f_px), "e_d_m": self.e_d_m,
            "v_cmd": {"x_px_s": self.v_x_px_s, "y_px_s": self.v_y_px_s,
                      "d_m_s": self.v_d_m_s},
        }, separators=(",", ":"))


@dataclass(frozen=True, slots=True)
class RobotCameraCommand(TrackerCommand):
    """A robot-camera correction for the control sink: the message and where it goes.

    ``target`` is (host, UDP port) when the tracker's parameters ask for UDP, else None
    (the correction is still shown and recorded).
    """

    message: ControlCommand
    target: tuple[str, int] | None = None


def image_error(x: float, y: float, x_star: float, y_star: float) -> tuple[float, float]:
    """e_f = [x - x*, y - y*], eq. (7)."""
    return (x - x_star, y - y_star)


def depth_error(d: float, d_star: float) -> float:
    """e_d = d - d*, eq. (8)."""
    return d - d_star


def _limit(v_target: float, v_prev: float, max_speed: float, max_accel: float,
           dt: float) -> float:
    v = max(-max_speed, min(max_speed, v_target))
    dv = max_accel * dt
    return max(v_prev - dv, min(v_prev + dv, v))


class ControlLoop:
    """Errors and velocity/acceleration-limited commands, one update per frame."""

    def __init__(self) -> None:
        self.seq = 0
        self._v = (0.0, 0.0, 0.0)
        self._i = [0.0, 0.0, 0.0]  # integral of the errors (px s, px s, m s)
        self._t_prev: float | None = None

    def reset(self) -> None:
        self.seq = 0
        self._v = (0.0, 0.0, 0.0)
        self._i = [0.0, 0.0, 0.0]
        self._t_prev = None

    def _pi(self, k: int, e: float | None, active: bool, limits: ControlLimits, dt: float,
            max_speed: float) -> float:
        if not active or e is None:
            self._i[k] = 0.0
            return 0.0
        v = limits.gain * e + limits.ki * self._i[k]
        if abs(v) < max_speed or (v > 0) != (e > 0):  # anti-windup at the speed limit
            self._i[k] += e * dt
            v = limits.gain * e + limits.ki * self._i[k]
        return v

    def update(self, *, t_s: float, state: str, x_px: float, y_px: float, d_m: float | None,
               target_xy_px: tuple[float, float], target_d_m: float, limits: ControlLimits,
               default_dt_s: float = 1.0 / 30.0) -> ControlCommand:
        dt = default_dt_s if self._t_prev is None else t_s - self._t_prev
        if not math.isfinite(dt) or dt <= 0:
            dt = default_dt_s
        self._t_prev = t_s
        e_f = image_error(x_px, y_px, *target_xy_px)
        e_d = depth_error(d_m, target_d_m) if d_m is not None else None
        tracking = state == "TRACKING"
        tx = self._pi(0, e_f[0], tracking, limits, dt, limits.max_speed_px_s)
        ty = self._pi(1, e_f[1], tracking, limits, dt, limits.max_speed_px_s)
        td = self._pi(2, e_d, tracking, limits, dt, limits.max_speed_m_s)
        vx = _limit(tx, self._v[0], limits.max_speed_px_s, limits.max_accel_px_s2, dt)
        vy = _limit(ty, self._v[1], limits.max_speed_px_s, limits.max_accel_px_s2, dt)
        vd = _limit(td, self._v[2], limits.max_speed_m_s, limits.max_accel_m_s2, dt)
        self._v = (vx, vy, vd)
        self.seq += 1
        return ControlCommand(
            seq=self.seq, t_s=t_s, state=state, x_px=x_px, y_px=y_px, d_m=d_m,
            target_x_px=target_xy_px[0], target_y_px=target_xy_px[1], target_d_m=target_d_m,
            e_f_px=e_f, e_d_m=e_d, v_x_px_s=vx, v_y_px_s=vy, v_d_m_s=vd,
        )


class UdpControlSender:
    """Sends one datagram per command; send errors are counted, never raised mid-run."""

    def __init__(self, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT) -> None:
        if not 1 <= int(port) <= 65535:
            raise PresenterError(f"control port {port} is not in 1..65535")
        self.host = host
        self.port = int(port)
        self.errors = 0
        self.last_error = ""
        self._sock: socket.socket | None = None

    def retarget(self, host: str, port: int) -> None:
        self.host, self.port = host, int(port)

    def send(self, cmd: ControlCommand) -> bool:
        if self._sock is None:
            self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.sendto(cmd.to_json().encode("utf-8"), (self.host, self.port))
        except OSError as exc:
            self.errors += 1
            self.last_error = f"{self.host}:{self.port}: {exc}"
            return False
        return True

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None
