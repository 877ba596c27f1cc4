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
    # quality inputs of the DEGRADED state (engine.dense.tracking docstring)
    inlier_fraction_weights: float | None = None  # share of W > 0.1, the optimiser's scale
    residual_ratio: float | None = None  # median |residual| / the sequence's typical one
    keyframe_distance_px: float | None = None  # eq. (21): frame pose vs its keyframe's
    keyframe_in_range: bool | None = None  # within theta_max / d_max of eq. (20)
    degraded_reason: str = ""  # why DEGRADED (empty otherwise)
