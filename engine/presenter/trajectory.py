"""The presenter's own trajectory: who is the presenter when two people look alike.

Beyond the VR-TV paper (its eq. 1 is a random walk, and its colour/motion likelihoods,
eq. 3-5, score a second person in the same clothes as highly as the presenter). While two such
people overlap in the image the particle cloud is dragged onto the other one, and once they
part the presenter's mode lies further away than the prediction noise reaches: the track has
been stolen. What tells the two apart is where each can be: a walking person's velocity
changes by at most about 2 m/s^2 (~0.0013 h per frame^2 at 30 fps, h the person's height in
pixels), while an estimate dragged onto someone walking the other way changes its velocity
many times faster.

An alpha-beta (constant-velocity) track of the estimate's image position. While the
estimate's velocity departs from the track's by more than a person can accelerate in a few
frames, the track *coasts* (extrapolates the presenter's last plausible motion) and the
filter draws a share of its particles around the coasting prediction: the presenter's expected
place is searched while the cloud sits on the other person, and the better colour match there
takes the cloud back. The track rejoins the estimate when the estimate comes back to it, or
after ``COAST_FRAMES`` (a lone presenter who stopped or turned round: nothing was found where
the old motion led).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

#: alpha-beta gains: the position follows the estimate, the velocity changes slowly
ALPHA = 0.5
BETA = 0.1
#: frames of consistent tracking before the track's velocity is trusted
WARM_FRAMES = 10
#: most frames the track coasts without meeting the estimate again
COAST_FRAMES = 15
#: a person's acceleration bound (h per frame^2, ~2 m/s^2 at 30 fps for a 1.75 m person)
#: times the frames over which a velocity difference is judged (the estimate's velocity is
#: smoothed over about that many)
ACCEL_H_PER_FRAME2 = 0.0013
JUDGE_FRAMES = 4


class Trajectory:
    """Constant-velocity alpha-beta track of (x, y) in pixels, coasting on implausible
    motion of the estimate."""

    def __init__(self) -> None:
        self.reset()

    def reset(self, xy: F64 | None = None, vel: F64 | None = None) -> None:
        self.pos: F64 | None = None if xy is None else np.asarray(xy[:2], np.float64).copy()
        self.vel: F64 = np.zeros(2) if vel is None else np.asarray(vel[:2], np.float64).copy()
        self.n = 0  # plausible updates in a row
        self.m = 0  # updates since the reset
        self.coasting = 0  # frames coasted so far (0 = following the estimate)

    def predicted(self) -> F64 | None:
        return None if self.pos is None else self.pos + self.vel

    def update(self, xy: F64, est_vel: F64, h_px: float) -> None:
        """This frame's estimate ``xy``, its smoothed velocity ``est_vel`` (px/frame) and the
        presenter's height ``h_px``."""
        z = np.asarray(xy[:2], dtype=np.float64)
        pred = self.predicted()
        if pred is None:
            self.reset(z)
            return
        limit = max(ACCEL_H_PER_FRAME2 * h_px * JUDGE_FRAMES, 1.0)
        implausible = float(np.hypot(*(np.asarray(est_vel[:2]) - self.vel))) > limit
        near = float(np.hypot(*(z - pred))) <= 0.5 * limit * JUDGE_FRAMES
        if self.coasting:
            if near:
                self.coasting = 0  # the estimate is back on the presenter's path
            elif self.coasting >= COAST_FRAMES:
                self.reset(z, est_vel)  # nothing where the old motion led
                return
            else:
                self.coasting += 1
                self.pos = pred
                return
        elif implausible and self.n >= WARM_FRAMES:
            self.coasting = 1
            self.pos = pred
            return
        r = z - pred
        # trusted only after WARM_FRAMES plausible updates in a row
        self.n = 0 if implausible else self.n + 1
        self.m += 1
        # warm-up: the gains of a running mean until the track has settled
        a, b = max(ALPHA, 1.0 / self.m), max(BETA, 1.0 / self.m)
        self.pos = pred + a * r
        self.vel = self.vel + b * r
