"""What the camera view shows of an RGB-D frame: colour, depth (false colour) or both.

Depth is drawn with OpenCV's TURBO map, near = red/yellow... far = blue, between the 2nd and
98th percentile of the frame's valid depths (at least 0.5 m apart); invalid depth (0) is
black. "Both" puts colour and depth side by side, colour on the left, so overlays drawn in
colour-image pixels stay where they belong.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

VIEW_MODES = ("colour", "depth", "both")


def depth_to_bgr(depth_m: NDArray[np.floating]) -> NDArray[np.uint8]:
    """False-colour BGR image of a depth map in metres (0 or NaN = invalid, drawn black)."""
    import cv2

    d = np.asarray(depth_m, dtype=np.float32)
    valid = np.isfinite(d) & (d > 0)
    out = np.zeros((*d.shape, 3), np.uint8)
    if not valid.any():
        return out
    sample = d[::4, ::4][valid[::4, ::4]]
    if sample.size == 0:
        sample = d[valid]
    near, far = (float(v) for v in np.percentile(sample, (2, 98)))
    far = max(far, near + 0.5)
    scaled = np.clip((far - np.where(valid, d, far)) / (far - near), 0.0, 1.0)
    colour = cv2.applyColorMap((scaled * 255).astype(np.uint8), cv2.COLORMAP_TURBO)
    out[valid] = colour[valid]
    return out


def compose_view(
    color_bgr: NDArray[np.uint8] | None,
    depth_m: NDArray[np.floating] | None,
    mode: str,
) -> NDArray[np.uint8] | None:
    """The image to show for ``mode`` (colour when the frame has no depth)."""
    if mode not in VIEW_MODES:
        raise ValueError(f"view mode {mode!r} is not one of {', '.join(VIEW_MODES)}")
    if depth_m is None or mode == "colour":
        return color_bgr
    depth = depth_to_bgr(depth_m)
    if mode == "depth" or color_bgr is None:
        return depth
    if depth.shape[:2] != color_bgr.shape[:2]:
        import cv2

        depth = cv2.resize(depth, (color_bgr.shape[1], color_bgr.shape[0]),
                           interpolation=cv2.INTER_NEAREST)
    return np.ascontiguousarray(np.hstack([color_bgr, depth]))
