"""One camera view's presenter tracker: particle filter + likelihoods + loss handling + jitter.

Per frame (VR-TV paper, Fig. 5):
1. pre-processing: HSV of the region the particles cover (integral histogram) and the
   motion history image of the whole frame;
2. systematic resampling over the previous weights and prediction, eq. (1);
3. colour likelihood eq. (2)-(3), motion likelihood eq. (4), fusion eq. (5);
4. weighted mean eq. (6), then the jitter low-pass;
5. loss test (Sec. III-C.7): LOST when P(z_col | s_t) < Pmin = p % of Pref. Pref starts at
   the best particle likelihood of the first frame and follows P slowly while P >= 60 % of
   it. While LOST the output holds the last good position and the filter searches with a
   diffuse prior of ``reinit_particles`` particles (half fresh every frame, half resampled
   from the last search) until P at the estimate is back above Pmin for
   ``reacquire_frames`` frames.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.presenter import filter as pf
from engine.presenter.jitter import JitterFilter
from engine.presenter.likelihood import (
    MotionHistory,
    apply_gains,
    binned_integral,
    colour_likelihood,
    colour_residuals,
    grey_world_gains,
    motion_likelihood,
    motion_residuals,
)
from engine.presenter.model import PatchModel
from engine.presenter.params import PresenterParams

F64 = NDArray[np.float64]

TRACKING = "TRACKING"
MOTION_STEP = 2  # subsampling of the motion history image
LOST = "LOST"


@dataclass(frozen=True, slots=True)
class ViewOutput:
    """One frame of one view. Arrays are read-only copies (safe to hand to another thread)."""

    state: str
    raw_xyh: tuple[float, float, float]
    filtered_xyh: tuple[float, float, float]
    p_col: float
    p_ref: float
    p_min: float
    n_particles: int
    particles_xyh: F64
    weights: F64
    lost_frames: int
    timings_ms: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.particles_xyh.flags.writeable = False
        self.weights.flags.writeable = False


class ViewTracker:
    """Tracks one presenter model in one camera's frames."""

    def __init__(self, model: PatchModel, params: PresenterParams, frame_rate_hz: float,
                 init_xyh: tuple[float, float, float] | None = None) -> None:
        self.model = model
        self.params = params
        self.frame_rate_hz = float(frame_rate_hz)
        self.rng = np.random.default_rng(params.seed)
        self.motion = MotionHistory(params.mhi_duration_frames, params.motion_threshold)
        self.jitter = JitterFilter(params.jitter_cutoff_hz, self._fps())
        self._init_xyh = np.asarray(init_xyh or model.state_of_main(), dtype=np.float64)
        h0 = float(self._init_xyh[2])
        self.h_limits = (max(0.25 * h0, 4.0), 4.0 * h0)
        self.particles: F64 = np.empty((0, 3))
        self.weights: F64 = np.empty(0)
        self.state = TRACKING
        self.p_ref: float | None = None
        self.last_good_xyh = self._init_xyh.copy()
        self.last_filtered_xyh = self._init_xyh.copy()
        self.lost_frames = 0
        self._above = 0
        self._sqrt_ref = np.ascontiguousarray(model.sqrt_hists)
        self._rel = np.ascontiguousarray(model.rel_boxes)
        self._gains: F64 | None = None

    # ------------------------------------------------------------------ configuration

    def _fps(self) -> float:
        return self.params.frame_rate_hz or self.frame_rate_hz or 30.0

    def set_params(self, params: PresenterParams) -> None:
        """Swap parameters; every change applies from the next frame on."""
        old = self.params
        self.params = params
        self.motion.duration_frames = params.mhi_duration_frames
        self.motion.threshold = params.motion_threshold
        self.jitter.configure(params.jitter_cutoff_hz, self._fps())
        if params.seed != old.seed:
            self.rng = np.random.default_rng(params.seed)

    def sigma_xyh(self, h: float) -> tuple[float, float, float]:
        p = self.params
        m = p.sigma_min_px
        return (max(p.sigma_x_frac * h, m), max(p.sigma_y_frac * h, m), p.sigma_h_frac * h)

    @property
    def lag_frames(self) -> float:
        return self.jitter.lag_frames

    # ------------------------------------------------------------------ per frame

    def _evaluate(self, bgr: NDArray[np.uint8], states: F64,
                  motion: bool = True) -> tuple[F64, F64 | None, Any]:
        """sum B^2 and E for each state row, and the integral context for re-use."""
        H, W = bgr.shape[:2]
        hs = states[:, 2]
        ws = hs * self.model.aspect
        x0 = int(max(math.floor(np.min(states[:, 0] - ws / 2)) - 1, 0))
        y0 = int(max(math.floor(np.min(states[:, 1] - hs / 2)) - 1, 0))
        x1 = int(min(math.ceil(np.max(states[:, 0] + ws / 2)) + 1, W))
        y1 = int(min(math.ceil(np.max(states[:, 1] + hs / 2)) + 1, H))
        ctx = None
        if x1 - x0 < 1 or y1 - y0 < 1:
            b2 = np.full(len(states), float(len(self._rel)))
        else:
            cell = max(1, math.ceil(max(x1 - x0, y1 - y0) / self.params.max_cells))
            # with cells of 4+ px, histogram every other pixel each way (a half-resolution
            # integral histogram): a quarter of the colour conversion and counting
            step = 2 if cell >= 4 else 1
            cell += cell % step
            roi = apply_gains(bgr[y0:y1:step, x0:x1:step], self._gains)
            roi_hsv = cv2.cvtColor(roi, cv2.COLOR_BGR2HSV)
            integral = binned_integral(roi_hsv, self.model.n_bins, cell // step,
                                       pixel_weight=float(step * step))
            ctx = (integral, cell, (x0, y0, x1 - x0, y1 - y0), (W, H))
            b2 = self._colour(ctx, states)
        e = None
        if motion and self.params.use_motion and self.motion.mhi is not None:
            e = motion_residuals(self.motion.motion_integral(), states, self._rel,
                                 self.model.aspect, MOTION_STEP)
        return b2, e, ctx

    def _colour(self, ctx: Any, states: F64) -> F64:
        integral, cell, roi, wh = ctx
        return colour_residuals(integral, cell, roi, wh, states, self._rel, self.model.aspect,
                                self._sqrt_ref)

    def step(self, bgr: NDArray[np.uint8]) -> ViewOutput:
        p = self.params
        t_start = time.perf_counter()
        H, W = bgr.shape[:2]
        timings: dict[str, float] = {}
        if p.use_motion:
            t0 = time.perf_counter()
            # half-resolution green channel: motion needs no colour and no fine detail
            self.motion.update(np.ascontiguousarray(bgr[::MOTION_STEP, ::MOTION_STEP, 1]))
            timings["motion_ms"] = (time.perf_counter() - t0) * 1000.0
        self._gains = grey_world_gains(bgr) if self.model.grey_world else None
        first = len(self.particles) == 0
        h_ref = float(self.last_good_xyh[2])
        t0 = time.perf_counter()
        if first:
            self.particles = pf.gaussian_cloud(self._init_xyh, self.sigma_xyh(h_ref),
                                               p.n_particles, self.rng)
            self.particles[0] = self._init_xyh
        elif self.state == TRACKING:
            idx = pf.systematic_resample(self.weights, p.n_particles, self.rng)
            self.particles = pf.predict(self.particles[idx], self.sigma_xyh(h_ref), self.rng,
                                        self.h_limits)
        else:
            # search: half a fresh diffuse prior, half resampled from the last search
            n = p.reinit_particles
            n_keep = n // 2
            idx = pf.systematic_resample(self.weights, n_keep, self.rng)
            kept = pf.predict(self.particles[idx], self.sigma_xyh(h_ref), self.rng,
                              self.h_limits)
            # scale of the diffuse prior: the last size, spread only if the scale is free
            k = min(0.25, 10.0 * p.sigma_h_frac)
            fresh = pf.diffuse_cloud((W, H), ((1.0 - k) * h_ref, (1.0 + k) * h_ref),
                                     n - n_keep, self.rng)
            self.particles = np.vstack([kept, fresh])
        timings["predict_ms"] = (time.perf_counter() - t0) * 1000.0

        t0 = time.perf_counter()
        b2, e, ctx = self._evaluate(bgr, self.particles)
        timings["likelihood_ms"] = (time.perf_counter() - t0) * 1000.0
        w = colour_likelihood(b2, p.lambda_col)  # eq. (3)
        if e is not None:
            w = w * motion_likelihood(e, p.lambda_mot)  # eq. (4)-(5)
        self.weights = pf.normalise(w)  # eq. (5)
        mean = pf.weighted_mean(self.particles, self.weights)  # eq. (6)
        # P(z_col | s_t) at the estimate (inside the particles' region: same integral)
        b2_mean = (self._colour(ctx, mean[None, :]) if ctx is not None
                   else self._evaluate(bgr, mean[None, :], motion=False)[0])
        p_col = float(colour_likelihood(b2_mean[0], p.lambda_col))
        if first:
            self.p_ref = max(float(np.max(colour_likelihood(b2, p.lambda_col))), p_col)
        assert self.p_ref is not None
        p_min = p.loss_percent / 100.0 * self.p_ref

        if self.state == TRACKING:
            if p_col < p_min:
                self.state = LOST
                self.lost_frames = 1
                self._above = 0
            else:
                self.last_good_xyh = mean.copy()
                if p_col >= p.pref_adapt_ratio * self.p_ref:  # slow Pref adaptation
                    self.p_ref += p.pref_adapt_rate * (p_col - self.p_ref)
        else:
            self.lost_frames += 1
            self._above = self._above + 1 if p_col >= p_min else 0
            if self._above >= p.reacquire_frames:
                self.state = TRACKING
                self.lost_frames = 0
                self.last_good_xyh = mean.copy()
                self.jitter.reset(mean)
                # back to the normal particle count around the re-acquired state
                idx = pf.systematic_resample(self.weights, p.n_particles, self.rng)
                self.particles = self.particles[idx]
                self.weights = np.full(p.n_particles, 1.0 / p.n_particles)

        if self.state == TRACKING:
            self.jitter.configure(p.jitter_cutoff_hz, self._fps())
            filtered = self.jitter(mean)
            self.last_filtered_xyh = filtered
            raw = mean
        else:
            raw = self.last_good_xyh
            filtered = self.last_filtered_xyh  # hold the last output while searching
        timings["total_ms"] = (time.perf_counter() - t_start) * 1000.0
        return ViewOutput(
            state=self.state,
            raw_xyh=(float(raw[0]), float(raw[1]), float(raw[2])),
            filtered_xyh=(float(filtered[0]), float(filtered[1]), float(filtered[2])),
            p_col=p_col,
            p_ref=float(self.p_ref),
            p_min=float(p_min),
            n_particles=len(self.particles),
            particles_xyh=self.particles.copy(),
            weights=self.weights.copy(),
            lost_frames=self.lost_frames,
            timings_ms=timings,
        )
