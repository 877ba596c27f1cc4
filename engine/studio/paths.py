"""Camera paths through the studio: ``T_world_cam`` as a function of time.

- ``rail``: a camera dolly on a straight 3.3 m rail along x (y = 0, lens at 1.5 m), travelled
  back and forth with a smooth (cosine) speed profile, camera looking at the set with a
  fixed orientation: the studio test of Tykkälä 2014 (Fig. 13). One cycle = there and back.
- ``pan``: a tripod at the rail centre panning +-30 degrees (sinusoidal), one cycle per period.
- ``handheld``: slow walk across +-0.6 m with smooth hand-held wobble (sum of sines with
  seeded phases): a few cm and a few degrees.
- ``static``: the camera stands still at the rail centre (presenter tests).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.geometry import R_from_pan_tilt_roll_deg, make_T

F64 = NDArray[np.float64]

PATHS = ("rail", "pan", "handheld", "static")
RAIL_LENGTH_M = 3.3
RAIL_Y_M = 0.0
LENS_HEIGHT_M = 1.5
TILT_DEG = -10.0
PAN_AMPLITUDE_DEG = 30.0


@dataclass(frozen=True, slots=True)
class CameraPath:
    """A camera path; ``period_s`` is the duration of one cycle (rail: there and back)."""

    kind: str = "rail"
    period_s: float = 6.0
    seed: int = 0

    def __post_init__(self) -> None:
        if self.kind not in PATHS:
            raise ValueError(f"unknown camera path {self.kind!r} (expected one of {PATHS})")
        if not self.period_s > 0:
            raise ValueError(f"path period must be positive, got {self.period_s}")

    def T_world_cam(self, t_s: float) -> F64:
        """Camera pose at time ``t_s`` (seconds since the start)."""
        phase = 2.0 * math.pi * t_s / self.period_s
        if self.kind == "rail":
            x = -0.5 * RAIL_LENGTH_M * math.cos(phase)  # starts at the left end
            return make_T(
                R_from_pan_tilt_roll_deg(0.0, TILT_DEG, 0.0), (x, RAIL_Y_M, LENS_HEIGHT_M)
            )
        if self.kind == "pan":
            pan = PAN_AMPLITUDE_DEG * math.sin(phase)
            return make_T(
                R_from_pan_tilt_roll_deg(pan, TILT_DEG, 0.0), (0.0, RAIL_Y_M, LENS_HEIGHT_M)
            )
        if self.kind == "handheld":
            return self._handheld(t_s)
        return make_T(R_from_pan_tilt_roll_deg(0.0, TILT_DEG, 0.0), (0.0, RAIL_Y_M, LENS_HEIGHT_M))

    def _handheld(self, t_s: float) -> F64:
        rng = np.random.default_rng([self.seed, 7])
        ph = rng.uniform(0.0, 2.0 * math.pi, size=(6, 3))
        freqs = np.array([0.23, 0.51, 1.13])  # Hz: body sway, arm, tremor-ish
        amps = np.array(
            [
                [0.04, 0.015, 0.004],  # x (m)
                [0.05, 0.02, 0.004],  # y
                [0.03, 0.012, 0.003],  # z
                [2.0, 0.8, 0.2],  # pan (deg)
                [1.5, 0.6, 0.2],  # tilt
                [1.2, 0.5, 0.15],  # roll
            ]
        )
        w = np.sum(amps * np.sin(2.0 * math.pi * freqs * t_s + ph), axis=1)
        walk = 0.6 * math.sin(2.0 * math.pi * t_s / self.period_s)
        pos = (walk + w[0], RAIL_Y_M + 0.3 + w[1], LENS_HEIGHT_M + 0.05 + w[2])
        R = R_from_pan_tilt_roll_deg(-4.0 * walk + w[3], TILT_DEG + w[4], w[5])
        return make_T(R, pos)
