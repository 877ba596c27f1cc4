"""Per-axis delay compensation and sub-frame interpolation of the output pose.

The render engine composites our pose with the camera's video, which usually reaches it later
(or earlier) than the pose. The operator sets one delay per axis in milliseconds: the pose sent
for a frame captured at ``t`` carries, on axis ``a``, the tracked value at ``t - delay_ms[a]``.

- A positive delay looks back into the pose history and interpolates linearly between the
  two tracked frames around ``t - delay`` (sub-frame accuracy).
- A negative delay looks ahead: the value is extrapolated from the last two good frames,
  at most ``max_extrapolation_ms`` ahead (beyond that the prediction is clamped).
- While the tracker is LOST (or initialising/relocalising) nothing is extrapolated: outputs
  hold the last good pose and carry the state, so a virtual set never drifts away.

Angles are unwrapped against the previous sample before interpolation so that a pan crossing
+-180 degrees interpolates through 180, not through 0.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from engine.outputs.studio_frame import StudioPose, wrap_deg
from engine.params import Params, param

AXES = ("x", "y", "z", "pan", "tilt", "roll")


@dataclass(frozen=True, slots=True)
class DelayParams(Params):
    """Operator-set output delays (ms) per axis; positive = output lags the tracked pose."""

    x_ms: float = param(0.0, lo=-200.0, hi=1000.0, step=1.0, help="delay of X (ms)")
    y_ms: float = param(0.0, lo=-200.0, hi=1000.0, step=1.0, help="delay of Y (ms)")
    z_ms: float = param(0.0, lo=-200.0, hi=1000.0, step=1.0, help="delay of Z (ms)")
    pan_ms: float = param(0.0, lo=-200.0, hi=1000.0, step=1.0, help="delay of pan (ms)")
    tilt_ms: float = param(0.0, lo=-200.0, hi=1000.0, step=1.0, help="delay of tilt (ms)")
    roll_ms: float = param(0.0, lo=-200.0, hi=1000.0, step=1.0, help="delay of roll (ms)")
    max_extrapolation_ms: float = param(50.0, lo=0.0, hi=200.0, step=1.0,
                                        help="longest look-ahead for negative delays (ms)")

    @staticmethod
    def uniform(ms: float) -> DelayParams:
        return DelayParams(ms, ms, ms, ms, ms, ms)

    def as_array(self) -> np.ndarray:
        return np.array([self.x_ms, self.y_ms, self.z_ms, self.pan_ms, self.tilt_ms,
                         self.roll_ms]) / 1000.0

    @property
    def is_zero(self) -> bool:
        return not np.any(self.as_array())


@dataclass(frozen=True, slots=True)
class TimedPose:
    """The compensated pose and whether it is held (tracker not good)."""

    pose: StudioPose
    held: bool


class DelayCompensator:
    """Keeps a short history of good poses and answers per-axis delayed queries."""

    def __init__(self, params: DelayParams | None = None, history_s: float = 2.0) -> None:
        self.params = params or DelayParams()
        self.history_s = history_s
        self._t: deque[float] = deque()
        self._v: deque[np.ndarray] = deque()
        self._last_good: StudioPose | None = None

    def set_params(self, params: DelayParams) -> None:
        self.params = params

    @property
    def has_pose(self) -> bool:
        return self._last_good is not None

    def reset(self) -> None:
        self._t.clear()
        self._v.clear()
        self._last_good = None

    def update(self, t_s: float, pose: StudioPose | None, good: bool) -> TimedPose | None:
        """Add the tracked pose of time ``t_s``; return what to send for that frame.

        ``good`` is False while LOST/initialising: the last good pose is held (``held=True``)
        and the history is left alone. Returns None before the first good pose.
        """
        if not self.add(t_s, pose, good):
            if self._last_good is None:
                return None
            return TimedPose(self._last_good, held=True)
        return self.value(t_s)

    def add(self, t_s: float, pose: StudioPose | None, good: bool) -> bool:
        """Put a tracked pose into the history; False (nothing added) unless ``good``."""
        if not good or pose is None:
            return False
        v = pose.as_array()
        if self._v:
            prev = self._v[-1]
            if self._t and t_s <= self._t[-1]:
                # Non-increasing time (source restart): start the history again.
                self._t.clear()
                self._v.clear()
            else:
                v[3:] = prev[3:] + _wrapped_delta(v[3:] - prev[3:])
        self._t.append(float(t_s))
        self._v.append(v)
        while self._t and self._t[-1] - self._t[0] > self.history_s:
            self._t.popleft()
            self._v.popleft()
        self._last_good = pose
        return True

    def held(self) -> TimedPose | None:
        """The last good pose, held (None before the first good pose)."""
        return None if self._last_good is None else TimedPose(self._last_good, held=True)

    def value(self, t_s: float, lead_s: float = 0.0) -> TimedPose:
        """What to send at media time ``t_s + lead_s`` (``t_s``: the newest good frame's).

        Per axis the value at ``t_s + lead_s - delay``; with ``lead_s > 0`` (an output tick
        after the newest frame) a non-negative delay never reaches past the newest frame
        (no extrapolation), a negative one predicts as for ``lead_s = 0``.
        """
        assert self._last_good is not None
        if self.params.is_zero or not self._t:
            return TimedPose(self._last_good, held=False)
        d = self.params.as_array()
        tq = np.where(d >= 0, np.minimum(t_s + lead_s - d, self._t[-1]), t_s - d)
        out = self._query(tq)
        out[3:] = [wrap_deg(a) for a in out[3:]]
        return TimedPose(StudioPose.from_array(out), held=False)

    def _query(self, tq: np.ndarray) -> np.ndarray:
        ts = np.fromiter(self._t, dtype=np.float64, count=len(self._t))
        vs = np.stack(self._v)
        out = np.empty(6)
        max_ahead = self.params.max_extrapolation_ms / 1000.0
        for a in range(6):
            q = tq[a]
            if len(ts) == 1 or q <= ts[0]:
                out[a] = vs[0, a] if q <= ts[0] else vs[-1, a]
            elif q >= ts[-1]:
                q = min(q, ts[-1] + max_ahead)
                dt = ts[-1] - ts[-2]
                slope = (vs[-1, a] - vs[-2, a]) / dt if dt > 0 else 0.0
                out[a] = vs[-1, a] + slope * (q - ts[-1])
            else:
                out[a] = float(np.interp(q, ts, vs[:, a]))
        return out


def _wrapped_delta(d: np.ndarray) -> np.ndarray:
    return (d + 180.0) % 360.0 - 180.0
