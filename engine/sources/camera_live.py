"""Live webcam through ``cv2.VideoCapture(N)`` (V4L2 on Linux).

The device is opened at construction so that a missing camera fails before tracking
starts. ``frames()`` follows the newest-frame policy (:mod:`engine.sources.grabber`): a
thread reads the camera, the consumer gets the newest frame and ``Frame.skipped_before``
counts the ones it skipped. When the camera stops delivering (unplugged, busy), the source
yields frames without a picture and ``link_lost_reason = "camera disconnected"`` and tries
to reopen the device every ``reconnect_s`` seconds. Timestamps are seconds of the monotonic
clock since the first frame of that call. Intrinsics are unknown unless given (a tracker
that needs them must be fed a calibrated source).
"""

from __future__ import annotations

import functools
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
DISCONNECTED = "camera disconnected"


class _NoFrame(Exception):
    pass


class CameraSource(Source):
    """Frames of live camera ``index``; ``live`` is True and ``len()`` is 0."""

    live = True

    def __init__(
        self,
        index: int = 0,
        *,
        intrinsics: Intrinsics | None = None,
        timeout_s: float = 1.0,
        reconnect_s: float = 1.0,
    ) -> None:
        if index < 0:
            raise SourceError(f"camera {index}: index must be >= 0")
        self.index = index
        self.name = f"camera {index}"
        self._intrinsics = intrinsics
        self.timeout_s = timeout_s
        self.reconnect_s = reconnect_s
        #: times the camera was reopened after it stopped delivering
        self.reconnects = 0
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

    def _grab(self, cap: cv2.VideoCapture) -> np.ndarray:
        ok, image = cap.read()
        if not ok or image is None:
            raise _NoFrame
        return np.asarray(image, dtype=np.uint8)

    def frames(self) -> Iterator[Frame]:
        from engine.sources.grabber import NewestGrabber

        if self._cap is None:
            raise SourceError(f"camera {self.index}: already closed")
        t0: float | None = None
        index = 0
        while True:
            cap = self._cap
            grabber: NewestGrabber[np.ndarray] = NewestGrabber(
                functools.partial(self._grab, cap), name=f"camera-{self.index}-grabber"
            )
            grabber.start()
            try:
                while True:
                    try:
                        got = grabber.take(self.timeout_s)
                    except _NoFrame:
                        got = None
                    if got is None:
                        break
                    image = got.item
                    if t0 is None:
                        t0 = got.arrival_s
                    if image.ndim == 2:
                        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
                    if self._intrinsics is not None and (
                        (image.shape[1], image.shape[0]) != self._intrinsics.size_wh
                    ):
                        raise SourceError(
                            f"camera {self.index}: frames are {image.shape[1]}x{image.shape[0]} "
                            f"but the intrinsics say {self._intrinsics.width}x"
                            f"{self._intrinsics.height}"
                        )
                    yield Frame(
                        index=index,
                        timestamp_s=got.arrival_s - t0,
                        color_bgr=image,
                        intrinsics=self._intrinsics,
                        skipped_before=got.skipped,
                        capture_mono_s=got.arrival_s,
                    )
                    index += 1
            finally:
                grabber.stop()
            # No frame within timeout_s: report it, reopen every reconnect_s until it works.
            while True:
                now = time.monotonic()
                yield Frame(index=index, timestamp_s=0.0 if t0 is None else now - t0,
                            color_bgr=None, intrinsics=self._intrinsics,
                            link_lost_reason=DISCONNECTED)
                index += 1
                time.sleep(self.reconnect_s)
                if self._cap is not None:
                    self._cap.release()
                self._cap = cv2.VideoCapture(self.index)
                if self._cap.isOpened():
                    self.reconnects += 1
                    break

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
