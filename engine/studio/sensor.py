"""Sensor effects applied after rendering: Kinect-like depth noise and dropouts, colour noise,
vignetting. All randomness comes from a generator seeded by (seed, frame index)."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8

F32 = NDArray[np.float32]


def kinect_sigma_m(z_m: F32) -> F32:
    """Axial noise std of a Kinect v1, sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2 m
    (Nguyen, Izadi, Lovell 2012, "Modeling Kinect sensor noise", eq. 3): grows with z^2."""
    return (0.0012 + 0.0019 * (z_m - 0.4) ** 2).astype(np.float32)


def add_depth_noise(depth_m: F32, scale: float, rng: np.random.Generator) -> F32:
    """Gaussian axial noise ``scale * sigma(z)`` on valid pixels (0 stays 0)."""
    n = rng.standard_normal(depth_m.shape, dtype=np.float32)
    out = depth_m + np.float32(scale) * kinect_sigma_m(depth_m) * n
    out[depth_m <= 0] = 0.0
    return np.maximum(out, 0.0).astype(np.float32)


def add_dropouts(depth_m: F32, exact_m: F32, fraction: float, rng: np.random.Generator) -> F32:
    """Holes (depth 0) like a structured-light sensor's: organic blobs covering about
    ``fraction`` of the image, plus half of the pixels at depth discontinuities (> 5 cm in
    the exact depth ``exact_m``: the shadow/edge dropouts of a Kinect)."""
    h, w = depth_m.shape
    out = depth_m.copy()
    if fraction > 0:
        gh, gw = max(4, h // 12), max(4, w // 12)
        grid = rng.random((gh, gw), dtype=np.float32)
        field = cv2.resize(grid, (w, h), interpolation=cv2.INTER_CUBIC)
        # threshold from a 1/16 subsample (sorting every pixel would be 10x slower)
        thr = np.float32(np.quantile(field[::4, ::4], 1.0 - fraction))
        out[field > thr] = 0.0
    edge = np.zeros((h, w), bool)
    edge[:, :-1] = np.abs(np.diff(exact_m, axis=1)) > 0.05
    edge[:-1, :] |= np.abs(np.diff(exact_m, axis=0)) > 0.05
    idx = np.flatnonzero(edge)
    drop = idx[rng.random(idx.size) < 0.5]
    out.reshape(-1)[drop] = 0.0
    return out


def add_color_noise(
    bgr: NDArray[np.uint8], std: float, rng: np.random.Generator
) -> NDArray[np.uint8]:
    n = rng.standard_normal(bgr.shape, dtype=np.float32) * np.float32(std)
    return np.clip(bgr.astype(np.float32) + n + 0.5, 0, 255).astype(np.uint8)


def vignette_gain(xn: NDArray[np.float64], yn: NDArray[np.float64], strength: float) -> F32:
    """Natural vignetting cos^4(theta) blended with 1 by ``strength`` in [0, 1]."""
    cos4 = 1.0 / (1.0 + xn * xn + yn * yn) ** 2
    return (1.0 - strength + strength * cos4).astype(np.float32)


def lens_blur(bgr: NDArray[np.uint8], sigma_px: float) -> NDArray[np.uint8]:
    """Gaussian blur of the colour image (optics): one sample per pixel leaves object edges
    aliased; a real lens band-limits them."""
    return u8(cv2.GaussianBlur(bgr, (0, 0), sigma_px))
