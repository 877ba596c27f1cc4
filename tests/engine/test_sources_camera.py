"""CameraSource: the no-device error (this machine has no camera), the newest-frame read loop,
unplugging and reconnecting, on a fake device."""

from __future__ import annotations

import time

import cv2
import numpy as np
import pytest

import engine.sources.camera_live as camera_live
from engine.camera import Intrinsics
from engine.errors import SourceError
from engine.sources import open_source
from engine.sources.camera_live import CameraSource


class FakeCapture:
    """Stands in for cv2.VideoCapture: yields ``n`` frames, then fails like an unplugged cam."""

    released = 0
    period_s = 0.02  # a camera delivers at its own rate

    def __init__(self, index: int, n: int = 3, opened: bool = True) -> None:
        self.index, self.n, self.opened, self.k = index, n, opened, 0

    def isOpened(self) -> bool:
        return self.opened

    def get(self, prop: int) -> float:
        return 25.0 if prop == cv2.CAP_PROP_FPS else 0.0

    def read(self) -> tuple[bool, np.ndarray | None]:
        time.sleep(self.period_s)
        if self.k >= self.n:
            return False, None
        self.k += 1
        return True, np.full((6, 8, 3), self.k, np.uint8)

    def release(self) -> None:
        FakeCapture.released += 1


def test_no_device_gives_clear_error() -> None:
    # index 63 exists nowhere, even on a machine with a webcam
    with pytest.raises(SourceError, match=r"^camera 63: cannot open \(no device\?\)$"):
        CameraSource(63)
    with pytest.raises(SourceError, match=r"^camera 63: cannot open \(no device\?\)$"):
        open_source("camera:63")


def test_bad_camera_specs() -> None:
    with pytest.raises(SourceError, match="expected camera:N"):
        open_source("camera:front")
    with pytest.raises(SourceError, match="index must be >= 0"):
        CameraSource(-1)


def test_live_frames_from_fake_device(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(camera_live.cv2, "VideoCapture", FakeCapture)
    src = open_source("camera:2")
    assert isinstance(src, CameraSource)
    assert src.live is True
    assert len(src) == 0
    assert src.nominal_fps == 25.0
    assert src.name == "camera 2"
    src.timeout_s, src.reconnect_s = 0.2, 0.01
    it = src.frames()
    frames = [next(it) for _ in range(3)]
    assert [f.index for f in frames] == [0, 1, 2]
    assert [int(f.color_bgr[0, 0, 0]) for f in frames] == [1, 2, 3]  # type: ignore[index]
    assert [f.skipped_before for f in frames] == [0, 0, 0]  # the consumer keeps up
    # unplugged: frames without a picture say why, then the camera is reopened
    lost = next(it)
    assert lost.color_bgr is None
    assert lost.link_lost_reason == "camera disconnected"
    again = next(it)
    assert src.reconnects == 1
    assert int(again.color_bgr[0, 0, 0]) == 1  # type: ignore[index]
    t = [f.timestamp_s for f in [*frames, lost, again]]
    assert t[0] == 0.0
    assert t == sorted(t)
    it.close()
    before = FakeCapture.released
    with src:
        pass
    assert FakeCapture.released == before + 1
    with pytest.raises(SourceError, match="already closed"):
        next(src.frames())


def test_slow_consumer_gets_the_newest_frame(monkeypatch: pytest.MonkeyPatch) -> None:
    class Fast(FakeCapture):
        period_s = 0.002

        def __init__(self, index: int) -> None:
            super().__init__(index, n=10_000)

    monkeypatch.setattr(camera_live.cv2, "VideoCapture", Fast)
    src = CameraSource(0)
    it = src.frames()
    got = []
    for _ in range(6):
        got.append(next(it))
        time.sleep(0.03)  # a tracker slower than the camera
    it.close()
    src.close()
    assert sum(f.skipped_before for f in got[1:]) >= 5 * 3
    values = [int(f.color_bgr[0, 0, 0]) for f in got]  # type: ignore[index]
    assert values == sorted(values)


def test_fake_device_size_checked_against_intrinsics(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(camera_live.cv2, "VideoCapture", FakeCapture)
    cam = Intrinsics(fx=10.0, fy=10.0, cx=3.5, cy=2.5, width=16, height=12)
    with pytest.raises(SourceError, match=r"frames are 8x6 but the intrinsics say 16x12"):
        next(CameraSource(0, intrinsics=cam).frames())
