"""The pipeline: sinks, mailbox, trace, faults, events, typed results (no Qt)."""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from engine.camera import Intrinsics
from engine.frames import Frame, FramePayload, SourceFiles
from engine.loop import AddSink, FrameRecord, RemoveSink, run_tracking
from engine.pipeline import (
    Mailbox,
    Pipeline,
    RunPhase,
    SinkBase,
    SinkHealth,
    SinkLevel,
    Trace,
    TraceSample,
)
from engine.results import TrackResult, TrackState
from engine.sources.base import Source


class Src(Source):
    name = "test source"
    nominal_fps = 100.0

    def __init__(self, n: int = 20) -> None:
        self.n = n
        self._intr = Intrinsics(fx=50, fy=50, cx=16, cy=12, width=32, height=24)

    @property
    def intrinsics(self) -> Intrinsics:
        return self._intr

    def __len__(self) -> int:
        return self.n

    def frames(self) -> Iterator[Frame]:
        for i in range(self.n):
            T = np.eye(4)
            T[0, 3] = 0.01 * i
            yield Frame(i, i / self.nominal_fps, np.zeros((24, 32, 3), np.uint8), self._intr,
                        gt_T_world_cam=T, payloads=(SourceFiles(color_path=f"{i}.png"),))


class Trk:
    name = "test"

    def __init__(self, fail_at: int = -1, lost: tuple[int, ...] = ()) -> None:
        self.fail_at = fail_at
        self.lost = lost
        self.params = None

    def set_params(self, params: object) -> None:
        self.params = params

    def reset(self) -> None:
        pass

    def track(self, frame: Frame) -> TrackResult:
        if frame.index == self.fail_at:
            raise RuntimeError(f"boom at {frame.index}")
        state = TrackState.LOST if frame.index in self.lost else TrackState.TRACKING
        return TrackResult(state, frame.gt_T_world_cam, inlier_fraction=0.5,
                           message="lost on purpose" if state is TrackState.LOST else "")


class Collect(SinkBase):
    name = "collect"

    def __init__(self) -> None:
        self.opened = 0
        self.seqs: list[int] = []
        self.faults: list[str] = []
        self.closed = 0

    def open(self, run: object) -> None:
        self.opened += 1

    def on_record(self, record: FrameRecord) -> None:
        self.seqs.append(record.seq)

    def on_fault(self, message: str) -> None:
        self.faults.append(message)

    def close(self) -> None:
        self.closed += 1


class Raises(Collect):
    name = "raises"

    def on_record(self, record: FrameRecord) -> None:
        super().on_record(record)
        if record.seq == 3:
            raise OSError("disk gone")


def test_mailbox_keeps_latest_and_counts_drops() -> None:
    box: Mailbox[int] = Mailbox()
    assert box.take() is None
    box.put(1)
    box.put(2)  # 1 was never taken
    assert box.take() == 2
    assert box.take() is None  # nothing new
    assert box.peek() == 2
    box.put(3)
    assert box.take() == 3
    assert (box.put_count, box.dropped) == (3, 1)


def test_mailbox_notifies_once_per_item_taken() -> None:
    box: Mailbox[int] = Mailbox()
    calls: list[int] = []
    box.notify = lambda: calls.append(box.put_count)
    box.put(1)
    box.put(2)  # the reader has not taken 1: no second wake-up (a stalled reader gets one)
    box.put(3)
    assert calls == [1]
    assert box.take() == 3
    box.put(4)
    assert calls == [1, 4]


def test_trace_cursor_and_missed() -> None:
    tr = Trace(3)
    rec = next(run_tracking(Src(1), Trk()))
    for _ in range(5):
        tr.append(TraceSample.of(rec))
    items, cur, missed = tr.since(0)
    assert (len(items), cur, missed) == (3, 5, 2)
    assert tr.since(cur) == ([], 5, 0)


def test_sinks_get_every_record_in_order_and_are_closed() -> None:
    a, b = Collect(), Collect()
    recs = list(run_tracking(Src(10), Trk(), sinks=[a, b]))
    assert [r.seq for r in recs] == list(range(10))
    for s in (a, b):
        assert (s.opened, s.seqs, s.closed) == (1, list(range(10)), 1)


def test_a_sink_that_raises_is_disabled_and_reported_tracking_goes_on() -> None:
    bad, good = Raises(), Collect()
    pipe = Pipeline(Src(10), Trk(), [bad, good])
    recs = list(pipe.records())
    assert len(recs) == 10
    assert good.seqs == list(range(10))
    assert bad.seqs == [0, 1, 2, 3]  # disabled after the failing record
    assert bad.closed == 1  # released at once
    health = {h.name: h for h in pipe.status().sinks}
    assert health["raises"].level is SinkLevel.FAILED
    assert "OSError: disk gone" in health["raises"].message
    events, _ = pipe.events_since(0)
    assert any("raises failed and is disabled" in e.message and "tracking goes on" in e.message
               for e in events)


def test_tracker_exception_faults_sinks_closes_them_and_propagates() -> None:
    s = Collect()
    with pytest.raises(RuntimeError, match="boom at 5"):
        list(run_tracking(Src(20), Trk(fail_at=5), sinks=[s]))
    assert s.seqs == [0, 1, 2, 3, 4]
    assert s.faults == ["RuntimeError: boom at 5"]
    assert s.closed == 1


def test_run_holds_sinks_open_after_a_fault_until_stopped() -> None:
    s = Collect()
    pipe = Pipeline(Src(1000), Trk(fail_at=5), [s], hold_on_fault=True)
    stop = threading.Event()
    th = threading.Thread(target=pipe.run, args=(stop.is_set,))
    th.start()
    deadline = time.monotonic() + 5
    while pipe.phase is not RunPhase.FAULT and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.1)
    assert pipe.phase is RunPhase.FAULT
    assert s.faults
    assert s.closed == 0
    st = pipe.status()
    assert st.error == "RuntimeError: boom at 5"
    stop.set()
    th.join(5)
    assert not th.is_alive()
    assert s.closed == 1
    assert pipe.status().phase is RunPhase.ENDED
    assert pipe.status().error  # the error stays visible after stop


def test_sinks_can_be_added_and_removed_while_running() -> None:
    late = Collect()
    pipe = Pipeline(Src(10), Trk())
    out = []
    for rec in pipe.records():
        out.append(rec.seq)
        if rec.seq == 2:
            pipe.send(AddSink(late))
        if rec.seq == 6:
            pipe.send(RemoveSink("collect"))
    assert late.seqs == [3, 4, 5, 6]
    assert (late.opened, late.closed) == (1, 1)


def test_state_changes_are_timed_events_with_the_reason() -> None:
    pipe = Pipeline(Src(12), Trk(lost=(4, 5, 6)))
    list(pipe.records())
    events, cursor = pipe.events_since(0)
    msgs = [e.message for e in events]
    assert "tracking LOST at frame 4: lost on purpose" in msgs
    assert "tracking recovered at frame 7 after 3 frames" in msgs
    assert all(e.mono_s > 0 and e.wall_s > 0 for e in events)
    assert pipe.events_since(cursor) == ([], cursor)


def test_mailbox_never_blocks_the_engine_and_trace_keeps_every_frame() -> None:
    pipe = Pipeline(Src(50), Trk(), trace_size=100)
    list(pipe.records())  # nobody takes from the mailbox (a stalled display)
    assert pipe.mailbox.put_count == 50
    assert pipe.mailbox.dropped == 49
    assert pipe.mailbox.take().seq == 49
    samples, _, missed = pipe.trace.since(0)
    assert [s.seq for s in samples] == list(range(50))
    assert missed == 0
    assert samples[3].payload(SourceFiles).color_path == "3.png"


def test_realtime_pacing_and_status_rates() -> None:
    pipe = Pipeline(Src(30), Trk(), realtime=True)  # 100 fps source
    t0 = time.monotonic()
    list(pipe.records())
    dt = time.monotonic() - t0
    assert dt >= 0.28  # 30 frames at 100 fps, not flat out
    st = pipe.status()
    assert st.target_fps == 100.0
    assert st.frames == 30
    assert st.tracker_ms is not None
    assert st.capture_to_done is not None
    assert st.capture_to_done.p50_ms >= 0


def test_records_carry_capture_and_done_times() -> None:
    rec = next(run_tracking(Src(1), Trk()))
    assert rec.capture_mono_s == rec.frame.capture_mono_s
    assert rec.done_mono_s >= rec.capture_mono_s
    assert rec.cpu_ms >= 0


def test_payloads_are_typed_and_frozen() -> None:
    f = next(Src(1).frames())
    assert f.payload(SourceFiles) == SourceFiles(color_path="0.png")

    @dataclasses.dataclass(frozen=True, slots=True)
    class Other(FramePayload):
        x: int = 1

    assert f.payload(Other) is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.payload(SourceFiles).color_path = "x"  # type: ignore[misc, union-attr]


def test_sink_health_is_asked_from_status() -> None:
    class Alarmed(SinkBase):
        name = "alarmed"

        def health(self) -> SinkHealth:
            return SinkHealth(self.name, SinkLevel.ALARM, "no route to host")

    pipe = Pipeline(Src(3), Trk(), [Alarmed()])
    list(pipe.records())
    [h] = pipe.status().sinks
    assert (h.level, h.message) == (SinkLevel.ALARM, "no route to host")


def test_sinks_are_registered_like_trackers() -> None:
    from engine.sinks import available_sinks

    assert {"pose-outputs", "recorder", "robot-camera", "pan-tilt-head", "3d-view"} <= set(
        available_sinks())


def test_after_frame_work_runs_after_the_sinks_have_the_record() -> None:
    """A tracker's after_frame (work its result need not wait for) is called once per
    tracked frame, after every sink got that frame's record; its time is kept."""
    order: list[str] = []

    class Late(Trk):
        def after_frame(self) -> None:
            order.append("after")

    class Log(Collect):
        def on_record(self, record: FrameRecord) -> None:
            order.append(f"rec{record.seq}")

    pipe = Pipeline(Src(4), Late(), [Log()])
    recs = list(pipe.records())
    assert len(recs) == 4
    assert order == ["rec0", "after", "rec1", "after", "rec2", "after", "rec3", "after"]
    assert [t.seq for t in pipe.frame_timings] == [0, 1, 2, 3]
    assert all(t.after_frame_ms >= 0.0 for t in pipe.frame_timings)
