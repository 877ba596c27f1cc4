"""Multiple-model adaptive estimation (Gaspar 2009 sec. 5.2, Athans & Chang 1976).

N constant-turn EKFs (:mod:`engine.ptz.ekf`) differing in the turn rate omega run in
parallel on the same measurements. Each model's posterior probability is updated with the
likelihood of its innovation, p_k^j ∝ p_{k-1}^j N(nu_k^j; 0, S_k^j), and the estimates are
combined (sec. 5.2):

    x_k = sum_j p_k^j x_k^j,     P_k = sum_j p_k^j [P_k^j + (x_k^j - x_k)(x_k^j - x_k)^T].

The estimated turn rate is sum_j p_k^j omega_j. ``min_prob`` keeps every model alive (an
optional floor, 0 gives the paper's pure MMAE). Divergence (non-finite state or a mean
normalised innovation squared above ``nis_reset`` over ``nis_window`` updates) asks the
caller to re-initialise.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.ptz.ekf import ConstantTurnEkf

F64 = NDArray[np.float64]

PAPER_OMEGAS_RAD_S = tuple(2.0 * math.pi / 50.0 * j for j in range(4))


@dataclass(frozen=True, slots=True)
class MmaeEstimate:
    x: F64  # combined state (9,)
    P: F64  # combined covariance (9, 9)
    probs: F64  # (N,) posterior model probabilities
    omega_rad_s: float  # probability-weighted turn rate
    mean_nis: float


class Mmae:
    def __init__(
        self,
        omegas_rad_s: Sequence[float] = PAPER_OMEGAS_RAD_S,
        q_psd: float = 1e-4,
        min_prob: float = 0.0,
        nis_reset: float = 25.0,
        nis_window: int = 15,
    ) -> None:
        if len(omegas_rad_s) < 1:
            raise ValueError("MMAE needs at least one model")
        self.omegas = np.asarray(omegas_rad_s, dtype=np.float64)
        self.filters = [ConstantTurnEkf(w, q_psd) for w in self.omegas]
        self.log_p = np.full(len(self.filters), -math.log(len(self.filters)))
        self.min_prob = float(min_prob)
        self.nis_reset = float(nis_reset)
        self._nis: deque[float] = deque(maxlen=max(1, nis_window))
        self.initialised = False

    @property
    def probs(self) -> F64:
        p: F64 = np.exp(self.log_p - self.log_p.max())
        return p / float(p.sum())

    def init(self, x0: F64, P0: F64) -> None:
        for f in self.filters:
            f.init(x0, P0)
        self.log_p[:] = -math.log(len(self.filters))
        self._nis.clear()
        self.initialised = True

    def predict(self, dt: float) -> None:
        for f in self.filters:
            f.predict(dt)

    def update(self, z: F64, R: F64, P_cam: F64, c_world: F64) -> bool:
        """Update all models; returns False when the bank diverged (caller re-inits)."""
        lls = np.empty(len(self.filters))
        nis = np.empty(len(self.filters))
        for j, f in enumerate(self.filters):
            step = f.update(z, R, P_cam, c_world)
            lls[j] = step.log_likelihood
            nis[j] = step.nis
        if not np.all(np.isfinite(lls)):
            return False
        lp = self.log_p + lls  # Bayes: p_k^j ∝ p_{k-1}^j N(nu^j; 0, S^j)
        lp -= lp.max() + math.log(np.exp(lp - lp.max()).sum())
        if self.min_prob > 0:
            p = np.maximum(np.exp(lp), self.min_prob)
            lp = np.log(p / p.sum())
        self.log_p = lp
        self._nis.append(float(self.probs @ nis))
        x = self.estimate().x
        diverged = not np.all(np.isfinite(x)) or (
            len(self._nis) == self._nis.maxlen and float(np.mean(self._nis)) > self.nis_reset
        )
        return not diverged

    def estimate(self) -> MmaeEstimate:
        p = self.probs
        xs = np.stack([f.x for f in self.filters])
        x = p @ xs
        P = np.zeros((9, 9))
        for pj, f, xj in zip(p, self.filters, xs, strict=True):
            d = xj - x
            P += pj * (f.P + np.outer(d, d))  # combined covariance, sec. 5.2
        return MmaeEstimate(
            x=x, P=P, probs=p, omega_rad_s=float(p @ self.omegas),
            mean_nis=float(np.mean(self._nis)) if self._nis else 0.0,
        )
