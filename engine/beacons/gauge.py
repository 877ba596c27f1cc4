"""Gauge alignment of the estimate (extension ``gauge_aligned_estimate``, beyond the paper).

Range-only data fix the map and the path only up to a rotation/reflection about the start.
Without a layout hint (``hint_sigma_m = 0``) nothing pins each particle's frame, so particles
in different frames would be averaged into a too-short, blurred path. Before averaging, each
particle's camera and map are rotated/mirrored about the start onto the previous estimate's
map (:func:`gauge_rotations`, :func:`rotate_about`); the particles themselves are unchanged.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from engine.beacons.startup import BearingRing

F64 = NDArray[np.float64]


def gauge_rotations(
    beacons_xy: F64, known: NDArray[np.bool_], rings: Mapping[int, BearingRing],
    reference_xy: F64, start_xy: F64,
) -> F64 | None:
    """Per-particle 2x2 rotation or reflection about the start, (M, 2, 2), that best maps the
    particle's map ``beacons_xy`` (M, n, 2) onto ``reference_xy`` (n, 2, relative to the start;
    the previous estimate's map). Beacons still in a start-up ring count with the particle's
    mixture mean. None: nothing to align on."""
    ok = known & np.all(np.isfinite(reference_xy), axis=1)
    if not np.any(ok):
        return None
    reps = beacons_xy[:, ok, :] - start_xy
    for j, i in enumerate(np.flatnonzero(ok)):
        ring = rings.get(int(i))
        if ring is not None:
            w = np.exp(ring.log_w)
            reps[:, j, 0] = np.sum(w * ring.hyp[..., 0], axis=1) - start_xy[0]
            reps[:, j, 1] = np.sum(w * ring.hyp[..., 1], axis=1) - start_xy[1]
    ref = reference_xy[ok]
    bx, by = reps[..., 0], reps[..., 1]
    dot = bx @ ref[:, 0] + by @ ref[:, 1]
    crs = bx @ ref[:, 1] - by @ ref[:, 0]
    dot_m = bx @ ref[:, 0] - by @ ref[:, 1]  # mirrored map (x, -y)
    crs_m = bx @ ref[:, 1] + by @ ref[:, 0]
    mirror = np.hypot(dot_m, crs_m) > np.hypot(dot, crs)
    th = np.where(mirror, np.arctan2(crs_m, dot_m), np.arctan2(crs, dot))
    c, s_ = np.cos(th), np.sin(th)
    sy = np.where(mirror, -1.0, 1.0)
    return np.stack([np.stack([c, -s_ * sy], axis=1), np.stack([s_, c * sy], axis=1)],
                    axis=1)  # R(th) @ diag(1, sy)


def rotate_about(rot: F64, x: F64, start_xy: F64) -> F64:
    """Points ``x`` (M, k, 2) of each particle mapped by its gauge matrix ``rot`` (M, 2, 2)
    about the start."""
    d = x - start_xy
    r = rot[:, None]  # (M, 1, 2, 2)
    out = np.empty_like(d)
    out[..., 0] = r[..., 0, 0] * d[..., 0] + r[..., 0, 1] * d[..., 1] + start_xy[0]
    out[..., 1] = r[..., 1, 0] * d[..., 0] + r[..., 1, 1] * d[..., 1] + start_xy[1]
    return out
