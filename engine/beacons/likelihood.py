"""Weighting of the particles: the range model, eq. (8), and the particle weight, eq. (10).

Eq. (8), the observation model of one range d from the camera s to beacon (feature) f::

    d = g(f, s) = sqrt((x_f - x_s)^2 + (y_f - y_s)^2) + w,   w ~ N(0, sigma_r^2)

Eq. (10), the weight of particle m, the range likelihood integrated over the beacon's
distribution::

    w_m = integral Pr(d_t | f_n, s_t^m) Pr(f_n | s_0:t-1^m, d_0:t-1) df_n

With each particle's point estimate of every beacon the integral is the likelihood at that
point (:func:`point_log_weights` with ``map_spread_weighting`` off, as in the paper).
Extensions here, each behind a switch of :class:`~engine.beacons.params.BeaconFilterParams`:

- *map-spread weighting* (``map_spread_weighting``): the integral of eq. (10) taken over the
  map cloud's spread along the line of sight (:func:`marginal_range_sigma`);
- *robust weighting* (``outlier_prob`` > 0): a Gaussian/uniform mixture instead of the
  Gaussian of eq. (8) (:func:`range_log_likelihood`) and a consensus gate that keeps a reading
  (nearly) every particle disagrees with out of weighting and Map Adjustment
  (:func:`consensus_inliers`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from engine.beacons.cloud import weighted_mean_cov

F64 = NDArray[np.float64]


def predicted_ranges(cam_xy: F64, beacons_xy: F64) -> F64:
    """Eq. (8) without noise: distance from each particle's camera to its beacons.

    ``cam_xy`` (M, 2), ``beacons_xy`` (M, k, 2) -> (M, k).
    """
    return np.hypot(beacons_xy[..., 0] - cam_xy[:, None, 0],
                    beacons_xy[..., 1] - cam_xy[:, None, 1])


def range_log_likelihood(
    residual_m: F64, sigma_m: float | F64, outlier_prob: float = 0.0, max_range_m: float = 60.0
) -> F64:
    """Log-likelihood of range residuals d - d' under w ~ N(0, sigma^2) of eq. (8).

    With ``outlier_prob`` > 0 (robust weighting, beyond the paper) the density is the mixture
    ``(1 - e) N(r; 0, sigma^2) + e / max_range`` so that one wild reading cannot zero a
    particle's weight.
    """
    gauss = -0.5 * (residual_m / sigma_m) ** 2 - np.log(math.sqrt(2.0 * math.pi) * sigma_m)
    if outlier_prob <= 0.0:
        return gauss
    return np.logaddexp(
        gauss + math.log1p(-outlier_prob), math.log(outlier_prob / max_range_m)
    )


def normalise_log_weights(log_w: F64) -> F64:
    """Normalise weights so they sum to 1 (sec. III.B), stable for very small likelihoods."""
    w: F64 = np.exp(log_w - np.max(log_w))
    return w / np.sum(w)


def logsumexp_rows(x: F64) -> F64:
    """log(sum(exp(x), axis=1)) without overflow, for (M, K) arrays."""
    mx: F64 = np.max(x, axis=1)
    total: F64 = np.sum(np.exp(x - mx[:, None]), axis=1)
    return mx + np.log(total)


def marginal_range_sigma(cam_xy: F64, beacons_xy: F64, weights: F64, sigma_m: float) -> F64:
    """Std of d - d' with the beacon integrated out, eq. (10) (``map_spread_weighting``).

    Eq. (10) weights a particle by the range likelihood integrated over the beacon's
    distribution, not at a point. With the map cloud's weighted covariance ``C`` of each
    beacon as that distribution, linearised along each particle's line of sight ``u``, the
    integral is a Gaussian of variance ``sigma_m^2 + u^T C u``: weights stay soft while the map
    is uncertain along the line of sight (no collapse onto a lucky map) and sharpen as it
    converges. ``cam_xy`` (M, 2), ``beacons_xy`` (M, k, 2), ``weights`` (M,) -> (M, k).
    """
    _, cov = weighted_mean_cov(beacons_xy, weights)  # (k, 2, 2)
    u = beacons_xy - cam_xy[:, None, :]
    u = u / np.maximum(np.hypot(u[..., 0], u[..., 1])[..., None], 1e-9)
    var = (u[..., 0] ** 2 * cov[None, :, 0, 0] + 2.0 * u[..., 0] * u[..., 1] * cov[None, :, 0, 1]
           + u[..., 1] ** 2 * cov[None, :, 1, 1])
    return np.sqrt(sigma_m**2 + np.maximum(var, 0.0))


def point_log_weights(
    cam_xy: F64, beacons_xy: F64, residual_m: F64, weights: F64, *, range_sigma_m: float,
    map_spread_weighting: bool, outlier_prob: float, max_range_m: float,
) -> F64:
    """Log of eq. (10) for beacons held as one point per particle: the product over beacons
    of the range likelihoods of eq. (8) (summed logs). ``beacons_xy`` (M, k, 2), ``residual_m``
    (M, k) -> (M,). With ``map_spread_weighting`` the likelihood is integrated over the map
    cloud (:func:`marginal_range_sigma`); with ``outlier_prob`` > 0 it is robust."""
    sig: float | F64 = range_sigma_m
    if map_spread_weighting:
        sig = marginal_range_sigma(cam_xy, beacons_xy, weights, range_sigma_m)
    ll = range_log_likelihood(residual_m, sig, outlier_prob, max_range_m)
    return np.asarray(np.sum(ll, axis=1), dtype=np.float64)


def consensus_inliers(
    residual_m: F64, predicted_m: F64, range_sigma_m: float, gate_sigma: float
) -> NDArray[np.bool_]:
    """Robust weighting's consensus gate: which of k readings to use this step, (k,).

    A reading whose median residual over the particles exceeds ``gate_sigma`` predicted std
    (range noise and the cloud's spread of predicted ranges) is one (nearly) every particle
    disagrees with: an outlier. If every reading disagrees the filter, not the sensors, is
    off, and all are kept. ``residual_m``, ``predicted_m`` (M, k).
    """
    med = np.median(residual_m, axis=0)
    spread = np.std(predicted_m, axis=0)
    gate = gate_sigma * np.sqrt(range_sigma_m**2 + spread**2)
    bad = np.abs(med) > gate
    if np.all(bad):
        return np.ones(residual_m.shape[1], dtype=bool)
    return np.asarray(~bad, dtype=bool)


def weighted_residual_rms(log_w: F64, residual_m: F64) -> float:
    """RMS of the residuals (M, k) under the normalised weights ``exp(log_w)`` (a quality
    figure of the step, before Map Adjustment)."""
    w = normalise_log_weights(log_w)
    return float(math.sqrt(np.sum(w @ (residual_m ** 2)) / max(residual_m.shape[1], 1)))
