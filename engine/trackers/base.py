"""The tracker interface every paper's tracker implements, and its per-frame result."""

from __future__ import annotations

import argparse
import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from engine.frames import Frame, readonly


class TrackState(enum.Enum):
    """Tracking state shown on the status light and sent with every output."""

    INITIALIZING = "INITIALIZING"
    TRACKING = "TRACKING"
    DEGRADED = "DEGRADED"
    RELOCALIZING = "RELOCALIZING"
    LOST = "LOST"

    @property
    def is_good(self) -> bool:
        return self in (TrackState.TRACKING, TrackState.DEGRADED)


@dataclass(frozen=True, slots=True)
class Overlay:
    """What a tracker wants drawn over the live image (pixel coordinates)."""

    points_uv: NDArray[np.float32] | None = None  # (N, 2)
    point_weights: NDArray[np.float32] | None = None  # (N,) in [0, 1]: green used, red rejected
    boxes_xywh: tuple[tuple[float, float, float, float], ...] = ()
    box_labels: tuple[str, ...] = ()
    polylines_uv: tuple[NDArray[np.float32], ...] = ()
    crosshair_uv: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        readonly(self.points_uv)
        readonly(self.point_weights)


@dataclass(frozen=True, slots=True)
class TrackResult:
    """One frame's tracker output.

    ``T_world_cam`` is the camera pose (held at the last good pose while LOST, never
    extrapolated). Box trackers fill ``box_xywh``; 2D trackers fill ``T_world_cam`` with the
    position and identity rotation. ``timings_ms`` has one entry per pipeline stage.
    """

    state: TrackState
    T_world_cam: NDArray[np.float64] | None = None
    box_xywh: tuple[float, float, float, float] | None = None
    residual: float | None = None
    inlier_fraction: float | None = None
    keyframe_id: int | None = None
    timings_ms: Mapping[str, float] = field(default_factory=dict)
    overlay: Overlay | None = None
    extras: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        readonly(self.T_world_cam)


@runtime_checkable
class Tracker(Protocol):
    """A tracker consumes frames in order and returns one result per frame."""

    name: str

    @property
    def params(self) -> Any: ...

    def set_params(self, params: Any) -> None:
        """Swap in new (frozen, validated) parameters; takes effect on the next frame."""

    def reset(self) -> None:
        """Forget all state; the next frame re-initialises."""

    def track(self, frame: Frame) -> TrackResult: ...


@dataclass(frozen=True, slots=True)
class TrackerSpec:
    """How to build a tracker by name, its parameter class and optional CLI hooks."""

    name: str
    description: str
    params_cls: type
    factory: Callable[[Any], Tracker]
    needs_depth: bool = False
    needs_image: bool = True
    output: str = "pose"  # "pose" | "box" | "position2d"
    add_cli_arguments: Callable[[argparse.ArgumentParser], None] | None = None
    params_from_cli: Callable[[argparse.Namespace, Any], Any] | None = None
