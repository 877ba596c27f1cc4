"""The output clock (pure scheduling) and clocked pose outputs on loopback."""

from __future__ import annotations

import contextlib
import itertools
import socket
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from engine.camera import Intrinsics
from engine.frames import Frame
from engine.outputs import OutputError
from engine.outputs import opentrackio as ot
from engine.outputs.clock import OutputClock, parse_rate
from engine.outputs.sender import OutputConfig, OutputSample, OutputSet, TargetSpec, check_targets
from engine.pipeline import Pipeline, RunPhase, SinkLevel
from engine.results import TrackResult, TrackState
from engine.sinks.pose_output import PoseOutputSink
from engine.sources.base import Source


def simulate(clock: OutputClock, arrivals: list[float], t_end: float, dt: float = 1e-4
             ) -> list[float]:
    """Fire times of ``clock`` for data arriving at ``arrivals`` (a 0.1 ms time step)."""
    fires: list[float] = []
    pending = sorted(arrivals)
    t = 0.0
    while t < t_end:
        arrived = False
        while pending and pending[0] <= t:
            pending.pop(0)
            clock.on_arrival(t)
            arrived = True
        if clock.should_fire(t, arrived):
            fires.append(t)
            clock.fired(t)
        t += dt
    return fires


def test_rates_parse_to_exact_video_rates() -> None:
    assert parse_rate("29.97") == pytest.approx(30000 / 1001)
    assert parse_rate("23.976") == pytest.approx(24000 / 1001)
    assert parse_rate(25) == 25.0
    assert parse_rate("59.94") == pytest.approx(60000 / 1001)
    with pytest.raises(OutputError):
        parse_rate("fast")
    with pytest.raises(OutputError):
        parse_rate("0")


def test_same_rate_locks_onto_the_frames_and_sends_on_arrival() -> None:
    P = 1 / 30
    rng = np.random.default_rng(0)
    # frames at 30 Hz, tracker done 8..20 ms after capture
    arrivals = [k * P + 0.008 + 0.012 * rng.random() for k in range(300)]
    fires = simulate(OutputClock(30.0), arrivals, 300 * P)
    gaps = np.diff(fires)
    assert len(fires) == pytest.approx(300, abs=2)  # exactly one send per slot
    assert gaps.max() <= 1.5 * P
    # after locking, each send happens right when a frame is done (no wait for a tick)
    late = [min(f - a for f in fires if f >= a) for a in arrivals[60:290]]
    assert np.percentile(late, 95) < 0.002


def test_lower_output_rate_keeps_its_rate() -> None:
    arrivals = [k / 30 + 0.01 for k in range(300)]  # 10 s of 30 fps
    fires = simulate(OutputClock(25.0), arrivals, 10.0)
    assert len(fires) == pytest.approx(250, abs=3)


def test_higher_output_rate_repeats_slots_between_frames() -> None:
    arrivals = [k / 25 + 0.01 for k in range(100)]  # 4 s of 25 fps
    fires = simulate(OutputClock(50.0), arrivals, 4.0)
    assert len(fires) == pytest.approx(200, abs=3)
    assert np.diff(fires).max() <= 1.5 / 50


def test_a_stalled_tracker_does_not_stop_the_slots_and_no_burst_follows() -> None:
    P = 1 / 30
    arrivals = [k * P + 0.01 for k in range(30)] + [2.0 + k * P for k in range(30)]
    fires = simulate(OutputClock(30.0), arrivals, 3.0)
    gaps = np.diff(fires)
    assert gaps.max() <= 1.5 * P  # slots go on through the 1 s gap
    assert gaps.min() >= 0.45 * P  # and no burst when frames come back


def test_a_held_slot_after_an_early_one_keeps_the_gap_below_one_and_a_half_periods() -> None:
    """A frame done at its window's opening, then none: the held slot goes early enough
    that the gap stays 0.15 periods below 1.5 (room for a late wake-up), and the rate holds."""
    P = 1 / 30
    c = OutputClock(30.0)
    c.start(0.0)
    c.fired(0.0)
    assert c.max_gap_s == pytest.approx(1.35 * P)
    c.on_arrival(P - c.window_s)  # the next frame right at its window's start
    assert c.should_fire(P - c.window_s, True)
    t1 = P - c.window_s
    c.fired(t1)
    assert c.wake_at() == pytest.approx(t1 + 1.35 * P)  # before the due time 2P
    assert c.wake_at() < c.due
    assert not c.should_fire(t1 + 1.3 * P, False)
    assert c.should_fire(t1 + 1.35 * P, False)
    c.fired(t1 + 1.35 * P)
    assert c.gap_bounded == 1
    assert c.missed == 0
    assert c.due == pytest.approx(3 * P, abs=0.05 * P)  # the grid is unchanged
    # frames that arrive early then late, alternately: every gap below 1.5 P, one per slot
    rng = np.random.default_rng(3)
    arrivals = [k * P + (0.002 if k % 2 else 0.030) + 0.001 * rng.random()
                for k in range(300)]
    fires = simulate(OutputClock(30.0), arrivals, 300 * P)
    assert np.diff(fires).max() <= 1.35 * P + 1e-4
    assert len(fires) == pytest.approx(300, abs=2)


def test_sender_wakes_late_skips_missed_slots() -> None:
    c = OutputClock(50.0)
    c.start(0.0)
    c.fired(0.0)
    c.fired(0.5)  # the sender thread slept through ~24 slots
    assert c.missed == 24
    assert c.due == pytest.approx(0.52)


def _rx() -> socket.socket:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(0.05)
    return rx


def _drain(rx: socket.socket, until: float) -> list[tuple[float, bytes]]:
    got = []
    while time.monotonic() < until:
        with contextlib.suppress(TimeoutError):
            got.append((time.monotonic(), rx.recv(65536)))
    return got


def test_clocked_outputs_hold_and_flag_lost_when_the_tracker_stops_delivering() -> None:
    rx = _rx()
    cfg = OutputConfig(targets=(TargetSpec("opentrackio", "127.0.0.1", rx.getsockname()[1]),))
    out = OutputSet(cfg, rate_hz=50.0, stale_after_s=0.1)
    try:
        T = np.eye(4)
        now = time.monotonic()
        out.submit(OutputSample(0, 0.0, "TRACKING", T, capture_mono_s=now, done_mono_s=now))
        got = _drain(rx, time.monotonic() + 0.5)  # no new sample: slots go on
        st = out.stats()
    finally:
        out.close()
        rx.close()
    samples = [ot.decode_datagrams([d])[0] for _, d in got]
    assert 20 <= len(samples) <= 28  # 50 Hz for 0.5 s
    status = [s["tracker"]["status"] for s in samples]
    assert status[0] == "TRACKING"
    assert status[-1] == "LOST"  # stale after 0.1 s
    assert len({s["timing"]["sequenceNumber"] for s in samples}) == len(samples)
    assert st.clocked
    assert st.held_ticks >= len(samples) - 2
    assert np.isfinite(st.capture_to_send_ms[0])


def test_bad_host_name_is_refused_in_one_line() -> None:
    cfg = OutputConfig(targets=(TargetSpec("freed", "no.such.host.invalid", 40000),))
    with pytest.raises(OutputError, match="cannot resolve") as info:
        check_targets(cfg)
    assert "\n" not in str(info.value)
    with pytest.raises(OutputError, match="cannot reach"):
        check_targets(OutputConfig(targets=(TargetSpec("freed", "192.0.2.1", 40000,
                                                       bind_host="127.0.0.1"),)))
    check_targets(OutputConfig(targets=(TargetSpec("freed", "127.0.0.1", 40000),)))


class _Src(Source):
    name = "paced"
    nominal_fps = 50.0
    live = False

    @property
    def intrinsics(self) -> Intrinsics:
        return Intrinsics(fx=50, fy=50, cx=16, cy=12, width=32, height=24)

    def __len__(self) -> int:
        return 100000

    def frames(self) -> Iterator[Frame]:
        i = 0
        while True:
            T = np.eye(4)
            T[0, 3] = 0.001 * i
            yield Frame(i, i / 50.0, None, self.intrinsics, gt_T_world_cam=T)
            i += 1


class _Explodes:
    name = "explodes"
    params = None

    def set_params(self, p: object) -> None: ...

    def reset(self) -> None: ...

    def track(self, frame: Frame) -> TrackResult:
        if frame.index == 10:
            raise RuntimeError("engine died")
        return TrackResult(TrackState.TRACKING, frame.gt_T_world_cam)


def test_engine_exception_mid_run_keeps_sending_flagged_lost_until_stop(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The sender's own slot times, and the slots it reported missed at each one, are what
    # its pacing is judged on: a loaded machine may wake it late (that is reported, never
    # hidden), and the receiving thread's own delays are not the sender's.
    fires: list[tuple[float, int]] = []  # (send time, slots skipped then), one per packet
    real_fired = OutputClock.fired

    def recording_fired(self: OutputClock, now: float) -> None:
        before = self.missed
        real_fired(self, now)
        fires.append((now, self.missed - before))

    monkeypatch.setattr(OutputClock, "fired", recording_fired)
    rx = _rx()
    cfg = OutputConfig(targets=(TargetSpec("opentrackio", "127.0.0.1", rx.getsockname()[1]),))
    sink = PoseOutputSink(cfg)  # real-time run: clocked at the source's 50 Hz
    P = 1 / 50
    pipe = Pipeline(_Src(), _Explodes(), [sink], realtime=True, hold_on_fault=True)
    stop = threading.Event()
    th = threading.Thread(target=pipe.run, args=(stop.is_set,))
    th.start()
    got: list[tuple[float, bytes]] = []
    try:
        deadline = time.monotonic() + 10.0
        while pipe.phase is not RunPhase.FAULT and time.monotonic() < deadline:
            got += _drain(rx, time.monotonic() + 0.05)
        assert pipe.phase is RunPhase.FAULT
        got += _drain(rx, time.monotonic() + 0.8)  # 40 slots after the fault
        health = sink.health()
        stopped_at = time.monotonic()
    finally:
        stop.set()
        th.join(5)
        rx.close()
    samples = sorted((ot.decode_datagrams([d])[0] for _, d in got),
                     key=lambda s: s["timing"]["sequenceNumber"])
    seqs = [s["timing"]["sequenceNumber"] for s in samples]
    status = [s["tracker"]["status"] for s in samples]
    assert seqs == list(range(len(samples)))  # every slot sent reached us, none twice
    n_tracking = status.index("LOST")
    assert n_tracking >= 1
    assert status == ["TRACKING"] * n_tracking + ["LOST"] * (len(status) - n_tracking)
    # TRACKING slots carry tracked frames (x = 1 mm per frame), in order, none made up;
    # every LOST slot holds the last good pose, frame 9's (held, not extrapolated). Frame 9
    # itself may never have gone out TRACKING: on a busy machine the fault can come before
    # the sender's next slot.
    x_mm = [s["transforms"][0]["translation"]["x"] * 1000.0 for s in samples]
    assert x_mm[:n_tracking] == pytest.approx(np.round(x_mm[:n_tracking]), abs=1e-6)
    assert np.all(np.diff(x_mm[:n_tracking]) >= 0)
    assert x_mm[n_tracking - 1] <= 9.0 + 1e-6
    assert x_mm[n_tracking:] == pytest.approx([9.0] * (len(samples) - n_tracking), abs=1e-6)
    assert all(s["transforms"][0]["translation"] == samples[n_tracking]["transforms"][0][
        "translation"] for s in samples[n_tracking:])
    # Slots kept on the sender's clock: each LOST packet left within a period of its slot's
    # due time unless the sender reported slots missed (due times are a period apart, so a
    # gap beyond two periods is only allowed by the slots skipped at either end of it).
    lost = fires[n_tracking:len(samples)]
    assert len(lost) >= 2
    for (t0, m0), (t1, m1) in itertools.pairwise(lost):
        assert t1 - t0 < P * (2 + m0 + m1), (t1 - t0, m0, m1)
    # and they go on until the stop: never silent for the sender's stall threshold
    # (the product's own "stalled" alarm)
    stall_s = max(0.5, 4 * P)
    assert fires[-1][0] > stopped_at - stall_s
    assert max(t1 - t0 for (t0, _), (t1, _) in itertools.pairwise(fires[n_tracking:])) < stall_s
    assert health.level is SinkLevel.OK  # packets leave; the state says LOST
    assert pipe.status().error == "RuntimeError: engine died"
