"""Start-up: where beacons and the first camera move begin (sec. III.B, and beyond it).

The paper's initialisation: the camera starts at the origin; the first measurement puts each
beacon on the circle of the measured radius; "the first two measurements [give] a rough idea
of where the next location states should be, i.e. in which quadrant the state is. Then a
random point is chosen in that quadrant to be the next location state" -- the signs of the
first move from the range changes, :func:`first_move_signs`. Where on its circle each beacon
starts the paper does not say; here the operator's layout chooses (its quadrant with
``hint_sigma_m = 0``, a bearing spread of ``hint_sigma_m`` around the layout's bearing
otherwise: :func:`point_bearings`), else the whole circle.

Extension (``ring_hypotheses`` > 0, start-up without a layout hint): while the camera moves on
a straight line a beacon and its mirror image about that line give identical ranges, so every
particle keeps, per beacon, a :class:`BearingRing` of bearing hypotheses on its first-range
circle, weighted by Bayes with the range likelihood (eq. (10) with the particle's beacon
distribution a mixture, :func:`ring_log_likelihood`), until one side dominates
(:func:`ring_confidence` >= ``ring_commit``); then each particle keeps one point drawn by
weight (:func:`sample_ring`). Known beacons (``known_beacons``) start the camera by
least-squares trilateration (:func:`trilaterate`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.beacons.likelihood import logsumexp_rows, range_log_likelihood

F64 = NDArray[np.float64]


def quadrant_span(angle_rad: float) -> tuple[float, float]:
    """The quadrant [q pi/2, (q + 1) pi/2) holding ``angle_rad``."""
    q = math.floor((angle_rad % (2 * math.pi)) / (math.pi / 2))
    return q * math.pi / 2, (q + 1) * math.pi / 2


def layout_span(layout_xy: F64, centre_xy: F64) -> tuple[float, float] | None:
    """Bearing interval of a layout beacon's quadrant seen from ``centre_xy`` (None: the
    layout has no position for it)."""
    if not np.all(np.isfinite(layout_xy)):
        return None
    d = layout_xy - centre_xy
    return quadrant_span(math.atan2(d[1], d[0]))


def point_bearings(
    m: int, r: float, prev_rel_xy: F64, layout_rel_xy: F64 | None,
    span: tuple[float, float] | None, hint_sigma_m: float, range_sigma_m: float,
    rng: np.random.Generator,
) -> F64:
    """Initial bearing of one beacon in each of ``m`` particles (one point per particle).

    A beacon re-initialised after repeated outliers keeps each particle's previous bearing
    (``prev_rel_xy`` (m, 2) finite: beacon minus camera); else around the layout's bearing
    with the hint's spread at range ``r`` (``layout_rel_xy`` seen from the cloud's centre);
    else uniform in the layout's quadrant ``span`` or the whole circle.
    """
    if np.all(np.isfinite(prev_rel_xy)):
        spread = max(hint_sigma_m, range_sigma_m) / max(r, 1e-3)
        return np.arctan2(prev_rel_xy[:, 1], prev_rel_xy[:, 0]) + rng.normal(0.0, spread, m)
    if layout_rel_xy is not None and span is not None and hint_sigma_m > 0.0:
        d = layout_rel_xy
        return math.atan2(d[1], d[0]) + rng.normal(0.0, hint_sigma_m / max(r, 1e-3), m)
    lo, hi = span if span is not None else (0.0, 2 * math.pi)
    return rng.uniform(lo, hi, m)


def on_circle(cam_xy: F64, r: float, theta: F64, range_sigma_m: float,
              rng: np.random.Generator) -> F64:
    """Points at bearings ``theta`` (m,) on the circle of radius ``r`` (+ range noise) around
    each particle's camera (sec. III.B's first-range circle) -> (m, 2)."""
    m = cam_xy.shape[0]
    rad = np.maximum(r + rng.normal(0.0, range_sigma_m, m), 0.0)
    out = np.empty((m, 2))
    out[:, 0] = cam_xy[:, 0] + rad * np.cos(theta)
    out[:, 1] = cam_xy[:, 1] + rad * np.sin(theta)
    return out


@dataclass(slots=True)
class BearingRing:
    """One beacon's start-up mixture in every particle: K bearing hypotheses on the circle of
    the first measured range around that particle's camera, with per-particle log-weights.

    ``hyp`` (M, K, 2) points, ``log_w`` (M, K) normalised per particle, ``centre`` (M, 2) the
    camera at initialisation, ``var_t`` the tangential variance one hypothesis stands for
    ((r * spacing)^2 / 12: each is the centre of a bearing cell of that width).
    """

    hyp: F64
    log_w: F64
    centre: F64
    var_t: float

    def take(self, idx: NDArray[np.intp]) -> None:
        self.hyp, self.log_w, self.centre = self.hyp[idx], self.log_w[idx], self.centre[idx]

    def prune(self, min_weight: float = 1e-6) -> None:
        """Drop hypothesis columns below ``min_weight`` in every particle (speed only: the
        mass dropped is at most K * min_weight per particle), renormalise."""
        keep = np.max(self.log_w, axis=0) > math.log(min_weight)
        if keep.all() or not keep.any():
            return
        self.hyp = self.hyp[:, keep]
        lw = self.log_w[:, keep]
        self.log_w = lw - logsumexp_rows(lw)[:, None]


def init_ring(cam_xy: F64, r: float, span: tuple[float, float] | None, ring_hypotheses: int,
              range_sigma_m: float, rng: np.random.Generator) -> BearingRing:
    """Multi-hypothesis start-up of one beacon (sec. III.B's first-range circle, kept
    multi-modal): K bearings per particle (a stratified grid with a random offset per
    particle, inside the layout's quadrant ``span`` if any, else the whole circle), equal
    weights. ``ring_hypotheses`` is K per 90 deg."""
    m = cam_xy.shape[0]
    lo, hi = span if span is not None else (0.0, 2 * math.pi)
    k = max(2, round(ring_hypotheses * (hi - lo) / (math.pi / 2)))
    spacing = (hi - lo) / k
    theta = lo + (np.arange(k)[None, :] + rng.random((m, 1))) * spacing
    rad = np.maximum(r + rng.normal(0.0, range_sigma_m, (m, 1)), 0.0)
    hyp = cam_xy[:, None, :] + rad[..., None] * np.stack(
        [np.cos(theta), np.sin(theta)], axis=-1)
    return BearingRing(hyp=hyp, log_w=np.full((m, k), -math.log(k)), centre=cam_xy.copy(),
                       var_t=(r * spacing) ** 2 / 12.0)


def sample_ring(ring: BearingRing, rng: np.random.Generator) -> F64:
    """One hypothesis per particle drawn by its weight (a sample of the particle's mixture;
    what the outlier gate and the first-move quadrant see) -> (M, 2)."""
    w = np.exp(ring.log_w)
    cum = np.cumsum(w, axis=1)
    u = rng.random(cum.shape[0]) * cum[:, -1]
    k = np.minimum(np.sum(cum < u[:, None], axis=1), cum.shape[1] - 1)
    return np.asarray(ring.hyp[np.arange(cum.shape[0]), k], dtype=np.float64)


def ring_confidence(ring: BearingRing, weights: F64) -> float:
    """Mean (over particles, by weight) weight of each particle's best hypothesis."""
    return float(weights @ np.exp(np.max(ring.log_w, axis=1)))


def ring_log_likelihood(
    cam_xy: F64, ring: BearingRing, measured_m: float, sigma_m: float,
    outlier_prob: float = 0.0, max_range_m: float = 60.0,
) -> F64:
    """Log-likelihood (M, K) of one range for every hypothesis of a :class:`BearingRing`.

    A hypothesis stands for a bearing cell: its tangential spread changes the range seen from
    the camera by ``sin(alpha)`` times the offset, alpha the angle at the hypothesis between
    the directions to the ring's centre and to the camera (0 on the line through the centre,
    where the cell's width does not matter), so its variance ``var_t sin^2(alpha)`` is added
    to ``sigma_m^2``.
    """
    to_cam = cam_xy[:, None, :] - ring.hyp
    to_c = ring.centre[:, None, :] - ring.hyp
    r_cam = np.hypot(to_cam[..., 0], to_cam[..., 1])
    r_c = np.maximum(np.hypot(to_c[..., 0], to_c[..., 1]), 1e-9)
    sin_a = (to_cam[..., 0] * to_c[..., 1] - to_cam[..., 1] * to_c[..., 0]) / (
        np.maximum(r_cam, 1e-9) * r_c)
    sig = np.sqrt(sigma_m**2 + ring.var_t * sin_a**2)
    return range_log_likelihood(measured_m - r_cam, sig, outlier_prob, max_range_m)


def ring_update(cam_xy: F64, ring: BearingRing, measured_m: float, sigma_m: float,
                outlier_prob: float, max_range_m: float) -> F64:
    """Eq. (10) with the particle's mixture over one ring beacon: returns each particle's
    log-likelihood (the log-sum over its hypotheses, (M,)) and updates the hypotheses'
    weights to their posterior (Bayes within the particle), pruning negligible ones."""
    ll_k = ring.log_w + ring_log_likelihood(cam_xy, ring, measured_m, sigma_m, outlier_prob,
                                            max_range_m)
    ll_j = logsumexp_rows(ll_k)
    ring.log_w = ll_k - ll_j[:, None]
    ring.prune()
    return ll_j


def first_move_signs(
    beacons_xy: F64, first_ranges_m: F64, ranges_m: F64, usable: NDArray[np.bool_],
    start_xy: F64, max_change_m: float | None,
) -> F64 | None:
    """Signs (sx, sy) of the first camera move, sec. III.B: the range changes between the
    first two measurements, r1 - r0 ~ -u . s1 with u the unit vectors from the start to the
    beacons (the cloud's mean, ``beacons_xy`` (M, n, 2)); ``usable`` the beacons read both
    times. ``max_change_m`` (robust weighting): a range cannot change by more than the camera
    can move in one step, larger changes are outliers. None: not enough to decide."""
    if np.count_nonzero(usable) < 2:
        return None
    mean_b = np.nanmean(beacons_xy[:, usable, :], axis=0) - start_xy
    norms = np.linalg.norm(mean_b, axis=1, keepdims=True)
    if np.any(norms < 1e-6):
        return None
    u = mean_b / norms
    dr = ranges_m[usable] - first_ranges_m[usable]
    if max_change_m is not None:
        ok = np.abs(dr) <= max_change_m
        if np.count_nonzero(ok) < 2:
            return None
        u, dr = u[ok], dr[ok]
    s1, *_ = np.linalg.lstsq(-u, dr, rcond=None)
    if not np.all(np.isfinite(s1)) or float(np.linalg.norm(s1)) < 1e-9:
        return None
    return np.where(s1 >= 0.0, 1.0, -1.0)


def trilaterate(
    beacons_xy: F64, ranges_m: F64, guess_xy: F64, iterations: int = 10
) -> F64 | None:
    """Gauss-Newton least-squares position from >= 3 known beacons (None if degenerate)."""
    if len(ranges_m) < 3:
        return None
    x = np.array(guess_xy, dtype=np.float64)
    for _ in range(iterations):
        diff = x[None, :] - beacons_xy
        r = np.maximum(np.linalg.norm(diff, axis=1), 1e-9)
        J = diff / r[:, None]
        res = ranges_m - r
        try:
            dx, *_ = np.linalg.lstsq(J, res, rcond=None)
        except np.linalg.LinAlgError:
            return None
        x = x + dx
        if float(np.linalg.norm(dx)) < 1e-6:
            break
    return x if np.all(np.isfinite(x)) else None
