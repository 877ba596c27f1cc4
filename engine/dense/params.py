"""Parameters of the dense RGB-D trackers (Tykkälä 2014): one frozen group, units in the names.

Used by the algorithm (:mod:`engine.dense.tracking`) and by its tracker adapter
(:mod:`engine.trackers.dense`, which registers ``dense`` and ``dense-incremental``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from engine.errors import ParamsError


@dataclass(frozen=True, slots=True)
class DenseParams:
    """Parameters of the dense trackers (one group; units in the names)."""

    n_points: int = field(
        default=8192,
        metadata={"help": "reference points selected by gradient (sec. 4.5)", "min": 256,
                  "max": 76800, "step": 1024},
    )
    iterations_coarse: int = field(
        default=2, metadata={"help": "Gauss-Newton iterations at 80x60", "min": 0, "max": 50}
    )
    iterations_mid: int = field(
        default=3, metadata={"help": "Gauss-Newton iterations at 160x120", "min": 0, "max": 50}
    )
    iterations_fine: int = field(
        default=10, metadata={"help": "Gauss-Newton iterations at 320x240", "min": 1, "max": 50}
    )
    tau_m: float = field(
        default=0.05,
        metadata={"help": "depth noise tau of eq. (12): larger depth differences get zero "
                  "weight (foreground rejection)", "min": 0.005, "max": 1.0, "step": 0.005},
    )
    min_residual_scale: float = field(
        default=0.0,
        metadata={"help": "noise floor (grey levels) of the median in eq. (9): keeps "
                  "high-gradient points in on nearly noise-free images", "min": 0.0,
                  "max": 50.0, "step": 0.5},
    )
    brightness_offset: bool = field(
        default=True,
        metadata={"help": "remove a global brightness offset (auto exposure) each iteration; "
                  "not in the paper (fixed studio lighting)"},
    )
    max_brightness_offset: float = field(
        default=25.0,
        metadata={"help": "LOST when the removed brightness offset exceeds this (grey levels)",
                  "min": 1.0, "max": 255.0},
    )
    brightness_gain: bool = field(
        default=False,
        metadata={"help": "affine brightness model (gain and offset, robust fit once per "
                  "level) instead of the offset alone; needs brightness_offset"},
    )
    stop_px: float = field(
        default=0.0,
        metadata={"help": "stop a level's iterations once an update moves the image by less "
                  "than this many pixels of that level (the counts become caps); 0: fixed "
                  "counts (the paper)", "min": 0.0, "max": 1.0, "step": 0.005},
    )
    coarse_point_fraction: float = field(
        default=1.0,
        metadata={"help": "share of the points used at 160x120 (half of it at 80x60); 1: all "
                  "points at every level (the paper)", "min": 0.05, "max": 1.0, "step": 0.05},
    )
    geometric_weight: float = field(
        default=0.0,
        metadata={"help": "weight of a point-to-plane depth residual (ICP-like) added to the "
                  "photometric cost, each in units of its robust scale; 0: photometric only "
                  "(the paper)", "min": 0.0, "max": 10.0, "step": 0.1},
    )
    use_depth_weights: bool = field(
        default=True, metadata={"help": "apply the depth-consistency weights of eq. (11)-(12)"}
    )
    min_depth_m: float = field(
        default=0.3, metadata={"help": "nearest usable depth", "min": 0.1, "max": 5.0}
    )
    max_depth_m: float = field(
        default=8.0, metadata={"help": "farthest usable depth", "min": 0.5, "max": 20.0}
    )
    min_inlier_fraction: float = field(
        default=0.3,
        metadata={"help": "LOST below this fraction of points with weight > 0.1", "min": 0.0,
                  "max": 1.0, "step": 0.05},
    )
    max_median_residual: float = field(
        default=40.0,
        metadata={"help": "LOST above this median |intensity residual| (grey levels)",
                  "min": 1.0, "max": 255.0},
    )
    residual_ratio: float = field(
        default=5.0,
        metadata={"help": "LOST above this multiple of the sequence's typical residual "
                  "(never below 4 grey levels)", "min": 1.5, "max": 100.0},
    )
    motion_model: bool = field(
        default=False,
        metadata={"help": "constant-velocity initial guess (the output is never "
                  "extrapolated)"},
    )
    max_step_m: float = field(
        default=0.2, metadata={"help": "divergence: largest plausible move per frame",
                               "min": 0.01, "max": 5.0}
    )
    max_step_deg: float = field(
        default=15.0, metadata={"help": "divergence: largest plausible turn per frame",
                                "min": 0.5, "max": 180.0}
    )
    relock_confirm_frames: int = field(
        default=2, metadata={"help": "good frames (RELOCALIZING) before TRACKING again",
                             "min": 0, "max": 30}
    )
    relocalize_candidates: int = field(
        default=3, metadata={"help": "nearest keyframes tried per frame while lost",
                             "min": 1, "max": 50}
    )
    ref_update_dist_m: float = field(
        default=0.05, metadata={"help": "incremental: new reference after this translation",
                                "min": 0.0, "max": 2.0, "step": 0.01}
    )
    ref_update_angle_deg: float = field(
        default=5.0, metadata={"help": "incremental: new reference after this rotation",
                               "min": 0.0, "max": 90.0}
    )
    ref_update_inlier_fraction: float = field(
        default=0.6, metadata={"help": "incremental: new reference when inliers fall below",
                               "min": 0.0, "max": 1.0, "step": 0.05}
    )
    keyframes_dir: str = field(
        default="", metadata={"help": "keyframe store folder (dense); empty: build online"}
    )
    theta_max_deg: float = field(
        default=30.0, metadata={"help": "keyframe pre-selection angle, eq. (20)",
                                "min": 1.0, "max": 180.0}
    )
    d_max_m: float = field(
        default=1.0, metadata={"help": "keyframe pre-selection distance, eq. (20)",
                               "min": 0.05, "max": 20.0}
    )
    kf_add_dist_m: float = field(
        default=0.15, metadata={"help": "online/sweep: add a keyframe this far from all others",
                                "min": 0.01, "max": 5.0, "step": 0.01}
    )
    kf_add_angle_deg: float = field(
        default=10.0, metadata={"help": "online/sweep: ...or turned this much from all others",
                                "min": 0.5, "max": 180.0}
    )
    compensate_depth_delay: bool = field(
        default=True,
        metadata={"help": "move reference points by the camera motion between the depth and "
                  "colour timestamps (Frame.depth_timestamp_s, e.g. TUM)"},
    )
    anchor_to_ground_truth: bool = field(
        default=True,
        metadata={"help": "start at the first frame's known pose (studio start mark) "
                  "instead of the identity"},
    )

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, int | float):
                continue
            if not math.isfinite(v):
                raise ParamsError(f"{f.name} must be finite, got {v}")
            lo, hi = f.metadata.get("min"), f.metadata.get("max")
            if lo is not None and v < lo:
                raise ParamsError(f"{f.name} must be >= {lo}, got {v}")
            if hi is not None and v > hi:
                raise ParamsError(f"{f.name} must be <= {hi}, got {v}")
        if self.min_depth_m >= self.max_depth_m:
            raise ParamsError(
                f"min_depth_m ({self.min_depth_m}) must be below max_depth_m ({self.max_depth_m})"
            )

    @property
    def iterations_fine_to_coarse(self) -> tuple[int, int, int]:
        return (self.iterations_fine, self.iterations_mid, self.iterations_coarse)

    @property
    def level_fraction_fine_to_coarse(self) -> tuple[float, float, float]:
        f = self.coarse_point_fraction
        return (1.0, f, 0.5 * f if f < 1.0 else 1.0)
