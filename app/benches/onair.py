"""``studiotrack bench onair``: the real operator window on the air path, with a GUI stall.

Runs the operator window (offscreen) on the built-in studio with the real tracker in real
time and the pose outputs on, blocks the GUI thread once in the middle for
``--stall-gui-ms`` (default 2000), and measures what the render engine receives:

- ``output_rate_hz``, ``packets_expected`` (whole output periods in the measured span),
  ``packets_sent`` (datagrams that arrived at the loopback receivers, or that the sender
  sent when ``--freed/--opentrackio`` point elsewhere), ``max_send_gap_ms``,
  ``send_gap_p99_ms`` (between consecutive packets of one target, the worst target);
- ``latency_capture_to_send_ms{p50,p95,max}``: frame capture -> its packet on the wire;
- ``gui_records_dropped`` (records the display skipped: the engine never waited),
  ``gui_stall_ms`` (the stall as measured);
- ``tracker_ms_window{median,p95}`` against ``tracker_ms_headless{median,p95}`` (the same
  tracker on the same source headless, first, in the same process), their ``ratio``, and
  ``fps_window`` against ``source_fps``; ``tracker_ms_headless_paced`` and
  ``tracker_ratio_window_vs_headless_paced``: the headless run again, paced at the source's
  rate (what real-time pacing alone costs, with no window in the process).

Goals (issue 11): no packet missing at the output rate across the stall, max gap <= 1.5
periods, capture -> send p95 <= 15 ms beyond the configured delay (0 here), tracker time in
the window within 1.3x headless, the source's rate sustained.
"""

from __future__ import annotations

import argparse
import itertools
import math
import socket
import statistics
import struct
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from engine.bench import BenchSpec
from engine.progress import log

DEFAULT_SOURCE = "synthetic:frames=100000,presenter=1,path=rail"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--freed", default=None, metavar="HOST:PORT",
                   help="FreeD target (default: a loopback receiver of the bench)")
    p.add_argument("--opentrackio", default=None, metavar="HOST:PORT",
                   help="OpenTrackIO target (default: a loopback receiver of the bench)")
    p.add_argument("--seconds", type=float, default=20.0,
                   help="measured run time after warm-up (default 20)")
    p.add_argument("--rate", default=None, metavar="HZ",
                   help="output rate (23.976 ... 60; default the source's)")
    p.add_argument("--stall-gui-ms", type=float, default=2000.0,
                   help="block the GUI thread once in the middle for this long (default 2000)")
    p.add_argument("--tracker", default="dense", help="tracker (default dense)")
    p.add_argument("--source", default=DEFAULT_SOURCE,
                   help=f"source (default {DEFAULT_SOURCE})")
    p.add_argument("--warmup", type=float, default=3.0,
                   help="seconds of the window run before measuring (default 3)")
    p.add_argument("--headless-frames", type=int, default=150,
                   help="frames tracked headless first for the reference timing (default 150)")


#: Linux: receive timestamps taken by the kernel (struct timespec, CLOCK_REALTIME)
_SO_TIMESTAMPNS = 35


class _Receiver:
    """Counts datagrams on a loopback port, with their arrival times (monotonic s).

    Arrival is the kernel's receive timestamp where Linux gives one (``SO_TIMESTAMPNS``):
    this receiver is a Python thread of the measured process, so the moment it wakes
    includes its own wait for the interpreter lock, which is not the sender's lateness and
    not what a render engine on another machine sees. ``thread_times`` keeps the wake-up
    times too (``clock``: "kernel" or "thread": which ``times`` holds)."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.clock = "thread"
        if sys.platform == "linux":
            try:
                self.sock.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
                self.clock = "kernel"
            except OSError:
                pass
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self.times: list[float] = []
        self.thread_times: list[float] = []
        self._stop = False
        self._t = threading.Thread(target=self._run, daemon=True, name="onair-rx")
        self._t.start()

    def _run(self) -> None:
        while not self._stop:
            try:
                _, anc, _, _ = self.sock.recvmsg(65536, socket.CMSG_SPACE(16))
            except TimeoutError:
                continue
            except OSError:
                return
            mono = time.monotonic()
            wall = time.time()
            t = mono
            for level, kind, data in anc:
                if level == socket.SOL_SOCKET and kind == _SO_TIMESTAMPNS and len(data) >= 16:
                    sec, nsec = struct.unpack("qq", data[:16])
                    t = mono - (wall - (sec + nsec * 1e-9))  # the kernel's time, monotonic
            self.times.append(t)
            self.thread_times.append(mono)

    def close(self) -> None:
        self._stop = True
        self._t.join(1.0)
        self.sock.close()


def _stats(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"median": None, "p95": None}
    a = np.asarray(values, dtype=np.float64)
    return {"median": round(float(np.median(a)), 3), "p95": round(float(np.percentile(a, 95)), 3)}


def headless_timing(source_spec: str, tracker: str, frames: int,
                    period_s: float | None = None) -> list[float]:
    """The tracker's time per frame headless, first frame excluded: frame after frame (as
    ``studiotrack track``), or with ``period_s`` paced as a live source delivers them (the
    next frame at the next period boundary, the process idle in between, no window)."""
    from engine.loop import run_tracking
    from engine.sources import open_source
    from engine.trackers import create_tracker

    ms: list[float] = []
    with open_source(source_spec) as src:
        t0 = time.perf_counter()
        for rec in run_tracking(src, create_tracker(tracker), max_frames=frames):
            if rec.seq > 0:
                ms.append(rec.process_ms)
            if period_s:
                t_next = t0 + (rec.seq + 1) * period_s
                time.sleep(max(0.0, t_next - time.perf_counter()))
    return ms


@dataclass
class OnAirResult:
    """What one window run measured (also used by the test suite's short version)."""

    rate_hz: float
    t0: float
    t1: float
    rx_times: list[list[float]]  # arrival times per target (the kernel's where it says)
    tracker_ms: list[float]
    frames: int
    dropped: int
    stall_ms: float
    stats: Any
    state_counts: dict[str, int] = field(default_factory=dict)
    tick_ms: list[float] = field(default_factory=list)
    cpu_s: dict[str, float] = field(default_factory=dict)
    alarms: list[str] = field(default_factory=list)
    slot_timings: list[Any] = field(default_factory=list)  # engine.outputs.sender.SlotTiming
    frame_timings: list[Any] = field(default_factory=list)  # engine.pipeline.FrameTiming
    switch_interval_s: float = float("nan")
    priorities: dict[str, Any] = field(default_factory=dict)
    rx_thread_times: list[list[float]] = field(default_factory=list)  # receiver wake-ups
    rx_clock: str = ""


def run_window(source: str, tracker: str, *, seconds: float, stall_ms: float,
               warmup_s: float = 3.0, rate: float | None = None,
               targets: tuple[str | None, str | None] = (None, None),
               settings: Any = None) -> OnAirResult:
    """Drive the real window (offscreen) through warm-up, measurement and a GUI stall.

    ``settings``: a QSettings for the window (default: a temporary ini file, so the bench
    never touches the operator's saved geometry)."""
    import tempfile

    from PySide6.QtCore import QEventLoop, QTimer

    from app.context import AppContext
    from app.main import create_application
    from app.main_window import MainWindow
    from app.run_owner import RunRequest
    from engine.outputs.sender import OutputConfig, TargetSpec

    create_application()
    loop = QEventLoop()  # a local loop: the bench runs inside any Qt application (tests)
    if settings is None:
        from PySide6.QtCore import QSettings

        tmp = tempfile.mkdtemp(prefix="studiotrack_onair_")
        settings = QSettings(f"{tmp}/settings.ini", QSettings.Format.IniFormat)
    ctx = AppContext(settings=settings)
    window = MainWindow(ctx, restore_geometry=False)
    window.resize(1600, 960)
    window.show()
    receivers: list[_Receiver] = []
    tspecs: list[TargetSpec] = []
    for proto, given in (("freed", targets[0]), ("opentrackio", targets[1])):
        if given:
            host, _, port = given.rpartition(":")
            tspecs.append(TargetSpec(proto, host or "127.0.0.1", int(port)))
        else:
            rx = _Receiver()
            receivers.append(rx)
            tspecs.append(TargetSpec(proto, "127.0.0.1", rx.port))
    ctx.run.apply_outputs(OutputConfig(targets=tuple(tspecs), rate_hz=rate))
    ctx.run.set_outputs_enabled(True)
    marks: dict[str, float] = {}
    state: dict[str, Any] = {}

    def start() -> None:
        ctx.run.start(RunRequest(source, tracker, realtime=True, page="Live"))

    def cpu_by_thread() -> dict[str, float]:
        """CPU seconds so far of the GUI, engine, sender and studio render threads
        (psutil, Linux; ``render`` is NaN for a source that renders on the engine thread)."""
        import psutil

        ids = {"gui": threading.main_thread().native_id, "engine": ctx.run.engine_thread_id}
        sink = ctx.run._pose_sink
        out = sink.outputs if sink is not None else None
        th = getattr(out, "_thread", None)
        ids["sender"] = getattr(th, "native_id", None)
        # the built-in studio renders ahead on its own thread, as a camera (GIL released)
        ids["render"] = next((t.native_id for t in threading.enumerate()
                              if t.name == "studio-render-ahead"), None)
        times = {t.id: t.user_time + t.system_time for t in psutil.Process().threads()}
        out = {k: times.get(v, float("nan")) if v is not None else float("nan")
               for k, v in ids.items()}
        # every other thread of the process (numba's pool, Qt's, the receivers)
        out["other"] = sum(c for tid, c in times.items() if tid not in ids.values())
        return out

    def begin() -> None:
        marks["t0"] = time.monotonic()
        marks["t1"] = marks["t0"]
        state["cpu0"] = cpu_by_thread()
        p = ctx.run.pipeline
        state["cursor"] = p.trace.total if p is not None else 0
        state["dropped0"] = p.mailbox.dropped if p is not None else 0
        log(f"onair: measuring {seconds:.0f} s (GUI stall {stall_ms:.0f} ms in the middle)")

    def stall() -> None:
        a = time.monotonic()
        time.sleep(stall_ms / 1000.0)  # the GUI thread is blocked: no event is processed
        marks["stall_ms"] = (time.monotonic() - a) * 1000.0

    def end() -> None:
        marks["t1"] = time.monotonic()
        try:
            p = ctx.run.pipeline
            if p is None:
                raise RuntimeError(f"the run did not open: {ctx.run.last_error}")
            samples, _, missed = p.trace.since(state["cursor"])
            state["samples"] = samples
            state["missed"] = missed
            state["dropped"] = p.mailbox.dropped - state["dropped0"]
            state["tick_ms"] = [t for t in window.tick_ms if t < stall_ms * 0.9]
            cpu1 = cpu_by_thread()
            state["cpu_s"] = {k: cpu1[k] - state["cpu0"][k] for k in cpu1}
            state["stats"] = ctx.run.output_stats()
            sink = ctx.run._pose_sink
            out = sink.outputs if sink is not None else None
            state["slots"] = [] if out is None else [
                t for t in list(out.slot_timings) if marks["t0"] <= t.sent_s <= marks["t1"]]
            first = samples[0].seq if samples else 0
            state["ftimes"] = [t for t in list(p.frame_timings) if t.seq >= first]
            state["switch"] = sys.getswitchinterval()
            state["prio"] = ctx.run.priorities()
            state["alarms"] = [e.message for e in ctx.log.entries() if e.level >= 40]
        except Exception as exc:
            state["error"] = f"{type(exc).__name__}: {exc}"
        finally:
            ctx.run.stop()
            window.close()
            loop.quit()

    def wait_for_frames() -> None:
        # the measurement starts ``warmup_s`` after the first record (opening the source
        # and compiling kernels can take seconds)
        if "first" not in marks and ctx.run.frames_received > 0:
            marks["first"] = time.monotonic()
        if "first" in marks and time.monotonic() - marks["first"] >= warmup_s:
            poll.stop()
            begin()
            QTimer.singleShot(round(1000 * seconds / 2), stall)
            QTimer.singleShot(round(1000 * seconds), end)
        elif (not ctx.run.is_running and ctx.run.last_error) or (
                time.monotonic() - marks["opened"] > 120.0):
            # a run that failed to open says why at once, not after the 120 s wait
            poll.stop()
            state["error"] = (f"the run did not open: {ctx.run.last_error}"
                              if not ctx.run.is_running
                              else f"no frame within 120 s ({ctx.run.last_error})")
            ctx.run.stop()
            window.close()
            loop.quit()

    marks["opened"] = time.monotonic()
    poll = QTimer()
    poll.setInterval(50)
    poll.timeout.connect(wait_for_frames)
    QTimer.singleShot(0, start)
    poll.start()
    loop.exec()
    window.deleteLater()
    for rx in receivers:
        rx.close()
    if "error" in state:
        from engine.errors import StudioTrackError

        raise StudioTrackError(f"bench onair: {state['error']}")
    samples = state.get("samples", [])
    counts: dict[str, int] = {}
    for s in samples:
        counts[s.state.value] = counts.get(s.state.value, 0) + 1
    st = state.get("stats")
    return OnAirResult(
        rate_hz=float(st.rate_hz) if st is not None else float("nan"),
        t0=marks["t0"], t1=marks["t1"],
        rx_times=[[t for t in rx.times if marks["t0"] <= t <= marks["t1"]] for rx in receivers],
        rx_thread_times=[[t for t in rx.thread_times if marks["t0"] <= t <= marks["t1"]]
                         for rx in receivers],
        rx_clock=",".join(sorted({rx.clock for rx in receivers})),
        tracker_ms=[s.process_ms for s in samples],
        frames=len(samples) + int(state.get("missed", 0)),
        dropped=int(state.get("dropped", 0)),
        stall_ms=marks.get("stall_ms", 0.0),
        stats=st,
        state_counts=counts,
        alarms=state.get("alarms", []),
        tick_ms=state.get("tick_ms", []),
        cpu_s=state.get("cpu_s", {}),
        slot_timings=state.get("slots", []),
        frame_timings=state.get("ftimes", []),
        switch_interval_s=state.get("switch", float("nan")),
        priorities=state.get("prio", {}),
    )


def summarize(res: OnAirResult, headless_ms: list[float], source_fps: float,
              stall_ms: float, paced_ms: list[float] | None = None) -> dict[str, Any]:
    span = res.t1 - res.t0
    rate = res.rate_hz
    gaps_all: list[float] = []
    sent: list[int] = []
    max_gap = p99 = 0.0
    for times in res.rx_times:
        sent.append(len(times))
        if len(times) >= 2:
            gaps = np.diff(np.asarray(times)) * 1000.0
            gaps_all.extend(gaps.tolist())
            max_gap = max(max_gap, float(gaps.max()))
            p99 = max(p99, float(np.percentile(gaps, 99)))
    st = res.stats
    if not res.rx_times and st is not None:  # external targets: what the sender sent
        sent = [t.samples_sent for t in st.targets]
        max_gap = float(st.send_gap_ms[2])
        p99 = float(st.send_gap_ms[1])
    lat = st.capture_to_send_ms if st is not None else (float("nan"),) * 3
    win = _stats(res.tracker_ms)
    head = _stats(headless_ms)
    paced = _stats(paced_ms or [])
    ratio, ratio_paced = (round(win["median"] / ref["median"], 3)
                          if win["median"] is not None and ref["median"] else None
                          for ref in (head, paced))
    period_ms = 1000.0 / rate if rate == rate and rate > 0 else float("nan")
    return {
        "output_rate_hz": round(rate, 3),
        "seconds": round(span, 3),
        # whole output periods in the span: a span of 589.5 periods holds 589 or 590
        # packets by phase (rounding it up read one packet missing where none was)
        "packets_expected": math.floor(span * rate + 1e-6) if rate == rate else None,
        "packets_sent": min(sent) if sent else 0,
        "packets_sent_per_target": sent,
        "max_send_gap_ms": round(max_gap, 3),
        "send_gap_p99_ms": round(p99, 3),
        "max_gap_periods": round(max_gap / period_ms, 3) if period_ms == period_ms else None,
        # how arrival was timed (kernel receive timestamps, else the receiving thread), and
        # the gap as the receiving thread saw it (its own waits for the interpreter included)
        "rx_clock": res.rx_clock or None,
        "max_send_gap_ms_rx_thread": _max_gap(res.rx_thread_times),
        # the sender's own send times (after each sendto)
        "max_send_gap_ms_sender": _max_gap([[t.sent_s for t in res.slot_timings]]),
        "latency_capture_to_send_ms": {"p50": _r(lat[0]), "p95": _r(lat[1]), "max": _r(lat[2])},
        "gui_records_dropped": res.dropped,
        "gui_stall_ms": round(res.stall_ms, 1),
        "gui_stall_asked_ms": stall_ms,
        "tracker_ms_window": win,
        "tracker_ms_headless": head,
        "tracker_ratio_window_vs_headless": ratio,
        # the same headless run paced at the source's rate: what real-time pacing alone
        # costs (caches and core power state after each idle gap), without any window
        "tracker_ms_headless_paced": paced,
        "tracker_ratio_window_vs_headless_paced": ratio_paced,
        "fps_window": round(res.frames / span, 3) if span > 0 else None,
        "gui_tick_ms": _stats(res.tick_ms),
        # CPU time per thread over the measured span: what the air path needs from 2 cores,
        # whatever else loads the machine (per frame and as % of one core)
        "cpu_ms_per_frame": {k: (round(1000 * v / res.frames, 3) if res.frames and v == v
                                 else None) for k, v in res.cpu_s.items()},
        "cpu_percent_of_core": {k: (round(100 * v / span, 1) if span > 0 and v == v else None)
                                for k, v in res.cpu_s.items()},
        "source_fps": source_fps,
        "frames_window": res.frames,
        "states": res.state_counts,
        "held_slots": None if st is None else st.held_ticks,
        "lost_slots": None if st is None else st.lost_ticks,
        "missed_slots": None if st is None else st.missed_ticks,
        "errors_logged": res.alarms[:5],
        "switch_interval_s": res.switch_interval_s,
        "thread_priorities": res.priorities,
        "send_timing": send_timing(res.slot_timings, period_ms),
        "engine_timing": engine_timing(res.frame_timings),
    }


def _pct(values: list[float]) -> dict[str, float | None]:
    a = np.asarray([v for v in values if v == v], dtype=np.float64)
    if a.size == 0:
        return {"p50": None, "p95": None, "max": None}
    p50, p95 = np.percentile(a, [50, 95])
    return {"p50": round(float(p50), 3), "p95": round(float(p95), 3),
            "max": round(float(a.max()), 3)}


def send_timing(slots: list[Any], period_ms: float) -> dict[str, Any]:
    """Where the sender's time went, slot by slot (:class:`engine.outputs.sender.SlotTiming`).

    ``late_ms``: sent after the slot's due time; ``overshoot_ms``: timer wakes after their
    deadline, split into ``run_queue_ms`` (runnable without a CPU: the OS) and
    ``gil_ms`` (the rest: the interpreter lock); ``work_ms``: wake -> packet on the wire;
    ``late_causes``: for each send more than a quarter period late, the biggest part.
    The latency parts of the slots that carried a fresh pose: ``capture_to_done_ms`` (the
    tracker, and its waits), ``done_to_arrival_ms`` (the other sinks, the hand-over),
    ``arrival_to_send_ms`` (the sender: its wake, or waiting for the slot's window).
    """
    if not slots:
        return {}
    timer = [s for s in slots if s.by_timer and s.deadline_s == s.deadline_s]
    over = [s.overshoot_ms for s in timer]
    rq = [s.run_queue_ms for s in timer]
    gil = [max(0.0, s.overshoot_ms - (s.run_queue_ms if s.run_queue_ms == s.run_queue_ms
                                      else 0.0)) for s in timer]
    work = [(s.sent_s - s.woke_s) * 1000.0 for s in slots if s.woke_s == s.woke_s]
    causes = {"run_queue": 0, "gil": 0, "work": 0, "fresh_late": 0}
    late_thr = 0.25 * period_ms
    late = [s for s in slots if s.late_ms > late_thr]
    for s in late:
        if s.by_timer and s.deadline_s == s.deadline_s:
            o = s.overshoot_ms
            q = s.run_queue_ms if s.run_queue_ms == s.run_queue_ms else 0.0
            w = (s.sent_s - s.woke_s) * 1000.0
            parts = {"run_queue": q, "gil": max(0.0, o - q), "work": w}
            causes[max(parts, key=lambda k: parts[k])] += 1
        else:
            causes["fresh_late"] += 1  # woken by a pose after the due time
    fresh = [s for s in slots if s.fresh and s.capture_s == s.capture_s and s.capture_s > 0]
    return {
        "slots": len(slots),
        "by_timer": sum(1 for s in slots if s.by_timer),
        "fresh": len(fresh),
        "late_ms": _pct([s.late_ms for s in slots]),
        "late_sends": len(late),
        "late_threshold_ms": round(late_thr, 3),
        "late_causes": causes,
        "overshoot_ms": _pct(over),
        "run_queue_ms": _pct(rq),
        "gil_ms": _pct(gil),
        "work_ms": _pct(work),
        "capture_to_done_ms": _pct([(s.done_s - s.capture_s) * 1000.0 for s in fresh]),
        "done_to_arrival_ms": _pct([(s.arrival_s - s.done_s) * 1000.0 for s in fresh]),
        "arrival_to_send_ms": _pct([(s.sent_s - s.arrival_s) * 1000.0 for s in fresh]),
        "fresh_sent_by_timer": sum(1 for s in fresh if s.by_timer),
        "worst_gaps": _worst_gaps(slots, 3),
    }


def _worst_gaps(slots: list[Any], n: int) -> list[dict[str, Any]]:
    """The ``n`` longest gaps between consecutive sends, each with both slots' timing: a
    gap is a period plus this slot's lateness minus the previous one's."""
    rows = []
    for a, b in itertools.pairwise(slots):
        rows.append({
            "gap_ms": round((b.sent_s - a.sent_s) * 1000.0, 3),
            "prev_late_ms": round(a.late_ms, 3), "late_ms": round(b.late_ms, 3),
            "by_timer": b.by_timer, "fresh": b.fresh,
            "overshoot_ms": _r(b.overshoot_ms), "run_queue_ms": _r(b.run_queue_ms),
            "work_ms": _r((b.sent_s - b.woke_s) * 1000.0),
        })
    rows.sort(key=lambda r: -r["gap_ms"])
    return rows[:n]


def engine_timing(frames: list[Any]) -> dict[str, Any]:
    """Where the engine thread's time went per frame (:class:`engine.pipeline.FrameTiming`)."""
    if not frames:
        return {}
    return {
        "frames": len(frames),
        "pace_overshoot_ms": _pct([f.pace_overshoot_ms for f in frames]),
        "source_wait_ms": _pct([f.source_wait_ms for f in frames]),
        "track_ms": _pct([f.track_ms for f in frames]),
        "track_cpu_ms": _pct([f.track_cpu_ms for f in frames]),
        "track_run_queue_ms": _pct([f.track_run_queue_ms for f in frames]),
        "track_gil_ms": _pct([f.track_gil_ms for f in frames]),
        "sinks_ms": _pct([f.sinks_ms for f in frames]),
        "after_frame_ms": _pct([f.after_frame_ms for f in frames]),
        "after_frame_max_ms": _r(max(f.after_frame_ms for f in frames)),
    }


def _max_gap(series: list[list[float]]) -> float | None:
    """The longest gap (ms) between consecutive times of any series."""
    gaps = [float(np.diff(np.asarray(t)).max()) * 1000.0 for t in series if len(t) >= 2]
    return round(max(gaps), 3) if gaps else None


def _r(x: float) -> float | None:
    return round(float(x), 3) if x == x else None


def run(args: argparse.Namespace) -> dict[str, Any]:
    import os

    from engine.outputs.clock import parse_rate

    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")  # the real window, offscreen
    from engine.sources import open_source

    rate = None if args.rate is None else parse_rate(args.rate)
    with open_source(args.source) as src:
        source_fps = float(src.nominal_fps)
    log(f"onair: {args.tracker} headless on {args.source} ({args.headless_frames} frames)")
    t = time.perf_counter()
    headless = headless_timing(args.source, args.tracker, args.headless_frames)
    paced = headless_timing(args.source, args.tracker, args.headless_frames,
                            period_s=1.0 / source_fps)
    log(f"onair: headless median {statistics.median(headless):.1f} ms, paced at "
        f"{source_fps:g} Hz {statistics.median(paced):.1f} ms "
        f"({time.perf_counter() - t:.0f} s); the window next")
    res = run_window(args.source, args.tracker, seconds=args.seconds,
                     stall_ms=args.stall_gui_ms, warmup_s=args.warmup, rate=rate,
                     targets=(args.freed, args.opentrackio))
    out = summarize(res, headless, source_fps, args.stall_gui_ms, paced)
    log(f"onair: {out['packets_sent']}/{out['packets_expected']} packets, max gap "
        f"{out['max_send_gap_ms']} ms, capture->send p95 "
        f"{out['latency_capture_to_send_ms']['p95']} ms, window {out['fps_window']} fps")
    return out


BENCHES = (BenchSpec(name="onair", help="the operator window on air with a GUI stall: "
                     "packets, gaps, latency, tracker time vs headless",
                     add_arguments=add_arguments, run=run),)
