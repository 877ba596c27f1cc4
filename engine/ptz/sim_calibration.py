"""The calibration chain run on ptz-sim views, as the operator runs it on a real camera.

:func:`calibrate_sim` uses only what the set-up tools see and what an operator knows: the
line-based distortion from views of a large board (sec. 3.3), the reference markers'
surveyed world positions, a rough guess of the camera (focal length and position, to tell
which marker is which), and DLTs from the marker images at a few commanded motor poses
(sec. 3.1), combined into the head geometry (:func:`engine.ptz.calibration.head_from_dlts`,
sec. 3.2). The simulator's head geometry, lens and angles are not read.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from engine.errors import CalibrationError
from engine.ptz.calibration import (
    DltPose,
    PtzCalibration,
    detect_markers,
    head_from_dlts,
    identify_markers,
)
from engine.ptz.distortion import estimate_radial_from_lines, propose_lines_chessboard
from engine.ptz.dlt import calibrate_dlt, outlier_mask
from engine.ptz.kinematics import PtzHead
from engine.ptz.sim import MARKER_BGR, PtzSimSource

#: motor poses (pan, tilt) of the DLT views
DLT_POSES = ((-20.0, -6.0), (0.0, -6.0), (20.0, -6.0), (0.0, -12.0))


def rough_guess(width: int, height: int, f_px: float = 750.0,
                centre_m: tuple[float, float, float] = (0.0, 0.1, 1.4)) -> PtzHead:
    """The operator's rough idea of the camera (to identify markers before the DLT)."""
    K = np.array([[f_px, 0, (width - 1) / 2], [0, f_px, (height - 1) / 2], [0, 0, 1.0]])
    return PtzHead(K=K, rotation_centre_world_m=np.asarray(centre_m, dtype=np.float64))


def calibrate_sim(src: PtzSimSource, poses: Sequence[tuple[float, float]] = DLT_POSES,
                  guess: PtzHead | None = None, noise_sigma: float = 2.0, seed: int = 11
                  ) -> tuple[PtzCalibration, dict[str, Any]]:
    """The chain's calibration from ``src``'s views (see the module docstring)."""
    if not len(src.markers):
        raise CalibrationError("ptz-sim calibration needs markers=1 (reference markers)")
    w, h = src.sc.width, src.sc.height
    rng = np.random.default_rng(seed)
    lines = []
    for img in src.lines_views():
        lines += propose_lines_chessboard(img, (15, 11))
    if len(lines) < 3:
        raise CalibrationError("line-based distortion: the board was not found")
    fit = estimate_radial_from_lines(lines, (w, h), n_terms=2)
    radial = fit.model
    guess = guess or rough_guess(w, h)
    decs, used, report_poses = [], [], []
    for pan, tilt in poses:
        img, _ = src.render(pan, tilt, ball=False)
        noisy = img.astype(np.float64) + rng.normal(0.0, noise_sigma, img.shape)
        img = np.clip(noisy + 0.5, 0, 255).astype(np.uint8)
        det = radial.undistort_px(detect_markers(img, MARKER_BGR))
        X, uv, _ = identify_markers(det, src.markers, guess.P(pan, tilt), 45.0)
        if len(X) < 8:
            continue
        try:
            res = calibrate_dlt(X, uv)
            bad = outlier_mask(res.residuals_px, 2.0)
            if bad.any() and (~bad).sum() >= 8:
                res = calibrate_dlt(X[~bad], uv[~bad])
        except CalibrationError:
            continue  # e.g. only one plane of markers in this view
        decs.append(res.decomposition)
        used.append((pan, tilt))
        report_poses.append(DltPose(pan, tilt, res.rmse_px, len(res.residuals_px)))
    if not decs:
        raise CalibrationError("no DLT view showed 8 identified reference markers")
    head = head_from_dlts(decs, used)
    cal = PtzCalibration(head=head, radial=radial, reference_points_world_m=src.markers.copy(),
                         marker_bgr=MARKER_BGR, dlt_poses=tuple(report_poses),
                         image_size=(w, h))
    report = {"lines": len(lines), "straightness_before_px": fit.rms_before_px,
              "straightness_after_px": fit.rms_after_px, "dlt_views": len(decs),
              "dlt_rmse_px": [p.rmse_px for p in report_poses]}
    return cal, report
