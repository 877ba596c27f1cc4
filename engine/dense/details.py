"""Per-frame details of the dense trackers (``TrackResult.details``).

The numbers are those of the frame's own alignment attempt, also when the frame is LOST
(a covered lens shows the failing attempt's inliers, not the previous frame's). Fields that
do not apply to a frame are None (e.g. no alignment on the first frame).
"""

from __future__ import annotations

from dataclasses import dataclass

from engine.results import TrackDetails


@dataclass(frozen=True, slots=True)
class DenseDetails(TrackDetails):
    """One frame of the dense tracker (Tykkälä 2014): alignment quality and keyframe events."""

    rms_residual: float | None = None  # grey levels, of the accepted or failing attempt
    valid_fraction: float | None = None  # points that project into the image with depth
    iterations: int | None = None  # Gauss-Newton iterations run (all levels)
    n_points: int | None = None  # reference points selected
    keyframes: int | None = None  # keyframes in the store (keyframe tracker)
    keyframe_added: bool = False
    frames_to_relock: int | None = None  # set on the frame that relocked after a loss
    lost_reason: str = ""  # why the attempt was rejected (empty when good)
