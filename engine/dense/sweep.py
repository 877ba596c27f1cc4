"""Building a keyframe store from a sweep of the empty studio (Tykkälä 2014 sec. 6.1).

The camera sweeps the static scene; it is tracked with the keyframe tracker in online mode
(Algorithms 2 and 3 alternating: track against the nearest keyframe, add the current frame as
a keyframe when it is farther than ``kf_add_dist_m`` / ``kf_add_angle_deg`` from every
existing one). The keyframes and their poses are the store.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass

from engine.dense.keyframes import KeyframeStore
from engine.errors import TrackerError
from engine.sources.base import Source
from engine.trackers.dense import DenseParams


@dataclass(frozen=True, slots=True)
class SweepResult:
    store: KeyframeStore
    frames: int
    lost_frames: int
    seconds: float


def sweep(
    source: Source,
    params: DenseParams | None = None,
    *,
    max_frames: int | None = None,
    progress: Callable[[int, int, int], None] | None = None,
    should_stop: Callable[[], bool] = lambda: False,
) -> SweepResult:
    """Track ``source`` and keep keyframes; ``progress(frame_index, keyframes, lost)``."""
    from engine.dense.tracking import DenseKeyframeTracker

    p = dataclasses.replace(params or DenseParams(), keyframes_dir="")
    tracker = DenseKeyframeTracker(p)
    t0 = time.perf_counter()
    n = lost = 0
    for frame in source.frames():
        if should_stop() or (max_frames is not None and n >= max_frames):
            break
        res = tracker.track(frame)
        n += 1
        if not res.state.is_good:
            lost += 1
        if progress is not None:
            store = tracker.store
            progress(frame.index, len(store) if store is not None else 0, lost)
    store = tracker.store
    if store is None or len(store) == 0:
        raise TrackerError(f"sweep of {source.name}: no frames with depth, no keyframes")
    return SweepResult(store, n, lost, time.perf_counter() - t0)
