"""The engine loop: source -> tracker -> immutable per-frame records.

Plain Python, no Qt: the CLI, benchmarks and tests iterate it directly; the GUI's engine
thread runs the same generator and polls its interruption flag through ``should_stop``.
Commands from the operator arrive as typed dataclasses through a ``queue.Queue`` and are
applied between frames, so a parameter edit takes effect on the next frame.
"""

from __future__ import annotations

import queue
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from engine.frames import Frame
from engine.sources.base import Source
from engine.trackers.base import Tracker, TrackResult, TrackState


@dataclass(frozen=True, slots=True)
class SetParams:
    """Swap the tracker's parameters (a frozen, validated params object)."""

    params: Any


@dataclass(frozen=True, slots=True)
class ResetTracker:
    """Forget tracker state; the next frame re-initialises."""


Command = SetParams | ResetTracker


@dataclass(frozen=True, slots=True)
class FrameRecord:
    """Everything the display and the outputs need about one processed frame."""

    seq: int
    frame: Frame
    result: TrackResult
    tracker_name: str
    process_ms: float
    fps: float
    source_len: int
    #: frames the live source skipped over the last second, per second (newest-frame policy)
    skipped_per_s: float = 0.0


def _apply_commands(tracker: Tracker, commands: queue.Queue[Command] | None) -> None:
    if commands is None:
        return
    while True:
        try:
            cmd = commands.get_nowait()
        except queue.Empty:
            return
        if isinstance(cmd, SetParams):
            tracker.set_params(cmd.params)
        elif isinstance(cmd, ResetTracker):
            tracker.reset()


def run_tracking(
    source: Source,
    tracker: Tracker,
    *,
    should_stop: Callable[[], bool] = lambda: False,
    commands: queue.Queue[Command] | None = None,
    max_frames: int | None = None,
    realtime: bool = False,
) -> Iterator[FrameRecord]:
    """Track every frame of ``source``; stop cooperatively when ``should_stop()`` is true.

    With ``realtime`` the loop paces itself to the source's nominal frame rate (for
    recorded sources shown to an operator); otherwise it runs flat out.
    """
    n = len(source)
    period_s = 1.0 / source.nominal_fps if realtime and source.nominal_fps > 0 else 0.0
    fps_ema = 0.0
    last_t = time.perf_counter()
    last_good: TrackResult | None = None
    skips: deque[tuple[float, int]] = deque()
    for seq, frame in enumerate(source.frames()):
        if should_stop() or (max_frames is not None and seq >= max_frames):
            return
        _apply_commands(tracker, commands)
        t0 = time.perf_counter()
        if frame.link_lost_reason is not None:
            result = _lost(frame.link_lost_reason, last_good)
        else:
            result = tracker.track(frame)
            last_good = result
        t1 = time.perf_counter()
        if frame.skipped_before:
            skips.append((t1, frame.skipped_before))
        while skips and skips[0][0] < t1 - 1.0:
            skips.popleft()
        if period_s:
            spare = period_s - (t1 - last_t)
            if spare > 0:
                time.sleep(spare)
        now = time.perf_counter()
        dt = now - last_t
        last_t = now
        inst = 1.0 / dt if dt > 0 else 0.0
        fps_ema = inst if seq == 0 else 0.9 * fps_ema + 0.1 * inst
        yield FrameRecord(
            seq=seq,
            frame=frame,
            result=result,
            tracker_name=tracker.name,
            process_ms=(t1 - t0) * 1000.0,
            fps=fps_ema,
            source_len=n,
            skipped_per_s=float(sum(k for _, k in skips)),
        )
        if max_frames is not None and seq + 1 >= max_frames:
            return  # without waiting for one more (live) frame


def _lost(reason: str, last: TrackResult | None) -> TrackResult:
    """LOST while the source has no picture: hold the last pose/box, say why."""
    return TrackResult(
        state=TrackState.LOST,
        T_world_cam=None if last is None else last.T_world_cam,
        box_xywh=None if last is None else last.box_xywh,
        extras={"lost_reason": reason},
    )


