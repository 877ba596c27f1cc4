"""Range-only particle-filter SLAM for 2D camera tracking (Yang, Wu, Moniri, Chibelushi 2007).

Each particle holds 2(n + 1) states, the camera position and n beacon ("feature") positions,
eq. (9)::

    x_t^m = (s_t^m, f_1,t^m, ..., f_n,t^m) = ((x, y)_t^m, (x, y)_1,t^m, ..., (x, y)_n,t^m)

One iteration, :meth:`BeaconSlamFilter.step` (sec. III.B, fig. 5), composes:

1. start-up on the first reading (:mod:`engine.beacons.startup`, sec. III.B);
2. motion model, a 2D zero-mean Gaussian on the camera (sec. III.A), the first move in the
   quadrant the first two measurements point to (:meth:`BeaconSlamFilter._predict`);
3. weighting with the range model eq. (8) and the particle weight eq. (10)
   (:mod:`engine.beacons.likelihood`, :meth:`BeaconSlamFilter._weigh`);
4. Map Adjustment, eq. (12) (:mod:`engine.beacons.map_adjustment`,
   :meth:`BeaconSlamFilter._adjust_map`);
5. normalisation and the weighted-mean estimate (:meth:`BeaconSlamFilter._estimate`);
6. systematic resampling (:func:`engine.particles.systematic_resample`,
   :meth:`BeaconSlamFilter._resample`).

Extensions beyond the paper, each a named function behind its own switch of
:class:`~engine.beacons.params.BeaconFilterParams` (``EXTENSIONS`` there lists the overrides
that turn each off):

- robust weighting (``outlier_prob`` > 0): mixture range density, consensus gate,
  re-initialisation of a beacon rejected ``REINIT_AFTER`` times in a row
  (:meth:`BeaconSlamFilter._gate`, :meth:`BeaconSlamFilter._stale_beacons`);
- map-spread weighting (``map_spread_weighting``): eq. (10) integrated over the map cloud,
  or over each particle's own beacon kernel with the 'kalman' gain;
- the 'kalman' Map Adjustment gain (``map_adjust_gain``, default): each particle's beacon a
  Gaussian kernel moved by its Kalman gain and narrowed by each reading, FastSLAM-style
  (:func:`~engine.beacons.map_adjustment.kalman_map_adjustment`); eq. (12)'s fixed p is this
  step for a round kernel of fixed width;
- ring start-up (``ring_hypotheses`` > 0): multi-hypothesis bearings per beacon until the path
  turns (:meth:`BeaconSlamFilter._update_rings`);
- gauge alignment (``gauge_aligned_estimate``): the estimate averaged in one frame;
- Liu-West roughening (``roughen_h`` > 0) and plain jitter (``beacon_jitter_m``) after
  resampling;
- the layout hint (``hint_sigma_m`` > 0), annealed Map Adjustment (``map_adjust_anneal``),
  resampling on a low effective sample size (``resample_ess_fraction`` < 1);
- and, as operating modes: missing readings per step (only the beacons read are weighted and
  adjusted), surveyed beacons (``known_beacons``: localisation only), a live-changeable
  particle count (resampled to the new size).

Why these exist (bench ``beacon``): the first version's map froze after a few steps (beacon
spread 1-12 cm while the real error was 0.5-4 m); integrating eq. (10) over the map cloud and
the Liu-West move keep it improving (final beacon error 1.7 -> 0.6 m with the 3 m layout
hint). Without a hint, a beacon and its mirror image about the straight first leg give equal
ranges; one point per beacon settled every particle between the two modes (shape error
~6 m), the ring start-up keeps both until the turn, and gauge alignment averages particles in
one frame (30 seeds, 200 particles, with MA, after the best rotation/mirror: path RMSE
0.98 -> 0.58 m, final beacon error 6.1 -> 1.0 m). Range-only data do not observe a common
rotation/translation of camera and map, so the absolute path error grows slowly with the
distance from the start while the shape stays at ~0.25 m.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.beacons.cloud import liu_west_roughen, weighted_mean_cov
from engine.beacons.gauge import gauge_rotations, rotate_about
from engine.beacons.likelihood import (
    consensus_inliers,
    normalise_log_weights,
    point_log_weights,
    predicted_ranges,
    range_log_likelihood,
    weighted_residual_rms,
)
from engine.beacons.map_adjustment import (
    annealed_gain,
    kalman_map_adjustment,
    kernel_range_sigma,
    map_adjustment,
)
from engine.beacons.params import BeaconFilterParams
from engine.beacons.startup import (
    BearingRing,
    first_move_signs,
    init_ring,
    layout_span,
    on_circle,
    point_bearings,
    ring_confidence,
    ring_update,
    sample_ring,
    trilaterate,
)
from engine.errors import ParamsError
from engine.particles import effective_sample_size, systematic_resample

F64 = NDArray[np.float64]
B = NDArray[np.bool_]

#: consecutive outlier rejections after which a beacon is re-initialised (robust weighting)
REINIT_AFTER = 5


@dataclass(frozen=True, slots=True)
class FilterEstimate:
    """Weighted-mean camera and map with their spread after one step."""

    step: int  # 0 = initialisation; -1 = no valid reading yet (the filter has not started)
    cam_xy: F64  # (2,)
    cam_cov: F64  # (2, 2)
    beacons_xy: F64  # (n, 2), NaN for beacons never read
    beacons_cov: F64  # (n, 2, 2)
    used: B  # (n,) readings used for weighting this step
    outliers: B  # (n,) readings rejected as outliers this step
    ess: float  # effective sample size before resampling
    residual_rms_m: float  # weighted RMS of (d - d') over used readings, before Map Adjustment

    def __post_init__(self) -> None:
        for a in (self.cam_xy, self.cam_cov, self.beacons_xy, self.beacons_cov, self.used,
                  self.outliers):
            a.flags.writeable = False


@dataclass(slots=True)
class _Weighting:
    """What the weighting of one step decided (readings by beacon index)."""

    log_w: F64  # (M,) log-likelihood of this step's readings per particle
    used: B  # (n,)
    outliers: B  # (n,)
    residual_rms_m: float


class BeaconSlamFilter:
    """The particle filter of sec. III, vectorised over particles with numpy.

    ``beacon_ids`` fixes the order of the n beacons; ``layout_xy`` (optional) is the
    operator's layout: only its quadrants are used in SLAM mode, its coordinates are the map
    in known-beacon mode. Call :meth:`step` once per time step with one range per beacon
    (NaN where missing).
    """

    def __init__(
        self,
        beacon_ids: Sequence[str],
        params: BeaconFilterParams | None = None,
        *,
        layout_xy: Mapping[str, Sequence[float]] | None = None,
        start_xy: Sequence[float] = (0.0, 0.0),
        seed: int | None = None,
    ) -> None:
        if len(beacon_ids) == 0:
            raise ParamsError("beacon SLAM needs at least one beacon id")
        if len(set(beacon_ids)) != len(beacon_ids):
            raise ParamsError(f"beacon ids must be unique, got {list(beacon_ids)}")
        self.ids: tuple[str, ...] = tuple(beacon_ids)
        self.n = len(self.ids)
        self.params = params or BeaconFilterParams()
        layout = dict(layout_xy or {})
        self.layout_xy = np.array(
            [layout.get(i, (math.nan, math.nan)) for i in self.ids], dtype=np.float64
        ).reshape(self.n, 2)
        self.start_xy = np.asarray(start_xy, dtype=np.float64).reshape(2)
        self._has_layout = bool(np.any(np.all(np.isfinite(self.layout_xy), axis=1)))
        self.seed = int(self.params.seed if seed is None else seed)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget everything; the next step re-initialises."""
        self.rng = np.random.default_rng(self.seed)
        self.t = 0
        m = int(self.params.n_particles)
        self.cam = np.tile(self.start_xy, (m, 1))
        self.beacons = np.full((m, self.n, 2), np.nan)
        self.beacon_cov = np.zeros((m, self.n, 2, 2))  # the 'kalman' gain's kernels
        self.known = np.zeros(self.n, dtype=bool)  # beacon initialised (read at least once)
        self.weights = np.full(m, 1.0 / m)
        self.first_ranges = np.full(self.n, np.nan)
        self.n_reads = np.zeros(self.n)  # readings used per beacon (annealed Map Adjustment)
        self.n_rejected = np.zeros(self.n, dtype=np.int64)  # consecutive outlier flags
        self.rings: dict[int, BearingRing] = {}  # beacons still multi-modal (start-up)
        self.gauge_ref = np.full((self.n, 2), np.nan)  # last estimate's map (gauge alignment)
        self.last: FilterEstimate | None = None

    def set_params(self, params: BeaconFilterParams) -> None:
        """New settings; a new particle count takes effect by resampling at the next step."""
        self.params = params

    @property
    def n_particles(self) -> int:
        return int(self.cam.shape[0])

    # ------------------------------------------------------------------ one step
    def step(self, ranges_m: Sequence[float] | F64) -> FilterEstimate:
        """One iteration of fig. 5 with one range per beacon in ``ids`` order (NaN = missing)."""
        p = self.params
        ranges = np.asarray(ranges_m, dtype=np.float64).reshape(self.n)
        mask = np.isfinite(ranges) & (ranges >= 0.0)
        if int(p.n_particles) != self.n_particles:
            self._resize(int(p.n_particles))
        m = self.n_particles
        wt = _Weighting(np.zeros(m), np.zeros(self.n, dtype=bool),
                        np.zeros(self.n, dtype=bool), math.nan)
        if self.t == 0:
            if not np.any(mask):  # nothing read yet: stay before the first step
                self.t = -1
            else:
                self._first_step(ranges, mask)  # sec. III.B
            wt.used = mask & self.known
        else:
            newly = mask & ~self.known
            self._predict(ranges, mask)  # motion model, sec. III.A
            active = np.flatnonzero(mask & self.known)
            if active.size:
                wt = self._weigh(ranges, active)  # eq. (8), (10)
                self._adjust_map(ranges, active[wt.used[active]])  # eq. (12)
            self.n_reads[wt.used] += 1.0
            for i in np.flatnonzero(newly | self._stale_beacons(mask)):
                self._init_beacon(int(i), float(ranges[i]))
        # normalisation (sec. III.B); weights carry over when resampling is skipped
        self.weights = normalise_log_weights(np.log(np.maximum(self.weights, 1e-300)) + wt.log_w)
        ess = effective_sample_size(self.weights)
        self._update_rings()
        est = self._estimate(wt, ess)
        if self.t > 0 and ess < p.resample_ess_fraction * m + 1e-9:
            self._resample(m)
        self.t += 1
        self.last = est
        return est

    def _first_step(self, ranges: F64, mask: B) -> None:
        """Initialisation (sec. III.B): camera at the start (or trilaterated from surveyed
        beacons), each beacon read on the circle of its first range."""
        p = self.params
        if p.known_beacons:
            for i in range(self.n):
                if np.all(np.isfinite(self.layout_xy[i])):
                    self.beacons[:, i, :] = self.layout_xy[i]
                    self.known[i] = True
            usable = mask & self.known
            pos = trilaterate(self.layout_xy[usable], ranges[usable], self.start_xy)
            if pos is not None:
                spread = max(p.range_sigma_m, 0.05)
                self.cam = pos + self.rng.normal(0.0, spread, (self.n_particles, 2))
        for b in np.flatnonzero(mask & ~self.known):
            self._init_beacon(int(b), float(ranges[b]))
        self.first_ranges = np.where(mask, ranges, np.nan)

    def _predict(self, ranges: F64, mask: B) -> None:
        """Motion model: camera += 2D zero-mean Gaussian (sec. III.A); the first move is
        drawn in the quadrant the first two measurements point to (sec. III.B)."""
        p = self.params
        noise = self.rng.normal(0.0, p.motion_sigma_m, (self.n_particles, 2))
        if self.t == 1 and p.quadrant_init and not p.known_beacons:
            max_change = (3.0 * (p.motion_sigma_m + p.range_sigma_m)
                          if p.outlier_prob > 0.0 else None)
            signs = first_move_signs(
                self.beacons, self.first_ranges, ranges,
                mask & np.isfinite(self.first_ranges) & self.known, self.start_xy, max_change)
            if signs is not None:
                noise = np.abs(noise) * signs
        self.cam = self.cam + noise

    def _weigh(self, ranges: F64, active: NDArray[np.intp]) -> _Weighting:
        """Weighting, eq. (10), with the range model of eq. (8), over the ``active`` beacons
        (read and initialised): the product over beacons of each particle's likelihood;
        point beacons by :func:`point_log_weights`, ring beacons by their mixture."""
        p = self.params
        d_pred = predicted_ranges(self.cam, self.beacons[:, active, :])  # eq. (8)
        resid = ranges[active][None, :] - d_pred
        inl = self._gate(resid, d_pred)
        used = np.zeros(self.n, dtype=bool)
        outliers = np.zeros(self.n, dtype=bool)
        outliers[active[~inl]] = True
        used[active[inl]] = True
        self.n_rejected[active[inl]] = 0
        self.n_rejected[active[~inl]] += 1
        is_ring = np.array([int(j) in self.rings for j in active], dtype=bool)
        pt = inl & ~is_ring
        log_w = np.zeros(self.n_particles)
        if np.any(pt) and p.map_spread_weighting and self._kernels():
            # eq. (10) integrated over each particle's own beacon kernel (with the 'kalman'
            # gain the beacon's distribution is the particle's kernel, not the cloud)
            sig = kernel_range_sigma(self.cam, self.beacons[:, active[pt], :],
                                     self.beacon_cov[:, active[pt]], p.range_sigma_m)
            log_w = np.sum(range_log_likelihood(resid[:, pt], sig, p.outlier_prob,
                                                p.max_range_m), axis=1)
        elif np.any(pt):
            log_w = point_log_weights(
                self.cam, self.beacons[:, active[pt], :], resid[:, pt], self.weights,
                range_sigma_m=p.range_sigma_m, map_spread_weighting=p.map_spread_weighting,
                outlier_prob=p.outlier_prob, max_range_m=p.max_range_m)
        for j in active[inl & is_ring]:
            log_w = log_w + ring_update(self.cam, self.rings[int(j)], float(ranges[j]),
                                        p.range_sigma_m, p.outlier_prob, p.max_range_m)
        return _Weighting(log_w, used, outliers, weighted_residual_rms(log_w, resid[:, inl]))

    def _gate(self, resid: F64, d_pred: F64) -> B:
        """Extension, robust weighting: the consensus gate's inliers among the readings (all
        when off, ``outlier_prob = 0``, or with fewer than two readings)."""
        p = self.params
        if p.outlier_prob > 0.0 and resid.shape[1] >= 2:
            return consensus_inliers(resid, d_pred, p.range_sigma_m, p.outlier_gate_sigma)
        return np.ones(resid.shape[1], dtype=bool)

    def _adjust_map(self, ranges: F64, adj: NDArray[np.intp]) -> None:
        """Map Adjustment, eq. (12), of the beacons used this step (every hypothesis of a
        ring beacon); the gain annealed if ``map_adjust_anneal``."""
        p = self.params
        if not (p.map_adjustment and not p.known_beacons and p.map_adjust_p > 0.0):
            return
        pts = np.array([j for j in adj if int(j) not in self.rings], dtype=np.intp)
        if pts.size and p.map_adjust_gain == "kalman":
            self.beacons[:, pts, :], self.beacon_cov[:, pts] = kalman_map_adjustment(
                self.cam, self.beacons[:, pts, :], self.beacon_cov[:, pts], ranges[pts],
                p.range_sigma_m)
        elif pts.size:
            gain: float | F64 = p.map_adjust_p
            if p.map_adjust_anneal:
                gain = annealed_gain(p.map_adjust_p, self.n_reads[pts])
            self.beacons[:, pts, :] = map_adjustment(self.cam, self.beacons[:, pts, :],
                                                     ranges[pts], gain)
        for j in adj:
            ring = self.rings.get(int(j))
            if ring is None:
                continue
            g: float | F64 = p.map_adjust_p
            if p.map_adjust_anneal:
                g = annealed_gain(p.map_adjust_p, self.n_reads[j : j + 1])[0]
            k = ring.hyp.shape[1]
            ring.hyp = map_adjustment(self.cam, ring.hyp, np.full(k, float(ranges[j])), g)

    def _stale_beacons(self, mask: B) -> B:
        """Extension, robust weighting: beacons read now but rejected ``REINIT_AFTER`` times
        in a row were initialised from an outlier (or have been moved): forget them so they
        start again from the current reading."""
        if self.params.known_beacons:
            return np.zeros(self.n, dtype=bool)
        stale = mask & (self.n_rejected >= REINIT_AFTER)
        self.known[stale] = False
        self.n_rejected[stale] = 0
        self.n_reads[stale] = 0.0
        return stale

    def _init_beacon(self, i: int, r: float) -> None:
        """Put beacon i on the circle of radius r around each particle's camera (sec. III.B):
        one point per particle (:func:`point_bearings`), or a start-up ring (extension
        ``ring_hypotheses``) without a layout hint; surveyed beacons at the layout."""
        p = self.params
        if p.known_beacons and np.all(np.isfinite(self.layout_xy[i])):
            self.beacons[:, i, :] = self.layout_xy[i]
            self.known[i] = True
            return
        prev = self.beacons[:, i, :] - self.cam
        centre = np.average(self.cam, axis=0, weights=self.weights)
        span = layout_span(self.layout_xy[i], centre) if p.quadrant_init else None
        self.rings.pop(i, None)
        if (not np.all(np.isfinite(prev)) and p.ring_hypotheses > 0
                and (span is None or p.hint_sigma_m <= 0.0)):
            self.rings[i] = init_ring(self.cam, r, span, p.ring_hypotheses, p.range_sigma_m,
                                      self.rng)
            self.beacons[:, i, :] = sample_ring(self.rings[i], self.rng)
        else:
            layout_rel = self.layout_xy[i] - centre if span is not None else None
            theta = point_bearings(self.n_particles, r, prev, layout_rel, span, p.hint_sigma_m,
                                   p.range_sigma_m, self.rng)
            self.beacons[:, i, :] = on_circle(self.cam, r, theta, p.range_sigma_m, self.rng)
            self._init_kernels(i)
        self.known[i] = True

    def _kernels(self) -> bool:
        """Each particle's beacons are Gaussian kernels ('kalman' Map Adjustment on)."""
        p = self.params
        return bool(p.map_adjust_gain == "kalman" and p.map_adjustment
                    and not p.known_beacons and p.map_adjust_p > 0.0)

    def _init_kernels(self, i: int) -> None:
        """'kalman' gain: beacon i's kernels, ``kernel_frac`` times its cloud's covariance."""
        _, cov = weighted_mean_cov(self.beacons[:, i, :], self.weights)
        self.beacon_cov[:, i] = self.params.kernel_frac * cov

    def _update_rings(self) -> None:
        """Extension, ring start-up: collapse a ring to one point per particle once each
        particle is sure of its side (``ring_commit``); every particle's point of a ring
        beacon is redrawn from its mixture."""
        if not self.rings:
            return
        for i in list(self.rings):
            if ring_confidence(self.rings[i], self.weights) >= self.params.ring_commit:
                self.beacons[:, i, :] = sample_ring(self.rings[i], self.rng)
                del self.rings[i]
                self._init_kernels(i)
        for i, ring in self.rings.items():
            self.beacons[:, i, :] = sample_ring(ring, self.rng)

    def _point_known(self) -> B:
        """Initialised beacons held as one point per particle (not in a start-up ring)."""
        if not self.rings:
            return self.known
        pk = self.known.copy()
        pk[list(self.rings)] = False
        return pk

    def _gauge_free(self) -> bool:
        """Extension, gauge alignment, applies: nothing else fixes each particle's frame."""
        p = self.params
        return bool(p.gauge_aligned_estimate and not p.known_beacons and (
            p.hint_sigma_m <= 0.0 or not self._has_layout))

    def _estimate(self, wt: _Weighting, ess: float) -> FilterEstimate:
        """Weighted mean and covariance of camera and map (ring beacons: their mixture), in
        one frame if gauge alignment applies."""
        rot = None
        if self._gauge_free():
            rot = gauge_rotations(self.beacons, self.known, self.rings, self.gauge_ref,
                                  self.start_xy)
        cam = self.cam if rot is None else rotate_about(rot, self.cam[:, None, :],
                                                        self.start_xy)[:, 0]
        cam_xy, cam_cov = weighted_mean_cov(cam, self.weights)
        b_xy = np.full((self.n, 2), np.nan)
        b_cov = np.full((self.n, 2, 2), np.nan)
        pk = self._point_known()
        if np.any(pk):
            pts = self.beacons[:, pk, :]
            bm, bc = weighted_mean_cov(pts if rot is None else rotate_about(rot, pts,
                                                                           self.start_xy),
                                       self.weights)
            b_xy[pk] = bm
            b_cov[pk] = bc
        for i, ring in self.rings.items():  # the mixture's mean and covariance
            wk = (self.weights[:, None] * np.exp(ring.log_w)).ravel()
            hyp = ring.hyp if rot is None else rotate_about(rot, ring.hyp, self.start_xy)
            b_xy[i], b_cov[i] = weighted_mean_cov(hyp.reshape(-1, 2), wk / np.sum(wk))
        if self._gauge_free():
            self.gauge_ref = b_xy - self.start_xy
        return FilterEstimate(step=self.t, cam_xy=cam_xy, cam_cov=cam_cov, beacons_xy=b_xy,
                              beacons_cov=b_cov, used=wt.used, outliers=wt.outliers, ess=ess,
                              residual_rms_m=wt.residual_rms_m)

    def _resample(self, m: int) -> None:
        """Systematic resampling (sec. III.B), then the extensions that diversify the map:
        the Liu-West move (``roughen_h``) and jitter (``beacon_jitter_m``)."""
        p = self.params
        self._resize(m)
        if p.roughen_h > 0.0 and not p.known_beacons and np.any(self._point_known()):
            known = np.flatnonzero(self._point_known())
            self.beacons[:, known, :] = liu_west_roughen(
                self.beacons[:, known, :], self.weights, p.roughen_h, self.rng)
        if p.beacon_jitter_m > 0.0 and not p.known_beacons:
            self.beacons = self.beacons + self.rng.normal(0.0, p.beacon_jitter_m,
                                                          self.beacons.shape)

    def _resize(self, m_new: int) -> None:
        """Resample to ``m_new`` particles (equal weights): every step, or a count change."""
        idx = systematic_resample(self.weights, m_new, self.rng)
        self.cam = self.cam[idx]
        self.beacons = self.beacons[idx]
        self.beacon_cov = self.beacon_cov[idx]
        for ring in self.rings.values():
            ring.take(idx)
        self.weights = np.full(m_new, 1.0 / m_new)
