"""A tiny deterministic presenter scene for unit tests (not the built-in studio renderer).

A static, coloured set (gradient wall, desk, coloured panels, mild sensor noise) and a
three-part presenter (head / torso / legs, distinct colours) that walks along x, can stand
still, or leave the frame and come back. Exact boxes of the presenter come with every frame.
The product's benchmarks use ``engine.studio`` (``synthetic:`` sources); this keeps the
presenter's unit tests small, fast and independent of it.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

XYWH = tuple[float, float, float, float]

HEAD_BGR = (140, 180, 230)
TORSO_BGR = (40, 40, 200)
LEGS_BGR = (120, 60, 20)


@dataclass(frozen=True, slots=True)
class SceneFrame:
    index: int
    bgr: NDArray[np.uint8]
    box_xywh: XYWH | None  # None while the presenter is out of the frame
    part_boxes: dict[str, XYWH]


def _background(w: int, h: int, rng: np.random.Generator) -> NDArray[np.uint8]:
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    bg = np.empty((h, w, 3), np.float32)
    bg[..., 0] = 90 + 40 * xx / w
    bg[..., 1] = 110 + 30 * yy / h
    bg[..., 2] = 100 + 20 * np.sin(xx / 37.0)
    # set pieces: a desk, two panels of unrelated colours
    bg[int(0.7 * h):, int(0.05 * w):int(0.3 * w)] = (30, 160, 60)
    bg[int(0.15 * h):int(0.45 * h), int(0.75 * w):int(0.95 * w)] = (200, 200, 60)
    bg[int(0.1 * h):int(0.3 * h), int(0.35 * w):int(0.5 * w)] = (150, 90, 160)
    bg += rng.normal(0, 3, bg.shape).astype(np.float32)
    return np.clip(bg, 0, 255).astype(np.uint8)


def presenter_frames(n: int = 60, width: int = 320, height: int = 240, *, seed: int = 0,
                     speed_px: float = 2.0, still: bool = False,
                     leave: tuple[int, int] | None = None,
                     height_frac: float = 0.6, noise: float = 2.0) -> Iterator[SceneFrame]:
    """Frames of the scene. ``leave=(a, b)``: out of the frame for frames a <= i < b."""
    rng = np.random.default_rng(seed)
    bg = _background(width, height, rng)
    ph = height_frac * height
    pw = 0.28 * ph
    x = 0.3 * width
    direction = 1.0
    for i in range(n):
        if not still:
            x += direction * speed_px
            if x + pw > 0.85 * width or x < 0.1 * width:
                direction = -direction
        out = leave is not None and leave[0] <= i < leave[1]
        img = bg.astype(np.float32)
        top = 0.2 * height
        parts: dict[str, XYWH] = {}
        box: XYWH | None = None
        if not out:
            # (name, colour, y from, y to, width fraction) along the body
            spec = (("head", HEAD_BGR, 0.0, 0.2, 0.6), ("torso", TORSO_BGR, 0.2, 0.58, 1.0),
                    ("legs", LEGS_BGR, 0.58, 1.0, 0.8))
            for name, colour, a, b, wf in spec:
                bx = x + (1 - wf) * pw / 2
                bw = wf * pw
                by, bh = top + a * ph, (b - a) * ph
                x0, y0 = round(bx), round(by)
                x1, y1 = round(bx + bw), round(by + bh)
                img[y0:y1, x0:x1] = colour
                parts[name] = (float(x0), float(y0), float(x1 - x0), float(y1 - y0))
            box = (float(round(x)), float(round(top)), float(round(x + pw) - round(x)),
                   float(round(top + ph) - round(top)))
        img += rng.normal(0, noise, img.shape).astype(np.float32)
        yield SceneFrame(i, np.clip(img, 0, 255).astype(np.uint8), box, parts)
