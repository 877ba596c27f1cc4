"""Operator parameters of the presenter tracker: all tunable live (applied on the next frame)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from engine.params import Params, Preset, param

LOSS_TESTS = ("contrast", "likelihood")
LOSS_REFERENCES = ("first", "anchored")

#: the VR-TV paper's filter as published (Sec. III-C): a pure random walk in (x, y, h) (eq. 1;
#: the paper gives no covariances: the default x/y ones and a scale std of 1.5 % of h per
#: frame), the fixed reference model, eq. (3)-(5) without the ring term, the weighted mean
#: (eq. 6) as the output box, and the likelihood loss test: Pmin = 10 % of Pref, Pref the first
#: frame's maximum likelihood, adapted while P >= 60 % of it, LOST at the first frame below
#: Pmin ("declare a loss whenever P(z_col|s_t) decreases below" it). (The histograms keep
#: the N brightness bins of the paper's ref. [6] for grey pixels.)
PAPER_PRESET = Preset(
    "the VR-TV paper's filter as published: random walk in x, y, h, fixed model, "
    "Pmin = 10 % of Pref, LOST at the first frame below it",
    velocity_gain=0.0, sigma_h_frac=0.015, ring_weight=0.0, mode_seek=False, model_update_rate=0.0,
    bg_weighting=0.0, fit_width=False, grey_world=False, loss_test="likelihood", loss_motion=0.0,
    loss_percent=10.0, pref_init_frames=0, pref_adapt_ratio=0.6, n_particles=100,
    trajectory_share=0.0, lambda_col=0.1, reacquire_frames=1, loss_bg_weighting=1.0,
    floor_scale=False, floor_lean=False, depth_sigma_m=0.0, loss_frames=1,
    exposure_normalise=False)


@dataclass(frozen=True, slots=True)
class PresenterParams(Params):
    """Multi-patch colour + motion particle filter (VR-TV paper, Sec. III-C)."""

    n_particles: int = param(100, lo=10, hi=5000, step=10,
                             help="particles while tracking (paper: 100)")
    sigma_x_frac: float = param(0.04, lo=0.0, hi=1.0, step=0.005,
                                help="prediction noise std in x per frame, fraction of the model "
                                "height (eq. 1 covariance)")
    sigma_y_frac: float = param(0.03, lo=0.0, hi=1.0, step=0.005,
                                help="prediction noise std in y per frame, fraction of the model "
                                "height (eq. 1)")
    sigma_min_px: float = param(3.0, lo=0.0, hi=100.0, step=0.5,
                                help="lower bound of the x/y prediction noise std (px): small "
                                "targets still move whole pixels")
    velocity_gain: float = param(0.5, lo=0.0, hi=1.0, step=0.05,
                                 help="drift of the prediction: this fraction of the estimate's "
                                 "smoothed velocity is added to eq. (1)'s random walk (0 = the "
                                 "paper's pure random walk)")
    depth_sigma_m: float = param(0.15, lo=0.0, hi=5.0, step=0.05,
                                 help="RGB-D sources: each hypothesis' body depth must agree "
                                 "with the presenter's tracked depth within this std (m; "
                                 "engine.presenter.depth): a look-alike behind or in front "
                                 "of the presenter does not take the track; 0 = off (the "
                                 "paper: colour and motion only)")
    trajectory_share: float = param(0.0, lo=0.0, hi=0.5, step=0.05,
                                    help="identity by trajectory (engine.presenter."
                                    "trajectory): while the estimate moves faster than a "
                                    "person can change speed, this share of the particles is "
                                    "drawn where the presenter's last plausible motion leads "
                                    "(a look-alike crossing does not drag the track away); "
                                    "0 = off")
    fit_width: bool = param(True,
                            help="output box width (and centre) from the foreground/background "
                            "colour extent around the estimate, for a full-body model (first box "
                            "at least 2x as tall as wide: a stride or arm swing widens it; a "
                            "head or face box keeps its aspect); off = always the model's fixed "
                            "aspect ratio")
    fit_width_max_frac: float = param(1.6, lo=1.0, hi=4.0, step=0.1,
                                      help="widest fitted output box, in model widths (a "
                                      "stride and swinging arms; a same-coloured neighbour "
                                      "or set piece beside the presenter is cut off here)")
    grey_world: bool = param(True,
                             help="grey-world colour balance of each frame before the histograms "
                             "(for auto-white-balancing cameras)")
    exposure_normalise: bool = param(False,
                                     help="with grey_world: also bring each frame's mean grey "
                                     "to the reference image's (at most 4x either way), as a "
                                     "camera's auto-exposure would: lights coming up or going "
                                     "down during a shot (beyond the paper)")
    sigma_h_frac: float = param(0.005, lo=0.0, hi=0.5, step=0.005,
                                help="prediction noise std of the scale h per frame, fraction of "
                                "h (eq. 1; with the ring term, which keeps h from shrinking "
                                "into the person); 0 keeps the size fixed")
    mode_seek: bool = param(False, help="output the mean of the particles' dominant mode "
                            "(mean-shift from eq. 6's mean, kernel half a box wide) instead of "
                            "eq. (6)'s mean of all: with a second person in view the mean lies "
                            "between the two")
    ring_weight: float = param(1.0, lo=0.0, hi=10.0, step=0.1,
                               help="scale term beyond eq. (3): the colour likelihood is also "
                               "multiplied by exp(-this x BC_ring / lambda_col), BC_ring = the "
                               "Bhattacharyya coefficient of a ring around the box with the "
                               "target's colours (a box smaller than the person has the "
                               "person's colours around it); 0 = eq. (3) alone")
    ring_margin_frac: float = param(0.25, lo=0.05, hi=1.0, step=0.05,
                                    help="width of that ring on each side, fraction of the "
                                    "box's width and height")
    lambda_col: float = param(0.1, lo=0.001, hi=10.0, step=0.01,
                              help="colour likelihood covariance lambda_col (eq. 3)")
    lambda_mot: float = param(2.0, lo=0.01, hi=100.0, step=0.1,
                              help="motion likelihood covariance lambda_mot (eq. 4)")
    use_motion: bool = param(True, help="fuse the motion-history likelihood (eq. 4-5)")
    motion_threshold: int = param(20, lo=1, hi=255, step=1,
                                  help="grey-level change that counts as motion")
    mhi_duration_frames: int = param(8, lo=1, hi=255, step=1,
                                     help="frames a motion pixel stays in the motion history "
                                     "image")
    loss_test: str = param("contrast", choices=LOSS_TESTS,
                           help="loss test: 'contrast' = the patches' colour distance from the "
                           "anchored model, placed between the target's own level (first "
                           "tracked frames, then slowly adapted) and the level of the most "
                           "target-like tenth of this frame's background (z = 0 target, 1 "
                           "background); LOST while z > loss_contrast. 'likelihood' = the "
                           "paper's test, P(z_col|s) < loss_percent % of Pref")
    loss_contrast: float = param(0.5, lo=0.05, hi=2.0, step=0.05,
                                 help="contrast loss test: LOST while z > this (0.5 = half-way "
                                 "from the target's colour match to the background's)")
    loss_bg_quantile: float = param(0.1, lo=0.01, hi=0.9, step=0.05,
                                    help="contrast loss test: the background level is this "
                                    "quantile of the sampled background boxes' colour distance "
                                    "(0.1 = the most presenter-like tenth: the desk, a similar "
                                    "wall; 0.5 = typical background)")
    loss_reference: str = param("first", choices=LOSS_REFERENCES,
                                help="contrast loss test: the colours the patches are compared "
                                "with: 'first' = the first frame's patches, 'anchored' = the "
                                "tracking model (model_anchor x first + the rest adapted)")
    loss_bg_weighting: float = param(1.0, lo=0.0, hi=2.0, step=0.25,
                                     help="contrast loss test: its reference's bins scaled by "
                                     "min(1, o*/o_b)^this, o = colours of a ring around the "
                                     "first box (as bg_weighting): what the set around the "
                                     "presenter shows does not count as the presenter; 0 = off")
    loss_motion: float = param(0.2, lo=0.0, hi=1.0, step=0.05,
                               help="contrast loss test, motion cue (static camera): while "
                               "TRACKING, no LOST when the fraction of pixels under the "
                               "patches that moved in the last frames exceeds the most "
                               "moving tenth of the background boxes' by this much (the "
                               "presenter walking through light the first frame did not "
                               "show); a moving camera moves the background too and turns it "
                               "off by itself; 0 = off")
    loss_percent: float = param(0.1, lo=0.0, hi=100.0, step=0.01,
                                help="likelihood loss test: loss when P(z_col|s) < Pmin = this "
                                "% of Pref, i.e. sum B^2 worse than the reference by "
                                "lambda_col x ln(100 / this)")
    pref_adapt_ratio: float = param(0.6, lo=0.0, hi=1.0, step=0.05,
                                    help="Pref adapts only while P >= this fraction of Pref")
    pref_adapt_rate: float = param(0.02, lo=0.0, hi=1.0, step=0.005,
                                   help="Pref adaptation rate per frame (slow)")
    pref_init_frames: int = param(10, lo=0, hi=100, step=1,
                                  help="Pref starts as the median P(z_col|s) of this many frames "
                                  "after the first (the first frame matches its own model "
                                  "exactly, an optimistic reference); no loss test meanwhile")
    loss_frames: int = param(2, lo=1, hi=5, step=1,
                             help="consecutive frames below Pmin before LOST is declared")
    model_update_rate: float = param(0.05, lo=0.0, hi=1.0, step=0.01,
                                     help="slow model update: per frame, the adapted patch "
                                     "histograms move this fraction towards the ones at the "
                                     "estimate (0 = the paper's fixed model)")
    model_update_ratio: float = param(0.7, lo=0.0, hi=1.0, step=0.05,
                                      help="update the model only while confidently on "
                                      "the target (guard against drift): contrast test z < "
                                      "this x loss_contrast; likelihood test P(z_col|s) >= "
                                      "this x Pref")
    model_anchor: float = param(0.2, lo=0.0, hi=1.0, step=0.05,
                                help="weight of the first frame's histograms in the reference "
                                "(the rest is the adapted model): the anchor limits drift")
    bg_weighting: float = param(0.25, lo=0.0, hi=1.0, step=0.05,
                                help="background-weighted reference (corrected BWH, Ning et al. "
                                "2012, after Comaniciu et al. 2003): reference bins are scaled "
                                "by min(1, o*/o_b)^this, o = colours of a ring around the first "
                                "box (3x its area; measured on the first frame, so turning it on "
                                "takes effect after a reset); 0 = off")
    reinit_particles: int = param(600, lo=10, hi=20000, step=50,
                                  help="particles of the diffuse prior while re-acquiring")
    reacquire_frames: int = param(1, lo=1, hi=30, step=1,
                                  help="consecutive frames above Pmin before the lock is declared")
    jitter_cutoff_hz: float = param(0.5, lo=0.0, hi=30.0, step=0.1,
                                    help="jitter low-pass cut-off (Hz); 0 = off. Lag behind a "
                                    "walking presenter: 2(1-a)/a frames (see jitter.py)")
    frame_rate_hz: float = param(0.0, lo=0.0, hi=1000.0, step=1.0,
                                 help="frame rate for the jitter filter; 0 = the source's")
    n_bins: int = param(10, lo=2, hi=32, step=1, help="histogram bins per axis N (paper: 10)")
    max_cells: int = param(64, lo=8, hi=512, step=8,
                           help="integral-histogram grid cells per side (cost bound)")
    auto_patches: int = param(3, lo=2, hi=4, step=1,
                              help="patches split from a first-frame box (2, 3 or 4)")
    floor_scale: bool = param(True,
                              help="second view with a floor calibration: each hypothesis's "
                              "box height is that of a person as tall as the first box "
                              "standing where the box is (engine.presenter.twoview), instead "
                              "of eq. (1)'s random walk in h (which drifts and moves the foot "
                              "point: d off by the drift)")
    floor_lean: bool = param(True,
                             help="second view with a floor calibration: the patches move "
                             "across the box with the lean of a standing person there "
                             "(verticals converge on the nadir: a person at the image's left "
                             "edge leans left, at its right edge right) instead of keeping "
                             "the first frame's geometry (engine.presenter.twoview)")
    use_part_boxes: bool = param(True,
                                 help="first-frame patches from the source's per-part boxes "
                                 "(built-in studio) instead of the automatic split")
    model_path: str = param("", help="saved model folder (model.json); empty = first frame's box")
    floor_path: str = param("", help="floor calibration of the second view: a floor.json file "
                            "or a studio project folder; empty = the source's (built-in "
                            "studio)")
    # framing / robot control (Sec. III-D)
    target_x_frac: float = param(0.5, lo=0.0, hi=1.0, step=0.01,
                                 help="framing target x* as a fraction of the image width")
    target_y_frac: float = param(0.5, lo=0.0, hi=1.0, step=0.01,
                                 help="framing target y* as a fraction of the image height")
    target_d_m: float = param(3.0, lo=0.0, hi=100.0, step=0.1,
                              help="target depth d* (m) from the robot")
    control_gain: float = param(3.0, lo=0.0, hi=100.0, step=0.1,
                                help="proportional gain: velocity command = gain x error (1/s)")
    control_ki: float = param(2.0, lo=0.0, hi=100.0, step=0.1,
                              help="integral gain (1/s^2): removes the steady lag behind a "
                              "presenter walking at constant speed (0 = proportional only)")
    max_speed_px_s: float = param(400.0, lo=0.0, hi=10000.0, step=10.0,
                                  help="velocity limit of the image-axis commands (px/s)")
    max_accel_px_s2: float = param(800.0, lo=0.0, hi=100000.0, step=10.0,
                                   help="acceleration limit of the image-axis commands (px/s^2)")
    max_speed_m_s: float = param(0.5, lo=0.0, hi=10.0, step=0.05,
                                 help="velocity limit of the depth command (m/s)")
    max_accel_m_s2: float = param(1.0, lo=0.0, hi=100.0, step=0.05,
                                  help="acceleration limit of the depth command (m/s^2)")
    control_udp: bool = param(False, help="send the control message over UDP")
    control_host: str = param("127.0.0.1", help="control message destination host")
    control_port: int = param(9870, lo=1, hi=65535, step=1,
                              help="control message destination UDP port")
    seed: int = param(0, lo=0, hi=2**31 - 1, step=1, help="random seed of the particle filter")

    PRESETS: ClassVar[Mapping[str, Preset]] = {"paper": PAPER_PRESET}

    def validate(self) -> None:
        if not self.control_host.strip():
            raise self.ERROR("PresenterParams.control_host must not be empty")
