"""Live webcam through ``cv2.VideoCapture(N)`` (V4L2 on Linux).

The device is opened at construction so that a missing camera fails before tracking
starts. ``frames()`` reads until the device stops delivering; timestamps are seconds of the
monotonic clock since the first frame of that call. Intrinsics are unknown unless given
(a tracker that needs them must be fed a calibrated source).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import cv2
import numpy as np

from engine.camera import Intrinsics
from engine.errors import SourceError
from engine.frames import Frame
from engine.sources.base import Source, SourceSpec

DEFAULT_FPS = 30.0


class CameraSource(Source):
    """Frames of live camera ``index``; ``live`` is True and ``len()`` is 0."""

    live = True

    def __init__(self, index: int = 0, *, intrinsics: Intrinsics | None = None) -> None:
        if index < 0:
            raise SourceError(f"camera {index}: index must be >= 0")
        self.index = index
        self.name = f"camera {index}"
        self._intrinsics = intrinsics
        self._cap: cv2.VideoCapture | None = cv2.VideoCapture(index)
        if not self._cap.isOpened():
            self._cap.release()
            self._cap = None
            raise SourceError(f"camera {index}: cannot open (no device?)")
        fps = float(self._cap.get(cv2.CAP_PROP_FPS))
        self.nominal_fps = fps if math.isfinite(fps) and fps > 0 else DEFAULT_FPS

    @property
    def intrinsics(self) -> Intrinsics | None:
        return self._intrinsics

    def __len__(self) -> int:
        return 0

    def frames(self) -> Iterator[Frame]:
        if self._cap is None:
            raise SourceError(f"camera {self.index}: already closed")
        cap = self._cap
        t0: float | None = None
        index = 0
        while True:
            ok, image = cap.read()
            now = time.monotonic()
            if not ok or image is None:
                raise SourceError(f"camera {self.index}: no frame received (unplugged or busy?)")
            if t0 is None:
                t0 = now
            if image.ndim == 2:
                image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
            if self._intrinsics is not None and (
                (image.shape[1], image.shape[0]) != self._intrinsics.size_wh
            ):
                raise SourceError(
                    f"camera {self.index}: frames are {image.shape[1]}x{image.shape[0]} but the "
                    f"intrinsics say {self._intrinsics.width}x{self._intrinsics.height}"
                )
            yield Frame(
                index=index,
                timestamp_s=now - t0,
                color_bgr=np.asarray(image, dtype=np.uint8),
                intrinsics=self._intrinsics,
            )
            index += 1

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None


def open_camera(rest: str) -> CameraSource:
    """``camera:N`` (``camera`` alone is camera 0)."""
    try:
        index = int(rest or "0")
    except ValueError:
        msg = f"camera spec {'camera:' + rest!r}: expected camera:N with N an integer"
        raise SourceError(msg) from None
    return CameraSource(index)


SOURCES = (
    SourceSpec(name="camera", description="live webcam N", opener=open_camera,
               example="camera:0"),
)
