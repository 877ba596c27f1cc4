"""The published experiment of Gaspar & Oliveira 2009 (sec. 6) as simulator scenarios.

Sec. 6.2: a red balloon on a Pioneer robot driving a circle, "the real target angular velocity
is 2 pi 0.0217 rad/s" (between the bank's models 2 pi / 50 [0, 1, 2, 3], sec. 6.1), 140 s
(figs. 4-6), "a lower bound of approximately 0.5 s" for the sampling interval (sec. 6.1), the
target an ellipse of 106 x 145 mm (here a sphere of 125 mm diameter), tracked "for distances
up to approximately 7 m" and down to 40 cm, where it fills the image (sec. 6.2).

- :func:`paper_circle` -- the circle of fig. 3 (1.5-5.5 m from the camera, the camera at the
  world origin as in the paper's fig. 3, 1 m above the balloon);
- :func:`paper_range` -- the same turn rate as an oscillation along the line of sight that
  passes 40 cm and 7 m (a circle cannot: at 40 cm its angular speed would be 64 deg/s, past
  what the stepping head follows at 2 Hz). Per axis the constant-turn model (``a''' = -w^2
  a'``) holds for it exactly, so the bank's models apply as for the circle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from engine.params import param
from engine.ptz.sim import CircleScenario

F64 = NDArray[np.float64]

#: sec. 6.2: "the real target angular velocity is 2 pi 0.0217 rad/s"
PAPER_OMEGA_RAD_S = 2.0 * math.pi * 0.0217
#: sec. 6.1: "a lower bound of approximately 0.5 s" for the sampling interval
PAPER_SAMPLING_S = 0.5
#: figs. 4-6: 140 s
PAPER_DURATION_S = 140.0
#: sec. 6.2: an ellipse of 106 x 145 mm; a sphere of the mean diameter
PAPER_TARGET_RADIUS_M = 0.0625
#: sec. 6.1: 640 x 480 images
PAPER_SIZE_PX = (640, 480)


@dataclass(frozen=True, slots=True)
class LineScenario(CircleScenario):
    """The ball oscillating along a line: ``centre + radius cos(phase0 + w t) direction``."""

    direction_world: tuple[float, float, float] = param(
        (0.0, 1.0, 0.0), help="unit direction of the oscillation (world)")

    def truth(self, t: float) -> tuple[F64, F64, F64]:
        w = self.omega_rad_s
        a = self.phase0_rad + w * t
        c = np.asarray(self.centre_world_m)
        u = np.asarray(self.direction_world, dtype=np.float64)
        u = u / max(float(np.linalg.norm(u)), 1e-12)
        r = self.radius_m
        return (c + r * math.cos(a) * u, -r * w * math.sin(a) * u,
                -r * w * w * math.cos(a) * u)


def _paper_base() -> CircleScenario:
    return CircleScenario(period_s=2.0 * math.pi / PAPER_OMEGA_RAD_S, fps=1.0 / PAPER_SAMPLING_S,
                          duration_s=PAPER_DURATION_S, ball_radius_m=PAPER_TARGET_RADIUS_M,
                          width=PAPER_SIZE_PX[0], height=PAPER_SIZE_PX[1])


def paper_circle() -> CircleScenario:
    """Fig. 3's circle: radius 2 m, 1.5-5.5 m from the camera, at the paper's turn rate."""
    return replace(_paper_base(), centre_world_m=(0.0, 3.5, 0.5), radius_m=2.0,
                   camera_height_m=1.5)


def paper_range() -> LineScenario:
    """The range run: along the optical axis from 7 m to 40 cm and back, three times in 140 s
    (the optical centre sits 4 cm ahead of the head's rotation centre)."""
    b = _paper_base()
    near, far = 0.40 + 0.04, 7.0 + 0.04
    return LineScenario(
        centre_world_m=(0.0, 0.5 * (near + far), 1.5), radius_m=0.5 * (far - near),
        period_s=b.period_s, fps=b.fps, duration_s=b.duration_s, ball_radius_m=b.ball_radius_m,
        width=b.width, height=b.height, camera_height_m=1.5, phase0_rad=0.0,
        direction_world=(0.0, 1.0, 0.0))
