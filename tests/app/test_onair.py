"""The air path in the real window: a GUI stall does not stop the outputs; every page's run
reaches the outputs; the header tells the truth; sessions record from the window."""

from __future__ import annotations

import contextlib
import socket
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from engine.outputs import opentrackio as ot
from engine.outputs.sender import OutputConfig, TargetSpec
from tests.app.conftest import SMALL_STUDIO


def test_gui_stall_does_not_stop_the_outputs(qtbot, settings_path: Path) -> None:  # type: ignore[no-untyped-def]
    """The short version of ``studiotrack bench onair``: the GUI thread blocks 0.8 s in the
    middle of a real-time run; packets go on at the output rate meanwhile (functional check:
    the timing figures are the bench's job)."""
    from PySide6.QtCore import QSettings

    from app.benches.onair import run_window, summarize

    res = run_window(SMALL_STUDIO, "ground-truth", seconds=2.4, stall_ms=800.0, warmup_s=1.0,
                     settings=QSettings(str(settings_path), QSettings.Format.IniFormat))
    out = summarize(res, [0.1], 30.0, 800.0)
    assert res.stall_ms >= 790
    assert out["output_rate_hz"] == 30.0
    # packets arrived while the GUI thread was blocked: find the stall in the tracker's
    # frames and count packets in it
    for times in res.rx_times:
        assert len(times) >= 0.6 * out["packets_expected"]
        gaps = np.diff(times)
        assert gaps.max() < 0.5  # a blocked GUI would show a gap of 0.8 s
    assert out["gui_records_dropped"] >= 10  # the display skipped records, the engine did not
    assert out["frames_window"] >= 0.6 * 30.0 * out["seconds"]
    assert out["latency_capture_to_send_ms"]["p50"] is not None
    if sys.platform == "linux":  # arrival timed by the kernel, not the receiving thread
        assert out["rx_clock"] == "kernel"
    assert out["max_send_gap_ms_sender"] is not None
    assert out["max_send_gap_ms_rx_thread"] is not None


def test_paced_headless_reference() -> None:
    """``bench onair``'s paced reference: frames come at the period (the run takes at least
    the frames' periods) and the summary gives its figures and the window's ratio to them."""
    from app.benches.onair import OnAirResult, headless_timing, summarize

    t = time.perf_counter()
    ms = headless_timing(SMALL_STUDIO, "ground-truth", 6, period_s=0.05)
    assert time.perf_counter() - t >= 5 * 0.05
    assert len(ms) == 5
    res = OnAirResult(rate_hz=30.0, t0=0.0, t1=1.0, rx_times=[], tracker_ms=[3.0, 3.0],
                      frames=30, dropped=0, stall_ms=0.0, stats=None)
    out = summarize(res, [1.0], 30.0, 0.0, paced_ms=[2.0, 2.0])
    assert out["tracker_ratio_window_vs_headless"] == 3.0
    assert out["tracker_ms_headless_paced"]["median"] == 2.0
    assert out["tracker_ratio_window_vs_headless_paced"] == 1.5


def _rx() -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(0.05)
    return s


def _page_texts(page) -> list[str]:  # type: ignore[no-untyped-def]
    """What a page shows in words: its visible labels and its status lights."""
    from PySide6.QtWidgets import QLabel

    from widgets.status_light import StatusLight

    out = [lab.text() for lab in page.findChildren(QLabel) if lab.isVisibleTo(page)]
    out += [s.text for s in page.findChildren(StatusLight)]
    return out


def _start_on_its_page(qtbot, window, tracker, factory):  # type: ignore[no-untyped-def]
    """Show the page that drives ``tracker``, start a run of ``factory``'s tracker from it
    on the small studio and wait until the page has drawn; returns (title, page)."""
    from app.pages import page_for_tracker
    from app.run_owner import RunRequest

    run = window.ctx.run
    spec = page_for_tracker(tracker)
    title = spec.title if spec is not None else "Live"
    window.show_page(title)
    page = window.page(title)
    with qtbot.waitSignal(run.started, timeout=30_000):
        run.start(RunRequest(SMALL_STUDIO, tracker, page=title, tracker_factory=factory))
    qtbot.waitUntil(lambda: (window.display_tick(force_header=True),
                             page.draws > 0)[1], timeout=30_000)
    return title, page


@pytest.mark.parametrize("title", ["PTZ", "Beacons", "Presenter"])
def test_runs_started_on_any_page_reach_the_outputs(qtbot, window, title) -> None:  # type: ignore[no-untyped-def]
    rx = _rx()
    run = window.ctx.run
    run.apply_outputs(OutputConfig(targets=(TargetSpec("opentrackio", "127.0.0.1",
                                                       rx.getsockname()[1]),)))
    run.set_outputs_enabled(True)
    page = window.page(title)
    window.show_page(title)
    try:
        with qtbot.waitSignal(run.started, timeout=60_000):
            if title == "PTZ":
                page.live.start("ptz-sim:duration=30", realtime=True)
            elif title == "Beacons":
                page.fps_spin.setValue(20.0)
                page.steps_spin.setValue(10000)
                page.start()
            else:
                from engine.presenter.model import auto_patches
                from engine.sources import open_source
                from tests.app.test_presenter_page import SOURCE

                with open_source(SOURCE) as src:
                    first = next(iter(src.frames()))
                page.source_edit.setText(SOURCE)
                page.set_reference(np.array(first.color_bgr))
                main = first.gt_box_xywh
                page.canvas.set_model(main, [(p.name, p.xywh) for p in auto_patches(main, 3)])
                assert page.start_tracking()
        qtbot.waitUntil(lambda: run.frames_received >= 8, timeout=60_000)
        st = run.output_stats()
        assert st is not None
        got = []
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline and len(got) < 3:
            with contextlib.suppress(TimeoutError):
                got.append(ot.decode_datagrams([rx.recv(65536)])[0])
        header = window.header.state
    finally:
        run.stop()
        rx.close()
    assert st.submitted >= 8  # every record of the page's run reached the pose sink
    if title == "Presenter":
        # a box tracker has no camera pose: nothing is sent, and the header says so
        assert got == []
        assert st.skipped_no_pose == st.processed
    else:
        assert len(got) >= 3
        assert all(np.isfinite(g["transforms"][0]["translation"]["x"]) for g in got)
    assert title in header.title or header.state in ("TRACKING", "DEGRADED", "STARTING",
                                                     "INITIALIZING", "LOST")


def test_header_follows_the_run_and_clears_after_stop(qtbot, window, live) -> None:  # type: ignore[no-untyped-def]
    run = window.ctx.run
    window.display_tick(force_header=True)
    assert window.header.state.state == "STOPPED"
    live.configure(source=SMALL_STUDIO, tracker="ground-truth", realtime=True)
    with qtbot.waitSignal(run.started, timeout=30_000):
        live.start()
    qtbot.waitUntil(lambda: (window.display_tick(force_header=True),
                             window.header.state.state == "TRACKING")[1], timeout=30_000)
    h = window.header.state
    assert "ground-truth" in h.title
    assert h.fps_text != "–"
    assert h.latency_text.startswith("capture")
    assert [t.text for t in h.targets] == ["off"]
    assert h.timecode  # generated at the output rate when the source has none
    assert window.header.timecode_label.text().startswith("TC ")
    assert not h.alarm
    with qtbot.waitSignal(run.finished, timeout=10_000):
        live.stop()
    window.display_tick(force_header=True)
    h = window.header.state
    assert h.state == "STOPPED"
    assert h.fps_text == "–"
    assert h.latency_text == "–"
    assert h.timecode == ""  # nothing stale after Stop


def test_session_recorded_from_the_window(qtbot, window, live, tmp_path) -> None:  # type: ignore[no-untyped-def]
    from engine.session.reader import read_index, read_records

    run = window.ctx.run
    live.configure(source="synthetic:frames=12,width=160,height=120", tracker="ground-truth",
                   realtime=False)
    live.record_check.setChecked(True)
    target = tmp_path / "session"
    live.session_dir = lambda: str(target)  # type: ignore[method-assign]
    with qtbot.waitSignal(run.finished, timeout=30_000):
        live.start()
    idx = read_index(target)
    assert idx.status == "complete"
    assert idx.frames_recorded == 12
    assert len(read_records(target)) == 12
    assert any("12 frames recorded" in e.message for e in window.ctx.log.entries())


def test_a_lost_frame_shows_its_own_numbers_and_no_used_points(qtbot, window, live) -> None:  # type: ignore[no-untyped-def]
    from engine.frames import Frame
    from engine.loop import FrameRecord
    from engine.results import Overlay, TrackResult, TrackState

    img = np.full((48, 64, 3), 90, np.uint8)
    pts = np.array([[5, 5], [10, 10], [20, 20]], np.float32)
    ones = np.ones(3, np.float32)

    def rec(state: TrackState, inliers: float) -> FrameRecord:
        res = TrackResult(state, np.eye(4), inlier_fraction=inliers,
                          overlay=Overlay(points_uv=pts, point_weights=ones),
                          message="" if state.is_good else "residual 30 > 7")
        return FrameRecord(1, Frame(1, 0.1, img), res, "dense", 5.0, 30.0, 0)

    live.draw(rec(TrackState.TRACKING, 0.9))
    assert live.image_view.point_counts()[-1] == 3  # used: green
    assert live.readouts["inliers"].text() == "90.0 %"
    live.draw(rec(TrackState.LOST, 0.999))
    counts = live.image_view.point_counts()
    assert counts[0] == 3
    assert sum(counts) == 3
    assert live.readouts["inliers"].text() == "99.9 % (rejected)"  # this frame's own number
    assert live.status_light.text == "LOST"
    live.draw(FrameRecord(2, Frame(2, 0.2, img), TrackResult(TrackState.LOST, np.eye(4)),
                          "dense", 5.0, 30.0, 0))
    assert sum(live.image_view.point_counts()) == 0  # no overlay of an earlier frame
    assert live.readouts["inliers"].text() == "–"


def test_nothing_says_tracking_on_any_page_after_stop(qtbot, window, live) -> None:  # type: ignore[no-untyped-def]
    """Stale-state check on every page: while a run tracks, pages that show the run's state
    say so; after Stop no page (nor the header) still says TRACKING or shows a frame rate."""


    run = window.ctx.run
    live.configure(source=SMALL_STUDIO, tracker="ground-truth", realtime=True)
    with qtbot.waitSignal(run.started, timeout=30_000):
        live.start()
    qtbot.waitUntil(lambda: run.frames_received >= 5, timeout=30_000)
    seen_tracking = []
    for title in window.pages:
        window.show_page(title)
        for _ in range(3):
            window.display_tick(force_header=True)
            qtbot.wait(20)
        if any("TRACKING" in t for t in _page_texts(window.page(title))):
            seen_tracking.append(title)
    assert "Live" in seen_tracking
    assert "Operations" in seen_tracking
    with qtbot.waitSignal(run.finished, timeout=10_000):
        live.stop()
    for title in window.pages:
        window.show_page(title)
        window.display_tick(force_header=True)
        stale = [t for t in _page_texts(window.page(title)) if "TRACKING" in t]
        assert stale == [], (title, stale)
        assert window.header.state.state == "STOPPED"
        assert window.header.state.fps_text == "–"
    ops = window.page("Operations")
    assert ops.values["fps"].text() == "–"


@pytest.mark.parametrize("tracker", ["dense", "presenter", "ptz", "beacon-slam"])
def test_an_engine_error_says_error_on_its_page_never_tracking(qtbot, window, tracker) -> None:  # type: ignore[no-untyped-def]
    """The engine raises mid-run on the page that drives the tracker: the run stays open
    (outputs hold LOST) and that page, like the header, says ERROR; nothing there still says
    TRACKING, the output chip says LOST instead of a green rate."""
    import dataclasses

    from engine.pipeline import RunPhase
    from tests.app.fakes import FakeParams, FakeTracker

    def failing() -> FakeTracker:
        t = FakeTracker(dataclasses.replace(FakeParams(), fail_at_frame=15))
        t.name = tracker  # the page of that tracker follows the run
        return t

    rx = _rx()
    run = window.ctx.run
    run.apply_outputs(OutputConfig(targets=(TargetSpec("opentrackio", "127.0.0.1",
                                                       rx.getsockname()[1]),)))
    run.set_outputs_enabled(True)
    title = tracker
    try:
        title, page = _start_on_its_page(qtbot, window, tracker, failing)
        qtbot.waitUntil(lambda: run.pipeline is not None
                        and run.pipeline.phase is RunPhase.FAULT, timeout=30_000)
        for _ in range(4):
            window.display_tick(force_header=True)
            qtbot.wait(30)
        shown = _page_texts(page)
        header = window.header.state
    finally:
        run.stop()
        run.set_outputs_enabled(False)
        rx.close()
    assert header.state == "ERROR"
    assert header.targets
    assert all(t.text.startswith("LOST") and t.level == "waiting" for t in header.targets), \
        header.targets
    assert not [t for t in shown if "TRACKING" in t], (title, shown)
    assert any("ERROR" in t or "injected failure" in t for t in shown), (title, shown)


@pytest.mark.parametrize("tracker", ["dense", "presenter", "ptz", "beacon-slam"])
def test_a_stalled_engine_says_lost_on_its_page_as_in_the_header(qtbot, window, tracker) -> None:  # type: ignore[no-untyped-def]
    """The tracker hangs mid-run (no record for seconds): the header says LOST (engine
    stalled) and the page that drives the tracker says LOST too; nothing says TRACKING."""
    import threading

    from tests.app.fakes import FakeParams, FakeTracker

    release = threading.Event()

    class Hanging(FakeTracker):
        def track(self, frame):  # type: ignore[no-untyped-def]
            if frame.index == 10:
                release.wait(30)
            return super().track(frame)

    def hanging() -> FakeTracker:
        t = Hanging(FakeParams())
        t.name = tracker
        return t

    run = window.ctx.run
    title = tracker
    try:
        title, page = _start_on_its_page(qtbot, window, tracker, hanging)
        qtbot.waitUntil(lambda: (window.display_tick(force_header=True),
                                 "stalled" in window.header.state.message)[1], timeout=30_000)
        window.display_tick(force_header=True)
        shown = _page_texts(page)
        header = window.header.state
    finally:
        release.set()
        run.stop()
    assert header.state == "LOST"
    assert not [t for t in shown if "TRACKING" in t], (title, shown)
    assert any("LOST" in t for t in shown), (title, shown)


def test_bench_says_where_late_sends_come_from() -> None:
    """The bench's send-timing summary: each late slot is put down to its biggest part
    (the OS run queue, the interpreter lock, the send's own work, or a pose that came late)."""
    from app.benches.onair import engine_timing, send_timing
    from engine.outputs.sender import SlotTiming
    from engine.pipeline import FrameTiming

    P = 1 / 30
    nan = float("nan")
    slots = [
        # on time, sent by a fresh pose inside the window
        SlotTiming(1.0, 0.995, False, True, nan, 0.9949, nan, 0.9948, 0.985, 0.9948),
        # a held slot whose wake-up came 12 ms late, 1 ms of it in the run queue: the GIL
        SlotTiming(1.0 + P, 1.0 + P + 0.0125, True, False, 1.0 + P, 1.0 + P + 0.012, 1.0,
                   0.9948, nan, nan),
        # a pose that came after the due time woke the sender: late by the pose
        SlotTiming(1.0 + 2 * P, 1.0 + 2 * P + 0.02, False, True, nan, 1.0 + 2 * P + 0.0199,
                   nan, 1.0 + 2 * P + 0.0199, 1.0 + P + 0.01, 1.0 + 2 * P + 0.0198),
    ]
    out = send_timing(slots, 1000 * P)
    assert out["slots"] == 3
    assert out["late_sends"] == 2
    assert out["late_causes"] == {"run_queue": 0, "gil": 1, "work": 0, "fresh_late": 1}
    assert out["gil_ms"]["max"] == pytest.approx(11.0, abs=0.01)
    assert out["worst_gaps"][0]["gap_ms"] == pytest.approx(1000 * (P + 0.0175), abs=0.01)
    assert out["worst_gaps"][0]["prev_late_ms"] == pytest.approx(-5.0, abs=0.01)
    assert out["capture_to_done_ms"]["p50"] is not None
    eng = engine_timing([FrameTiming(0, 0.1, 0.2, 9.0, 3.0, 2.0, 0.4)])
    assert eng["track_gil_ms"]["p50"] == pytest.approx(4.0)
    assert send_timing([], 33.3) == {}
