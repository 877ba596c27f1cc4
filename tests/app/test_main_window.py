"""Main window + Live page with the real built-in studio and the real opencv-odometry tracker."""

from __future__ import annotations

import time

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QLabel

import engine.trackers as trackers
from app.run_owner import running_threads
from tests.app.conftest import REAL_TRACKER, SMALL_STUDIO
from tests.app.fakes import EXPLODE_SPEC


def _configure(live, source: str = SMALL_STUDIO, tracker: str = REAL_TRACKER) -> None:  # type: ignore[no-untyped-def]
    live.configure(source=source, tracker=tracker, realtime=False)


def test_pages_are_discovered_with_live_first(window) -> None:  # type: ignore[no-untyped-def]
    assert window.nav.count() >= 1
    assert window.nav.item(0).text() == "Live"
    assert window.stack.currentWidget().widget() is window.page("Live")  # inside its scroll area
    assert window.nav.count() == window.stack.count()


def test_click_start_and_stop(qtbot, window, live) -> None:  # type: ignore[no-untyped-def]
    _configure(live)
    run = window.ctx.run
    assert live.start_button.isEnabled()
    assert not live.stop_button.isEnabled()
    with qtbot.waitSignal(run.started, timeout=30_000):
        qtbot.mouseClick(live.start_button, Qt.MouseButton.LeftButton)
    assert not live.start_button.isEnabled()
    assert live.stop_button.isEnabled()
    assert not live.tracker_box.isEnabled()
    qtbot.waitUntil(lambda: run.frames_received >= 3, timeout=30_000)
    with qtbot.waitSignal(run.finished, timeout=10_000):
        qtbot.mouseClick(live.stop_button, Qt.MouseButton.LeftButton)
    assert live.start_button.isEnabled()
    assert not live.stop_button.isEnabled()
    assert live.status_light.text == "STOPPED"
    assert running_threads() == []
    assert "Engine idle" in window.engine_label.text()


def test_switch_sources(qtbot, window, live, tmp_path) -> None:  # type: ignore[no-untyped-def]
    picker = live.source_picker
    picker.set_spec("camera:2")
    assert picker.spec() == "camera:2"
    picker.set_spec(str(tmp_path / "clip.mp4"))
    assert picker.kind == "video"
    picker.set_spec(str(tmp_path))
    assert picker.kind == "folder"
    assert picker.spec() == str(tmp_path)
    # tracking one source, then another: the second run starts from its own first frame
    run = window.ctx.run
    _configure(live, "synthetic:frames=4,width=160,height=120,path=pan")
    with qtbot.waitSignal(run.finished, timeout=60_000):
        live.start()
    assert run.run_info is not None
    assert "pan" in run.run_info.source_spec
    assert run.frames_received == 4
    _configure(live, "synthetic:frames=3,width=160,height=120,path=handheld")
    with qtbot.waitSignal(run.finished, timeout=60_000):
        live.start()
    assert "handheld" in run.run_info.source_spec
    assert run.frames_received == 3
    assert live.status_light.text == "STOPPED"


def test_bad_source_path_shows_one_line_error(qtbot, window, live, tmp_path) -> None:  # type: ignore[no-untyped-def]
    missing = tmp_path / "no_such_sequence"
    _configure(live, str(missing))
    with qtbot.waitSignal(window.ctx.run.finished, timeout=10_000):
        live.start()
    text = window.status_text()
    assert f"SourceError: {missing}: no such file or folder" in text
    assert "\n" not in text
    assert live.start_button.isEnabled()
    assert live.status_light.text == "ERROR"
    assert "no such file" in window.log_dock.view.shown_text()
    assert str(missing) in window.ctx.recent_files()


def test_survives_engine_error_and_starts_again(qtbot, monkeypatch, ctx) -> None:  # type: ignore[no-untyped-def]
    real = dict(trackers.available_trackers())
    monkeypatch.setattr(trackers, "available_trackers", lambda: {**real, "explode": EXPLODE_SPEC})
    from app.main_window import MainWindow

    window = MainWindow(ctx)
    qtbot.addWidget(window)
    window.show()
    live = window.page("Live")
    _configure(live, tracker="explode")
    run = ctx.run
    with qtbot.waitSignal(run.failed, timeout=30_000):
        live.start()
    assert "RuntimeError: injected failure at frame 5" in window.status_text()
    assert live.error_label.text() == "RuntimeError: injected failure at frame 5"
    assert window.isVisible()
    # the run holds (outputs keep sending LOST) until the operator stops: ERROR, Stop live
    window.display_tick(force_header=True)
    assert window.header.state.state == "ERROR"
    assert live.stop_button.isEnabled()
    with qtbot.waitSignal(run.finished, timeout=10_000):
        live.stop_button.click()
    assert live.start_button.isEnabled()
    assert running_threads() == []
    window.display_tick(force_header=True)
    assert window.header.state.state == "STOPPED"
    # one click starts the real tracker again
    _configure(live)
    with qtbot.waitSignal(run.started, timeout=30_000):
        live.start_button.click()
    qtbot.waitUntil(lambda: run.frames_received >= 2, timeout=30_000)
    live.stop_button.click()
    assert not run.is_running
    assert run.last_error is None


def test_param_edit_reaches_the_running_tracker(qtbot, window, live) -> None:  # type: ignore[no-untyped-def]
    _configure(live)
    run = window.ctx.run
    with qtbot.waitSignal(run.started, timeout=30_000):
        live.start()
    spin = live.param_form.editor("max_depth_m")
    with qtbot.waitSignal(run.params_changed, timeout=5_000) as blocker:
        spin.setValue(5.5)
    assert blocker.args[0].max_depth_m == pytest.approx(5.5)
    assert run.run_info.params.max_depth_m == pytest.approx(5.5)
    live.stop()


def test_live_view_shows_image_and_moving_plots(qtbot, window, live) -> None:  # type: ignore[no-untyped-def]
    """The screenshot test: a non-blank live image and plots that move between two grabs."""
    _configure(live)
    run = window.ctx.run
    with qtbot.waitSignal(run.started, timeout=30_000):
        live.start()
    qtbot.waitUntil(lambda: run.frames_received >= 4, timeout=60_000)
    live.redraw()
    first = window.grab().toImage()
    lengths_1 = live.pose_plots.curve_lengths()
    n1 = run.frames_received
    qtbot.waitUntil(lambda: run.frames_received >= n1 + 4, timeout=60_000)
    live.redraw()
    second = window.grab().toImage()
    lengths_2 = live.pose_plots.curve_lengths()
    state_while_running = live.status_light.state
    fps_text, latency_text = live.fps_label.text(), live.latency_label.text()
    live.stop()
    # nothing stale after Stop: the read-outs clear, the light says STOPPED
    assert live.fps_label.text() == "–"
    assert live.readouts["inliers"].text() == "–"
    assert live.status_light.text == "STOPPED"

    assert not first.isNull()
    assert first.width() > 800
    image = live.image_view.image_rgb
    assert image is not None
    assert image.shape == (120, 160, 3)
    assert float(image.astype(np.float32).var()) > 100.0  # a textured studio, not a blank frame
    # the image as drawn on screen is not blank either
    view = live.image_view.grab().toImage()
    px = np.array(
        [
            view.pixelColor(x, y).lightness()
            for x in range(0, view.width(), 7)
            for y in range(0, view.height(), 7)
        ],
        dtype=np.float32,
    )
    assert px.var() > 50.0
    assert all(n >= 4 for n in lengths_1)
    assert all(b > a for a, b in zip(lengths_1, lengths_2, strict=True))
    assert first != second  # the window changed between the two grabs
    assert live.pose_plots.has_gt  # the studio has ground truth: dashed curves shown
    gt_x = live.pose_plots.gt_curves[0].xData
    assert gt_x is not None
    assert len(gt_x) == lengths_2[0]
    assert fps_text != "–"
    assert latency_text != "–"
    assert state_while_running is not None  # TRACKING / LOST ... of the last frame


def test_geometry_and_recent_files_persist(qtbot, ctx, settings_path) -> None:  # type: ignore[no-untyped-def]
    from app.main_window import MainWindow

    w1 = MainWindow(ctx)
    qtbot.addWidget(w1)
    w1.show()
    assert not w1.geometry_restored  # nothing saved yet
    ctx.add_recent_file("/data/a")
    ctx.add_recent_file("/data/b")
    ctx.add_recent_file("/data/a")
    w1.close()
    assert ctx.recent_files() == ["/data/a", "/data/b"]
    assert settings_path.exists()
    assert len(ctx.settings.value("window/geometry")) > 0
    w2 = MainWindow(ctx)
    qtbot.addWidget(w2)
    # (the offscreen platform clamps sizes to its 800x800 screen, so compare the flag)
    assert w2.geometry_restored
    w3 = MainWindow(ctx, restore_geometry=False)
    qtbot.addWidget(w3)
    assert not w3.geometry_restored
    assert (w3.width(), w3.height()) == (1600, 960)


def test_broken_page_is_replaced_by_an_error_page(qtbot, ctx) -> None:  # type: ignore[no-untyped-def]
    from app.main_window import MainWindow
    from app.pages import PageSpec

    def broken(_ctx):  # type: ignore[no-untyped-def]
        raise ValueError("boom")

    w = MainWindow(ctx, pages=[PageSpec("Broken", 5, broken)])
    qtbot.addWidget(w)
    assert "could not be built" in w.page("Broken").findChildren(QLabel)[0].text()
    assert "ValueError: boom" in w.status_text()


def _window_with_fakes(qtbot, monkeypatch, ctx):  # type: ignore[no-untyped-def]
    """A shown main window whose source and tracker menus also offer the fast fakes."""
    import engine.sources as sources
    from app.main_window import MainWindow
    from tests.app.fakes import FAKE_SPEC, open_fake

    real_open = sources.open_source
    monkeypatch.setattr(
        sources,
        "open_source",
        lambda spec: open_fake(spec) if spec.startswith("fake") else real_open(spec),
    )
    real = dict(trackers.available_trackers())
    monkeypatch.setattr(trackers, "available_trackers", lambda: {**real, "fake": FAKE_SPEC})
    window = MainWindow(ctx)
    qtbot.addWidget(window)
    window.show()
    return window


def test_display_is_decoupled_and_window_responsive_flat_out(qtbot, monkeypatch, ctx) -> None:  # type: ignore[no-untyped-def]
    """A tracker far faster than the display: records arrive, the timer draws a subset, and
    the GUI event loop keeps serving timers."""
    window = _window_with_fakes(qtbot, monkeypatch, ctx)
    live = window.page("Live")
    live.configure(source="fake:100000000", tracker="fake", realtime=False)
    run = ctx.run
    with qtbot.waitSignal(run.started, timeout=10_000):
        live.start()
    qtbot.waitUntil(lambda: run.frames_received >= 300, timeout=30_000)
    # the event loop still runs timers promptly while the engine runs flat out
    from PySide6.QtCore import QTimer

    for _ in range(3):
        timer = QTimer()
        timer.setSingleShot(True)
        with qtbot.waitSignal(timer.timeout, timeout=1_000):
            timer.start(10)
    qtbot.waitUntil(lambda: live._frames_shown >= 2, timeout=5_000)
    live.stop()
    live.redraw()  # the display drains the rest of the run's history
    received, shown = run.frames_received, live.draws
    assert shown < received  # drawing is on the display clock, not per record
    # every frame reached the plots, except those pushed out of the history between ticks
    assert live.pose_plots.est.total + live.samples_missed == received
    assert live.pose_plots.est.total > shown


def test_records_tick_the_display_without_the_timer(qtbot, monkeypatch, ctx) -> None:  # type: ignore[no-untyped-def]
    """The display draws when a record arrives (the engine's idle time), not only on its
    timer; the timer is the fallback when no record comes."""
    window = _window_with_fakes(qtbot, monkeypatch, ctx)
    window.display_timer.timeout.disconnect()  # only records can tick it now
    live = window.page("Live")
    live.configure(source="fake:100000", tracker="fake", realtime=True)
    with qtbot.waitSignal(ctx.run.started, timeout=10_000):
        live.start()
    t0 = window._ticks
    qtbot.waitUntil(lambda: window._ticks >= t0 + 10, timeout=10_000)
    qtbot.waitUntil(lambda: live._frames_shown >= 5, timeout=10_000)
    live.stop()


def test_closing_the_window_stops_the_engine(qtbot, window, live) -> None:  # type: ignore[no-untyped-def]
    _configure(live)
    run = window.ctx.run
    with qtbot.waitSignal(run.started, timeout=30_000):
        live.start()
    with qtbot.waitSignal(run.finished, timeout=10_000):
        window.close()
    assert not run.is_running
    assert running_threads() == []


def test_loss_and_recovery_are_logged_once(qtbot, monkeypatch, ctx) -> None:  # type: ignore[no-untyped-def]
    import engine.sources as sources
    from app.main_window import MainWindow
    from tests.app.fakes import FAKE_SPEC, FakeParams, open_fake

    monkeypatch.setattr(sources, "open_source", open_fake)
    monkeypatch.setattr(trackers, "available_trackers", lambda: {"fake": FAKE_SPEC})
    window = MainWindow(ctx)
    qtbot.addWidget(window)
    live = window.page("Live")
    live.configure(source="fake:12", tracker="fake", realtime=False)
    live.param_form.set_params(FakeParams(lost_frames=(3, 4, 5)))
    with qtbot.waitSignal(ctx.run.finished, timeout=10_000):
        live.start()
    lines = [e.message for e in ctx.log.entries() if e.origin == "tracker"]
    # every state change once, in order (the fake reports DEGRADED on frames 0 and 10)
    assert lines == [
        "DEGRADED from frame 0",
        "tracking LOST at frame 3",
        "tracking recovered at frame 6 after 3 frames",
        "DEGRADED from frame 10",
    ]


def test_form_follows_a_run_started_elsewhere(qtbot, monkeypatch, ctx) -> None:  # type: ignore[no-untyped-def]
    import engine.sources as sources
    from app.main_window import MainWindow
    from tests.app.fakes import EXPLODE_SPEC, FAKE_SPEC, FakeParams, open_fake

    monkeypatch.setattr(sources, "open_source", open_fake)
    monkeypatch.setattr(
        trackers, "available_trackers", lambda: {"explode": EXPLODE_SPEC, "fake": FAKE_SPEC}
    )
    window = MainWindow(ctx)
    qtbot.addWidget(window)
    live = window.page("Live")
    live.configure(tracker="explode")
    # e.g. a replay page starts the shared engine with another tracker and params
    with qtbot.waitSignal(ctx.run.started, timeout=10_000):
        ctx.run.start("fake:100000000", "fake", params=FakeParams(gain=2.5), realtime=True,
                      page="Replay")
    assert live.tracker_name == "fake"
    assert live.param_form.params == FakeParams(gain=2.5)
    assert not live.start_button.isEnabled()
    assert "Replay" in live.stop_button.toolTip()
    ctx.run.set_params(FakeParams(gain=3.0))
    assert live.param_form.params == FakeParams(gain=3.0)
    ctx.run.stop()


def test_every_page_has_its_own_nav_icon(window) -> None:  # type: ignore[no-untyped-def]
    from app.icons import has_asset

    for title in window.pages:
        slug = title.lower().replace(" ", "_")
        assert has_asset(f"icons/{slug}.svg"), f"app/assets/icons/{slug}.svg missing"


@pytest.mark.parametrize("title", ["Live", "Presenter", "Beacons", "PTZ"])
def test_page_fits_a_1280x800_window(window, title) -> None:  # type: ignore[no-untyped-def]
    """No horizontal scrolling at 1280 x 800: the page's minimum width fits beside the nav."""
    room = 1280 - window.nav.width() - 24  # frame and scroll-bar margin
    assert window.page(title).minimumSizeHint().width() <= room


def test_a_run_that_ends_plots_its_last_frames(qtbot, window, live) -> None:  # type: ignore[no-untyped-def]
    """The plots are redrawn at most every PLOT_INTERVAL_S; the frames after the last timed
    redraw are drawn when the run ends (a short run plots completely)."""
    live.configure(source="synthetic:frames=9,width=160,height=120", tracker=REAL_TRACKER,
                   realtime=False)
    run = window.ctx.run
    with qtbot.waitSignal(run.finished, timeout=60_000):
        live.start()
    qtbot.waitUntil(lambda: live.status_light.text == "STOPPED", timeout=10_000)
    # the display clock's tick after the end drains the last samples and draws them
    qtbot.waitUntil(lambda: live.pose_plots.curve_lengths()[0] == 9, timeout=5_000)
    # the same, step by step: samples that come right after a timed redraw wait for the next
    # one, and the run's end draws them
    samples, _, _ = run.trace_since(0)
    assert len(samples) == 9
    live.pose_plots.clear_data()
    live.pose_plots.redraw()
    live._plots_due = time.monotonic() + 60.0  # a timed redraw just happened
    live.add_samples(samples, 0)
    assert live.pose_plots.curve_lengths()[0] == 0
    live.run_ended(run.status())
    assert live.pose_plots.curve_lengths()[0] == 9
