"""A zoom lens for the built-in studio: a known lens file and the encoder script of a shot.

``synthetic:zoom=sweep`` renders every frame through :func:`studio_zoom_lens` at the frame's
zoom encoder value (wide -> tele -> wide once over the shot, a raised cosine), so the whole
chain - calibration, lens file, encoders, outputs - has exact ground truth; ``zoom=N`` holds
encoder value N. Frames carry the encoders as :class:`engine.lens.LensEncoders`; their
``intrinsics`` are the truth at that value.

The lens (at 640x480, scaled with the image): 3x zoom, focal length 420 -> 1260 px
(exponential in the encoder, as zoom lenses are), barrel distortion at the wide end turning
slightly pincushion at the tele end (k1 -0.22 -> +0.03, k2 +0.06 -> 0), the principal point
wandering by a few pixels, the entrance pupil moving forward 0.05 -> 0.18 m. The table has
65 samples: between them the bilinear interpolation of :class:`engine.lens.LensFile` is the
truth by definition.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from engine.lens import LensEncoders, LensFile, LensSample

ZOOM_MAX_RAW = 65535
FOCUS_RAW = 30000  # the shot's fixed focus encoder value
F_WIDE_PX, F_TELE_PX = 420.0, 1260.0
ZOOM_MODES = ("sweep", "fixed")


def truth_sample(zoom_raw: int, width: int = 640, height: int = 480) -> LensSample:
    """The known lens at one zoom encoder value (the analytic model the table samples)."""
    s = width / 640.0
    z = min(max(zoom_raw / ZOOM_MAX_RAW, 0.0), 1.0)
    f = F_WIDE_PX * (F_TELE_PX / F_WIDE_PX) ** z * s
    return LensSample(
        zoom_raw=int(zoom_raw), focus_raw=0,
        fx_px=f, fy_px=f * 1.0005,
        cx_px=(width - 1) / 2.0 + 3.0 * s * math.sin(math.pi * z),
        cy_px=(height - 1) / 2.0 - 2.0 * s * z,
        k1=-0.22 + 0.25 * z ** 0.7, k2=0.06 * (1.0 - z) ** 2, k3=0.0, p1=0.0, p2=0.0,
        entrance_pupil_m=0.05 + 0.13 * z, note="built-in studio zoom lens (truth)",
    )


@lru_cache(maxsize=8)
def studio_zoom_lens(width: int = 640, height: int = 480, n: int = 65) -> LensFile:
    """The known lens file of the built-in studio's zoom lens (``n`` zoom samples)."""
    zs = np.round(np.linspace(0, ZOOM_MAX_RAW, n)).astype(int)
    return LensFile(width, height, tuple(truth_sample(int(z), width, height) for z in zs),
                    sensor_width_mm=9.59, zoom_range_raw=(0, ZOOM_MAX_RAW),
                    focus_range_raw=(0, 65535), name="built-in studio zoom lens")


@dataclass(frozen=True, slots=True)
class ZoomScript:
    """The zoom encoder over a shot: a sweep (wide -> tele -> wide) or a fixed value."""

    mode: str = "sweep"
    value_raw: int = 0  # fixed mode
    cycle_frames: int = 300  # sweep: frames of one wide -> tele -> wide cycle
    sweep_max_raw: int = ZOOM_MAX_RAW  # sweep: the encoder value at the tele end

    def __post_init__(self) -> None:
        if self.mode not in ZOOM_MODES:
            raise ValueError(f"zoom mode {self.mode!r}: expected one of {', '.join(ZOOM_MODES)}")
        if not 0 <= self.value_raw <= ZOOM_MAX_RAW:
            raise ValueError(f"zoom value {self.value_raw} is outside 0..{ZOOM_MAX_RAW}")
        if not 0 < self.sweep_max_raw <= ZOOM_MAX_RAW:
            raise ValueError(f"zoom sweep end {self.sweep_max_raw} is outside 1..{ZOOM_MAX_RAW}")
        if self.cycle_frames < 2:
            raise ValueError("zoom sweep needs at least 2 frames per cycle")

    def encoders(self, index: int) -> LensEncoders:
        if self.mode == "fixed":
            z = self.value_raw
        else:
            z = round(self.sweep_max_raw * 0.5 * (1.0 - math.cos(2 * math.pi * index
                                                                  / self.cycle_frames)))
        return LensEncoders(zoom_raw=int(z), focus_raw=FOCUS_RAW)
