"""The engine loop: :func:`run_tracking` iterates a pipeline; the record and commands.

Plain Python, no Qt. The loop itself is :class:`engine.pipeline.Pipeline` (source ->
tracker -> sinks, paced, with the latest record published for a display); this module is
the generator form used by the CLI, benchmarks and tests, and re-exports the per-frame
record and the typed commands (:mod:`engine.records`)::

    for rec in run_tracking(source, tracker, max_frames=100):
        print(rec.seq, rec.result.state, rec.process_ms)

Commands from the operator arrive as typed dataclasses through a ``queue.Queue`` and are
applied between frames, so a parameter edit takes effect on the next frame.
"""

from __future__ import annotations

import queue
from collections.abc import Callable, Generator, Sequence

from engine.pipeline import Pipeline, Sink
from engine.records import (
    AddSink,
    Command,
    FrameRecord,
    RemoveSink,
    ResetTracker,
    SetParams,
)
from engine.results import Tracker
from engine.sources.base import Source
from engine.timecode import TimecodeClock

__all__ = [
    "AddSink",
    "Command",
    "FrameRecord",
    "RemoveSink",
    "ResetTracker",
    "SetParams",
    "run_tracking",
]


def run_tracking(
    source: Source,
    tracker: Tracker,
    *,
    should_stop: Callable[[], bool] = lambda: False,
    commands: queue.Queue[Command] | None = None,
    max_frames: int | None = None,
    realtime: bool = False,
    sinks: Sequence[Sink] = (),
    timecode: TimecodeClock | None = None,
) -> Generator[FrameRecord, None, None]:
    """Track every frame of ``source``; stop cooperatively when ``should_stop()`` is true.

    With ``realtime`` the loop paces itself to the source's nominal frame rate (for
    recorded sources shown to an operator); otherwise it runs flat out. ``sinks`` get every
    record before it is yielded (see :class:`engine.pipeline.Pipeline`). An exception of
    the source or the tracker propagates after the sinks were told (``on_fault``) and
    closed.
    """
    pipe = Pipeline(source, tracker, sinks, realtime=realtime, max_frames=max_frames,
                    commands=commands, timecode=timecode)
    yield from pipe.records(should_stop)
