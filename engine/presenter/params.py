"""Operator parameters of the presenter tracker: all tunable live (applied on the next frame)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

from engine.errors import ParamsError


def _f(default: object, help: str, lo: float | None = None, hi: float | None = None,
       step: float | None = None) -> object:
    meta: dict[str, object] = {"help": help}
    if lo is not None:
        meta["min"] = lo
    if hi is not None:
        meta["max"] = hi
    if step is not None:
        meta["step"] = step
    return field(default=default, metadata=meta)


@dataclass(frozen=True, slots=True)
class PresenterParams:
    """Multi-patch colour + motion particle filter (VR-TV paper, Sec. III-C)."""

    n_particles: int = _f(100, "particles while tracking (paper: 100)", 10, 5000, 10)  # type: ignore[assignment]
    sigma_x_frac: float = _f(0.04, "prediction noise std in x per frame, fraction of the model "
                             "height (eq. 1 covariance)", 0.0, 1.0, 0.005)  # type: ignore[assignment]
    sigma_y_frac: float = _f(0.03, "prediction noise std in y per frame, fraction of the model "
                             "height (eq. 1)", 0.0, 1.0, 0.005)  # type: ignore[assignment]
    sigma_min_px: float = _f(3.0, "lower bound of the x/y prediction noise std (px): small "
                             "targets still move whole pixels", 0.0, 100.0, 0.5)  # type: ignore[assignment]
    velocity_gain: float = _f(0.5, "drift of the prediction: this fraction of the estimate's "
                              "smoothed velocity is added to eq. (1)'s random walk (0 = the "
                              "paper's pure random walk)", 0.0, 1.0, 0.05)  # type: ignore[assignment]
    fit_width: bool = _f(True, "output box width (and centre) from the foreground/background "
                         "colour extent around the estimate, for a full-body model (first "
                         "box at least 2x as tall as wide: a stride or arm swing widens it; a "
                         "head or face box keeps its aspect); off = always the model's fixed "
                         "aspect ratio")  # type: ignore[assignment]
    grey_world: bool = _f(True, "grey-world colour balance of each frame before the "
                          "histograms (for auto-white-balancing cameras)")  # type: ignore[assignment]
    sigma_h_frac: float = _f(0.0, "prediction noise std of the scale h per frame, fraction of "
                             "h (eq. 1); 0 keeps the size fixed (a presenter walking parallel "
                             "to the set; HS histograms barely constrain scale, so a free h "
                             "drifts and drags y with it)", 0.0, 0.5, 0.005)  # type: ignore[assignment]
    lambda_col: float = _f(0.15, "colour likelihood covariance lambda_col (eq. 3)",
                           0.001, 10.0, 0.01)  # type: ignore[assignment]
    lambda_mot: float = _f(2.0, "motion likelihood covariance lambda_mot (eq. 4)",
                           0.01, 100.0, 0.1)  # type: ignore[assignment]
    use_motion: bool = _f(True, "fuse the motion-history likelihood (eq. 4-5)")  # type: ignore[assignment]
    motion_threshold: int = _f(20, "grey-level change that counts as motion", 1, 255, 1)  # type: ignore[assignment]
    mhi_duration_frames: int = _f(8, "frames a motion pixel stays in the motion history image",
                                  1, 255, 1)  # type: ignore[assignment]
    loss_percent: float = _f(0.1, "loss when P(z_col|s) < Pmin = this % of Pref (with "
                             "lambda_col 0.15: sum B^2 worse than the reference by 1.04)",
                             0.0, 100.0, 0.01)  # type: ignore[assignment]
    pref_adapt_ratio: float = _f(0.6, "Pref adapts only while P >= this fraction of Pref",
                                 0.0, 1.0, 0.05)  # type: ignore[assignment]
    pref_adapt_rate: float = _f(0.02, "Pref adaptation rate per frame (slow)", 0.0, 1.0, 0.005)  # type: ignore[assignment]
    pref_init_frames: int = _f(10, "Pref starts as the median P(z_col|s) of this many frames "
                               "after the first (the first frame matches its own model "
                               "exactly, an optimistic reference); no loss test meanwhile",
                               0, 100, 1)  # type: ignore[assignment]
    loss_frames: int = _f(2, "consecutive frames below Pmin before LOST is declared",
                          1, 5, 1)  # type: ignore[assignment]
    model_update_rate: float = _f(0.05, "slow model update: per frame, the adapted patch "
                                  "histograms move this fraction towards the ones at the "
                                  "estimate (0 = the paper's fixed model)", 0.0, 1.0, 0.01)  # type: ignore[assignment]
    model_update_ratio: float = _f(0.3, "update the model only while P(z_col|s) >= this "
                                   "fraction of Pref (guard against drift)", 0.0, 1.0, 0.05)  # type: ignore[assignment]
    model_anchor: float = _f(0.2, "weight of the first frame's histograms in the reference "
                             "(the rest is the adapted model): the anchor limits drift",
                             0.0, 1.0, 0.05)  # type: ignore[assignment]
    bg_weighting: float = _f(0.25, "background-weighted reference (corrected BWH, Ning et al. "
                             "2012, after Comaniciu et al. 2003): reference bins are scaled "
                             "by min(1, o*/o_b)^this, o = colours of a ring around the first "
                             "box (3x its area; measured on the first frame, so turning it on "
                             "takes effect after a reset); 0 = off", 0.0, 1.0, 0.05)  # type: ignore[assignment]
    reinit_particles: int = _f(600, "particles of the diffuse prior while re-acquiring",
                               10, 20000, 50)  # type: ignore[assignment]
    reacquire_frames: int = _f(2, "consecutive frames above Pmin before the lock is declared",
                               1, 30, 1)  # type: ignore[assignment]
    jitter_cutoff_hz: float = _f(0.5, "jitter low-pass cut-off (Hz); 0 = off. Lag behind a "
                                 "walking presenter: 2(1-a)/a frames (see jitter.py)",
                                 0.0, 30.0, 0.1)  # type: ignore[assignment]
    frame_rate_hz: float = _f(0.0, "frame rate for the jitter filter; 0 = the source's",
                              0.0, 1000.0, 1.0)  # type: ignore[assignment]
    n_bins: int = _f(10, "histogram bins per axis N (paper: 10)", 2, 32, 1)  # type: ignore[assignment]
    max_cells: int = _f(64, "integral-histogram grid cells per side (cost bound)", 8, 512, 8)  # type: ignore[assignment]
    auto_patches: int = _f(3, "patches split from a first-frame box (2, 3 or 4)", 2, 4, 1)  # type: ignore[assignment]
    use_part_boxes: bool = _f(True, "first-frame patches from the source's per-part boxes "
                              "(built-in studio) instead of the automatic split")  # type: ignore[assignment]
    model_path: str = _f("", "saved model folder (model.json); empty = first frame's box")  # type: ignore[assignment]
    # framing / robot control (Sec. III-D)
    target_x_frac: float = _f(0.5, "framing target x* as a fraction of the image width",
                              0.0, 1.0, 0.01)  # type: ignore[assignment]
    target_y_frac: float = _f(0.5, "framing target y* as a fraction of the image height",
                              0.0, 1.0, 0.01)  # type: ignore[assignment]
    target_d_m: float = _f(3.0, "target depth d* (m) from the robot", 0.0, 100.0, 0.1)  # type: ignore[assignment]
    control_gain: float = _f(1.0, "proportional gain: velocity command = gain x error (1/s)",
                             0.0, 100.0, 0.1)  # type: ignore[assignment]
    max_speed_px_s: float = _f(200.0, "velocity limit of the image-axis commands (px/s)",
                               0.0, 10000.0, 10.0)  # type: ignore[assignment]
    max_accel_px_s2: float = _f(400.0, "acceleration limit of the image-axis commands (px/s^2)",
                                0.0, 100000.0, 10.0)  # type: ignore[assignment]
    max_speed_m_s: float = _f(0.5, "velocity limit of the depth command (m/s)", 0.0, 10.0, 0.05)  # type: ignore[assignment]
    max_accel_m_s2: float = _f(1.0, "acceleration limit of the depth command (m/s^2)",
                               0.0, 100.0, 0.05)  # type: ignore[assignment]
    control_udp: bool = _f(False, "send the control message over UDP")  # type: ignore[assignment]
    control_host: str = _f("127.0.0.1", "control message destination host")  # type: ignore[assignment]
    control_port: int = _f(9870, "control message destination UDP port", 1, 65535, 1)  # type: ignore[assignment]
    seed: int = _f(0, "random seed of the particle filter", 0, 2**31 - 1, 1)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, (bool, str)):
                continue
            if isinstance(v, float) and not math.isfinite(v):
                raise ParamsError(f"presenter.{f.name} must be finite, got {v}")
            lo, hi = f.metadata.get("min"), f.metadata.get("max")
            if lo is not None and v < lo:
                raise ParamsError(f"presenter.{f.name} must be >= {lo}, got {v}")
            if hi is not None and v > hi:
                raise ParamsError(f"presenter.{f.name} must be <= {hi}, got {v}")
        if self.auto_patches not in (2, 3, 4):
            raise ParamsError(f"presenter.auto_patches must be 2, 3 or 4, got {self.auto_patches}")
        if not self.control_host.strip():
            raise ParamsError("presenter.control_host must not be empty")
