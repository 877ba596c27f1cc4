"""RealSense stream intrinsics (``rs2_intrinsics``) -> our :class:`~engine.camera.Intrinsics`.

Our camera model is the Caltech/OpenCV forward model of Tykkälä 2014 eq. (3)-(4)
(coefficients k1 k2 p1 p2 k3, applied to points when projecting). The SDK's models
(``rs2_distortion``), and what we do with each:

==========================  ========================================================  =========
SDK model                   meaning (librealsense ``rsutil.h``)                       here
==========================  ========================================================  =========
None                        pinhole                                                   exact
Brown Conrady               OpenCV's forward model, same coefficient order            exact
Modified Brown Conrady      forward; tangential terms use the radially scaled point   fitted
Inverse Brown Conrady       the same forward model (the SDK projects and deprojects   fitted
                            both alike; "inverse" only says the image can be
                            deprojected)
F-Theta, Kannala Brandt4    fisheye models                                            refused
==========================  ========================================================  =========

A Brown Conrady model whose coefficients are all zero is the pinhole (D4xx depth and aligned
streams report "Inverse Brown Conrady" with zeros); a fisheye model never is. "Fitted":
forward Caltech coefficients are fitted by linear least squares to the SDK model over the
whole image; the fit is accepted when it reproduces the model within
:data:`MAX_FIT_ERROR_PX` everywhere, otherwise the source refuses the stream with one line
naming the model and the error.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics, dist5
from engine.errors import SourceError

F64 = NDArray[np.float64]

#: largest pixel error of a fitted model conversion that is accepted
MAX_FIT_ERROR_PX = 0.05
EXACT_MODELS = ("none", "brown_conrady")
FITTED_MODELS = ("modified_brown_conrady", "inverse_brown_conrady")
SUPPORTED_MODELS = EXACT_MODELS + FITTED_MODELS
#: the SDK's names (``rs2_distortion_to_string``) by model key
MODEL_NAMES = {"none": "None", "brown_conrady": "Brown Conrady",
               "modified_brown_conrady": "Modified Brown Conrady",
               "inverse_brown_conrady": "Inverse Brown Conrady", "ftheta": "Ftheta",
               "kannala_brandt4": "Kannala Brandt4"}


def model_key(name: str) -> str:
    """Canonical model key: "Brown Conrady", "distortion.brown_conrady" -> "brown_conrady"."""
    key = str(name).strip().lower().rsplit(".", 1)[-1].replace(" ", "_").replace("-", "")
    return {"kannala_brandt4": "kannala_brandt4", "f_theta": "ftheta"}.get(key, key)


def _radial(c: Sequence[float], r2: F64) -> F64:
    return 1.0 + c[0] * r2 + c[1] * r2 * r2 + c[4] * r2 * r2 * r2


def modified_brown_conrady(xy: F64, c: Sequence[float]) -> F64:
    """Undistorted -> distorted normalised points as ``rs2_project_point_to_pixel`` does for
    "Modified" and "Inverse Brown Conrady" (librealsense ``rsutil.h``)."""
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    f = _radial(c, r2)
    x, y = x * f, y * f
    dx = x + 2 * c[2] * x * y + c[3] * (r2 + 2 * x * x)
    dy = y + 2 * c[3] * x * y + c[2] * (r2 + 2 * y * y)
    return np.stack([dx, dy], axis=1)


def fit_caltech(undist: F64, dist: F64) -> tuple[float, float, float, float, float]:
    """Least-squares (k1, k2, p1, p2, k3) with ``dist ~ D(undist)`` of eq. (3)-(4).

    The model is linear in the coefficients: ``x_d - x = k1 x r^2 + k2 x r^4 + k3 x r^6
    + 2 p1 x y + p2 (r^2 + 2 x^2)`` and the same for y with p1 and p2 exchanged.
    """
    x, y = undist[:, 0], undist[:, 1]
    r2 = x * x + y * y
    ax = np.stack([x * r2, x * r2**2, 2 * x * y, r2 + 2 * x * x, x * r2**3], axis=1)
    ay = np.stack([y * r2, y * r2**2, r2 + 2 * y * y, 2 * x * y, y * r2**3], axis=1)
    A = np.concatenate([ax, ay])
    b = np.concatenate([dist[:, 0] - x, dist[:, 1] - y])
    k1, k2, p1, p2, k3 = np.linalg.lstsq(A, b, rcond=None)[0]
    return (float(k1), float(k2), float(p1), float(p2), float(k3))


def _pixel_grid(width: int, height: int, n: int = 41) -> F64:
    u, v = np.meshgrid(np.linspace(-0.5, width - 0.5, n), np.linspace(-0.5, height - 0.5, n))
    return np.stack([u.ravel(), v.ravel()], axis=1)


def intrinsics_from_sdk(
    *,
    width: int,
    height: int,
    fx: float,
    fy: float,
    ppx: float,
    ppy: float,
    model: str,
    coeffs: Sequence[float],
    depth_scale: float,
    where: str,
) -> tuple[Intrinsics, float]:
    """Our intrinsics for an SDK stream, and the conversion's worst pixel error (0 if exact).

    ``depth_scale`` is depth units per metre (1 / the SDK's Depth Units). Raises
    :class:`SourceError` naming ``where`` for a model we do not support.
    """
    from engine.camera import distort_normalized

    key = model_key(model)
    name = MODEL_NAMES.get(key, str(model))
    c = [float(v) for v in list(coeffs)[:5]] + [0.0] * max(0, 5 - len(list(coeffs)))
    if not all(np.isfinite(c)):
        raise SourceError(f"{where}: distortion coefficients are not finite: {c}")
    base = Intrinsics(fx=float(fx), fy=float(fy), cx=float(ppx), cy=float(ppy),
                      width=int(width), height=int(height), depth_scale=float(depth_scale))
    if key == "none" or (key in SUPPORTED_MODELS and not any(c)):
        return base, 0.0
    if key == "brown_conrady":
        return dataclasses.replace(base, dist_k1k2p1p2k3=dist5(c)), 0.0
    if key not in FITTED_MODELS:
        raise SourceError(
            f"{where}: distortion model {name!r} is not supported (supported: None, Brown "
            "Conrady, Modified Brown Conrady, Inverse Brown Conrady; fisheye models are not)"
        )
    uv = _pixel_grid(int(width), int(height))
    xy_pix = np.stack([(uv[:, 0] - ppx) / fx, (uv[:, 1] - ppy) / fy], axis=1)
    undist = xy_pix  # the image's undistorted field is close to the pixel grid
    dist = modified_brown_conrady(undist, c)
    k = fit_caltech(undist, dist)
    err = distort_normalized(undist, np.asarray(k)) - dist
    err_px = float(np.max(np.hypot(err[:, 0] * fx, err[:, 1] * fy)))
    if err_px > MAX_FIT_ERROR_PX:
        raise SourceError(
            f"{where}: distortion model {name!r} with coefficients {c} cannot be expressed "
            f"in the Caltech model (best fit is off by {err_px:.2f} px > {MAX_FIT_ERROR_PX} px)"
        )
    return dataclasses.replace(base, dist_k1k2p1p2k3=k), err_px
