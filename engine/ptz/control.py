"""Pan/tilt decision with discrete steps (Gaspar 2009 sec. 2 and 6.1).

The camera moves in discrete, limited steps; the decision keeps the distance between the
image centre and the target below a dead band: when the (predicted) target leaves the dead
band, the motor angles that would centre it are computed and rounded to whole steps,
at most ``max_steps`` per command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.ptz.dlt import project_P
from engine.ptz.kinematics import PtzHead

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class StepLimits:
    pan_step_deg: float = 1.0
    tilt_step_deg: float = 1.0
    max_steps: int = 3
    pan_range_deg: tuple[float, float] = (-170.0, 170.0)
    tilt_range_deg: tuple[float, float] = (-30.0, 90.0)


def quantise(angle_deg: float, step_deg: float, lo: float, hi: float) -> float:
    return float(np.clip(round(angle_deg / step_deg) * step_deg, lo, hi))


def angles_to_centre(head: PtzHead, p_world: F64) -> tuple[float, float]:
    """Motor (pan, tilt) that put a world point on the optical axis (offset ignored)."""
    d = np.asarray(p_world, dtype=np.float64) - np.asarray(head.rotation_centre_world_m)
    pan = math.degrees(math.atan2(-d[0], d[1])) - head.pan0_deg
    tilt = math.degrees(math.atan2(d[2], math.hypot(d[0], d[1]))) - head.tilt0_deg
    return pan, tilt


def decide(
    head: PtzHead,
    pan_deg: float,
    tilt_deg: float,
    target_world: F64,
    size_wh: tuple[int, int],
    deadband_px: float,
    limits: StepLimits,
) -> tuple[float, float]:
    """Next commanded (pan, tilt): unchanged inside the dead band, else stepped to centre."""
    uv = project_P(head.P(pan_deg, tilt_deg), np.asarray(target_world).reshape(1, 3))[0]
    w, h = size_wh
    if abs(uv[0] - (w - 1) / 2) <= deadband_px and abs(uv[1] - (h - 1) / 2) <= deadband_px:
        return pan_deg, tilt_deg
    pan_t, tilt_t = angles_to_centre(head, target_world)
    lim_p = limits.max_steps * limits.pan_step_deg
    lim_t = limits.max_steps * limits.tilt_step_deg
    pan_c = pan_deg + float(np.clip(pan_t - pan_deg, -lim_p, lim_p))
    tilt_c = tilt_deg + float(np.clip(tilt_t - tilt_deg, -lim_t, lim_t))
    return (
        quantise(pan_c, limits.pan_step_deg, *limits.pan_range_deg),
        quantise(tilt_c, limits.tilt_step_deg, *limits.tilt_range_deg),
    )
