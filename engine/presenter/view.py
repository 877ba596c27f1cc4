"""One camera view's presenter tracker: particle filter + likelihoods + loss handling + jitter.

Per frame (VR-TV paper, Fig. 5):
1. pre-processing: HSV of the region the particles cover (integral histogram, bilinear
   hue-saturation votes) and the motion history image of the whole frame;
2. systematic resampling over the previous weights and prediction, eq. (1), plus a damped
   constant-velocity drift (``velocity_gain``; 0 = the paper's pure random walk);
3. colour likelihood eq. (2)-(3), motion likelihood eq. (4), fusion eq. (5);
4. weighted mean eq. (6), then the jitter low-pass;
5. loss test. The paper's (Sec. III-C.7, ``loss_test='likelihood'``): LOST when
   P(z_col | s_t) < Pmin = p % of Pref for ``loss_frames`` frames, Pref the median P of the
   first ``pref_init_frames`` tracked frames (the first frame matches its own model exactly)
   that then follows P slowly while P >= 60 % of it. The default (``'contrast'``) asks
   whether the estimate still looks like the *first frame's* patches rather than like the
   background: per patch z_p = (B_p^2(s_t) - mu_p) / (beta_p - mu_p), with B_p^2 against the
   first frame's patch histograms (``loss_reference``; the adapted model can follow a tracker
   that slid onto the desk), the colours common in a ring around the first box scaled down
   (``loss_bg_weighting``: a patch split from a bare box is much wall and desk, and a
   reference of wall and desk matches the empty set), mu_p the target's own level (median
   over the first tracked frames, then slowly adapted while z is small) and beta_p the
   level of the most target-like tenth of boxes sampled over this frame's background (the
   desk, a similar wall), and z the median over the patches. z = 0 is the target, 1 the
   best background; LOST while z > ``loss_contrast``.
   While LOST the output holds the last good position and the filter searches with a
   diffuse prior of ``reinit_particles`` particles (half fresh every frame, half resampled
   from the last search) until the test passes again at the search's best hypothesis for
   ``reacquire_frames`` frames.

Beyond the paper (each switchable, measured in ``studiotrack bench presenter``):
- slow model update: while P >= ``model_update_ratio`` x Pref the adapted patch histograms
  move ``model_update_rate`` towards the estimate's; the reference is ``model_anchor`` x the
  first frame's + the rest adapted, so it can never drift wholly away (cf. the paper's [5]);
- background-weighted reference (corrected BWH): reference bins are scaled down by how
  common their colour is in a ring around the first box (``bg_weighting``);
- scale: the state's h follows a random walk (eq. 1, ``sigma_h_frac``); histograms alone
  barely constrain it (a smaller box inside the person matches as well), so the colour
  likelihood also penalises target colours in a ring around the box (``ring_weight``);
- identity by trajectory (``trajectory_share``, ``engine.presenter.trajectory``): while the
  estimate accelerates faster than a person can (dragged onto a look-alike), a share of the
  particles is drawn where the presenter's last plausible motion leads;
- output width: for a full-body model (first box >= 2x as tall as wide) the output box's width
  and centre come from ``engine.presenter.extent`` (stride / arm swing); the state stays
  (x, y, h) with the first frame's aspect ratio.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8
from engine.particles import systematic_resample
from engine.presenter import filter as pf
from engine.presenter import frame_colour as fc
from engine.presenter import step_kernels as sk
from engine.presenter.depth import (
    RESEED_FRAMES,
    DepthReference,
    depth_likelihood,
    estimate_depth,
    torso_depths,
)
from engine.presenter.extent import measure_extent
from engine.presenter.jitter import JitterFilter
from engine.presenter.likelihood import (
    S_MIN_DEFAULT,
    SOFT_DEFAULT,
    V_MIN_DEFAULT,
    MotionHistory,
    apply_gains,
    colour_likelihood,
    direct_histogram,
    grey_world_gains,
    motion_likelihood,
    motion_residuals,
    n_bins_total,
)
from engine.presenter.model import PatchModel
from engine.presenter.params import PresenterParams
from engine.presenter.trajectory import Trajectory

F64 = NDArray[np.float64]

TRACKING = "TRACKING"
MOTION_STEP = 2  # subsampling of the motion history image
LOST = "LOST"
#: width / height at or below which a model is a full-body one whose output width is fitted
#: (``PresenterParams.fit_width``): a standing presenter is ~3-4x as tall as wide, a head or
#: face box ~1-1.5x; the rule looks at the first frame's box only
FULL_BODY_ASPECT = 0.5
#: background boxes sampled for the contrast loss test (the quantile of their colour distance
#: taken as the background's level is ``PresenterParams.loss_bg_quantile``)
BG_SAMPLES = 96
BG_EVERY = 3  # frames between two background samplings (it changes slowly)
#: motion cue of the loss test: pixels that changed in this many last frames count as moving
#: (the motion history holds ``mhi_duration_frames``, too long to notice the target has gone)
MOTION_RECENT_FRAMES = 3
#: the background's motion level: this quantile of the sampled boxes' moving fraction
MOTION_BG_QUANTILE = 0.9


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
    #: output box (centre x, width) when ``fit_width`` measured one; None = fixed aspect
    box_cx_w: tuple[float, float] | None = None
    #: the contrast loss statistic z at the tested state (0 = target, 1 = background)
    loss_z: float = float("nan")

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
        self._below = 0
        self._n_frames = 0
        self._vel_xy = np.zeros(2)
        self.trajectory = Trajectory()
        self.depth_ref = DepthReference()  # the presenter's depth (RGB-D sources)
        self._box_dx_w: tuple[float, float] | None = None  # smoothed centre offset, width
        self._prev_mean: F64 | None = None
        self._p_boot: list[float] = []
        self._sqrt_ref = np.ascontiguousarray(model.sqrt_hists)
        self._hist0 = np.asarray(model.hists, dtype=np.float64).copy()
        self._hist_adapt = self._hist0.copy()
        self._bin_w: F64 | None = None  # background weights of the reference bins (BWH)
        self._rel = np.ascontiguousarray(model.rel_boxes)
        self._gains: F64 | None = None
        self._lut = fc.IDENTITY_LUT  # this frame's gain table (fc.gain_lut(self._gains))
        self._bin_w_pow: dict[float, F64] = {}  # bin_w ** exponent, made once each
        self._loss_ref_key: tuple[Any, ...] | None = None  # what _sqrt_ref0 was made from
        self._fg_of: Any = None  # the _sqrt_ref the fit_width foreground was pooled from
        self._fg: F64 | None = None
        self._sqrt_ref0 = np.ascontiguousarray(np.sqrt(self._hist0))  # fixed: loss test
        rel = self._rel
        area = (rel[:, 2] - rel[:, 0]) * (rel[:, 3] - rel[:, 1])
        pooled = (area / max(float(area.sum()), 1e-12)) @ self._hist0
        self._sqrt_pooled = np.ascontiguousarray(np.sqrt(pooled))  # target colours: ring
        # contrast loss test, per patch: the target's own B_p^2 level and the most
        # target-like background's
        self._mu: F64 | None = None
        self._beta: F64 | None = None
        self._mu_boot: list[F64] = []
        self._bg_rng = np.random.default_rng([params.seed, 17])
        self._last_fixed: F64 | None = None
        self.loss_z = float("nan")
        self._recent_motion: Any = None  # this frame's integral of recent motion (lazy)
        self._motion_bg: float | None = None  # the background boxes' moving fraction
        self.motion_margin = float("nan")  # moving fraction at the estimate minus that
        #: scale model replacing eq. (1)'s random walk in h: the heights of the predicted
        #: (x, y, h) rows (NaN = keep), e.g. a calibrated view's standing person
        #: (engine.presenter.twoview.StandingPerson.heights); None = the random walk
        self.scale_model: Callable[[F64], F64 | None] | None = None

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
        self._set_reference()  # model_anchor / bg_weighting changes
        if params.seed != old.seed:
            self.rng = np.random.default_rng(params.seed)

    def set_patch_boxes(self, rel_boxes: F64, aspect: float | None = None) -> None:
        """Move the patches inside the main region (x0, y0, x1, y1 fractions) and give the
        main region this width / height (None: keep it) from the next step on, e.g. with a
        calibrated view's lean of a standing person (engine.presenter.twoview.
        StandingPerson)."""
        rel = np.ascontiguousarray(rel_boxes, dtype=np.float64)
        mx, my, mw, mh = self.model.main_xywh
        main = (mx, my, mw if aspect is None else float(aspect) * mh, mh)
        self.model = dataclasses.replace(self.model, rel_boxes=rel, main_xywh=main)
        self._rel = rel

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
        """Colour residual (sum_p B_p^2 plus the ring term) and E for each state row, and
        the integral context for re-use."""
        H, W = bgr.shape[:2]
        p = self.params
        grow = 1.0 + (2.0 * p.ring_margin_frac if p.ring_weight > 0 else 0.0)
        x0, y0, x1, y1 = sk.roi_bounds(states, self.model.aspect, grow, W, H)
        ctx = None
        if x1 - x0 < 1 or y1 - y0 < 1:
            b2 = np.full(len(states), float(len(self._rel)))
        else:
            cell = max(1, math.ceil(max(x1 - x0, y1 - y0) / p.max_cells))
            # with cells of 4+ px, histogram every other pixel each way (a half-resolution
            # integral histogram): a quarter of the colour conversion and counting
            step = 2 if cell >= 4 else 1
            cell += cell % step
            ctx = self._integral(bgr, (x0, y0, x1, y1), step, cell)
            b2 = fc.colour_b2(ctx, states, self._rel, self.model.aspect, self._sqrt_ref,
                              p.ring_weight, p.ring_margin_frac, self._sqrt_pooled)
        e = None
        if motion and p.use_motion and self.motion.mhi is not None:
            e = motion_residuals(self.motion.motion_integral(), states, self._rel,
                                 self.model.aspect, MOTION_STEP)
        return b2, e, ctx

    def _integral(self, bgr: NDArray[np.uint8], roi_xyxy: tuple[int, int, int, int],
                  step: int, cell: int) -> fc.RoiIntegral:
        """The integral histogram of ``roi_xyxy`` (grey-world balanced, HSV, bilinear votes)
        on ``cell`` px cells from every ``step``-th pixel each way (counts in full-resolution
        pixels)."""
        x0, y0, x1, y1 = roi_xyxy
        integral, used = fc.roi_integral(bgr, roi_xyxy, step, cell // step, self.model.n_bins,
                                         self._gains, S_MIN_DEFAULT, V_MIN_DEFAULT,
                                         float(step * step), SOFT_DEFAULT, self._lut)
        return fc.RoiIntegral(integral, used, n_bins_total(self.model.n_bins), cell,
                              (x0, y0, x1 - x0, y1 - y0), (bgr.shape[1], bgr.shape[0]))

    def _colour(self, ctx: Any, states: F64) -> F64:
        """sum_p B_p^2 (eq. 2-3, no ring term) of each state row."""
        return fc.colour_b2(ctx, states, self._rel, self.model.aspect, self._sqrt_ref)

    def _fixed_residual(self, ctx: Any, states: F64) -> F64:
        """B_p^2 (states x patches) against the anchored model without background weighting
        (the loss test's reference)."""
        return fc.patch_b2(ctx, states, self._rel, self.model.aspect, self._sqrt_ref0)

    def _background_levels(self, bgr: NDArray[np.uint8], xyh: F64) -> None:
        """beta_p: per patch, the ``loss_bg_quantile`` of B_p^2 over boxes of the target's
        size sampled over this frame away from ``xyh`` (IoU < 0.1), on a coarse whole-frame
        integral histogram; smoothed over frames. It follows global light changes of the
        background."""
        H, W = bgr.shape[:2]
        x, y, h = (float(v) for v in xyh)
        w = h * self.model.aspect
        step = max(1, math.ceil(max(W, H) / 160))  # coarse: at most 160 px a side
        cell = 2
        # the frame subsampled by step, on cells of 2 subsampled px: coordinates in those
        hs_, ws_ = (H + step - 1) // step, (W + step - 1) // step
        integral, used = fc.roi_integral(bgr, (0, 0, W, H), step, cell, self.model.n_bins,
                                         self._gains, S_MIN_DEFAULT, V_MIN_DEFAULT,
                                         float(step * step), SOFT_DEFAULT, self._lut)
        ctx = fc.RoiIntegral(integral, used, n_bins_total(self.model.n_bins), cell,
                             (0, 0, ws_, hs_), (ws_, hs_))
        rng = self._bg_rng
        n = 4 * BG_SAMPLES
        k = rng.uniform(0.8, 1.25, n)
        lo_x, hi_x, lo_y, hi_y = sk.background_bounds(k, w, h, W, H)
        cx = rng.uniform(lo_x, hi_x)
        cy = rng.uniform(lo_y, hi_y)
        boxes = sk.background_boxes(k, cx, cy, x, y, w, h, W, H, BG_SAMPLES)
        if len(boxes) < 8:
            return  # no room for background beside the target: beta stays as it was
        states = boxes / step
        r = fc.patch_b2(ctx, states, self._rel, self.model.aspect, self._sqrt_ref0)
        beta = sk.quantile_columns(r, self.params.loss_bg_quantile)
        self._beta = beta if self._beta is None else self._beta + 0.2 * (beta - self._beta)
        recent = self._recent_motion_integral()
        if recent is not None:
            moving = 1.0 - motion_residuals(recent, boxes, self._rel, self.model.aspect,
                                            MOTION_STEP)
            self._motion_bg = sk.quantile(moving, MOTION_BG_QUANTILE)

    def _recent_motion_integral(self) -> Any:
        """Integral of the pixels that moved in the last ``MOTION_RECENT_FRAMES`` frames
        (once per frame; None when the motion cue of the loss test is off)."""
        p = self.params
        if p.loss_motion <= 0 or not p.use_motion or self.motion.mhi is None:
            return None
        if self._recent_motion is None:
            self._recent_motion = self.motion.motion_integral(MOTION_RECENT_FRAMES)
        return self._recent_motion

    def _moving_target(self, xyh: F64) -> bool:
        """Motion cue of the loss test: the patches at ``xyh`` hold more recent motion than
        the most moving tenth of the background by ``loss_motion`` (eq. 4's motion image, as
        a fraction of the patches' area)."""
        recent = self._recent_motion_integral()
        if recent is None or self._motion_bg is None:
            self.motion_margin = float("nan")
            return False
        moving = 1.0 - float(motion_residuals(recent, xyh[None, :], self._rel,
                                              self.model.aspect, MOTION_STEP)[0])
        self.motion_margin = moving - self._motion_bg
        return self.motion_margin > self.params.loss_motion

    def _loss_z(self, ctx: Any, xyh: F64, fixed: F64 | None = None) -> float:
        """z = median over the patches of (B_p^2 - mu_p) / (beta_p - mu_p) at ``xyh`` (NaN
        before mu is known): one patch that changes (a turn, background between the legs, a
        hand in front) does not decide, all of them on the background do. ``fixed``: the
        B_p^2 against the loss test's reference at ``xyh`` if computed already."""
        if ctx is None:
            return float("nan")
        r = fixed if fixed is not None else np.asarray(
            self._fixed_residual(ctx, xyh[None, :])[0], dtype=np.float64)
        self._last_fixed = r
        if self._mu is None or self._beta is None:
            return float("nan")
        zp = (r - self._mu) / np.maximum(self._beta - self._mu, 0.05)
        return sk.median_small(zp)

    def _patch_hists(self, ctx: Any, xyh: F64) -> F64 | None:
        """Normalised patch histograms at one state from the frame's integral (None if a
        patch is not wholly inside the image)."""
        ox, oy, _rw, _rh = ctx.roi_xywh
        W, H = ctx.image_wh
        out = np.empty((len(self._rel), ctx.n_bins_total))
        ok = sk.patch_hists(ctx.integral, float(ctx.cell), float(ox), float(oy), int(W), int(H),
                            float(xyh[0]), float(xyh[1]), float(xyh[2]), self._rel,
                            float(self.model.aspect), ctx.used, int(ctx.n_bins_total), out)
        return out if ok else None

    def _update_model(self, ctx: Any, mean: F64) -> None:
        """Slow blend of the reference histograms towards the estimate's, anchored to the
        first frame's (beyond the paper, which keeps the model fixed; cf. its ref. [5])."""
        p = self.params
        if p.model_update_rate <= 0 or ctx is None:
            return
        q = self._patch_hists(ctx, mean)
        if q is None:
            return
        self._hist_adapt += p.model_update_rate * (q - self._hist_adapt)
        self._set_reference()

    def _set_reference(self) -> None:
        """sqrt of the reference histograms: anchored blend, then background weights."""
        p = self.params
        ref = p.model_anchor * self._hist0 + (1.0 - p.model_anchor) * self._hist_adapt
        # the loss test's reference: the first frame's patches (or the anchored model), with
        # the colours common around the first box scaled down - a box-split patch is much
        # background (the wall beside the head, the desk between the legs), and a reference
        # made of background matches an empty set. From the first frame's patches it is the
        # same every frame: made again only when what it is made of changes
        key = (p.loss_reference, p.loss_bg_weighting, id(self._bin_w))
        if p.loss_reference != "first" or key != self._loss_ref_key:
            loss_ref = self._hist0 if p.loss_reference == "first" else ref
            if self._bin_w is not None and p.loss_bg_weighting > 0:
                loss_ref = loss_ref * self._bin_w_power(p.loss_bg_weighting)
                loss_ref = loss_ref / np.maximum(loss_ref.sum(axis=1, keepdims=True), 1e-12)
            self._sqrt_ref0 = np.ascontiguousarray(np.sqrt(loss_ref))
            self._loss_ref_key = key
        if self._bin_w is not None and p.bg_weighting > 0:
            ref = ref * self._bin_w_power(p.bg_weighting)
            ref /= np.maximum(ref.sum(axis=1, keepdims=True), 1e-12)
        self._sqrt_ref = np.ascontiguousarray(np.sqrt(ref))

    def _bin_w_power(self, exponent: float) -> F64:
        """``self._bin_w ** exponent`` (made once per exponent and background weighting)."""
        assert self._bin_w is not None
        got = self._bin_w_pow.get(exponent)
        if got is None:
            got = self._bin_w ** exponent
            self._bin_w_pow[exponent] = got
        return got

    def _background_weights(self, bgr: NDArray[np.uint8]) -> None:
        """v_b = min(1, o*/o_b) from the ring around the first box (corrected BWH: only the
        reference is weighted; o* = the smallest non-zero ring bin above 1 % of the peak)."""
        x, y, h = (float(v) for v in self._init_xyh)
        w = h * self.model.aspect
        k = 3.0 ** 0.5  # the enlarged box has 3x the area
        img = u8(cv2.cvtColor(apply_gains(bgr, self._gains), cv2.COLOR_BGR2HSV))
        inner = (round(x - w / 2), round(y - h / 2), round(w), round(h))
        outer = (round(x - k * w / 2), round(y - k * h / 2), round(k * w), round(k * h))
        n = self.model.n_bins
        ring = np.maximum(direct_histogram(img, outer, n) - direct_histogram(img, inner, n), 0)
        if ring.sum() <= 0:
            return
        o = ring / ring.sum()
        nz = o[o > 0.01 * o.max()]
        o_star = float(nz.min()) if len(nz) else float(o.max())
        self._bin_w = np.minimum(1.0, o_star / np.maximum(o, 1e-12))
        self._bin_w_pow = {}
        self._set_reference()

    def step(self, bgr: NDArray[np.uint8],
             depth_m: NDArray[np.float32] | None = None) -> ViewOutput:
        """One frame; ``depth_m`` (metres, 0 = invalid, registered to ``bgr``) adds the
        depth agreement of :mod:`engine.presenter.depth` while tracking."""
        p = self.params
        if depth_m is not None and (p.depth_sigma_m <= 0.0
                                    or depth_m.shape[:2] != bgr.shape[:2]):
            depth_m = None
        t_start = time.perf_counter()
        H, W = bgr.shape[:2]
        timings: dict[str, float] = {}
        if p.use_motion:
            t0 = time.perf_counter()
            # half-resolution green channel: motion needs no colour and no fine detail
            self.motion.update(bgr[:, :, 1], MOTION_STEP)
            timings["motion_ms"] = (time.perf_counter() - t0) * 1000.0
        self._gains = (grey_world_gains(bgr, level=self.model.grey_level
                                        if p.exposure_normalise else None)
                       if self.model.grey_world else None)
        self._lut = fc.gain_lut(self._gains)
        self._recent_motion = None
        first = len(self.particles) == 0
        if first and (p.bg_weighting > 0 or p.loss_bg_weighting > 0):
            self._background_weights(bgr)
        h_ref = float(self.last_good_xyh[2])
        t0 = time.perf_counter()
        if first:
            self.particles = pf.gaussian_cloud(self._init_xyh, self.sigma_xyh(h_ref),
                                               p.n_particles, self.rng)
            self.particles[0] = self._init_xyh
        elif self.state == TRACKING:
            # systematic resampling, eq. (1)'s random walk (filter.predict) and on top of it
            # the constant-velocity drift, compiled in one pass with the same draws
            u = self.rng.random()
            noise = self.rng.standard_normal((p.n_particles, 3))
            self.particles = sk.resample_predict(
                self.weights, u, p.n_particles, self.particles, noise,
                np.asarray(self.sigma_xyh(h_ref), dtype=np.float64), self.h_limits[0],
                self.h_limits[1], p.velocity_gain * float(self._vel_xy[0]),
                p.velocity_gain * float(self._vel_xy[1]))
            n_traj = round(p.trajectory_share * p.n_particles)
            pred = self.trajectory.predicted() if self.trajectory.coasting else None
            if pred is not None and n_traj > 0:
                # the estimate's motion was implausible: search where the presenter's went
                at = self.rng.choice(p.n_particles, n_traj, replace=False)
                self.particles[at] = pf.gaussian_cloud(
                    np.array([pred[0], pred[1], h_ref]), self.sigma_xyh(h_ref), n_traj,
                    self.rng)
        else:
            # search: half a fresh diffuse prior, half resampled from the last search
            n = p.reinit_particles
            n_keep = n // 2
            idx = systematic_resample(self.weights, n_keep, self.rng)
            kept = pf.predict(self.particles[idx], self.sigma_xyh(h_ref), self.rng,
                              self.h_limits)
            # scale of the diffuse prior: around the last size, wider if the scale is free
            k = min(0.35, 10.0 * p.sigma_h_frac)
            fresh = pf.diffuse_cloud((W, H), ((1.0 - k) * h_ref, (1.0 + k) * h_ref),
                                     n - n_keep, self.rng)
            self.particles = np.vstack([kept, fresh])
        if self.scale_model is not None:
            h_model = self.scale_model(self.particles)
            if h_model is not None:
                ok = np.isfinite(h_model)
                self.particles[ok, 2] = h_model[ok]
        timings["predict_ms"] = (time.perf_counter() - t0) * 1000.0

        t0 = time.perf_counter()
        b2, e, ctx = self._evaluate(bgr, self.particles)
        timings["likelihood_ms"] = (time.perf_counter() - t0) * 1000.0
        w = colour_likelihood(b2, p.lambda_col)  # eq. (3) (times the ring term)
        if e is not None:
            w = w * motion_likelihood(e, p.lambda_mot)  # eq. (4)-(5)
        if depth_m is not None and not first and (self.state == TRACKING
                                                  or self.lost_frames < RESEED_FRAMES):
            # while tracking, and for a second after a loss (the presenter covered by
            # someone crossing in front is found again at its own depth, not the other's)
            w = w * depth_likelihood(torso_depths(depth_m, self.particles, self.model.aspect),
                                     self.depth_ref.z_m, p.depth_sigma_m)
        self.weights = pf.normalise(w)  # eq. (5)
        mean = pf.weighted_mean(self.particles, self.weights)  # eq. (6)
        if p.mode_seek and self.state == TRACKING:
            h_m = float(mean[2])
            mean = pf.mode_mean(self.particles, self.weights,
                                (0.5 * h_m * self.model.aspect, 0.25 * h_m))
        # while searching the weights are many-peaked: test (and re-acquire at) the best one
        probe = mean if self.state == TRACKING else self.particles[int(np.argmax(w))]
        # P(z_col | s_t) at the estimate (inside the particles' region: same integral)
        fixed = None
        if ctx is not None:
            # one call: sum_p B_p^2 (no ring term) and the loss test's B_p^2 at the probe
            ox, oy, rw, rh = ctx.roi_xywh
            b2_probe, fixed = sk.probe_residuals(
                ctx.integral, float(ctx.cell), float(ox), float(oy), float(rw), float(rh),
                int(ctx.image_wh[0]), int(ctx.image_wh[1]),
                np.ascontiguousarray(probe[None, :], dtype=np.float64), self._rel,
                float(self.model.aspect), ctx.compact(self._sqrt_ref),
                ctx.compact(self._sqrt_ref0))
        else:
            b2_probe = float(self._evaluate(bgr, probe[None, :], motion=False)[0][0])
        p_col = float(colour_likelihood(b2_probe, p.lambda_col))
        if first or self._n_frames % BG_EVERY == 0:
            # the background's level around the tested state, then z there
            self._background_levels(bgr, self.last_good_xyh if self.state != TRACKING
                                    else probe)
        z = self._loss_z(ctx, probe, fixed)
        self._n_frames += 1
        if first:
            self.p_ref = max(float(np.max(colour_likelihood(b2, p.lambda_col))), p_col)
        booting = 1 < self._n_frames <= 1 + p.pref_init_frames
        if booting:
            # Pref from the first tracked frames, not the self-match of the first one
            self._p_boot.append(p_col)
            self.p_ref = float(np.median(self._p_boot))
            if ctx is not None and self._last_fixed is not None:
                self._mu_boot.append(self._last_fixed)
                self._mu = np.median(np.asarray(self._mu_boot), axis=0)
        assert self.p_ref is not None
        p_min = p.loss_percent / 100.0 * self.p_ref
        if p.loss_test == "contrast" and math.isfinite(z):
            bad = z > p.loss_contrast
            if bad and self.state == TRACKING and p.loss_motion > 0:
                # the colours moved away from the first frame's, but the patches move as
                # the presenter does and the background does not: still the presenter
                bad = not self._moving_target(probe)
        elif p.loss_test == "contrast":
            bad = False  # no background beside the target to compare with: never LOST
        else:
            bad = p_col < p_min

        if self.state == TRACKING:
            self._below = self._below + 1 if (bad and not booting) else 0
            if self._below >= p.loss_frames:
                self.state = LOST
                self.lost_frames = self._below
                self._above = 0
            elif self._below == 0:
                self.last_good_xyh = mean.copy()
                if depth_m is not None:
                    z_est, spread = estimate_depth(depth_m, mean, self.model.aspect)
                    self.depth_ref.update(z_est, p.depth_sigma_m, spread, self._fps())
                if not booting and p_col >= p.pref_adapt_ratio * self.p_ref:  # slow Pref adapt
                    self.p_ref += p.pref_adapt_rate * (p_col - self.p_ref)
                if not booting and self._mu is not None and self._last_fixed is not None \
                        and math.isfinite(z) and z < 0.5 * p.loss_contrast:
                    # the target's own level follows slow changes of pose and light
                    self._mu = self._mu + p.pref_adapt_rate * (self._last_fixed - self._mu)
                if p.loss_test == "contrast" and math.isfinite(z):
                    confident = z < p.model_update_ratio * p.loss_contrast
                else:
                    confident = p_col >= p.model_update_ratio * self.p_ref
                if confident:
                    self._update_model(ctx, mean)
        else:
            self.lost_frames += 1
            if self.lost_frames >= RESEED_FRAMES:
                self.depth_ref.reset()  # gone for a while: may come back at any depth
            if not bad and depth_m is not None:
                # lock only at the presenter's kept depth (engine.presenter.depth)
                z_probe = float(torso_depths(depth_m, probe[None, :], self.model.aspect)[0])
                bad = not self.depth_ref.agrees(z_probe, p.depth_sigma_m)
            self._above = self._above + 1 if not bad else 0
            if self._above >= p.reacquire_frames:
                self.state = TRACKING
                self.lost_frames = 0
                self._below = 0
                mean = probe.copy()
                self.last_good_xyh = mean.copy()
                self.jitter.reset(mean)
                # back to the normal particle count around the re-acquired state
                self.particles = pf.gaussian_cloud(mean, self.sigma_xyh(float(mean[2])),
                                                   p.n_particles, self.rng)
                self.weights = np.full(p.n_particles, 1.0 / p.n_particles)

        if self.state == TRACKING and self._below == 0:
            sure = not (p.loss_test == "contrast" and math.isfinite(z)
                        and z > 0.5 * p.loss_contrast)
            if self._prev_mean is not None and sure:
                self._vel_xy = 0.5 * self._vel_xy + 0.5 * (mean[:2] - self._prev_mean[:2])
            # unsure (the patches half-way to the background: an occlusion, another
            # person): keep the last confident velocity instead of learning this motion
            self._prev_mean = mean.copy()
        else:
            self._vel_xy[:] = 0.0
            self._prev_mean = None
        if self.state == TRACKING and p.trajectory_share > 0:
            self.trajectory.update(mean, self._vel_xy, float(mean[2]))
        else:
            self.trajectory.reset()
        if self.state == TRACKING:
            self.jitter.configure(p.jitter_cutoff_hz, self._fps())
            filtered = self.jitter(mean)
            self.last_filtered_xyh = filtered
            raw = mean
        else:
            raw = self.last_good_xyh
            filtered = self.last_filtered_xyh  # hold the last output while searching
        box_cx_w = None
        if p.fit_width and self.model.aspect <= FULL_BODY_ASPECT:
            if self.state == TRACKING:
                self._fit_width(bgr, mean)
            if self._box_dx_w is not None:
                box_cx_w = (float(raw[0]) + self._box_dx_w[0], self._box_dx_w[1])
        self.loss_z = z
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
            box_cx_w=box_cx_w,
            loss_z=z,
        )

    def _fit_width(self, bgr: NDArray[np.uint8], mean: F64) -> None:
        """Smoothed output-box width and centre offset from ``extent.measure_extent``."""
        if self._fg_of is not self._sqrt_ref or self._fg is None:
            # the reference's colours pooled by patch area (made again when it changed)
            ref = np.square(self._sqrt_ref)
            rel = self._rel
            area = (rel[:, 2] - rel[:, 0]) * (rel[:, 3] - rel[:, 1])
            self._fg = (area / max(float(area.sum()), 1e-12)) @ ref
            self._fg_of = self._sqrt_ref
        got = measure_extent(bgr, self._gains, mean, self.model.aspect, self._fg,
                             self.model.n_bins, w_max_frac=self.params.fit_width_max_frac,
                             lut=self._lut)
        if got is None:
            return
        dx, w = got[0] - float(mean[0]), got[1]
        if self._box_dx_w is None:
            self._box_dx_w = (dx, w)
        else:
            a = 0.5  # temporal smoothing of the measured extent
            self._box_dx_w = (self._box_dx_w[0] + a * (dx - self._box_dx_w[0]),
                              self._box_dx_w[1] + a * (w - self._box_dx_w[1]))
