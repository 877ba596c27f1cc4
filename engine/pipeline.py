"""The air path: source -> tracker -> sinks, driven on one engine thread.

A :class:`Pipeline` pulls frames from a source (paced to its frame rate when real time),
applies the operator's typed commands between frames, tracks each frame, hands the
:class:`engine.loop.FrameRecord` to every :class:`Sink` (pose outputs, recorder, robot
control, head commands, 3D view...) and publishes it for a display:

- :attr:`Pipeline.mailbox`: the latest record only. Publishing never waits; a record the
  display did not take before the next one arrived is dropped and counted.
- :attr:`Pipeline.trace`: a bounded history of light :class:`TraceSample` (no images) that
  plots read, so a slow display still draws every frame's numbers.
- :meth:`Pipeline.status`: a thread-safe :class:`RunStatus` snapshot (state, rates,
  latency, every sink's :class:`SinkHealth`).
- :attr:`Pipeline.events`: timed :class:`RunEvent` lines for every state change (LOST,
  relock, sink failure or recovery, engine error).

A source or a tracker may bring sinks of its own (``sinks()``): the ones that carry out the
tracker's commands (ptz-sim's simulated head, the presenter's robot-camera control), so any
pipeline that runs them closes their loop. A sink that raises is disabled for the rest of
the run, reported (``FAILED`` in its health, an event) and tracking goes on. An exception
of the source or the tracker is a *fault*: every sink hears ``on_fault`` (pose outputs then
keep sending the last good pose flagged LOST at their own rate); :meth:`Pipeline.records`
then closes the sinks and re-raises (CLI), while :meth:`Pipeline.run` with
``hold_on_fault`` keeps them open until ``should_stop()`` (the operator's Stop) and returns
the status with the error.

Example::

    pipe = Pipeline(open_source("synthetic"), create_tracker("dense"),
                    [PoseOutputSink(config)], realtime=True, hold_on_fault=True)
    status = pipe.run(should_stop=stop_event.is_set)   # on the engine thread
    pipe.mailbox.take()                                # GUI thread: newest record or None
"""

from __future__ import annotations

import collections
import contextlib
import enum
import math
import queue
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, Protocol, TypeVar, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from engine.frames import FramePayload
from engine.realtime import (
    PriorityGrant,
    freeze_heap,
    raise_priority,
    run_queue_s,
    thaw_heap,
    use_air_switch_interval,
)
from engine.records import AddSink, Command, FrameRecord, RemoveSink, ResetTracker, SetParams
from engine.results import TrackDetails, Tracker, TrackResult, TrackState
from engine.sources.base import Source
from engine.timecode import TimecodeClock, nearest_rate

T = TypeVar("T")

#: a real-time run's engine thread asks for this nice value (refused without the right to:
#: reported, never an error)
ENGINE_NICE = -5
#: how often the engine thread looks at the sinks' health for events (s)
HEALTH_POLL_S = 0.25
#: a real-time run is "falling behind" when its rate over the last second is below this
#: fraction of the target, or frames were pulled this late (s)
BEHIND_FRACTION = 0.9
BEHIND_LATE_S = 0.1


def one_line(exc: BaseException) -> str:
    """``"TypeName: first line of the message"``."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


# ------------------------------------------------------------------------------ sinks
class SinkLevel(enum.Enum):
    """How a sink is doing; the header is green only for OK."""

    OFF = "OFF"  # configured but not in use
    WAITING = "WAITING"  # open, nothing to do yet (no pose so far)
    OK = "OK"  # doing its job
    WARNING = "WARNING"  # doing its job with trouble (dropped samples, slow)
    ALARM = "ALARM"  # its job is failing now (send errors, stalled)
    FAILED = "FAILED"  # it raised and was disabled for the rest of the run

    @property
    def is_bad(self) -> bool:
        return self in (SinkLevel.ALARM, SinkLevel.FAILED)


@dataclass(frozen=True, slots=True)
class LatencyStats:
    """Percentiles of a latency (ms) over the last samples."""

    p50_ms: float
    p95_ms: float
    max_ms: float
    n: int

    @staticmethod
    def of(values_ms: Sequence[float] | NDArray[np.float64]) -> LatencyStats | None:
        a = np.asarray(values_ms, dtype=np.float64)
        a = a[np.isfinite(a)]
        if a.size == 0:
            return None
        p50, p95 = np.percentile(a, [50, 95])
        return LatencyStats(float(p50), float(p95), float(a.max()), int(a.size))

    def to_json_dict(self) -> dict[str, float]:
        return {"p50": self.p50_ms, "p95": self.p95_ms, "max": self.max_ms}


@dataclass(frozen=True, slots=True)
class TargetHealth:
    """One destination of a sink (e.g. a FreeD host)."""

    name: str
    level: SinkLevel
    rate_hz: float = 0.0
    packets: int = 0
    errors: int = 0
    message: str = ""


@dataclass(frozen=True, slots=True)
class SinkHealth:
    """A sink's state for the status header and the log (any thread may ask)."""

    name: str
    level: SinkLevel
    message: str = ""
    targets: tuple[TargetHealth, ...] = ()
    latency: LatencyStats | None = None  # capture -> the sink's action (packet on the wire)
    counters: Mapping[str, float] = field(default_factory=dict)


@runtime_checkable
class Sink(Protocol):
    """Something that acts on every record: sends, records, moves a device.

    ``open``, ``on_record``, ``on_fault`` and ``close`` run on the engine thread and must not
    block (a sink that does slow I/O has its own thread); ``health`` may be called from any
    thread. An exception from any of them disables the sink for the rest of the run.
    """

    name: str

    def open(self, run: RunInfo) -> None: ...

    def on_record(self, record: FrameRecord) -> None: ...

    def on_fault(self, message: str) -> None: ...

    def close(self) -> None: ...

    def health(self) -> SinkHealth: ...


class SinkBase:
    """Convenience base: no-op ``open``/``on_fault``/``close``, OK health."""

    name = "sink"

    def open(self, run: RunInfo) -> None:
        pass

    def on_record(self, record: FrameRecord) -> None:
        pass

    def on_fault(self, message: str) -> None:
        pass

    def close(self) -> None:
        pass

    def health(self) -> SinkHealth:
        return SinkHealth(self.name, SinkLevel.OK)


# ------------------------------------------------------------------- run description
class RunPhase(enum.Enum):
    STARTING = "STARTING"  # opening source, tracker, sinks
    RUNNING = "RUNNING"
    FAULT = "FAULT"  # the source or tracker raised; sinks hold (LOST) until stop
    ENDED = "ENDED"  # the source ended, the run was stopped, or a fault was closed


@dataclass(frozen=True, slots=True)
class RunInfo:
    """What a run tracks (sinks get it in ``open``)."""

    source_spec: str
    source_name: str
    source_len: int
    live: bool
    nominal_fps: float
    tracker_name: str
    params: Any
    realtime: bool


@dataclass(frozen=True, slots=True)
class RunEvent:
    """A timed state change: tracking LOST/recovered, sink failure/recovery, engine error."""

    mono_s: float
    wall_s: float
    level: str  # "info" | "warning" | "error"
    origin: str  # "tracker" | "sink:<name>" | "engine"
    message: str


@dataclass(frozen=True, slots=True)
class RunStatus:
    """A snapshot of a run for the status header (thread-safe to take, frozen)."""

    phase: RunPhase
    info: RunInfo | None
    state: TrackState | None  # of the latest frame
    message: str  # the latest frame's tracker message
    frames: int
    fps: float  # over the last second
    target_fps: float  # the source's rate when real time, else 0
    falling_behind: bool
    late_frames: int  # frames pulled more than a frame late (real time)
    tracker_ms: LatencyStats | None  # tracker wall time per frame
    capture_to_done: LatencyStats | None  # capture -> tracker done
    display_dropped: int  # records replaced before the display took them
    sinks: tuple[SinkHealth, ...]
    error: str  # the fault, one line ("" if none)
    last_record_mono_s: float  # when the latest record was made (0: none yet)
    timecode: str | None = None


@dataclass(frozen=True, slots=True)
class FrameTiming:
    """Where the engine thread's time went for one frame (ms; NaN where unknown).

    ``pace_overshoot_ms``: woke after the frame's pacing slot (real time; 0 when it did
    not sleep); ``source_wait_ms``: waiting for the source's next frame (the render-ahead
    thread, a camera); ``track_ms``/``track_cpu_ms``: the tracker's wall and CPU time, of
    which ``track_run_queue_ms`` runnable without a CPU (the OS) and ``track_gil_ms`` the
    rest (blocked: the interpreter lock held by another thread); ``sinks_ms``: handing the
    record to the sinks; ``after_frame_ms``: the tracker's work after the record went out
    (``after_frame``: a dense keyframe built; 0 when none).
    """

    seq: int
    pace_overshoot_ms: float
    source_wait_ms: float
    track_ms: float
    track_cpu_ms: float
    track_run_queue_ms: float
    sinks_ms: float
    after_frame_ms: float = 0.0

    @property
    def track_gil_ms(self) -> float:
        return max(0.0, self.track_ms - self.track_cpu_ms - self.track_run_queue_ms)


# ------------------------------------------------------------------------- mailbox
class Mailbox(Generic[T]):
    """Holds the latest item; ``put`` never waits, replacing an untaken item counts a drop.

    ``notify`` (optional, set by the reader) is called by ``put`` when an item arrives in an
    empty box: once per item the reader takes, never for the ones it drops, so a reader
    that stalls gets one wake-up, not a queue of them. It must not block (the window's is a
    queued Qt signal: the display draws right after a frame, in the engine's idle time).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._item: T | None = None
        self._fresh = False
        self.put_count = 0
        self.dropped = 0
        self.notify: Callable[[], None] | None = None

    def put(self, item: T) -> None:
        with self._lock:
            was_fresh = self._fresh
            if was_fresh:
                self.dropped += 1
            self._item = item
            self._fresh = True
            self.put_count += 1
        notify = self.notify
        if notify is not None and not was_fresh:
            notify()

    def take(self) -> T | None:
        """The latest item if it was not taken yet, else None."""
        with self._lock:
            if not self._fresh:
                return None
            self._fresh = False
            return self._item

    @property
    def waiting(self) -> bool:
        """An item is there that was not taken yet."""
        with self._lock:
            return self._fresh

    def peek(self) -> T | None:
        """The latest item, taken or not."""
        with self._lock:
            return self._item

    def clear(self) -> None:
        with self._lock:
            self._item = None
            self._fresh = False


# --------------------------------------------------------------------------- trace
@dataclass(frozen=True, slots=True)
class TraceSample:
    """The numbers of one processed frame, without images (for plots and statistics)."""

    seq: int
    index: int
    timestamp_s: float
    capture_mono_s: float
    done_mono_s: float
    state: TrackState
    T_world_cam: NDArray[np.float64] | None
    gt_T_world_cam: NDArray[np.float64] | None
    box_xywh: tuple[float, float, float, float] | None
    gt_box_xywh: tuple[float, float, float, float] | None
    residual: float | None
    inlier_fraction: float | None
    keyframe_id: int | None
    process_ms: float
    details: TrackDetails | None
    payloads: tuple[FramePayload, ...]

    @staticmethod
    def of(rec: FrameRecord) -> TraceSample:
        f, r = rec.frame, rec.result
        return TraceSample(
            seq=rec.seq, index=f.index, timestamp_s=f.timestamp_s,
            capture_mono_s=rec.capture_mono_s, done_mono_s=rec.done_mono_s, state=r.state,
            T_world_cam=r.T_world_cam, gt_T_world_cam=f.gt_T_world_cam, box_xywh=r.box_xywh,
            gt_box_xywh=f.gt_box_xywh, residual=r.residual, inlier_fraction=r.inlier_fraction,
            keyframe_id=r.keyframe_id, process_ms=rec.process_ms, details=r.details,
            payloads=tuple(p for p in f.payloads if type(p).light),
        )

    def payload(self, kind: type[Any]) -> Any:
        for p in self.payloads:
            if isinstance(p, kind):
                return p
        return None


class Trace:
    """A bounded history of :class:`TraceSample`; readers keep their own cursor."""

    def __init__(self, size: int) -> None:
        self.size = max(0, int(size))
        self._lock = threading.Lock()
        self._items: collections.deque[TraceSample] = collections.deque(maxlen=self.size or 1)
        self.total = 0  # samples ever appended (cursor space)

    def append(self, sample: TraceSample) -> None:
        if not self.size:
            return
        with self._lock:
            self._items.append(sample)
            self.total += 1

    def since(self, cursor: int) -> tuple[list[TraceSample], int, int]:
        """Samples appended after ``cursor`` (oldest first), the new cursor, and how many
        of those were already pushed out of the history (missed)."""
        with self._lock:
            total = self.total
            n_new = total - cursor
            if n_new <= 0:
                return [], total, 0
            kept = min(n_new, len(self._items))
            items = list(self._items)[len(self._items) - kept:]
            return items, total, n_new - kept


# ------------------------------------------------------------------------ pipeline
class _Slot:
    """A sink in the pipeline, with its failure state."""

    def __init__(self, sink: Sink) -> None:
        self.sink = sink
        self.name = str(getattr(sink, "name", type(sink).__name__))
        self.opened = False
        self.failed = ""
        self.last_level: SinkLevel | None = None

    def health(self) -> SinkHealth:
        if self.failed:
            return SinkHealth(self.name, SinkLevel.FAILED, self.failed)
        try:
            return self.sink.health()
        except Exception as exc:
            return SinkHealth(self.name, SinkLevel.FAILED, f"health(): {one_line(exc)}")


class Pipeline:
    """Source -> tracker -> sinks on the calling thread (see the module docstring).

    ``commands`` (a queue of :mod:`engine.loop` commands) may be shared with a controller;
    :meth:`send` puts one. ``clock`` and ``sleep`` are injectable for tests.
    """

    def __init__(
        self,
        source: Source,
        tracker: Tracker,
        sinks: Sequence[Sink] = (),
        *,
        realtime: bool = False,
        max_frames: int | None = None,
        hold_on_fault: bool = False,
        trace_size: int = 0,
        source_spec: str = "",
        commands: queue.Queue[Command] | None = None,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
        timecode: TimecodeClock | None = None,
        freeze_gc: bool | None = None,
    ) -> None:
        self.source = source
        #: freeze the heap from the first frame to the end of the run
        #: (:func:`engine.realtime.freeze_heap`); None = in real-time runs (on air), where a
        #: full collection (30-110 ms holding the interpreter) would stall the outputs
        self.freeze_gc = bool(realtime) if freeze_gc is None else freeze_gc
        self.gc_frozen: int | None = None  # objects frozen at the first frame (None: not)
        self._thawed = False
        #: the OS priorities the run's threads got: "engine" (real time), and each sink's
        #: own thread that reports one (a ``priority`` :class:`PriorityGrant` attribute)
        self.priorities: dict[str, PriorityGrant] = {}
        self.tracker = tracker
        self.realtime = bool(realtime)
        self.max_frames = max_frames
        self.hold_on_fault = hold_on_fault
        self.mailbox: Mailbox[FrameRecord] = Mailbox()
        self.trace = Trace(trace_size)
        self.events: collections.deque[RunEvent] = collections.deque(maxlen=2000)
        self.events_total = 0
        self._commands: queue.Queue[Command] = commands if commands is not None else queue.Queue()
        self._clock = clock
        self._sleep = sleep
        self._lock = threading.Lock()
        # then the sinks the source and the tracker bring to carry out the tracker's commands
        # (ptz-sim's simulated head, the presenter's robot-camera control)
        own = (*_own_sinks(source), *_own_sinks(tracker))
        self._slots: list[_Slot] = [_Slot(s) for s in (*sinks, *own)]
        fps = float(getattr(source, "nominal_fps", 0.0) or 0.0)
        #: every record's timecode: the source's, else generated from a start value at the
        #: output rate (default 00:00:00:00 at the video rate nearest the source's)
        self.timecode = timecode if timecode is not None else TimecodeClock(
            rate=nearest_rate(fps))
        self.info = RunInfo(
            source_spec=source_spec or str(getattr(source, "name", "")),
            source_name=str(getattr(source, "name", source_spec)),
            source_len=_safe_len(source),
            live=bool(getattr(source, "live", False)),
            nominal_fps=fps,
            tracker_name=str(getattr(tracker, "name", "tracker")),
            params=getattr(tracker, "params", None),
            realtime=self.realtime,
        )
        self._phase = RunPhase.STARTING
        self._error = ""
        self._frames = 0
        self._late = 0
        self._last: FrameRecord | None = None
        self._last_state: TrackState | None = None
        self._lost_since: int | None = None
        self._done_times: collections.deque[float] = collections.deque(maxlen=512)
        self._lateness: collections.deque[tuple[float, float]] = collections.deque(maxlen=64)
        self._tracker_ms: collections.deque[float] = collections.deque(maxlen=600)
        self._cap_done_ms: collections.deque[float] = collections.deque(maxlen=600)
        self._next_health = 0.0
        #: the engine thread's timing of the last frames (:class:`FrameTiming`)
        self.frame_timings: collections.deque[FrameTiming] = collections.deque(maxlen=4096)

    # ------------------------------------------------------------------ control
    def send(self, command: Command) -> None:
        """Queue a typed command; it applies before the next frame (thread-safe)."""
        self._commands.put(command)

    @property
    def phase(self) -> RunPhase:
        return self._phase

    def sink_names(self) -> list[str]:
        with self._lock:
            return [s.name for s in self._slots]

    def events_since(self, cursor: int) -> tuple[list[RunEvent], int]:
        """Events after ``cursor`` and the new cursor (events beyond the history are lost)."""
        with self._lock:
            total = self.events_total
            n = min(total - cursor, len(self.events))
            return (list(self.events)[len(self.events) - n:] if n > 0 else []), total

    def status(self) -> RunStatus:
        with self._lock:
            last = self._last
            slots = list(self._slots)
            now = self._clock()
            recent = [t for t in self._done_times if t > now - 1.0]
            if len(recent) >= 2:
                fps = (len(recent) - 1) / max(recent[-1] - recent[0], 1e-6)
            else:
                fps = float(len(recent))
            target = self.info.nominal_fps if self.realtime else 0.0
            late_recent = any(t > now - 1.0 and late > BEHIND_LATE_S
                              for t, late in self._lateness)
            running = self._phase is RunPhase.RUNNING and self._frames > 5
            behind = bool(target and running and (fps < BEHIND_FRACTION * target
                                                   or late_recent))
            tracker_ms = LatencyStats.of(list(self._tracker_ms))
            cap_done = LatencyStats.of(list(self._cap_done_ms))
            phase, error, frames, late = self._phase, self._error, self._frames, self._late
        return RunStatus(
            phase=phase,
            info=self.info,
            state=None if last is None else last.result.state,
            message="" if last is None else last.result.message,
            frames=frames,
            fps=fps,
            target_fps=target,
            falling_behind=behind,
            late_frames=late,
            tracker_ms=tracker_ms,
            capture_to_done=cap_done,
            display_dropped=self.mailbox.dropped,
            sinks=tuple(s.health() for s in slots),
            error=error,
            last_record_mono_s=0.0 if last is None else last.done_mono_s,
            timecode=None if last is None or last.timecode is None else str(last.timecode),
        )

    # --------------------------------------------------------------------- runs
    def records(self, should_stop: Callable[[], bool] = lambda: False) -> Iterator[FrameRecord]:
        """Yield every record (after the sinks had it). A source/tracker exception: the
        sinks hear ``on_fault`` and are closed, then it propagates."""
        self._open_sinks()
        try:
            yield from self._loop(should_stop)
        except Exception as exc:
            self._fault(exc)
            raise
        finally:
            self._close_sinks()

    def run(self, should_stop: Callable[[], bool] = lambda: False) -> RunStatus:
        """Drive the run to its end or until ``should_stop()``; never raises for a source or
        tracker error (the status says it). With ``hold_on_fault`` the sinks stay open after
        a fault (pose outputs send LOST) until ``should_stop()``."""
        self._open_sinks()
        try:
            for _ in self._loop(should_stop):
                pass
        except Exception as exc:
            self._fault(exc)
            if self.hold_on_fault:
                while not should_stop():
                    self._apply_commands()
                    self._poll_health(self._clock())
                    self._sleep(0.02)
        finally:
            self._close_sinks()
        return self.status()

    # ----------------------------------------------------------------- internals
    def _event(self, level: str, origin: str, message: str) -> None:
        ev = RunEvent(self._clock(), time.time(), level, origin, message)
        with self._lock:
            self.events.append(ev)
            self.events_total += 1

    def _fail_slot(self, slot: _Slot, what: str, exc: BaseException) -> None:
        slot.failed = f"{what}: {one_line(exc)}"
        self._event("error", f"sink:{slot.name}", f"{slot.name} failed and is disabled "
                    f"({slot.failed}); tracking goes on")
        if what != "close" and slot.opened:
            with contextlib.suppress(Exception):
                slot.sink.close()
            slot.opened = False

    def _open_slot(self, slot: _Slot) -> None:
        try:
            slot.sink.open(self.info)
            slot.opened = True
        except Exception as exc:
            self._fail_slot(slot, "open", exc)
            return
        grant = getattr(slot.sink, "priority", None)
        if isinstance(grant, PriorityGrant):
            self._note_priority(slot.name, grant)

    def _open_sinks(self) -> None:
        for slot in list(self._slots):
            self._open_slot(slot)
        if self.realtime:
            use_air_switch_interval()
            self._note_priority("engine", raise_priority("engine", nice=ENGINE_NICE))

    def _note_priority(self, name: str, grant: PriorityGrant) -> None:
        with self._lock:
            self.priorities[name] = grant
        self._event("info", "engine", grant.line())

    def _close_sinks(self) -> None:
        if self.gc_frozen is not None and not self._thawed:
            self._thawed = True
            thaw_heap()
        with self._lock:
            self._phase = RunPhase.ENDED
            slots = list(self._slots)
        for slot in slots:
            if slot.opened:
                try:
                    slot.sink.close()
                except Exception as exc:
                    self._fail_slot(slot, "close", exc)
                slot.opened = False

    def _fault(self, exc: BaseException) -> None:
        msg = one_line(exc)
        with self._lock:
            self._phase = RunPhase.FAULT
            self._error = msg
        self._event("error", "engine", f"engine error: {msg}"
                    + ("; outputs hold the last good pose flagged LOST" if self._slots else ""))
        for slot in list(self._slots):
            if slot.opened and not slot.failed:
                try:
                    slot.sink.on_fault(msg)
                except Exception as e:
                    self._fail_slot(slot, "on_fault", e)

    def _apply_commands(self) -> None:
        while True:
            try:
                cmd = self._commands.get_nowait()
            except queue.Empty:
                return
            if isinstance(cmd, SetParams):
                self.tracker.set_params(cmd.params)
            elif isinstance(cmd, ResetTracker):
                self.tracker.reset()
            elif isinstance(cmd, AddSink):
                slot = _Slot(cmd.sink)
                with self._lock:
                    self._slots.append(slot)
                self._open_slot(slot)
            elif isinstance(cmd, RemoveSink):
                with self._lock:
                    gone = [s for s in self._slots if s.name == cmd.name]
                    self._slots = [s for s in self._slots if s.name != cmd.name]
                for slot in gone:
                    if slot.opened:
                        try:
                            slot.sink.close()
                        except Exception as exc:
                            self._fail_slot(slot, "close", exc)
                        slot.opened = False

    def _poll_health(self, now: float) -> None:
        if now < self._next_health:
            return
        self._next_health = now + HEALTH_POLL_S
        for slot in list(self._slots):
            h = slot.health()
            prev = slot.last_level
            slot.last_level = h.level
            if h.level is prev or h.level is SinkLevel.FAILED:
                continue
            if h.level.is_bad:
                self._event("error", f"sink:{slot.name}",
                            f"{slot.name}: {h.level.value}" + (f" - {h.message}" if h.message
                                                                else ""))
            elif prev is not None and prev.is_bad:
                self._event("info", f"sink:{slot.name}", f"{slot.name}: recovered "
                            f"({h.level.value})")

    def _note_state(self, rec: FrameRecord) -> None:
        state, index = rec.result.state, rec.frame.index
        prev, self._last_state = self._last_state, state
        if state is TrackState.LOST and self._lost_since is None:
            self._lost_since = index
            why = f": {rec.result.message}" if rec.result.message else ""
            self._event("warning", "tracker", f"tracking LOST at frame {index}{why}")
        elif state.is_good and self._lost_since is not None:
            self._event("info", "tracker", f"tracking recovered at frame {index} after "
                        f"{index - self._lost_since} frames")
            self._lost_since = None
        elif prev is None or (state is not prev and state is TrackState.DEGRADED):
            why = f": {rec.result.message}" if rec.result.message else ""
            self._event("info", "tracker", f"{state.value} from frame {index}{why}")

    def _loop(self, should_stop: Callable[[], bool]) -> Iterator[FrameRecord]:
        period = (1.0 / self.info.nominal_fps
                  if self.realtime and self.info.nominal_fps > 0 else 0.0)
        if self.freeze_gc and self.gc_frozen is None:
            self.gc_frozen = freeze_heap()
        with self._lock:
            self._phase = RunPhase.RUNNING
        frames = iter(self.source.frames())
        # a real-time run tells a source that makes its frames ahead (the built-in studio)
        # when it is done with one, so the next is made in its idle time
        source_idle = getattr(frames, "consumer_idle", None) if period else None
        source_idle = source_idle if callable(source_idle) else None
        seq = 0
        anchor = self._clock()
        k = 0  # frames since the pacing anchor
        fps_ema = 0.0
        last_t = time.perf_counter()
        n = self.info.source_len
        name = self.info.tracker_name
        last_good: TrackResult | None = None
        skips: collections.deque[tuple[float, int]] = collections.deque()
        after_frame = getattr(self.tracker, "after_frame", None)
        after_frame = after_frame if callable(after_frame) else None
        while True:
            if should_stop() or (self.max_frames is not None and seq >= self.max_frames):
                return
            self._apply_commands()
            late_s = 0.0
            overshoot_ms = 0.0
            if period:
                due = anchor + k * period
                now = self._clock()
                slept = False
                while due - now > 0 and not should_stop():
                    self._sleep(min(due - now, 0.05))
                    now = self._clock()
                    slept = True
                late_s = max(0.0, now - due)
                if slept:
                    overshoot_ms = late_s * 1000.0
                if late_s > period:
                    # more than a frame behind: measured, not made up by rushing
                    with self._lock:
                        self._late += 1
                    anchor, k = now, 0
            w0 = time.perf_counter()
            try:
                frame = next(frames)
            except StopIteration:
                return
            k += 1
            t0 = time.perf_counter()
            rq0 = run_queue_s()
            c0 = time.thread_time()
            if frame.link_lost_reason is not None:
                # a live source without a picture (device gone): LOST, the tracker not called
                result = _link_lost(frame.link_lost_reason, last_good)
            else:
                result = self.tracker.track(frame)
                last_good = result
            c1 = time.thread_time()
            t1 = time.perf_counter()
            rq1 = run_queue_s()
            done = self._clock()
            if frame.skipped_before:
                skips.append((done, frame.skipped_before))
            while skips and skips[0][0] < done - 1.0:
                skips.popleft()
            dt = t1 - last_t
            last_t = t1
            inst = 1.0 / dt if dt > 0 else 0.0
            fps_ema = inst if seq == 0 else 0.9 * fps_ema + 0.1 * inst
            rec = FrameRecord(
                seq=seq, frame=frame, result=result, tracker_name=name,
                process_ms=(t1 - t0) * 1000.0, fps=fps_ema, source_len=n,
                capture_mono_s=frame.capture_mono_s, done_mono_s=done,
                cpu_ms=(c1 - c0) * 1000.0, late_ms=late_s * 1000.0,
                skipped_per_s=float(sum(n_skip for _, n_skip in skips)),
                timecode=self.timecode.stamp(frame),
            )
            for slot in list(self._slots):
                if slot.opened and not slot.failed:
                    try:
                        slot.sink.on_record(rec)
                    except Exception as exc:
                        self._fail_slot(slot, "on_record", exc)
            sinks_ms = (time.perf_counter() - t1) * 1000.0
            self.mailbox.put(rec)
            if source_idle is not None:
                source_idle()
            self.trace.append(TraceSample.of(rec))
            with self._lock:
                self._last = rec
                self._frames += 1
                self._done_times.append(done)
                self._lateness.append((done, late_s))
                self._tracker_ms.append(rec.process_ms)
                cap = (done - frame.capture_mono_s) * 1000.0
                if math.isfinite(cap) and cap >= 0:
                    self._cap_done_ms.append(cap)
            self._note_state(rec)
            self._poll_health(done)
            after_ms = 0.0
            if after_frame is not None and frame.link_lost_reason is None:
                # work the frame's result did not wait for (a new keyframe), now that the
                # sinks and the window have the record; before the next frame is paced
                a0 = time.perf_counter()
                after_frame()
                after_ms = (time.perf_counter() - a0) * 1000.0
            self.frame_timings.append(FrameTiming(
                seq=seq, pace_overshoot_ms=overshoot_ms, source_wait_ms=(t0 - w0) * 1000.0,
                track_ms=rec.process_ms, track_cpu_ms=rec.cpu_ms,
                track_run_queue_ms=(rq1 - rq0) * 1000.0, sinks_ms=sinks_ms,
                after_frame_ms=after_ms))
            seq += 1
            yield rec
            if self.max_frames is not None and seq >= self.max_frames:
                return  # without waiting for one more (live) frame


def _link_lost(reason: str, last: TrackResult | None) -> TrackResult:
    """LOST while the source has no picture: hold the last pose/box, say why."""
    return TrackResult(
        state=TrackState.LOST,
        T_world_cam=None if last is None else last.T_world_cam,
        box_xywh=None if last is None else last.box_xywh,
        message=reason,
    )


def _own_sinks(obj: Any) -> Sequence[Sink]:
    fn = getattr(obj, "sinks", None)
    return tuple(fn()) if callable(fn) else ()


def _safe_len(source: Any) -> int:
    try:
        return len(source)
    except Exception:
        return 0
