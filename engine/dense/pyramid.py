"""Grey image pyramid of sec. 4.6: 640x480 -> 320x240 (5x5 Gaussian) -> 160x120 -> 80x60.

Level 0 is the half-resolution image (5x5 Gaussian then 2x2 averaging, so that every level
keeps the pixel-centre convention ``u_L = (u + 0.5) / 2^(L+1) - 0.5``); levels 1 and 2 are
2x2 block averages. Only intensities are downsampled: the geometry (depth) stays at full
resolution (sec. 3.2).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from engine.arrays import f32

F32 = NDArray[np.float32]

N_LEVELS = 3


def level_scales() -> NDArray[np.float64]:
    """Scale of each level relative to the input image: 1/2, 1/4, 1/8."""
    return np.array([0.5**(lev + 1) for lev in range(N_LEVELS)], dtype=np.float64)


def gray_from_bgr(color_bgr: NDArray[np.uint8]) -> F32:
    """Grey float32 image in [0, 255] from BGR (or already grey) uint8."""
    import cv2

    if color_bgr.ndim == 2:
        return color_bgr.astype(np.float32)
    return cv2.cvtColor(color_bgr, cv2.COLOR_BGR2GRAY).astype(np.float32)


def _half(img: F32) -> F32:
    """2x2 block average (odd trailing row/column dropped)."""
    h, w = img.shape[0] // 2 * 2, img.shape[1] // 2 * 2
    v = img[:h, :w]
    return (0.25 * (v[0::2, 0::2] + v[1::2, 0::2] + v[0::2, 1::2] + v[1::2, 1::2])).astype(
        np.float32, copy=False
    )


def build_pyramid(gray_full: F32) -> tuple[F32, F32, F32]:
    """(level0, level1, level2) contiguous float32 images for a full-resolution grey image."""
    import cv2

    blurred = f32(cv2.GaussianBlur(gray_full, (5, 5), 0.0, borderType=cv2.BORDER_REFLECT101))
    l0 = _half(blurred)
    l1 = _half(l0)
    l2 = _half(l1)
    return (np.ascontiguousarray(l0), np.ascontiguousarray(l1), np.ascontiguousarray(l2))
