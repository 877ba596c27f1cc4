"""Dense RGB-D camera trackers after Tykkälä et al. 2014.

- ``dense-incremental``: Algorithm 2, tracking against a recent reference frame that is
  replaced when the camera has moved far enough from it.
- ``dense``: Algorithm 3, tracking against the nearest keyframe of a keyframe store
  (``--keyframes DIR``, built by ``studiotrack sweep``); without a store it builds its
  keyframes online (the paper's sec. 6.1 alternation of Algorithms 2 and 3).

The implementation lives in :mod:`engine.dense` and is imported when a tracker is built, so
that tracker discovery stays fast.

Beyond the paper (each a parameter): the median of eq. (9) is taken over the points the depth
test of eq. (12) keeps (a presenter does not inflate the Tukey scale); a global brightness
offset (auto exposure) is removed once per pyramid level (``brightness_offset``); reference
points are moved by the camera motion between the depth and colour timestamps when a source
gives both (``compensate_depth_delay``, TUM); points on depth discontinuities are not selected.
Off by default (measured on TUM fr1_xyz and the studio rail without a clear gain, see
``studiotrack bench dense``): an affine brightness model (``brightness_gain``), a per-level
convergence stop (``convergence_step``, the counts become caps) and a point-to-plane depth
residual added to the photometric cost (``geometric_weight``, as in the authors' follow-up
"direct ICP"; the current depth is moved to the colour instant like the reference points).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

from engine.errors import ParamsError
from engine.trackers.base import Tracker, TrackerSpec


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
    convergence_step: float = field(
        default=0.0,
        metadata={"help": "stop a level's iterations when the update |x| falls below this "
                  "(the iteration counts are then a cap); 0: fixed counts (the paper)",
                  "min": 0.0, "max": 0.01, "step": 1e-5},
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
                  "colour timestamps (frame.extras['depth_timestamp_s'], e.g. TUM)"},
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


def _make_incremental(params: DenseParams) -> Tracker:
    from engine.dense.tracking import DenseIncrementalTracker

    return DenseIncrementalTracker(params)


def _make_keyframe(params: DenseParams) -> Tracker:
    from engine.dense.tracking import DenseKeyframeTracker

    return DenseKeyframeTracker(params)


def _add_cli(parser: argparse.ArgumentParser) -> None:
    """Options of both dense trackers; idempotent, as the CLI may call it once per tracker."""
    if "--keyframes" in parser._option_string_actions:
        return
    g = parser.add_argument_group("dense trackers")
    g.add_argument("--points", type=int, default=None, help="reference points (default 8192)")
    g.add_argument(
        "--iterations", default=None, metavar="C,M,F",
        help="Gauss-Newton iterations coarse,mid,fine (default 2,3,10)",
    )
    g.add_argument("--tau", type=float, default=None, help="depth noise tau in metres")
    g.add_argument(
        "--keyframes", default=None, metavar="DIR",
        help="keyframe store built by `studiotrack sweep` (tracker dense)",
    )


def _params_from_cli(args: argparse.Namespace, params: Any) -> Any:
    upd: dict[str, Any] = {}
    if getattr(args, "points", None) is not None:
        upd["n_points"] = args.points
    its = getattr(args, "iterations", None)
    if its:
        try:
            c, m, f = (int(s) for s in str(its).split(","))
        except ValueError:
            raise ParamsError(f"--iterations {its!r}: expected three integers C,M,F") from None
        upd.update(iterations_coarse=c, iterations_mid=m, iterations_fine=f)
    if getattr(args, "tau", None) is not None:
        upd["tau_m"] = args.tau
    if getattr(args, "keyframes", None):
        upd["keyframes_dir"] = str(args.keyframes)
    return dataclasses.replace(params, **upd) if upd else params


TRACKERS = (
    TrackerSpec(
        name="dense-incremental",
        description="Dense RGB-D photometric tracking against a recent reference frame "
        "(Tykkälä 2014, Algorithm 2): fast, drifts slowly",
        params_cls=DenseParams,
        factory=_make_incremental,
        needs_depth=True,
        output="pose",
        add_cli_arguments=_add_cli,
        params_from_cli=_params_from_cli,
    ),
    TrackerSpec(
        name="dense",
        description="Dense RGB-D keyframe tracking (Tykkälä 2014, Algorithm 3): driftless "
        "against a keyframe store (--keyframes DIR), ignores moving presenters",
        params_cls=DenseParams,
        factory=_make_keyframe,
        needs_depth=True,
        output="pose",
        add_cli_arguments=_add_cli,
        params_from_cli=_params_from_cli,
    ),
)
