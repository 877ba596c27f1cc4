"""Grey image pyramid of sec. 4.6: 640x480 -> 320x240 (5x5 Gaussian) -> 160x120 -> 80x60.

Level 0 is the half-resolution image (5x5 Gaussian then 2x2 averaging, so that every level
keeps the pixel-centre convention ``u_L = (u + 0.5) / 2^(L+1) - 0.5``); levels 1 and 2 are
2x2 block averages. Only intensities are downsampled: the geometry (depth) stays at full
resolution (sec. 3.2). The filters are OpenCV's (separable Gaussian straight from the 8-bit
grey image to float32, area resizing = exact 2x2 means); for 8-bit images the same sums are
computed at level-0 resolution only by a numba kernel (:func:`engine.dense.kernels.pyramid_u8`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8

F32 = NDArray[np.float32]

N_LEVELS = 3


def level_scales() -> NDArray[np.float64]:
    """Scale of each level relative to the input image: 1/2, 1/4, 1/8."""
    return np.array([0.5**(lev + 1) for lev in range(N_LEVELS)], dtype=np.float64)


def gray_from_bgr(color_bgr: NDArray[np.uint8]) -> F32:
    """Grey float32 image in [0, 255] from BGR (or already grey) uint8."""
    return gray_u8(color_bgr).astype(np.float32)


def gray_u8(color_bgr: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Grey uint8 image from BGR (or already grey) uint8 (OpenCV's BT.601 weights)."""
    import cv2

    if color_bgr.ndim == 2:
        return np.asarray(color_bgr)
    return u8(cv2.cvtColor(color_bgr, cv2.COLOR_BGR2GRAY))


_GAUSS5 = np.array([1.0, 4.0, 6.0, 4.0, 1.0], dtype=np.float32) / 16.0


def _ro_u8(a: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """A read-only view (one numba type for the kernel, whatever the caller's flags)."""
    v = a.view()
    v.setflags(write=False)
    return v


def build_pyramid(gray_full: NDArray[np.floating] | NDArray[np.uint8]) -> tuple[F32, F32, F32]:
    """(level0, level1, level2) contiguous float32 images for a full-resolution grey image
    (uint8 or float)."""
    import cv2

    g = np.ascontiguousarray(gray_full)
    if g.dtype == np.uint8 and g.shape[0] >= 8 and g.shape[1] >= 8:
        # the tracker's case (8-bit grey frames and keyframes): the same filters at level-0
        # resolution only (engine.dense.kernels.pyramid_u8: equal to the OpenCV path below
        # to the bit on the rail frames, ~1.5x faster)
        from engine.dense import kernels

        l0, l1, l2 = kernels.pyramid_u8(_ro_u8(g))
        return l0, l1, l2
    if g.dtype not in (np.uint8, np.float32):
        g = g.astype(np.float32)
    # 5x5 Gaussian (OpenCV's ksize-5 kernel 1 4 6 4 1 / 16, reflect-101 border), then 2x2
    # block means: cv2.INTER_AREA at exactly half size is the 2x2 mean (odd edge dropped)
    blurred = cv2.sepFilter2D(g, cv2.CV_32F, _GAUSS5, _GAUSS5, borderType=cv2.BORDER_REFLECT101)
    out = [blurred]
    for _ in range(N_LEVELS):
        src = out[-1]
        h, w = src.shape[0] // 2, src.shape[1] // 2
        out.append(cv2.resize(src[: 2 * h, : 2 * w], (w, h), interpolation=cv2.INTER_AREA))
    return (
        np.ascontiguousarray(out[1]), np.ascontiguousarray(out[2]), np.ascontiguousarray(out[3])
    )
