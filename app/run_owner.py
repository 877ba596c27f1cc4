"""The run owner: the one camera pipeline of the window, owned by the application context.

Every page starts and stops runs here (``ctx.run``), so the outputs, the recorder, the 3D
view and the status header work for every tracker. A run is an
:class:`engine.pipeline.Pipeline` driven on a :class:`RunThread` (a ``QThread``): the source,
the tracker and the sinks open *on the engine thread* (a bad folder reports through
``failed``, never raises in the GUI thread), and the thread runs until the source ends or
``stop()``. The engine never waits for the window: the GUI reads the latest record
(:meth:`RunOwner.take_latest`, coalesced, drops counted), the light history
(:meth:`RunOwner.trace_since`) and the :class:`engine.pipeline.RunStatus` at its own display
rate. An engine exception mid-run keeps the sinks open (pose outputs send the last good pose
flagged LOST at the output rate) until the operator stops; the header says ERROR.

Signals (GUI thread): ``started(RunInfo)`` once the run opened, ``failed(str)`` one line when
opening failed or the engine raised mid-run, ``finished(RunStatus | None)`` when it is over;
``outputs_changed()`` when the pose outputs are switched or reconfigured; ``params_changed``.
Nothing here calls ``terminate()`` or ``processEvents()``.

Example (a page)::

    ctx.run.start(RunRequest("synthetic", "dense", page="Live"))
    rec = ctx.run.latest()              # newest FrameRecord or None
    ctx.run.set_params(new_params)      # applies on the next frame
    ctx.run.stop()
"""

from __future__ import annotations

import dataclasses
import queue
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from PySide6.QtCore import QObject, QThread, Signal, Slot

from engine.loop import AddSink, Command, FrameRecord, RemoveSink, ResetTracker, SetParams
from engine.outputs.sender import OutputConfig, TargetSpec, check_targets
from engine.pipeline import (
    Pipeline,
    RunEvent,
    RunInfo,
    RunPhase,
    RunStatus,
    Sink,
    SinkHealth,
    TraceSample,
    one_line,
)
from engine.sinks.pose_output import PoseOutputSink
from engine.sinks.view_feed import ViewFeedSink
from engine.sources.base import Source

#: every RunThread this module created; pruned by :func:`running_threads`
_THREADS: list[QThread] = []

#: light history kept per run for plots (a page hidden this long catches up when shown)
TRACE_SIZE = 2048
#: a run's status is recomputed at most this often for the window (percentiles, health)
STATUS_MAX_AGE_S = 0.1

DEFAULT_OUTPUTS = OutputConfig(
    targets=(
        TargetSpec("freed", "127.0.0.1", 40000),
        TargetSpec("opentrackio", "127.0.0.1", 55555, "json"),
    )
)


def running_threads() -> list[QThread]:
    """QThreads created by this module that are still running (for the test fixture)."""
    alive = [t for t in _THREADS if t.isRunning()]
    _THREADS[:] = alive
    return list(alive)


@dataclass(frozen=True, slots=True)
class RunRequest:
    """What a page asks the owner to run.

    ``tracker_factory`` builds a special tracker instead of the registry's (e.g. the sweep's
    keyframe-adding dense tracker); ``sinks`` are extra sinks for this run only (e.g. the
    sweep recorder); ``page`` names the page that started it (shown in the header);
    ``record_dir`` records the run as a session folder (on the recorder's own thread).
    """

    source_spec: str
    tracker: str
    params: Any | None = None
    realtime: bool = True
    max_frames: int | None = None
    page: str = "Live"
    tracker_factory: Callable[[], Any] | None = None
    sinks: tuple[Sink, ...] = ()
    record_dir: str | None = None  # record a replayable session folder of this run


def _outputs_pose(tracker: str) -> bool:
    """Whether ``tracker`` outputs a camera pose (not a box or a 2D position)."""
    from engine.errors import TrackerError
    from engine.trackers import get_spec

    try:
        return get_spec(tracker).output == "pose"
    except TrackerError:  # a name outside the registry (a test fake): treat as a pose
        return True


def _default_open_source(spec: str) -> Source:
    from engine.sources import open_source

    return open_source(spec)


def _default_create_tracker(name: str, params: Any | None) -> Any:
    from engine.trackers import create_tracker

    return create_tracker(name, params)


class RunThread(QThread):
    """Opens the source, the tracker and the sinks, then drives the pipeline to its end."""

    opened = Signal(int, object)  # run id, RunInfo
    open_failed = Signal(int, str)  # run id, one line
    run_done = Signal(int, object)  # run id, final RunStatus or None
    record_ready = Signal(int)  # run id: a record arrived for the display (once per take)

    def __init__(
        self,
        run_id: int,
        request: RunRequest,
        sinks: Sequence[Sink],
        commands: queue.Queue[Command],
        open_source: Callable[[str], Source],
        create_tracker: Callable[[str, Any | None], Any],
        source_setup: Callable[[Source], Source] | None = None,
    ) -> None:
        super().__init__()
        self.setObjectName(f"studiotrack-engine-{run_id}")
        self._source_setup = source_setup
        self.run_id = run_id
        self.request = request
        self._sinks = list(sinks)
        self._commands = commands
        self._open_source = open_source
        self._create_tracker = create_tracker
        self.pipeline: Pipeline | None = None  # set on the engine thread once opened
        self.native_id: int | None = None  # the OS thread id (CPU accounting in benches)

    def run(self) -> None:
        import threading

        self.native_id = threading.get_native_id()
        source: Source | None = None
        status: RunStatus | None = None
        req = self.request
        try:
            source = self._open_source(req.source_spec)
            if self._source_setup is not None:  # the project's lens file (issue 13)
                source = self._source_setup(source)
            tracker = (req.tracker_factory() if req.tracker_factory is not None
                       else self._create_tracker(req.tracker, req.params))
            extra: list[Sink] = []
            if req.record_dir:
                source, rec_sink = self._recorder(source, tracker)
                extra.append(rec_sink)
            pipe = Pipeline(
                source, tracker, [*self._sinks, *req.sinks, *extra], realtime=req.realtime,
                max_frames=req.max_frames, hold_on_fault=True, trace_size=TRACE_SIZE,
                source_spec=req.source_spec, commands=self._commands,
            )
            self.pipeline = pipe
            run_id = self.run_id
            pipe.mailbox.notify = lambda: self.record_ready.emit(run_id)
            self.opened.emit(self.run_id, pipe.info)
            status = pipe.run(self.isInterruptionRequested)
        except Exception as exc:  # opening failed: one line, the window goes on
            self.open_failed.emit(self.run_id, one_line(exc))
        finally:
            if source is not None:
                try:
                    source.close()
                except Exception as exc:
                    self.open_failed.emit(self.run_id, f"closing source: {one_line(exc)}")
            self.run_done.emit(self.run_id, status)


    def _recorder(self, source: Source, tracker: Any) -> tuple[Source, Sink]:
        """The session recorder for this run: frames normalised as replay reads them, the
        writing on its own thread (the engine never waits for the disk)."""
        from engine.session.recorder import RecorderSink, SessionRecorder
        from engine.sinks.background import BackgroundSink

        req = self.request
        assert req.record_dir is not None
        pose = next((s for s in self._sinks if isinstance(s, PoseOutputSink)), None)
        recorder = SessionRecorder(
            req.record_dir, source=source, source_spec=req.source_spec,
            tracker_name=str(getattr(tracker, "name", req.tracker)),
            tracker_params=getattr(tracker, "params", None),
            outputs_config=None if pose is None else pose.config)

        def stats() -> dict[str, Any] | None:
            st = pose.stats() if pose is not None else None
            return None if st is None else dict(st.to_json_dict())

        sink = RecorderSink(recorder, outputs_config=None if pose is None else pose.config,
                            outputs_stats=stats if pose is not None else None)
        return recorder.normalizing(source), BackgroundSink(sink)


class RunOwner(QObject):
    """The window's one run (see the module docstring).

    ``open_source`` and ``create_tracker`` are injectable (tests use fakes); by default they
    are :func:`engine.sources.open_source` and :func:`engine.trackers.create_tracker`.
    """

    started = Signal(object)  # RunInfo
    failed = Signal(str)
    finished = Signal(object)  # RunStatus | None
    outputs_changed = Signal()
    params_changed = Signal(object)
    #: a record is waiting for the display (queued from the engine thread, at most one per
    #: record taken): the window draws right after the frame instead of at a random phase
    record_ready = Signal()

    def __init__(
        self,
        parent: QObject | None = None,
        *,
        log: Any = None,
        open_source: Callable[[str], Source] | None = None,
        create_tracker: Callable[[str, Any | None], Any] | None = None,
        stop_timeout_ms: int = 10_000,
    ) -> None:
        super().__init__(parent)
        self.log = log
        self._open_source = open_source or _default_open_source
        self._create_tracker = create_tracker or _default_create_tracker
        self._stop_timeout_ms = stop_timeout_ms
        self._thread: RunThread | None = None
        self._current: RunThread | None = None  # the current epoch's thread (kept after end)
        self._retired: dict[int, RunThread] = {}
        self._run_id = 0
        self._active: int | None = None
        self._commands: queue.Queue[Command] = queue.Queue()
        self.request: RunRequest | None = None
        self.run_info: RunInfo | None = None
        self.last_error: str | None = None
        self.final_status: RunStatus | None = None
        self.stopped_by_user = False
        self._fault_reported = False
        self._event_cursor = 0
        # pose outputs: the configuration and switch live here, the sink in the run
        self.outputs_config: OutputConfig = DEFAULT_OUTPUTS
        self.outputs_enabled = False
        self._pose_sink: PoseOutputSink | None = None
        self._view_publish: Callable[..., Any] | None = None
        self._status_cache: tuple[Any, float, RunStatus] | None = None
        self._view_sink: ViewFeedSink | None = None
        #: the studio set-up applied to every run's source (the project's lens file: see
        #: AppContext.apply_project_setup); None = the source as it is
        self.source_setup: Callable[[Source], Source] | None = None

    # ------------------------------------------------------------------ state
    @property
    def is_running(self) -> bool:
        """True from ``start()`` until ``finished`` was emitted."""
        return self._active is not None

    @property
    def epoch(self) -> int:
        """The current run's id (changes with every start: pages reset their cursors)."""
        return self._run_id

    @property
    def pipeline(self) -> Pipeline | None:
        """The pipeline of the current run, or of the one that just ended (None before it
        opened and after a new start)."""
        t = self._current
        return t.pipeline if t is not None and t.run_id == self._run_id else None

    def latest(self) -> FrameRecord | None:
        """The newest record of the running run (None when idle: nothing stale)."""
        p = self.pipeline
        return p.mailbox.peek() if p is not None and self.is_running else None

    def take_latest(self) -> FrameRecord | None:
        """The newest record if not taken yet (the display clock; untaken ones are drops)."""
        p = self.pipeline
        return p.mailbox.take() if p is not None and self.is_running else None

    def record_waiting(self) -> bool:
        """A record of the running run is there that the display has not taken."""
        p = self.pipeline
        return p is not None and self.is_running and p.mailbox.waiting

    def trace_since(self, cursor: int) -> tuple[list[TraceSample], int, int]:
        """The run's history after ``cursor`` (also the last frames of a run that just
        ended, so a short run's plots are complete)."""
        p = self.pipeline
        if p is None:
            return [], cursor, 0
        return p.trace.since(cursor)

    @property
    def engine_thread_id(self) -> int | None:
        """The OS id of the current run's engine thread (None before it started)."""
        t = self._current
        return None if t is None else t.native_id

    @property
    def frames_received(self) -> int:
        """Frames the current (or last) run processed."""
        st = self.status()
        return st.frames if st is not None else 0

    def status(self) -> RunStatus | None:
        """The running run's status (at most :data:`STATUS_MAX_AGE_S` old: the header, the
        pages and the display clock all ask); after it ended, its final status."""
        p = self.pipeline
        if p is not None and self.is_running:
            now = time.monotonic()
            cached = self._status_cache
            if cached is not None and cached[0] is p and now - cached[1] < STATUS_MAX_AGE_S:
                return cached[2]
            st = p.status()
            self._status_cache = (p, now, st)
            return st
        return self.final_status

    # ---------------------------------------------------------------- control
    def start(self, request: RunRequest | str, tracker: str | None = None,
              params: Any | None = None, **kw: Any) -> None:
        """Start a run (stopping the current one first). Errors arrive through ``failed``.

        ``start(RunRequest(...))`` or ``start(source_spec, tracker, params, realtime=...,
        page=..., ...)`` (the :class:`RunRequest` fields).
        """
        if not isinstance(request, RunRequest):
            if tracker is None:
                raise TypeError("start(source_spec, tracker, ...) needs a tracker name")
            request = RunRequest(request, tracker, params, **kw)
        if self.is_running:
            self._say("info", f"stopping {self._describe()} to start {request.tracker}")
            self.stop()
        if self._thread is not None:
            self._retired[self._thread.run_id] = self._thread
            self._thread = None
        self._run_id += 1
        self._active = self._run_id
        self._commands = queue.Queue()
        self.request = request
        self.run_info = None
        self._status_cache = None
        self.last_error = None
        self.final_status = None
        self.stopped_by_user = False
        self._fault_reported = False
        self._event_cursor = 0
        sinks: list[Sink] = []
        self._pose_sink = None
        if self.outputs_enabled:
            self._pose_sink = PoseOutputSink(self.outputs_config)
            sinks.append(self._pose_sink)
        self._view_sink = None
        if self._view_publish is not None and _outputs_pose(request.tracker):
            self._view_sink = ViewFeedSink(self._view_publish)
            sinks.append(self._view_sink)
        thread = RunThread(self._run_id, request, sinks, self._commands, self._open_source,
                           self._create_tracker, self.source_setup)
        thread.opened.connect(self._on_opened)
        thread.open_failed.connect(self._on_open_failed)
        thread.run_done.connect(self._on_done)
        thread.record_ready.connect(self._on_record_ready)
        self._thread = thread
        self._current = thread
        _THREADS.append(thread)
        self._say("info", f"starting {request.tracker} on {request.source_spec or '(none)'}"
                  + (f" ({request.page})" if request.page else ""))
        thread.start()

    def stop(self) -> bool:
        """Stop the run and wait for the engine thread; emits ``finished``.

        Returns False if the thread did not end within the timeout (e.g. a blocked camera
        read); it is then left to end on its own and still counts in :func:`running_threads`.
        """
        thread = self._thread
        self.stopped_by_user = True
        if thread is None:
            return True
        thread.requestInterruption()
        ended = thread.wait(self._stop_timeout_ms)
        if ended:
            self._retired[thread.run_id] = thread
            self._thread = None
        if self._active == thread.run_id:
            self._end_run(thread.pipeline.status() if thread.pipeline is not None else None,
                          stopped=True)
        return bool(ended)

    def send(self, command: Command) -> None:
        """Queue a typed command; the engine applies it before the next frame."""
        self._commands.put(command)

    def set_params(self, params: Any) -> None:
        """Swap the tracker's (frozen, validated) params on the next frame."""
        self.send(SetParams(params))
        if self.run_info is not None:
            self.run_info = dataclasses.replace(self.run_info, params=params)
        self.params_changed.emit(params)

    def reset_tracker(self) -> None:
        self.send(ResetTracker())

    # ---------------------------------------------------------------- outputs
    def set_outputs_enabled(self, on: bool) -> None:
        """Switch the pose outputs; a running run gets (or loses) its pose sink at once."""
        if on == self.outputs_enabled:
            return
        if on:
            check_targets(self.outputs_config)
        self.outputs_enabled = on
        if self.is_running:
            if on:
                self._pose_sink = PoseOutputSink(self.outputs_config)
                self.send(AddSink(self._pose_sink))
            elif self._pose_sink is not None:
                self.send(RemoveSink(self._pose_sink.name))
                self._pose_sink = None
        self._say("info", "outputs on: " + ", ".join(
            f"{t.name} (bind {t.effective_bind})" for t in self.outputs_config.targets)
            if on else "outputs off")
        self.outputs_changed.emit()

    def apply_outputs(self, config: OutputConfig) -> None:
        """Put a new output configuration in force; a target that cannot be reached at all
        (a host name that does not resolve...) is refused with one line (OutputError)."""
        check_targets(config)
        self.outputs_config = config
        if self._pose_sink is not None:
            self._pose_sink.set_config(config)
        self.outputs_changed.emit()

    def output_health(self) -> SinkHealth | None:
        """The pose outputs' health while a run feeds them (None: off or no run)."""
        sink = self._pose_sink
        return sink.health() if sink is not None and self.is_running else None

    def priorities(self) -> dict[str, dict[str, object]]:
        """The OS priorities the current run's threads got (engine, output sender)."""
        p = self.pipeline
        if p is None:
            return {}
        return {name: g.to_json_dict() for name, g in dict(p.priorities).items()}

    def output_stats(self) -> Any:
        sink = self._pose_sink
        return sink.stats() if sink is not None else None

    def set_view_publish(self, publish: Callable[..., Any] | None) -> None:
        """Feed the 3D view's live camera (``publish(T_world_cam, intrinsics)``) from the
        running and every later pose run (None: stop feeding)."""
        self._view_publish = publish
        if self.is_running:
            if self._view_sink is not None:
                self.send(RemoveSink(self._view_sink.name))
                self._view_sink = None
            if publish is not None and self.request is not None and _outputs_pose(
                    self.request.tracker):
                self._view_sink = ViewFeedSink(publish)
                self.send(AddSink(self._view_sink))

    # ------------------------------------------------------------------ polling
    def poll(self) -> None:
        """Called by the display clock: engine events become timed log lines; a fault is
        reported once through ``failed``."""
        p = self.pipeline
        if p is None or not self.is_running:
            return
        events, self._event_cursor = p.events_since(self._event_cursor)
        for ev in events:
            self._log_event(ev)
        if p.phase is RunPhase.FAULT and not self._fault_reported:
            self._fault_reported = True
            self._status_cache = None  # the fault is read at once, never a cached state
            self.last_error = p.status().error
            self.failed.emit(self.last_error)

    def shutdown(self) -> None:
        self.stop()

    # ---------------------------------------------------------------- internals
    def _describe(self) -> str:
        r = self.request
        return "the run" if r is None else f"{r.tracker} ({r.page})"

    def _say(self, level: str, text: str) -> None:
        fn = getattr(self.log, level, None)
        if callable(fn):
            fn(text, origin="engine")

    def _log_event(self, ev: RunEvent) -> None:
        fn = getattr(self.log, ev.level, None)
        if callable(fn):
            fn(ev.message, origin=ev.origin, time_s=ev.wall_s)

    def _end_run(self, status: RunStatus | None, stopped: bool = False) -> None:
        p = self.pipeline
        if p is not None:  # the last events (recovery, sink closing) still get logged
            events, self._event_cursor = p.events_since(self._event_cursor)
            for ev in events:
                self._log_event(ev)
        self.final_status = status
        self._status_cache = None
        self._active = None
        req = self.request
        if req is not None and req.record_dir and status is not None:
            rec = next((h for h in status.sinks if h.name == "recorder"), None)
            if rec is not None:
                n = int(rec.counters.get("frames", 0))
                if rec.level.is_bad:
                    self._say("error", f"session {req.record_dir}: {rec.message}")
                else:
                    self._say("info", f"session {req.record_dir}: {n} frames recorded")
        if stopped:
            frames = status.frames if status is not None else 0
            self._say("info", f"run stopped after {frames} frames")
        self.finished.emit(status)

    @Slot(int, object)
    def _on_opened(self, run_id: int, info: object) -> None:
        if run_id != self._active:
            return
        assert isinstance(info, RunInfo)
        self.run_info = info
        self._status_cache = None
        self._say("info", f"tracking {info.source_name} with {info.tracker_name}")
        self.started.emit(info)

    @Slot(int, str)
    def _on_open_failed(self, run_id: int, message: str) -> None:
        if run_id != self._active:
            return
        self.last_error = message
        self._say("error", f"engine stopped: {message}")
        self.failed.emit(message)

    @Slot(int)
    def _on_record_ready(self, run_id: int) -> None:
        if run_id == self._active:
            self.record_ready.emit()

    @Slot(int, object)
    def _on_done(self, run_id: int, status: object) -> None:
        thread = self._retired.pop(run_id, None)
        current = self._thread
        if current is not None and current.run_id == run_id:
            current.wait(self._stop_timeout_ms)  # run() has returned: joins at once
            thread = current
        if run_id == self._active:
            st = status if isinstance(status, RunStatus) else None
            if st is not None and st.error and not self._fault_reported:
                self._fault_reported = True
                self.last_error = st.error
                self.failed.emit(st.error)
            if not (st is not None and st.error) and self.last_error is None:
                frames = st.frames if st is not None else 0
                self._say("info", f"run ended after {frames} frames")
            self._end_run(st)
        if thread is not None and current is thread:
            self._thread = None
