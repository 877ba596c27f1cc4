"""Map Adjustment, eq. (12): the paper's own step between weighting and resampling.

"For each particle, after applying the motion model and weighting, when the observation is
received, each feature's state is then adjusted so that the difference between the predicted
observation and real observation is smaller"::

    movement = p * (d - d') / r        applied to the vector (f - s), r = |f - s| = d'

i.e. a step of length p (d - d') along the unit vector from camera to beacon (p = 1 puts the
beacon on the measured circle). Extension (``map_adjust_anneal``, beyond the paper): the gain
``max(p, 1 / (k + 1))`` for the k-th reading of a beacon (:func:`annealed_gain`), a running
mean of the range circles that settles as the beacon is seen more.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def map_adjustment(
    cam_xy: F64, beacons_xy: F64, measured_m: F64, p: float | F64
) -> F64:
    """Eq. (12): move each beacon estimate along the camera->beacon line by p (d - d').

    ``cam_xy`` (M, 2), ``beacons_xy`` (M, k, 2), ``measured_m`` (k,) -> adjusted (M, k, 2).
    movement = p (d - d') / r applied to (f - s), with r = d' = |f - s|.
    """
    diff = beacons_xy - cam_xy[:, None, :]
    r = np.hypot(diff[..., 0], diff[..., 1])
    scale = np.asarray(p) * (measured_m[None, :] - r) / np.maximum(r, 1e-9)
    return beacons_xy + scale[:, :, None] * diff


def annealed_gain(p: float, n_reads: F64) -> F64:
    """``max(p, 1 / (k + 1))`` per beacon with k = ``n_reads`` readings used so far."""
    return np.maximum(p, 1.0 / (n_reads + 1.0))
