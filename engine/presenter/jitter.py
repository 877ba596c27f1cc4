"""Jitter low-pass on the tracker output (VR-TV paper, Sec. III-C.6).

A critically damped second-order low-pass: two identical one-pole stages
``y += alpha (x - y)``. Each stage's time constant is set so that the cascade's -3 dB point is
the operator's cut-off ``f_c``: tau = sqrt(sqrt(2) - 1) / (2 pi f_c), alpha = 1 - exp(-dt/tau).

Its lag is known in closed form: for a ramp input (a presenter walking at constant speed v) a
one-pole stage settles at a lag of (1 - alpha)/alpha samples, so the cascade lags by
``2 (1 - alpha) / alpha`` frames = that times dt seconds, i.e. v times that in pixels. White
noise variance is multiplied by ``noise_gain`` (computed numerically from the impulse
response). Cut-off 0 turns the filter off (no lag, no smoothing).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def stage_alpha(cutoff_hz: float, frame_rate_hz: float) -> float:
    """Per-stage smoothing factor for a cascade -3 dB at ``cutoff_hz`` (1.0 = off)."""
    if cutoff_hz <= 0 or frame_rate_hz <= 0:
        return 1.0
    tau_s = math.sqrt(math.sqrt(2.0) - 1.0) / (2.0 * math.pi * cutoff_hz)
    return 1.0 - math.exp(-1.0 / (frame_rate_hz * tau_s))


def ramp_lag_frames(cutoff_hz: float, frame_rate_hz: float) -> float:
    """Steady-state lag (frames) of the cascade behind a constant-speed input."""
    a = stage_alpha(cutoff_hz, frame_rate_hz)
    return 2.0 * (1.0 - a) / a


def ramp_lag_s(cutoff_hz: float, frame_rate_hz: float) -> float:
    return ramp_lag_frames(cutoff_hz, frame_rate_hz) / frame_rate_hz if frame_rate_hz > 0 else 0.0


def noise_gain(cutoff_hz: float, frame_rate_hz: float) -> float:
    """Output / input variance for white noise (sum of the squared impulse response)."""
    a = stage_alpha(cutoff_hz, frame_rate_hz)
    if a >= 1.0:
        return 1.0
    k = np.arange(2000)
    h = a * a * (k + 1) * (1 - a) ** k  # impulse response of two identical one-pole stages
    return float(np.sum(h * h))


class JitterFilter:
    """Vector low-pass (x, y, h or x, y, d); cut-off and frame rate changeable between samples."""

    def __init__(self, cutoff_hz: float, frame_rate_hz: float) -> None:
        self.cutoff_hz = float(cutoff_hz)
        self.frame_rate_hz = float(frame_rate_hz)
        self._s1: F64 | None = None
        self._s2: F64 | None = None

    def configure(self, cutoff_hz: float, frame_rate_hz: float) -> None:
        self.cutoff_hz = float(cutoff_hz)
        self.frame_rate_hz = float(frame_rate_hz)

    def reset(self, value: F64 | None = None) -> None:
        if value is None:
            self._s1 = self._s2 = None
        else:
            self._s1 = np.array(value, dtype=np.float64)
            self._s2 = np.array(value, dtype=np.float64)

    @property
    def lag_frames(self) -> float:
        return ramp_lag_frames(self.cutoff_hz, self.frame_rate_hz)

    @property
    def lag_s(self) -> float:
        return ramp_lag_s(self.cutoff_hz, self.frame_rate_hz)

    def __call__(self, value: F64) -> F64:
        x = np.asarray(value, dtype=np.float64)
        a = stage_alpha(self.cutoff_hz, self.frame_rate_hz)
        if self._s1 is None or self._s2 is None or a >= 1.0:
            self.reset(x)
            return x.copy()
        self._s1 = self._s1 + a * (x - self._s1)
        self._s2 = self._s2 + a * (self._s1 - self._s2)
        return self._s2.copy()
