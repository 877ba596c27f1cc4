"""``beacon-slam``: 2D camera tracking from ranges to studio beacons (Yang et al. 2007).

Consumes frames of the beacon sources (:mod:`engine.sources.beacons`): no image, the readings
in the frame's :class:`engine.sources.beacons.RangeReadings`. The beacons are unknown at
start (SLAM, particles of eq. 9 with Map Adjustment, eq. 12) or surveyed (``known_beacons``:
localisation only). The output is ``T_world_cam`` with the position (x, y, 0) and identity
rotation; ``details`` (:class:`BeaconDetails`) carries the particle cloud, the beacon map
with covariances and what was rejected.

The beacon ids come from the readings' ``layout`` (else their ``beacon_ids``, else the
first frame's readings); readings of other ids are ignored and counted
(``details.ignored_ids``). Frames without readings (live heartbeats) do not step the filter.
A change of ``known_beacons``/``quadrant_init``/``ring_hypotheses`` applies when a beacon is
next initialised (reset); every other parameter (particle count, sigmas, p, ``ring_commit``)
at the next step.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.beacons.filter import BeaconSlamFilter
from engine.beacons.params import BeaconFilterParams
from engine.frames import Frame
from engine.sources.beacons import RangeReadings
from engine.trackers.base import TrackDetails, TrackerSpec, TrackResult, TrackState

#: camera spread (sqrt of the covariance trace) above which the state is DEGRADED
DEGRADED_SPREAD_M = 2.0


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, slots=True)
class BeaconDetails(TrackDetails):
    """One filter step: camera estimate, particle cloud, beacon map, what was rejected."""

    step: int
    cam_xy: tuple[float, float]
    cam_cov: np.ndarray  # (2, 2)
    particles_xy: np.ndarray  # (M, 2)
    beacon_ids: tuple[str, ...]
    beacons_xy: np.ndarray  # (B, 2), NaN before a beacon is initialised
    beacons_cov: np.ndarray  # (B, 2, 2)
    ess: float
    n_particles: int
    used_ids: tuple[str, ...]
    outlier_ids: tuple[str, ...]
    ignored_ids: tuple[str, ...]
    input_stats: Mapping[str, object] | None = None


class BeaconSlamTracker:
    """Adapter from frames of range readings to :class:`BeaconSlamFilter`."""

    name = "beacon-slam"

    def __init__(self, params: BeaconFilterParams | None = None) -> None:
        self._params = params or BeaconFilterParams()
        self.reset()

    @property
    def params(self) -> BeaconFilterParams:
        return self._params

    def set_params(self, params: BeaconFilterParams) -> None:
        self._params = params
        if self.filter is not None:
            self.filter.set_params(params)

    def reset(self) -> None:
        self.filter: BeaconSlamFilter | None = None
        self._last: TrackResult | None = None
        self._ignored: set[str] = set()

    def _make_filter(self, readings: RangeReadings, ranges: dict[str, float]
                     ) -> BeaconSlamFilter:
        layout = readings.layout
        if layout:
            ids = list(layout)
        elif readings.beacon_ids:
            ids = list(readings.beacon_ids)
        else:
            ids = sorted(ranges)
        return BeaconSlamFilter(ids, self._params, layout_xy=layout or None)

    def track(self, frame: Frame) -> TrackResult:
        t0 = time.perf_counter()
        readings = frame.payload(RangeReadings)
        ranges = dict(readings.ranges) if readings is not None else {}
        if not ranges or readings is None:
            if self._last is not None:
                return self._last
            return TrackResult(state=TrackState.INITIALIZING, message="no readings yet")
        if self.filter is None:
            self.filter = self._make_filter(readings, ranges)
        f = self.filter
        self._ignored.update(k for k in ranges if k not in f.ids)
        r = np.array([ranges.get(i, math.nan) for i in f.ids], dtype=np.float64)
        est = f.step(r)
        t1 = time.perf_counter()
        n_used = int(np.count_nonzero(est.used))
        spread = float(math.sqrt(max(np.trace(est.cam_cov), 0.0)))
        if est.step <= 0:  # -1: no valid reading yet, 0: the initialisation step
            state = TrackState.INITIALIZING
        elif n_used < 2 or spread > DEGRADED_SPREAD_M:
            state = TrackState.DEGRADED
        else:
            state = TrackState.TRACKING
        T = np.eye(4)
        T[0, 3], T[1, 3] = float(est.cam_xy[0]), float(est.cam_xy[1])
        n_read = int(np.count_nonzero(np.isfinite(r)))
        details = BeaconDetails(
            step=est.step,
            cam_xy=(float(est.cam_xy[0]), float(est.cam_xy[1])),
            cam_cov=_ro(est.cam_cov),
            particles_xy=_ro(f.cam),
            beacon_ids=tuple(f.ids),
            beacons_xy=_ro(est.beacons_xy),
            beacons_cov=_ro(est.beacons_cov),
            ess=float(est.ess),
            n_particles=int(f.n_particles),
            used_ids=tuple(i for i, u in zip(f.ids, est.used, strict=True) if u),
            outlier_ids=tuple(i for i, o in zip(f.ids, est.outliers, strict=True) if o),
            ignored_ids=tuple(sorted(self._ignored)),
            input_stats=readings.input_stats,
        )
        res = TrackResult(
            state=state,
            T_world_cam=T,
            residual=None if math.isnan(est.residual_rms_m) else est.residual_rms_m,
            inlier_fraction=(n_used / n_read) if n_read and est.step > 0 else None,
            timings_ms={"filter": (t1 - t0) * 1000.0},
            details=details,
            message=(f"{n_used} beacon(s) in use, camera spread {spread:.2f} m" if state is
                     TrackState.DEGRADED else ""),
        )
        self._last = res
        return res


def _add_cli_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("beacon-slam")
    g.add_argument("--beacon-particles", type=int, default=None, help="particle count M")
    g.add_argument("--beacon-motion-sigma", type=float, default=None, help="motion std (m/step)")
    g.add_argument("--beacon-range-sigma", type=float, default=None, help="range std (m)")
    g.add_argument("--beacon-p", type=float, default=None, help="Map Adjustment gain p (eq. 12)")
    g.add_argument("--beacon-no-ma", action="store_true", help="disable Map Adjustment")
    g.add_argument("--beacon-known", action="store_true", help="beacons surveyed (layout = map)")
    g.add_argument("--beacon-seed", type=int, default=None, help="filter seed")


def _params_from_cli(args: argparse.Namespace, params: BeaconFilterParams) -> BeaconFilterParams:
    kw: dict[str, Any] = {}
    for opt, name in (("beacon_particles", "n_particles"), ("beacon_motion_sigma",
                      "motion_sigma_m"), ("beacon_range_sigma", "range_sigma_m"),
                      ("beacon_p", "map_adjust_p"), ("beacon_seed", "seed")):
        v = getattr(args, opt, None)
        if v is not None:
            kw[name] = v
    if getattr(args, "beacon_no_ma", False):
        kw["map_adjustment"] = False
    if getattr(args, "beacon_known", False):
        kw["known_beacons"] = True
    return dataclasses.replace(params, **kw) if kw else params


TRACKERS = (
    TrackerSpec(
        name="beacon-slam",
        description="2D camera position from ranges to studio beacons: particle-filter SLAM "
        "with Map Adjustment (Yang 2007), or localisation with surveyed beacons",
        params_cls=BeaconFilterParams,
        factory=BeaconSlamTracker,
        needs_depth=False,
        needs_image=False,
        output="position2d",
        add_cli_arguments=_add_cli_arguments,
        params_from_cli=_params_from_cli,
    ),
)
