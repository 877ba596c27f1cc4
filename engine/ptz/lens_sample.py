"""Lens-file samples from the pan-tilt calibration tools (the DLT and the line-based model).

The studio project's pan-tilt calibration (:class:`engine.ptz.calibration.PtzCalibration`,
saved from the PTZ page or ``studiotrack calibrate dlt|lines``) holds the head's intrinsics
from a DLT (Gaspar 2009 sec. 3.1: alpha_u, alpha_v, u0, v0 read from P) and the line-based
inverse radial distortion (sec. 3.3). A lens file (:mod:`engine.lens`) stores the
Brown-Conrady terms of OpenCV instead, in normalised pinhole coordinates about the principal
point::

    x_d = x_u (1 + k1 r^2 + k2 r^4 + k3 r^6) + tangential (p1, p2),   r = |x_u|

:func:`brown_conrady_from_radial` converts one into the other by linear least squares over
a grid of distorted pixels covering the image (the inverse model gives each one's ideal
pixel); the fit's residual in pixels says how well the three terms reproduce the model (the
two models are centred on the distortion centre and on the principal point respectively).
:func:`lens_sample_from_ptz` makes the sample at the operator's encoders.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.errors import CalibrationError
from engine.lens import LensError, LensFile, LensSample
from engine.ptz.calibration import PtzCalibration
from engine.ptz.distortion import RadialModel

F64 = NDArray[np.float64]

#: grid of distorted pixels the conversion is fitted on (columns, rows), corners included
FIT_GRID = (33, 25)


@dataclass(frozen=True, slots=True)
class BrownFit:
    """Brown-Conrady terms fitted to an inverse radial model, and the fit's error."""

    k1: float
    k2: float
    k3: float
    p1: float
    p2: float
    rms_px: float  # distorted-pixel error of the Brown-Conrady terms over the grid
    max_px: float


def brown_conrady_from_radial(radial: RadialModel, K: F64, image_size: tuple[int, int]
                              ) -> BrownFit:
    """k1, k2, k3, p1, p2 reproducing ``radial`` for a camera ``K`` over the image (the
    tangential terms take up, to first order, a distortion centre off the principal point)."""
    w, h = image_size
    K = np.asarray(K, dtype=np.float64)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    if not (np.all(np.isfinite(K)) and fx > 0 and fy > 0):
        raise CalibrationError(f"lens sample: the camera matrix is not usable (fx {fx:g}, "
                               f"fy {fy:g})")
    gu, gv = np.meshgrid(np.linspace(0.0, w - 1.0, FIT_GRID[0]),
                         np.linspace(0.0, h - 1.0, FIT_GRID[1]))
    d_px = np.stack([gu.ravel(), gv.ravel()], axis=1)
    u_px = radial.undistort_px(d_px)  # sec. 3.3: distorted -> ideal
    if not np.all(np.isfinite(u_px)):
        raise CalibrationError("lens sample: the line-based model is not finite over the "
                               "image")
    scale = np.array([fx, fy])
    xu = (u_px - [cx, cy]) / scale
    xd = (d_px - [cx, cy]) / scale
    x, y = xu[:, 0], xu[:, 1]
    r2 = x * x + y * y
    radial_terms = np.stack([r2, r2**2, r2**3], axis=1)
    # OpenCV's model, linear in (k1, k2, k3, p1, p2), rows for x then y, in pixels:
    # x_d - x_u = x_u (k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2), y alike
    A = np.concatenate([
        fx * np.column_stack([x[:, None] * radial_terms, 2 * x * y, r2 + 2 * x * x]),
        fy * np.column_stack([y[:, None] * radial_terms, r2 + 2 * y * y, 2 * x * y])])
    b = np.concatenate([(xd - xu)[:, 0] * fx, (xd - xu)[:, 1] * fy])
    k, *_ = np.linalg.lstsq(A, b, rcond=None)
    err = (A @ k - b).reshape(2, -1)
    e = np.hypot(err[0], err[1])
    return BrownFit(float(k[0]), float(k[1]), float(k[2]), float(k[3]), float(k[4]),
                    float(np.sqrt(np.mean(e * e))), float(e.max()))


def lens_sample_from_ptz(cal: PtzCalibration | None, zoom_raw: int, focus_raw: int = 0, *,
                         lens: LensFile | None = None, entrance_pupil_m: float = 0.0
                         ) -> tuple[LensSample, dict[str, Any]]:
    """The lens sample at (``zoom_raw``, ``focus_raw``) from a pan-tilt calibration: focal
    length and principal point from its DLT head (or, with the lens lines only, from
    ``lens`` interpolated at these encoders), distortion from its line-based model (none
    without one); and a report (what was used, the conversion's error). Every problem is
    one line (:class:`engine.errors.CalibrationError`)."""
    if cal is None or (cal.head is None and cal.radial is None):
        raise CalibrationError("lens sample: the project has no pan-tilt calibration (on the "
                               "PTZ page solve a DLT and/or estimate the lens lines, and save "
                               "them to the project)")
    size = cal.image_size
    if size is None and lens is not None:
        size = (lens.width, lens.height)
    if size is None:
        raise CalibrationError("lens sample: the pan-tilt calibration has no image size (save "
                               "the head or the distortion to the project again)")
    if lens is not None and (lens.width, lens.height) != tuple(size):
        raise LensError(f"lens sample: the pan-tilt calibration is {size[0]}x{size[1]} px, "
                        f"the lens file is {lens.width}x{lens.height}")
    report: dict[str, Any] = {"image_size": [int(size[0]), int(size[1])]}
    if cal.head is not None:
        K = np.asarray(cal.head.K, dtype=np.float64)
        report["intrinsics_from"] = "DLT"
        poses = cal.dlt_poses
        rms = float(np.mean([p.rmse_px for p in poses])) if poses else None
        dlt_note = (f"DLT ({len(poses)} view(s), {poses[0].points} points)" if poses
                    else "DLT")
    else:
        if lens is None or not lens.complete:
            raise CalibrationError("lens sample: the lens lines give the distortion only; "
                                   "solve a DLT on the PTZ page (Save head to project) or "
                                   "calibrate a first sample from chessboard views")
        K = lens.intrinsics_at(zoom_raw, focus_raw).K
        report["intrinsics_from"] = "lens file"
        rms, dlt_note = None, "focal length from the lens file"
    k1 = k2 = k3 = p1 = p2 = 0.0
    note = dlt_note
    if cal.radial is not None:
        fit = brown_conrady_from_radial(cal.radial, K, (int(size[0]), int(size[1])))
        k1, k2, k3, p1, p2 = fit.k1, fit.k2, fit.k3, fit.p1, fit.p2
        report.update(distortion_from="lens lines", fit_rms_px=fit.rms_px,
                      fit_max_px=fit.max_px, radial_k=list(cal.radial.k))
        note += f" + lens lines (Brown-Conrady fit {fit.rms_px:.2f} px rms)"
    else:
        report["distortion_from"] = None
        note += ", no distortion model"
    sample = LensSample(zoom_raw=int(zoom_raw), focus_raw=int(focus_raw),
                        fx_px=float(K[0, 0]), fy_px=float(K[1, 1]), cx_px=float(K[0, 2]),
                        cy_px=float(K[1, 2]), k1=k1, k2=k2, k3=k3, p1=p1, p2=p2,
                        entrance_pupil_m=float(entrance_pupil_m), rms_px=rms, note=note)
    return sample, report
