"""Parameters of the dense RGB-D trackers (Tykkälä 2014): one frozen group, units in the names.

Used by the algorithm (:mod:`engine.dense.tracking`) and by its tracker adapter
(:mod:`engine.trackers.dense`, which registers ``dense`` and ``dense-incremental``).

The defaults go beyond the paper where measurements said so (``studiotrack bench dense``);
``preset=paper`` (``--param preset=paper``, the form's preset box) runs Algorithms 1-3 as
published: photometric cost only, fixed 2/3/10 iterations with every point at every level,
the Tukey scale of eq. (9) over all residuals, no brightness model, no depth-timing
compensation, gradient-only point selection.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from engine.params import Params, Preset, param


@dataclass(frozen=True, slots=True)
class DenseParams(Params):
    """Parameters of the dense trackers (one group; units in the names)."""

    # -- Algorithm 1 (sec. 3-4) -------------------------------------------------------------
    n_points: int = param(8192, lo=256, hi=76800, step=1024,
                          help="reference points selected by gradient (sec. 4.5)")
    iterations_coarse: int = param(2, lo=0, hi=50, help="Gauss-Newton iterations at 80x60")
    iterations_mid: int = param(3, lo=0, hi=50, help="Gauss-Newton iterations at 160x120")
    iterations_fine: int = param(10, lo=1, hi=50, help="Gauss-Newton iterations at 320x240")
    tau_m: float = param(0.05, lo=0.005, hi=1.0, step=0.005,
                         help="depth noise tau of eq. (12): larger depth differences get zero "
                         "weight (foreground rejection)")
    use_depth_weights: bool = param(True,
                                    help="apply the depth-consistency weights of eq. (11)-(12)")
    min_depth_m: float = param(0.3, lo=0.1, hi=5.0, help="nearest usable depth")
    max_depth_m: float = param(8.0, lo=0.5, hi=20.0, help="farthest usable depth")
    # -- beyond the paper -------------------------------------------------------------------
    scale_over_kept: bool = param(True,
                                  help="take the median of eq. (9) over the points the depth "
                                  "test of eq. (12) keeps (a presenter does not inflate the "
                                  "Tukey scale); off: over all residuals (the paper)")
    min_residual_scale: float = param(0.0, lo=0.0, hi=50.0, step=0.5,
                                      help="noise floor (grey levels) of the median in eq. (9): "
                                      "keeps high-gradient points in on nearly noise-free "
                                      "images")
    edge_depth_ratio: float = param(0.05, lo=0.0, hi=1.0, step=0.01,
                                    help="do not select points whose 5x5 neighbourhood spans "
                                    "more than this share of their depth (depth edges); 0: "
                                    "gradient-only selection (the paper)")
    brightness_offset: bool = param(True,
                                    help="remove a global brightness offset (auto exposure) "
                                    "once per level; not in the paper (fixed studio lighting)")
    max_brightness_offset: float = param(25.0, lo=1.0, hi=255.0,
                                         help="LOST when the removed brightness offset exceeds "
                                         "this (grey levels)")
    brightness_gain: bool = param(False,
                                  help="affine brightness model (gain and offset, robust fit "
                                  "once per level) instead of the offset alone; needs "
                                  "brightness_offset")
    stop_px: float = param(0.001, lo=0.0, hi=1.0, step=0.001,
                           help="stop a level's iterations once an update moves the image by "
                           "less than this many pixels of that level (the counts become caps); "
                           "0: fixed counts (the paper). The iteration converges linearly "
                           "(each update ~0.7 of the last): stopping leaves ~2x this, a bias "
                           "that the incremental tracker accumulates over reference updates "
                           "(0.005 doubled its rail drift, 0.001 leaves it as with fixed "
                           "counts); 12 iterations instead of 15 on the rail")
    coarse_point_fraction: float = param(0.5, lo=0.05, hi=1.0, step=0.05,
                                         help="share of the points used at 160x120 (half of it "
                                         "at 80x60); 1: all points at every level (the paper). "
                                         "0.25 tracked the same on TUM fr1_xyz and the rail but "
                                         "lost a fast pan at 320x240 that 0.5 follows")
    geometric_weight: float = param(2.0, lo=0.0, hi=10.0, step=0.1,
                                    help="weight of a point-to-plane depth residual (ICP-like) "
                                    "added to the photometric cost at the finest level, each in "
                                    "units of its robust scale (1: neither favoured); 0: "
                                    "photometric only (the paper). 2 from the built-in studio "
                                    "with Kinect-like noise (hand-held, pan: 2 and 3 better "
                                    "than 1, 5 and 10 worse; 3 broke RPE <= 8 mm/s on TUM "
                                    "fr1_xyz)")
    min_geometric_scale_m: float = param(1e-6, lo=1e-9, hi=0.01, step=1e-6,
                                         help="floor of the geometric term's robust scale "
                                         "(median |point-to-plane residual|), a guard "
                                         "against zero only, like the photometric one: a "
                                         "floor above the depth noise weights the geometric "
                                         "term below the photometric (1 mm: the noise-free "
                                         "studio rail drifted 8 mm in one cycle, 1.4 mm at "
                                         "1 um)")
    geometric_points: int = param(8192, lo=0, hi=76800, step=1024,
                                  help="points of the geometric term, spread over all valid "
                                  "depth (walls and floors too; as many as the photometric "
                                  "term by default); 0: the photometric points")
    geometric_noise_model: bool = param(True,
                                        help="each point-to-plane residual in units of its "
                                        "depth noise, sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2 m "
                                        "(Kinect v1, Nguyen 2012 eq. 3: far points are noisier, "
                                        "~z^2); off: every point alike")
    compensate_depth_delay: bool = param(True,
                                         help="move reference points by the camera motion "
                                         "between the depth and colour timestamps "
                                         "(Frame.depth_timestamp_s, e.g. TUM)")
    rolling_shutter: bool = param(True,
                                  help="model the colour camera's rolling shutter where its "
                                  "calibration gives a readout time (camera.json "
                                  "rolling_shutter_s): each point warped as seen by its row, "
                                  "the camera's velocity the motion from the previous frame to "
                                  "this frame's estimate; off: one instant per image (the "
                                  "paper)")
    threads: int = param(1, lo=1, hi=16,
                         help="threads sharing the point passes of each iteration (numba); 1: "
                         "the tracker's own thread only (steadiest on a busy machine)")
    # -- loss, relocalisation, motion model -------------------------------------------------
    min_inlier_fraction: float = param(0.15, lo=0.0, hi=1.0, step=0.05,
                                       help="LOST below this fraction of inliers (weight "
                                       "> 0.1 at the sequence's typical residual scale)")
    degraded_inlier_fraction: float = param(0.4, lo=0.0, hi=1.0, step=0.05,
                                            help="DEGRADED below this fraction of inliers "
                                            "(e.g. a large part of the view occluded)")
    degraded_residual_ratio: float = param(2.5, lo=1.0, hi=100.0, step=0.1,
                                           help="DEGRADED above this multiple of the "
                                           "sequence's typical median residual")
    max_median_residual: float = param(40.0, lo=1.0, hi=255.0,
                                       help="LOST above this median |intensity residual| (grey "
                                       "levels)")
    residual_ratio: float = param(5.0, lo=1.5, hi=100.0,
                                  help="LOST above this multiple of the sequence's typical "
                                  "residual (never below 4 grey levels)")
    motion_model: bool = param(False,
                               help="constant-velocity initial guess (the output is never "
                               "extrapolated)")
    max_step_m: float = param(0.2, lo=0.01, hi=5.0,
                              help="divergence: largest plausible move per frame")
    max_step_deg: float = param(15.0, lo=0.5, hi=180.0,
                                help="divergence: largest plausible turn per frame")
    relock_confirm_frames: int = param(2, lo=0, hi=30,
                                       help="good frames (RELOCALIZING) before TRACKING again")
    relocalize_candidates: int = param(3, lo=1, hi=50,
                                       help="nearest keyframes tried per frame while lost")
    # -- references and keyframes -----------------------------------------------------------
    ref_update_dist_m: float = param(0.05, lo=0.0, hi=2.0, step=0.01,
                                     help="incremental: new reference after this translation")
    ref_update_angle_deg: float = param(5.0, lo=0.0, hi=90.0,
                                        help="incremental: new reference after this rotation")
    ref_update_inlier_fraction: float = param(0.6, lo=0.0, hi=1.0, step=0.05,
                                              help="incremental: new reference when inliers "
                                              "fall below")
    keyframes_dir: str = param("", help="keyframe store folder (dense); empty: build online")
    max_resident_references: int = param(
        64, lo=1, hi=100000,
        help="keyframe references held in memory, about 1.2 MB each: a stored keyframe's that "
        "was used least recently is dropped and rebuilt from the store (about 20 ms) when the "
        "camera comes back; online keyframes are always held")
    theta_max_deg: float = param(30.0, lo=1.0, hi=180.0,
                                 help="keyframe pre-selection angle, eq. (20)")
    d_max_m: float = param(1.0, lo=0.05, hi=20.0, help="keyframe pre-selection distance, eq. (20)")
    kf_add_dist_m: float = param(0.15, lo=0.01, hi=5.0, step=0.01,
                                 help="online/sweep: add a keyframe this far from all others")
    kf_add_angle_deg: float = param(10.0, lo=0.5, hi=180.0,
                                    help="online/sweep: ...or turned this much from all others")
    anchor_to_ground_truth: bool = param(True,
                                         help="start at the first frame's known pose (studio "
                                         "start mark) instead of the identity")

    PRESETS: ClassVar[Mapping[str, Preset]] = {
        "paper": Preset(
            "Tykkälä 2014 as published: photometric cost (eq. 1) with the Tukey weights of "
            "eq. (9)-(10) (scale over all residuals) times the depth weights of eq. (11)-(12), "
            "fixed 2/3/10 iterations with all 8192 points at every level (sec. 4.9), "
            "gradient-only point selection (eq. 14-15), no brightness model, no depth-timing "
            "compensation, no motion model (the last pose is the guess: Alg. 2-3). The paper "
            "gives no value for: the depth noise tau of eq. (12) (0.05 m kept), the keyframe "
            "pre-selection thresholds of eq. (20) ('user defined': 30 deg, 1 m kept), when a "
            "sweep adds a keyframe (0.15 m / 10 deg kept), when the incremental reference is "
            "updated ('if reference update signaled': 5 cm / 5 deg / 60 % inliers kept), the "
            "usable depth range (0.3-8 m kept). Loss detection and relocalisation are ours "
            "and kept (the paper avoids the need, sec. 7.3)",
            n_points=8192, iterations_coarse=2, iterations_mid=3, iterations_fine=10,
            scale_over_kept=False, min_residual_scale=0.0, edge_depth_ratio=0.0,
            brightness_offset=False, brightness_gain=False, stop_px=0.0,
            coarse_point_fraction=1.0, geometric_weight=0.0, geometric_noise_model=False,
            compensate_depth_delay=False, rolling_shutter=False,
            motion_model=False,
        ),
    }

    def validate(self) -> None:
        if self.min_depth_m >= self.max_depth_m:
            raise self.ERROR(
                f"DenseParams: min_depth_m ({self.min_depth_m}) must be below max_depth_m "
                f"({self.max_depth_m})"
            )

    @property
    def iterations_fine_to_coarse(self) -> tuple[int, int, int]:
        return (self.iterations_fine, self.iterations_mid, self.iterations_coarse)

    @property
    def level_fraction_fine_to_coarse(self) -> tuple[float, float, float]:
        f = self.coarse_point_fraction
        return (1.0, f, 0.5 * f if f < 1.0 else 1.0)
