"""Range-beacon simulator: the paper's studio (sec. IV) or any layout.

The paper's experiment: four fixed beacons A(10, 10), B(22, 0), C(-12, -16), D(5, 15), a
camera that starts at the origin and moves for 120 time steps, changing direction at about
step 20 (fig. 6, 7). The paper's path itself is only shown as a figure, so
:func:`paper_camera_path` is a path "like the paper's": it starts at the origin, heads
north-east, turns sharply at step 20 and then curves back, staying inside the beacons.

Readings: ``range = |f - s| + w`` with ``w ~ N(0, noise_sigma_m^2)`` (eq. 8); each reading is
missing with probability ``dropout_prob``; an outlier (probability ``outlier_prob``) replaces
the range with a uniform draw in [0, ``outlier_max_m``] (multipath / wrong-beacon echoes).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.errors import ParamsError
from engine.params import Params, param

F64 = NDArray[np.float64]

#: the paper's four beacons (sec. IV), metres
PAPER_LAYOUT: dict[str, tuple[float, float]] = {
    "A": (10.0, 10.0),
    "B": (22.0, 0.0),
    "C": (-12.0, -16.0),
    "D": (5.0, 15.0),
}


def paper_camera_path(n_steps: int = 120, speed_m: float = 0.15) -> F64:
    """(n_steps + 1, 2) camera positions from the origin, step length ``speed_m``.

    Heading 40 deg for 20 steps, a sharp turn to -60 deg over 4 steps (the paper's "changes
    its direction at about time step 20"), then a steady left-hand curve of 2.2 deg/step.
    """
    if n_steps < 1:
        raise ParamsError(f"n_steps must be >= 1, got {n_steps}")
    heading = np.empty(n_steps)
    for k in range(n_steps):
        if k < 20:
            h = 40.0
        elif k < 24:
            h = 40.0 - 25.0 * (k - 19)
        else:
            h = -60.0 + 2.2 * (k - 23)
        heading[k] = math.radians(h)
    steps = speed_m * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    return np.vstack([np.zeros((1, 2)), np.cumsum(steps, axis=0)])


@dataclass(frozen=True, slots=True)
class SimConfig(Params):
    """Simulator settings (noise in metres, probabilities per reading)."""

    n_steps: int = param(120, lo=1, help="time steps after the start")
    speed_m: float = param(0.15, lo=0.0, help="camera step length (m)")
    noise_sigma_m: float = param(0.1, lo=0.0, help="range noise std (m)")
    dropout_prob: float = param(0.0, lo=0.0, hi=1.0, help="probability a reading is missing")
    outlier_prob: float = param(0.0, lo=0.0, hi=1.0, help="probability a reading is an outlier")
    outlier_max_m: float = param(40.0, lo=0.0, help="outliers are uniform in [0, this] (m)")
    seed: int = param(0, help="random seed")


@dataclass(frozen=True, slots=True)
class SimRun:
    """A simulated run: ids, true beacons (n, 2), true path (T, 2), ranges (T, n) NaN=missing."""

    ids: tuple[str, ...]
    beacons_xy: F64
    path_xy: F64
    ranges_m: F64
    outlier_mask: NDArray[np.bool_]

    def ranges_dict(self, t: int) -> dict[str, float]:
        """Readings of step t as {beacon id: range}, missing ones left out."""
        row = self.ranges_m[t]
        return {i: float(r) for i, r in zip(self.ids, row, strict=True) if math.isfinite(r)}


def simulate(
    layout: Mapping[str, Sequence[float]] | None = None,
    config: SimConfig | None = None,
    path_xy: F64 | None = None,
) -> SimRun:
    """Simulate range readings from every beacon of ``layout`` along the camera path."""
    cfg = config or SimConfig()
    lay = dict(layout if layout is not None else PAPER_LAYOUT)
    if not lay:
        raise ParamsError("beacon layout is empty")
    ids = tuple(lay)
    beacons = np.array([lay[i] for i in ids], dtype=np.float64).reshape(len(ids), 2)
    path = (
        paper_camera_path(cfg.n_steps, cfg.speed_m)
        if path_xy is None
        else np.asarray(path_xy, dtype=np.float64).reshape(-1, 2)
    )
    rng = np.random.default_rng(cfg.seed)
    true = np.linalg.norm(beacons[None, :, :] - path[:, None, :], axis=2)
    ranges = true + rng.normal(0.0, cfg.noise_sigma_m, true.shape)
    outl = rng.random(true.shape) < cfg.outlier_prob
    ranges = np.where(outl, rng.uniform(0.0, cfg.outlier_max_m, true.shape), ranges)
    drop = rng.random(true.shape) < cfg.dropout_prob
    ranges = np.where(drop, np.nan, np.maximum(ranges, 0.0))
    for a in (beacons, path, ranges, outl):
        a.flags.writeable = False
    return SimRun(ids=ids, beacons_xy=beacons, path_xy=path, ranges_m=ranges,
                  outlier_mask=outl & ~drop)
