"""Video files (mp4, avi, ...) decoded by OpenCV's ``cv2.VideoCapture`` (FFmpeg backend).

Timestamps are the container's presentation times (``CAP_PROP_POS_MSEC``), which matter
for files with dropped/duplicated frames (``tree.avi`` announces 444 frames at 15 fps but
decodes 68 spread over 29.5 s); when the backend gives no increasing times the source falls
back to ``index / fps``. ``len()`` is the container's frame count, an upper estimate for
such files. Intrinsics are unknown unless given.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from engine.camera import Intrinsics
from engine.errors import SourceError
from engine.frames import Frame, SourceFiles
from engine.sources.base import Source, SourceSpec

DEFAULT_FPS = 30.0
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v")


def _open_capture(path: Path) -> cv2.VideoCapture:
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        cap.release()
        raise SourceError(f"{path}: cannot open video (corrupt, truncated or unsupported format)")
    return cap


class VideoSource(Source):
    """Frames (BGR uint8) of a video file; ``intrinsics`` only if passed in."""

    def __init__(self, path: str | Path, *, intrinsics: Intrinsics | None = None) -> None:
        path = Path(path).expanduser()
        if not path.exists():
            raise SourceError(f"{path}: no such video file")
        if not path.is_file():
            raise SourceError(f"{path}: not a file")
        if path.stat().st_size == 0:
            raise SourceError(f"{path}: video file is empty (0 bytes)")
        self.path = path
        self.name = f"video {path.name}"
        cap = _open_capture(path)
        try:
            fps = float(cap.get(cv2.CAP_PROP_FPS))
            count = float(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            ok, first = cap.read()
        finally:
            cap.release()
        if not ok or first is None:
            raise SourceError(f"{path}: video contains no decodable frame")
        self.nominal_fps = fps if math.isfinite(fps) and fps > 0 else DEFAULT_FPS
        self._len = int(count) if math.isfinite(count) and count > 0 else 0
        self.frame_size_wh = (int(first.shape[1]), int(first.shape[0]))
        if intrinsics is not None and intrinsics.size_wh != self.frame_size_wh:
            raise SourceError(
                f"{path}: frames are {self.frame_size_wh[0]}x{self.frame_size_wh[1]} but the "
                f"intrinsics say {intrinsics.width}x{intrinsics.height}"
            )
        self._intrinsics = intrinsics
        self._end_note = ""

    @property
    def intrinsics(self) -> Intrinsics | None:
        return self._intrinsics

    def __len__(self) -> int:
        return self._len

    def end_notes(self) -> tuple[str, ...]:
        return (self._end_note,) if self._end_note else ()

    def _check_end(self, decoded: int, last_t: float) -> None:
        """After the last decodable frame: did the file end early (truncated copy)?

        The container's frame count is only an upper estimate (files with dropped frames
        announce more than they hold), so the test is on time: the last frame must lie
        within two frame periods (or 2 %) of the announced duration."""
        self._end_note = ""
        if self._len <= 0 or decoded >= self._len:
            return
        duration = self._len / self.nominal_fps
        slack = max(2.0 / self.nominal_fps, 0.02 * duration)
        if decoded == 0 or last_t < duration - slack:
            last = (f"frame {decoded - 1} at {last_t:.3f} s" if decoded else "none")
            self._end_note = (
                f"{self.path}: video ended after {decoded} of the {self._len} frames its "
                f"header announces ({duration:.1f} s); the file looks truncated or damaged; "
                f"last good frame: {last}"
            )

    def frames(self) -> Iterator[Frame]:
        cap = _open_capture(self.path)
        self._end_note = ""
        try:
            use_pos = True
            last_t = -math.inf
            index = 0
            while True:
                ok, image = cap.read()
                if not ok or image is None:
                    self._check_end(index, last_t)
                    return
                t_s = float(cap.get(cv2.CAP_PROP_POS_MSEC)) / 1000.0
                if use_pos and (not math.isfinite(t_s) or t_s <= last_t):
                    use_pos = False  # the backend gives no usable times: fall back for good
                if not use_pos:
                    t_s = max(index / self.nominal_fps, last_t + 1e-6)
                last_t = t_s
                if image.ndim == 2:
                    image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
                yield Frame(
                    index=index,
                    timestamp_s=t_s,
                    color_bgr=np.asarray(image, dtype=np.uint8),
                    intrinsics=self._intrinsics,
                    payloads=(SourceFiles(color_path=str(self.path)),),
                )
                index += 1
        finally:
            cap.release()


def _is_video_file(path: Path) -> bool:
    return path.is_file() and path.suffix.lower() in VIDEO_SUFFIXES


SOURCES = (
    SourceSpec(
        name="video",
        description=f"a video file ({', '.join(VIDEO_SUFFIXES)})",
        opener=VideoSource,
        detect=_is_video_file,
        example="take1.mp4",
    ),
)
