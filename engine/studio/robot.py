"""A robot-mounted TV camera for the built-in studio (the VR-TV paper's Fig. 2, Sec. III-D).

The paper's robot translates the main camera along x, y, z and zooms it, "keeping the error
vector as small as possible while ... avoiding jittering and abrupt accelerations", with
"suitable safety thresholds in order to limit the acceleration values". :class:`RobotRig` is
that end effector: the camera keeps a fixed orientation (the operator's framing), its
position follows a Cartesian velocity command, each axis limited in speed and acceleration,
inside a working box; the zoom follows a rate command within its range. The tracking camera
rides piggy-back on the TV camera with a fixed offset (``piggyback_m``, in the TV camera's
frame: x right, y down, z forward), so the two see the scene from slightly different places.

Time advances in :meth:`RobotRig.advance` (one call per frame, before it is rendered);
commands set the target velocity (:meth:`RobotRig.command_velocity`) and may come from
another thread.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.geometry import make_T

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class RobotLimits:
    """The arm's safety thresholds (per Cartesian axis) and working box (world, m)."""

    max_speed_m_s: float = 1.5
    max_accel_m_s2: float = 2.0
    max_zoom_rate_s: float = 0.5  # relative focal-length change per second
    zoom_range: tuple[float, float] = (1.0, 3.0)  # x the TV lens's widest focal length
    box_min_m: tuple[float, float, float] = (-3.0, -1.0, 0.6)
    box_max_m: tuple[float, float, float] = (3.0, 1.0, 2.6)


def _limit(v_target: float, v: float, max_speed: float, max_accel: float, dt: float) -> float:
    vt = max(-max_speed, min(max_speed, v_target))
    dv = max_accel * dt
    return max(v - dv, min(v + dv, vt))


class RobotRig:
    """The TV camera on the arm; its state is read and advanced on the engine thread."""

    def __init__(self, T_world_tv0: F64, limits: RobotLimits | None = None,
                 piggyback_m: tuple[float, float, float] = (0.0, -0.12, 0.02)) -> None:
        self.limits = limits or RobotLimits()
        T0 = np.asarray(T_world_tv0, dtype=np.float64)
        self.R_world_tv = T0[:3, :3].copy()
        self.p_world = T0[:3, 3].copy()
        self.v_world = np.zeros(3)
        self.zoom = 1.0
        self.zoom_rate = 0.0
        self.piggyback_m = np.asarray(piggyback_m, dtype=np.float64)
        self._lock = threading.Lock()
        self._v_target = np.zeros(3)
        self._zoom_target = 0.0
        self.commands = 0

    def command_velocity(self, v_world_m_s: F64, zoom_rate_s: float = 0.0) -> None:
        """The controller's wish: a Cartesian velocity (world, m/s) and a zoom rate (1/s)."""
        v = np.asarray(v_world_m_s, dtype=np.float64)
        if v.shape != (3,) or not np.all(np.isfinite(v)) or not math.isfinite(zoom_rate_s):
            return  # a malformed command is ignored: the arm keeps its last safe wish
        with self._lock:
            self._v_target = v.copy()
            self._zoom_target = float(zoom_rate_s)
            self.commands += 1

    def advance(self, dt: float) -> None:
        """Move for ``dt`` seconds under the limits (speed, acceleration, working box)."""
        if not dt > 0:
            return
        lim = self.limits
        with self._lock:
            vt, zt = self._v_target.copy(), self._zoom_target
        v = np.array([_limit(vt[k], self.v_world[k], lim.max_speed_m_s, lim.max_accel_m_s2, dt)
                      for k in range(3)])
        p = self.p_world + v * dt
        lo, hi = np.asarray(lim.box_min_m), np.asarray(lim.box_max_m)
        clipped = np.clip(p, lo, hi)
        v[clipped != p] = 0.0  # at the end of travel the axis stops
        self.p_world, self.v_world = clipped, v
        zr = max(-lim.max_zoom_rate_s, min(lim.max_zoom_rate_s, zt))
        z = self.zoom * math.exp(zr * dt)
        self.zoom = min(max(z, lim.zoom_range[0]), lim.zoom_range[1])
        self.zoom_rate = zr if lim.zoom_range[0] < z < lim.zoom_range[1] else 0.0

    def T_world_tv(self) -> F64:
        return make_T(self.R_world_tv, self.p_world)

    def T_world_tracking(self) -> F64:
        """The piggy-back tracking camera: same orientation, offset in the TV camera frame."""
        return make_T(self.R_world_tv, self.p_world + self.R_world_tv @ self.piggyback_m)
