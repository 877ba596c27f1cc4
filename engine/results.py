"""What a tracker returns for each frame, and the tracker interface.

Trackers are pure: a frame in, one frozen :class:`TrackResult` out - no I/O. What is
specific to one tracker travels typed:

- ``details``: one frozen dataclass per tracker deriving from :class:`TrackDetails`
  (e.g. :class:`engine.dense.details.DenseDetails`, ``PtzDetails`` in
  :mod:`engine.trackers.ptz`), for display, benches and logs;
- ``commands``: frozen dataclasses deriving from :class:`TrackerCommand` that something
  outside the tracker must carry out (a pan-tilt head move, a robot-camera correction).
  The pipeline hands every record to its sinks; the sink that knows the device executes
  the command (:mod:`engine.sinks`).

Example::

    res = tracker.track(frame)
    if isinstance(res.details, PtzDetails):
        print(res.details.omega_rad_s)
    for cmd in res.commands_of(PanTiltCommand):
        head.command(cmd.pan_deg, cmd.tilt_deg)
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar, runtime_checkable

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


class TrackDetails:
    """Base of the per-tracker detail records (frozen dataclasses, read-only arrays)."""

    __slots__ = ()


class TrackerCommand:
    """Base of the typed commands a tracker asks a sink to carry out."""

    __slots__ = ()


D = TypeVar("D", bound=TrackDetails)
C = TypeVar("C", bound=TrackerCommand)


@dataclass(frozen=True, slots=True)
class TrackResult:
    """One frame's tracker output.

    ``T_world_cam`` is the camera pose (held at the last good pose while LOST, never
    extrapolated). Box trackers fill ``box_xywh``; 2D trackers fill ``T_world_cam`` with the
    position and identity rotation. ``timings_ms`` has one entry per pipeline stage.
    ``message`` is one line saying why the state is what it is when that is not obvious
    (why LOST, what initialisation waits for). ``residual`` and ``inlier_fraction`` are
    those of *this* frame, also when it is LOST.
    """

    state: TrackState
    T_world_cam: NDArray[np.float64] | None = None
    box_xywh: tuple[float, float, float, float] | None = None
    residual: float | None = None
    inlier_fraction: float | None = None
    keyframe_id: int | None = None
    timings_ms: Mapping[str, float] = field(default_factory=dict)
    overlay: Overlay | None = None
    details: TrackDetails | None = None
    commands: tuple[TrackerCommand, ...] = ()
    message: str = ""

    def __post_init__(self) -> None:
        readonly(self.T_world_cam)
        if not isinstance(self.commands, tuple):
            object.__setattr__(self, "commands", tuple(self.commands))

    def details_as(self, kind: type[D]) -> D | None:
        """``details`` if it is a ``kind``, else None."""
        return self.details if isinstance(self.details, kind) else None

    def commands_of(self, kind: type[C]) -> tuple[C, ...]:
        """The commands of type ``kind``, in order."""
        return tuple(c for c in self.commands if isinstance(c, kind))


@runtime_checkable
class Tracker(Protocol):
    """A tracker consumes frames in order and returns one result per frame.

    A tracker whose commands need a device may also define ``sinks()`` returning the
    :class:`engine.pipeline.Sink` objects that carry them out (the presenter's robot-camera
    control); every pipeline running the tracker then adds them. A tracker with work its
    frame's result need not wait for may define ``after_frame()`` (the dense keyframe
    tracker builds a new keyframe there); the pipeline calls it once the record reached the
    sinks, and the tracker's next ``track`` does what is still pending first, so results
    never depend on whether it ran.
    """

    name: str

    @property
    def params(self) -> Any: ...

    def set_params(self, params: Any) -> None:
        """Swap in new (frozen, validated) parameters; takes effect on the next frame."""

    def reset(self) -> None:
        """Forget all state; the next frame re-initialises."""

    def track(self, frame: Frame) -> TrackResult: ...
