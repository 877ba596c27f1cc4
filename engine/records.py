"""What crosses between the engine loop, its sinks and its controller.

:class:`FrameRecord` is one processed frame (frozen; its arrays read-only); the commands are
the typed messages a controller (the GUI's run owner, a test) sends to a running pipeline
through a ``queue.Queue``; they apply between frames.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from engine.frames import Frame
from engine.results import TrackResult
from engine.timecode import Timecode


@dataclass(frozen=True, slots=True)
class SetParams:
    """Swap the tracker's parameters (a frozen, validated params object)."""

    params: Any


@dataclass(frozen=True, slots=True)
class ResetTracker:
    """Forget tracker state; the next frame re-initialises."""


@dataclass(frozen=True, slots=True)
class AddSink:
    """Open a sink and give it every record from the next frame on."""

    sink: Any  # engine.pipeline.Sink


@dataclass(frozen=True, slots=True)
class RemoveSink:
    """Close the sink of this name and stop feeding it."""

    name: str


Command = SetParams | ResetTracker | AddSink | RemoveSink


@dataclass(frozen=True, slots=True)
class FrameRecord:
    """Everything the display and the sinks need about one processed frame.

    ``process_ms`` is the tracker's wall time for this frame, ``cpu_ms`` the engine
    thread's CPU time in it (the difference is time spent waiting, e.g. for the GIL).
    ``capture_mono_s`` (the frame's) and ``done_mono_s`` (tracker finished) are on
    ``time.monotonic()``; ``late_ms`` is how far behind its due time the frame was pulled
    from a paced (real-time) source, 0 otherwise.
    """

    seq: int
    frame: Frame
    result: TrackResult
    tracker_name: str
    process_ms: float
    fps: float
    source_len: int
    capture_mono_s: float = 0.0
    done_mono_s: float = 0.0
    cpu_ms: float = 0.0
    late_ms: float = 0.0
    #: frames the live source skipped over the last second, per second (newest-frame policy)
    skipped_per_s: float = 0.0
    #: SMPTE timecode of the frame: the source's own, else generated from the start value
    #: at the output rate (:class:`engine.timecode.TimecodeClock`)
    timecode: Timecode | None = None
