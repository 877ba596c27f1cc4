"""The one bridge between the Qt GUI and the plain-Python engine loop.

:class:`EngineBridge` lives in the GUI thread. ``start()`` creates a fresh
:class:`EngineThread` (a ``QThread`` subclass) that opens the source and the tracker *on the
engine thread* (a bad folder or a camera that does not open is reported through ``failed``,
never raised in the GUI thread), then iterates :func:`engine.loop.run_tracking`, polling
``isInterruptionRequested()`` once per frame. Nothing here calls ``terminate()`` or
``processEvents()``.

Signals (all emitted in the GUI thread, in this order per run):

- ``started()`` - the source and the tracker opened; ``bridge.run_info`` describes the run.
- ``result_ready(FrameRecord)`` - one per processed frame (immutable record).
- ``failed(str)`` - one line ``"TypeName: message"``; the run ends after it.
- ``finished()`` - the run is over (source exhausted, stopped, or failed).

Commands reach the engine as typed dataclasses through a ``queue.Queue``
(:class:`engine.loop.SetParams`, :class:`engine.loop.ResetTracker`) and apply on the next frame.
"""

from __future__ import annotations

import dataclasses
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from PySide6.QtCore import QObject, QThread, Signal, Slot

from engine.loop import Command, FrameRecord, ResetTracker, SetParams, run_tracking
from engine.sources.base import Source

#: every EngineThread this module created; pruned by :func:`running_threads`
_THREADS: list[QThread] = []

#: how many records may be queued towards the GUI before the engine waits (bounds memory
#: when the GUI is busy; the engine never blocks longer than one interruption poll)
MAX_IN_FLIGHT = 8


def running_threads() -> list[QThread]:
    """QThreads created by this module that are still running (for the test fixture)."""
    alive = [t for t in _THREADS if t.isRunning()]
    # keep references only to running threads; finished ones may be garbage-collected
    _THREADS[:] = alive
    return list(alive)


def one_line(exc: BaseException) -> str:
    """``"TypeName: first line of the message"`` - what the status bar shows."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


@dataclass(frozen=True, slots=True)
class RunInfo:
    """What the current run tracks: set before ``started`` is emitted."""

    run_id: int
    source_spec: str
    source_name: str
    source_len: int
    live: bool
    nominal_fps: float
    tracker_name: str
    params: Any
    realtime: bool


def _default_open_source(spec: str) -> Source:
    from engine.sources import open_source

    return open_source(spec)


def _default_create_tracker(name: str, params: Any | None) -> Any:
    from engine.trackers import create_tracker

    return create_tracker(name, params)


class EngineThread(QThread):
    """Opens a source and a tracker and runs the engine loop until done or interrupted.

    Internal signals carry the run id so the bridge can drop anything a previous (already
    stopped) run still had queued.
    """

    opened = Signal(int, object)  # run id, RunInfo
    record_ready = Signal(int, object)  # run id, FrameRecord
    run_failed = Signal(int, str)  # run id, one-line message
    run_done = Signal(int)  # run id

    def __init__(
        self,
        run_id: int,
        source_spec: str,
        tracker_name: str,
        params: Any | None,
        realtime: bool,
        commands: queue.Queue[Command],
        open_source: Callable[[str], Source],
        create_tracker: Callable[[str, Any | None], Any],
        max_frames: int | None = None,
    ) -> None:
        super().__init__()
        self.setObjectName(f"studiotrack-engine-{run_id}")
        self.run_id = run_id
        self._spec = source_spec
        self._tracker_name = tracker_name
        self._params = params
        self._realtime = realtime
        self._commands = commands
        self._open_source = open_source
        self._create_tracker = create_tracker
        self._max_frames = max_frames
        self.in_flight = threading.Semaphore(MAX_IN_FLIGHT)

    def _should_stop(self) -> bool:
        return self.isInterruptionRequested()

    def _wait_for_room(self) -> bool:
        """Back-pressure: wait until the GUI consumed records; False if interrupted."""
        while not self.in_flight.acquire(timeout=0.05):
            if self.isInterruptionRequested():
                return False
        return True

    def run(self) -> None:
        source: Source | None = None
        try:
            source = self._open_source(self._spec)
            tracker = self._create_tracker(self._tracker_name, self._params)
            info = RunInfo(
                run_id=self.run_id,
                source_spec=self._spec,
                source_name=str(getattr(source, "name", self._spec)),
                source_len=len(source),
                live=bool(getattr(source, "live", False)),
                nominal_fps=float(getattr(source, "nominal_fps", 0.0)),
                tracker_name=str(getattr(tracker, "name", self._tracker_name)),
                params=getattr(tracker, "params", self._params),
                realtime=self._realtime,
            )
            self.opened.emit(self.run_id, info)
            for record in run_tracking(
                source,
                tracker,
                should_stop=self._should_stop,
                commands=self._commands,
                max_frames=self._max_frames,
                realtime=self._realtime,
            ):
                if not self._wait_for_room():
                    break
                self.record_ready.emit(self.run_id, record)
        except Exception as exc:  # every engine failure ends the run with one line
            self.run_failed.emit(self.run_id, one_line(exc))
        finally:
            if source is not None:
                try:
                    source.close()
                except Exception as exc:
                    self.run_failed.emit(self.run_id, f"closing source: {one_line(exc)}")
            self.run_done.emit(self.run_id)


class EngineBridge(QObject):
    """Runs the engine loop in a QThread and re-emits its events in the GUI thread.

    ``open_source`` and ``create_tracker`` are injectable (tests use fakes, e.g. a tracker
    that raises mid-run); by default they are :func:`engine.sources.open_source` and
    :func:`engine.trackers.create_tracker`.
    """

    started = Signal()
    result_ready = Signal(object)  # FrameRecord
    failed = Signal(str)
    finished = Signal()
    params_changed = Signal(object)  # the params object sent with set_params()

    def __init__(
        self,
        parent: QObject | None = None,
        *,
        open_source: Callable[[str], Source] | None = None,
        create_tracker: Callable[[str, Any | None], Any] | None = None,
        stop_timeout_ms: int = 10_000,
    ) -> None:
        super().__init__(parent)
        self._open_source = open_source or _default_open_source
        self._create_tracker = create_tracker or _default_create_tracker
        self._stop_timeout_ms = stop_timeout_ms
        self._thread: EngineThread | None = None
        # stopped threads stay referenced until their last queued event (run_done) arrives,
        # so no queued signal outlives its sender
        self._retired: dict[int, EngineThread] = {}
        self._run_id = 0
        self._active_run: int | None = None
        self._commands: queue.Queue[Command] = queue.Queue()
        self.run_info: RunInfo | None = None
        self.last_error: str | None = None
        self.frames_received = 0

    # ------------------------------------------------------------------ control
    @property
    def is_running(self) -> bool:
        """True from ``start()`` until ``finished`` was emitted."""
        return self._active_run is not None

    def start(
        self,
        source_spec: str,
        tracker_name: str,
        params: Any | None = None,
        *,
        realtime: bool = False,
        max_frames: int | None = None,
    ) -> None:
        """Start a run (stopping the current one first). Errors arrive through ``failed``."""
        if self.is_running:
            self.stop()
        if self._thread is not None:  # did not stop in time: keep it referenced until done
            self._retired[self._thread.run_id] = self._thread
            self._thread = None
        self._run_id += 1
        self._active_run = self._run_id
        self._commands = queue.Queue()
        self.run_info = None
        self.last_error = None
        self.frames_received = 0
        thread = EngineThread(
            self._run_id,
            source_spec,
            tracker_name,
            params,
            realtime,
            self._commands,
            self._open_source,
            self._create_tracker,
            max_frames=max_frames,
        )
        # the receiver (self) lives in the GUI thread: these are queued connections
        thread.opened.connect(self._on_opened)
        thread.record_ready.connect(self._on_record)
        thread.run_failed.connect(self._on_failed)
        thread.run_done.connect(self._on_done)
        self._thread = thread
        _THREADS.append(thread)
        thread.start()

    def stop(self) -> bool:
        """Request interruption and wait for the engine thread; emits ``finished``.

        Returns False if the thread did not end within the timeout (e.g. a blocked camera
        read); it is then left to end on its own and still counts in :func:`running_threads`.
        """
        thread = self._thread
        if thread is None:
            return True
        thread.requestInterruption()
        ended = thread.wait(self._stop_timeout_ms)
        if ended:
            self._retired[thread.run_id] = thread
            self._thread = None
        if self._active_run == thread.run_id:
            self._end_run()
        return bool(ended)

    def send_command(self, command: Command) -> None:
        """Queue a typed command; the engine applies it before the next frame."""
        self._commands.put(command)

    def set_params(self, params: Any) -> None:
        """Swap the tracker's (frozen, validated) params on the next frame."""
        self.send_command(SetParams(params))
        if self.run_info is not None:
            self.run_info = dataclasses.replace(self.run_info, params=params)
        self.params_changed.emit(params)

    def reset_tracker(self) -> None:
        self.send_command(ResetTracker())

    # ------------------------------------------------------------ engine events
    def _end_run(self) -> None:
        self._active_run = None
        self.finished.emit()

    @Slot(int, object)
    def _on_opened(self, run_id: int, info: object) -> None:
        if run_id != self._active_run:
            return
        assert isinstance(info, RunInfo)
        self.run_info = info
        self.started.emit()

    @Slot(int, object)
    def _on_record(self, run_id: int, record: object) -> None:
        thread = self._thread
        if thread is not None and thread.run_id == run_id:
            thread.in_flight.release()
        if run_id != self._active_run:
            return
        assert isinstance(record, FrameRecord)
        self.frames_received += 1
        self.result_ready.emit(record)

    @Slot(int, str)
    def _on_failed(self, run_id: int, message: str) -> None:
        if run_id != self._active_run:
            return
        self.last_error = message
        self.failed.emit(message)

    @Slot(int)
    def _on_done(self, run_id: int) -> None:
        self._retired.pop(run_id, None)
        thread = self._thread
        if thread is not None and thread.run_id == run_id:
            # run() has returned; wait() only joins the OS thread (immediate)
            thread.wait(self._stop_timeout_ms)
            self._thread = None
        if run_id == self._active_run:
            self._end_run()
