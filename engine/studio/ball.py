"""The red target ball on a horizontal circular path (like the robot of Gaspar 2009, sec. 6:
constant speed on a circle, a period of tens of seconds).

Position p(t) = c + r (cos(w t + phi0), sin(w t + phi0), 0) with w = 2 pi / period: a planar
constant-turn motion with angular velocity w (counter-clockwise seen from above).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.studio.render import Prims
from engine.studio.scene import LABEL_BALL, SPH, StudioScene

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class BallPath:
    centre_m: tuple[float, float, float] = (0.6, 2.6, 1.2)
    circle_radius_m: float = 1.0
    period_s: float = 30.0
    ball_radius_m: float = 0.1
    phase0_rad: float = 0.0

    def __post_init__(self) -> None:
        if not (self.period_s > 0 and self.circle_radius_m >= 0 and self.ball_radius_m > 0):
            raise ValueError("ball period and ball radius must be positive, circle radius >= 0")

    @property
    def omega_rad_s(self) -> float:
        return 2.0 * math.pi / self.period_s

    def state(self, t_s: float) -> tuple[F64, F64, F64]:
        """Position, velocity and acceleration (world, m, m/s, m/s^2) at time ``t_s``."""
        w = self.omega_rad_s
        a = w * t_s + self.phase0_rad
        r = self.circle_radius_m
        c = np.asarray(self.centre_m, dtype=np.float64)
        pos = c + r * np.array([math.cos(a), math.sin(a), 0.0])
        vel = r * w * np.array([-math.sin(a), math.cos(a), 0.0])
        acc = -r * w * w * np.array([math.cos(a), math.sin(a), 0.0])
        return pos, vel, acc

    def prims(self, pos: F64, scene: StudioScene) -> Prims:
        r = self.ball_radius_m
        geom = np.zeros((1, 9))
        geom[0, :4] = (*pos, r)
        mat = np.zeros((1, 6), np.int32)
        mat[0, 0] = scene.flat_mat["ball"]
        lo, hi = pos - r, pos + r
        corners = np.array(
            [[[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]]
        )
        return Prims(
            np.array([SPH], np.int32), geom, mat, np.array([LABEL_BALL], np.uint8), corners
        )
