"""Timing of the air path: the sender's prepared held slots and slot timings, the engine's
frame timings, thread priorities (best effort), the frozen heap of a show."""

from __future__ import annotations

import contextlib
import gc
import os
import socket
import sys
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from engine import realtime
from engine.camera import Intrinsics
from engine.frames import Frame
from engine.outputs import freed as fd
from engine.outputs import opentrackio as ot
from engine.outputs.sender import OutputConfig, OutputSample, OutputSet, SlotTiming, TargetSpec
from engine.pipeline import FrameTiming, Pipeline
from engine.results import TrackResult, TrackState
from engine.sources.ahead import read_ahead
from engine.sources.base import Source


def _rx() -> socket.socket:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(0.02)
    return rx


def _drain(rx: socket.socket, until: float) -> list[bytes]:
    got = []
    while time.monotonic() < until:
        with contextlib.suppress(TimeoutError):
            got.append(rx.recv(65536))
    return got


def _pose(x_m: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = x_m
    return T


def test_held_slots_go_out_as_prepared_and_a_fresh_pose_replaces_them() -> None:
    """Slots without a new pose are encoded ahead (only bytes go on the wire at their due
    time); the datagrams are the ones the slot would have made: OpenTrackIO sequence numbers
    count on without a gap, and a fresh pose is sent, never the prepared held one."""
    rx_f, rx_o = _rx(), _rx()
    cfg = OutputConfig(targets=(TargetSpec("freed", "127.0.0.1", rx_f.getsockname()[1]),
                                TargetSpec("opentrackio", "127.0.0.1", rx_o.getsockname()[1])))
    out = OutputSet(cfg, rate_hz=50.0, stale_after_s=5.0)
    try:
        now = time.monotonic()
        out.submit(OutputSample(0, 0.0, "TRACKING", _pose(0.5), capture_mono_s=now,
                                done_mono_s=now))
        time.sleep(0.3)  # ~15 slots, all but the first held
        now = time.monotonic()
        out.submit(OutputSample(1, 0.02, "TRACKING", _pose(1.5), capture_mono_s=now,
                                done_mono_s=now))
        time.sleep(0.1)
        freed = _drain(rx_f, time.monotonic() + 0.05)
        otio = _drain(rx_o, time.monotonic() + 0.05)
        held, used = out.held_ticks, out.prepared_used
        timings = list(out.slot_timings)
    finally:
        out.close()
        rx_f.close()
        rx_o.close()
    assert held >= 8
    assert used >= held - 3  # a late wake-up may re-encode; most go out as prepared
    x_mm = [fd.decode_d1(d).x_mm for d in freed]
    assert x_mm[0] == pytest.approx(500.0, abs=1.0)
    assert x_mm[-1] == pytest.approx(1500.0, abs=1.0)  # the fresh pose, not a held one
    first_new = next(i for i, x in enumerate(x_mm) if abs(x - 1500.0) < 1.0)
    assert all(abs(x - 500.0) < 1.0 for x in x_mm[:first_new])
    samples = [ot.decode_datagrams([d])[0] for d in otio]
    seqs = [s["timing"]["sequenceNumber"] for s in samples]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # no slot lost or repeated
    headers = [int.from_bytes(d[6:8], "big") for d in otio]
    assert headers == list(range(headers[0], headers[0] + len(headers)))
    # the slots' own timing: each was sent at or after its wake-up, timer wakes after their
    # deadline; the fresh ones carry their frame's capture time
    assert len(timings) >= len(freed) - 1
    assert all(isinstance(t, SlotTiming) for t in timings)
    for t in timings:
        if t.by_timer and np.isfinite(t.deadline_s):
            assert t.woke_s >= t.deadline_s - 1e-3
            assert t.sent_s >= t.woke_s
            assert t.overshoot_ms == pytest.approx((t.woke_s - t.deadline_s) * 1000.0)
        assert t.late_ms == pytest.approx((t.sent_s - t.due_s) * 1000.0)
    assert sum(1 for t in timings if t.fresh and np.isfinite(t.capture_s)) >= 1


def test_a_new_configuration_discards_the_prepared_slot() -> None:
    rx_a, rx_b = _rx(), _rx()
    cfg_a = OutputConfig(targets=(TargetSpec("freed", "127.0.0.1", rx_a.getsockname()[1]),))
    cfg_b = OutputConfig(targets=(TargetSpec("freed", "127.0.0.1", rx_b.getsockname()[1]),))
    out = OutputSet(cfg_a, rate_hz=50.0, stale_after_s=5.0)
    try:
        now = time.monotonic()
        out.submit(OutputSample(0, 0.0, "TRACKING", _pose(0.25), capture_mono_s=now,
                                done_mono_s=now))
        time.sleep(0.15)
        out.set_config(cfg_b)
        got_b = _drain(rx_b, time.monotonic() + 0.2)
    finally:
        out.close()
        rx_a.close()
        rx_b.close()
    assert len(got_b) >= 5  # the held pose now goes to the new target
    assert fd.decode_d1(got_b[-1]).x_mm == pytest.approx(250.0, abs=1.0)


class _Paced(Source):
    name = "paced"
    nominal_fps = 100.0
    live = False

    @property
    def intrinsics(self) -> Intrinsics:
        return Intrinsics(fx=50, fy=50, cx=16, cy=12, width=32, height=24)

    def __len__(self) -> int:
        return 30

    def frames(self) -> Iterator[Frame]:
        for i in range(30):
            yield Frame(i, i / 100.0, None, self.intrinsics, gt_T_world_cam=_pose(0.01 * i))


class _Watches:
    """A tracker that notes what the heap and its thread's priority are while it tracks."""

    name = "watches"
    params = None

    def __init__(self) -> None:
        self.frozen: list[int] = []

    def set_params(self, p: object) -> None: ...

    def reset(self) -> None: ...

    def track(self, frame: Frame) -> TrackResult:
        self.frozen.append(gc.get_freeze_count())
        return TrackResult(TrackState.TRACKING, frame.gt_T_world_cam)


def test_a_real_time_run_freezes_the_heap_while_on_air_and_times_its_frames() -> None:
    before = gc.get_freeze_count()
    tracker = _Watches()
    pipe = Pipeline(_Paced(), tracker, realtime=True)
    status = pipe.run()
    assert status.frames == 30
    assert pipe.gc_frozen is not None
    assert pipe.gc_frozen > 0
    assert min(tracker.frozen) > 0  # frozen for every frame
    assert gc.get_freeze_count() == before  # thawed at the end (nothing kept past the run)
    assert sys.getswitchinterval() <= realtime.AIR_SWITCH_INTERVAL_S
    grant = pipe.priorities["engine"]
    assert grant.role == "engine"
    assert grant.granted  # what is in force: granted or "unchanged", never raised
    assert any("engine thread priority" in e.message for e in pipe.events)
    times = list(pipe.frame_timings)
    assert [t.seq for t in times] == list(range(30))
    for t in times:
        assert isinstance(t, FrameTiming)
        assert min(t.track_ms, t.source_wait_ms, t.track_gil_ms) >= 0
    # a run that is not real time leaves the heap and the priorities alone
    headless = Pipeline(_Paced(), _Watches(), realtime=False)
    headless.run()
    assert headless.gc_frozen is None
    assert not headless.priorities


def test_overlapping_shows_keep_the_heap_frozen_until_the_last_ends() -> None:
    before = gc.get_freeze_count()
    assert realtime.freeze_heap() > 0
    realtime.freeze_heap()
    realtime.thaw_heap()
    assert gc.get_freeze_count() > 0  # one show still on air
    realtime.thaw_heap()
    assert gc.get_freeze_count() == before == 0


def test_priorities_refused_are_reported_never_raised(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*_a: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse, raising=False)
    monkeypatch.setattr(os, "setpriority", refuse, raising=False)
    grant = realtime.raise_priority("output sender", fifo=10, nice=-10)
    assert not grant.ok
    assert grant.granted == "unchanged"
    assert "not permitted" in grant.reason.lower() or "platform" in grant.reason
    assert "refused" in grant.line()
    assert "\n" not in grant.line()
    assert grant.to_json_dict()["asked"] in ("SCHED_FIFO 10", "nice -10")


def test_a_nice_value_is_asked_for_and_never_lowers_a_thread(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    if sys.platform != "linux":
        pytest.skip("per-thread priorities are Linux's")
    calls: list[tuple[int, int, int]] = []
    current = {"nice": 0}
    monkeypatch.setattr(os, "getpriority", lambda which, who: current["nice"])
    monkeypatch.setattr(os, "setpriority",
                        lambda which, who, value: calls.append((which, who, value)))
    grant = realtime.raise_priority("engine", nice=-5)
    assert grant.ok
    assert grant.granted == "nice -5"
    assert calls == [(os.PRIO_PROCESS, threading.get_native_id(), -5)]
    current["nice"] = -15  # already above: left alone
    calls.clear()
    grant = realtime.raise_priority("engine", nice=-5)
    assert grant.granted == "nice -15"
    assert not calls


def test_the_render_ahead_worker_runs_in_the_background() -> None:
    if sys.platform != "linux":
        pytest.skip("per-thread scheduling is Linux's")
    mine = os.sched_getscheduler(threading.get_native_id())
    seen: list[int] = []

    def make(i: int) -> Frame:
        seen.append(os.sched_getscheduler(threading.get_native_id()))
        return Frame(i, i / 30.0, None, Intrinsics(fx=50, fy=50, cx=16, cy=12, width=32,
                                                    height=24))

    frames = list(read_ahead(make, 3, background=True))
    assert len(frames) == 3
    assert seen
    assert all(p == os.SCHED_IDLE for p in seen)
    assert os.sched_getscheduler(threading.get_native_id()) == mine  # the consumer's own


def test_background_priority_falls_back_to_nice_where_idle_is_refused(monkeypatch) -> None:
    if sys.platform != "linux":
        pytest.skip("per-thread priorities are Linux's")
    out: list[str] = []

    def refuse(*_a: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    def worker() -> None:
        mine = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
        monkeypatch.setattr(os, "sched_setscheduler", refuse)
        out.append(realtime.background_priority(4))
        out.append(f"nice {min(19, mine + 4)}")

    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert out[0] == out[1]


def test_run_queue_time_is_counted_per_thread() -> None:
    a = realtime.run_queue_s()
    if not np.isfinite(a):
        pytest.skip("the kernel gives no per-thread scheduler statistics")
    t = time.perf_counter()
    while time.perf_counter() - t < 0.02:
        pass
    b = realtime.run_queue_s()
    assert b >= a >= 0.0
