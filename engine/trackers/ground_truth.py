"""Ground-truth pass-through "tracker" for exercising outputs, recording and soak runs.

It reports the source's ``gt_T_world_cam`` (the built-in studio and TUM sequences have one)
as the tracked pose, so output, recording and soak measurements are not dominated by a real
tracker's cost. Frames without ground truth give LOST and hold the last pose, like any tracker.
It is not a tracker for a live studio (a live camera has no ground truth).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from engine.frames import Frame
from engine.params import Params
from engine.trackers.base import TrackerSpec, TrackResult, TrackState


@dataclass(frozen=True, slots=True)
class GroundTruthParams(Params):
    """No parameters: the pose is the source's ground truth."""


class GroundTruthTracker:
    name = "ground-truth"

    def __init__(self, params: GroundTruthParams) -> None:
        self._params = params
        self._last: np.ndarray | None = None

    @property
    def params(self) -> GroundTruthParams:
        return self._params

    def set_params(self, params: GroundTruthParams) -> None:
        self._params = params

    def reset(self) -> None:
        self._last = None

    def track(self, frame: Frame) -> TrackResult:
        t0 = time.perf_counter()
        gt = frame.gt_T_world_cam
        if gt is None or not np.all(np.isfinite(gt)):
            state = TrackState.LOST if self._last is not None else TrackState.INITIALIZING
            T = None if self._last is None else self._last.copy()
        else:
            self._last = np.array(gt, dtype=np.float64)
            state, T = TrackState.TRACKING, self._last.copy()
        return TrackResult(
            state=state, T_world_cam=T, residual=0.0, inlier_fraction=1.0,
            timings_ms={"total": (time.perf_counter() - t0) * 1000.0},
        )


TRACKERS = (
    TrackerSpec(
        name="ground-truth",
        description="passes the source's ground-truth pose through (built-in studio, TUM): "
        "for testing outputs, recording and soak runs, not for live use",
        params_cls=GroundTruthParams,
        factory=GroundTruthTracker,
        needs_image=False,
    ),
)
