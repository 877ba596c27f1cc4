"""The frame every source yields and the tracker consumes, and its typed payloads.

A frame carries the images, the calibration, the capture time and generic ground truth
(``gt_T_world_cam``, ``gt_box_xywh``). Anything source-specific travels as *payloads*:
frozen dataclasses deriving from :class:`FramePayload`, declared by the module that
produces them (the built-in studio's truth in :mod:`engine.studio.sim`, the pan-tilt head
reading in :mod:`engine.ptz.kinematics`, range readings in :mod:`engine.sources.beacons`...)
and looked up by type::

    truth = frame.payload(StudioTruth)      # StudioTruth | None
    if truth is not None and truth.covered: ...

A payload whose class sets ``light = False`` holds images (label maps, exact depth); the
pipeline's history keeps only light payloads.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar, overload

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics

A = TypeVar("A", bound=np.ndarray[Any, Any])


@overload
def readonly(a: A) -> A: ...
@overload
def readonly(a: None) -> None: ...
def readonly(a: np.ndarray[Any, Any] | None) -> np.ndarray[Any, Any] | None:
    """Mark an array read-only so that it can cross threads inside a frozen record."""
    if a is not None and a.flags.writeable:
        a.flags.writeable = False
    return a


class FramePayload:
    """Base of the typed, frozen data a source attaches to a frame.

    Subclasses are ``@dataclass(frozen=True, slots=True)``; ``light`` says whether the
    payload is small enough to be kept in the run history (no images).
    """

    __slots__ = ()
    light: ClassVar[bool] = True


P = TypeVar("P", bound=FramePayload)


@dataclass(frozen=True, slots=True)
class SourceFiles(FramePayload):
    """Where a frame was read from (file sources): the colour image or video, the depth."""

    color_path: str | None = None
    depth_path: str | None = None


@dataclass(frozen=True, slots=True)
class Heartbeat(FramePayload):
    """Marks a frame without data: a live source had nothing new for ``waited_s`` and yields
    it only so that the engine loop can poll its stop flag. Trackers hold their last result;
    runs, trajectories and estimates leave heartbeat frames out."""

    waited_s: float = 0.0


def _now() -> float:
    return time.monotonic()


@dataclass(frozen=True, slots=True)
class Frame:
    """One time step of a source.

    ``color_bgr`` is uint8 (H, W, 3) BGR (OpenCV order) or None for non-image sources
    (range beacons); ``depth_m`` is float32 (H, W) metres with 0 where invalid.
    ``gt_T_world_cam`` is the ground-truth camera pose if known; ``gt_box_xywh`` the
    ground-truth target box (OTB convention: top-left x, y, width, height) if known.
    ``capture_mono_s`` is when the frame came to be, on ``time.monotonic()`` (a live source
    sets its grab time; by default the time the frame object was made, i.e. read or
    rendered); ``depth_timestamp_s`` is the depth image's own time stamp on the
    ``timestamp_s`` clock when the sensor gives one (TUM). ``payloads`` are the
    source-specific typed data (see the module docstring).
    ``skipped_before`` is the number of frames a live source dropped since the previous frame
    it yielded because the consumer was slower (the newest-frame policy of
    :mod:`engine.sources.grabber`; 0 for recorded sources). ``link_lost_reason`` is set (e.g.
    "camera disconnected") on frames without a picture that a live source yields while its
    device is gone; the loop reports them LOST without calling the tracker.
    """

    index: int
    timestamp_s: float
    color_bgr: NDArray[np.uint8] | None
    intrinsics: Intrinsics | None = None
    depth_m: NDArray[np.float32] | None = None
    gt_T_world_cam: NDArray[np.float64] | None = None
    gt_box_xywh: tuple[float, float, float, float] | None = None
    payloads: tuple[FramePayload, ...] = ()
    capture_mono_s: float = field(default_factory=_now)
    depth_timestamp_s: float | None = None
    skipped_before: int = 0
    link_lost_reason: str | None = None

    def __post_init__(self) -> None:
        readonly(self.color_bgr)
        readonly(self.depth_m)
        readonly(self.gt_T_world_cam)
        if not isinstance(self.payloads, tuple):
            object.__setattr__(self, "payloads", tuple(self.payloads))
        if not math.isfinite(self.capture_mono_s):
            object.__setattr__(self, "capture_mono_s", _now())

    def payload(self, kind: type[P]) -> P | None:
        """The frame's payload of type ``kind`` (or a subclass), None if it has none."""
        for p in self.payloads:
            if isinstance(p, kind):
                return p
        return None

    @property
    def gray_f32(self) -> NDArray[np.float32]:
        """Grey image in [0, 255] as float32 (computed on demand)."""
        import cv2

        if self.color_bgr is None:
            raise ValueError(f"frame {self.index} has no image")
        if self.color_bgr.ndim == 2:
            return self.color_bgr.astype(np.float32)
        return cv2.cvtColor(self.color_bgr, cv2.COLOR_BGR2GRAY).astype(np.float32)
