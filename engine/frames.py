"""The frame every source yields and the tracker consumes."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics


def readonly(a: np.ndarray | None) -> np.ndarray | None:
    """Mark an array read-only so that it can cross threads inside a frozen record."""
    if a is not None and a.flags.writeable:
        a.flags.writeable = False
    return a


@dataclass(frozen=True, slots=True)
class Frame:
    """One time step of a source.

    ``color_bgr`` is uint8 (H, W, 3) BGR (OpenCV order) or None for non-image sources
    (range beacons); ``depth_m`` is float32 (H, W) metres with 0 where invalid.
    ``gt_T_world_cam`` is the ground-truth camera pose if known; ``gt_box_xywh`` the
    ground-truth target box (OTB convention: top-left x, y, width, height) if known.
    ``extras`` carries source-specific data (e.g. range readings, presenter truth).
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
    extras: dict[str, Any] = field(default_factory=dict)
    skipped_before: int = 0
    link_lost_reason: str | None = None

    def __post_init__(self) -> None:
        readonly(self.color_bgr)
        readonly(self.depth_m)
        readonly(self.gt_T_world_cam)

    @property
    def gray_f32(self) -> NDArray[np.float32]:
        """Grey image in [0, 255] as float32 (computed on demand)."""
        import cv2

        if self.color_bgr is None:
            raise ValueError(f"frame {self.index} has no image")
        if self.color_bgr.ndim == 2:
            return self.color_bgr.astype(np.float32)
        return cv2.cvtColor(self.color_bgr, cv2.COLOR_BGR2GRAY).astype(np.float32)
