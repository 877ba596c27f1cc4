"""The Beacons page runs the simulator through beacon-slam and edits the layout."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import QSettings

from app.context import AppContext
from app.pages import discover_pages
from app.pages.beacons import BeaconsPage, ellipse_points
from engine.beacons.simulator import PAPER_LAYOUT


@pytest.fixture
def page(qtbot, tmp_path: Path) -> BeaconsPage:  # type: ignore[no-untyped-def]
    ctx = AppContext(settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat))
    w = BeaconsPage(ctx)
    qtbot.addWidget(w)
    w.resize(1280, 800)
    yield w
    w.run.stop()


def test_page_is_discovered() -> None:
    assert any(p.title == "Beacons" for p in discover_pages())


def test_page_runs_the_simulator(qtbot, page: BeaconsPage) -> None:  # type: ignore[no-untyped-def]
    page.steps_spin.setValue(40)
    page.fps_spin.setValue(100.0)
    page.outlier_spin.setValue(0.05)
    with qtbot.waitSignal(page.run.finished, timeout=20000):
        page.start_button.click()
        assert not page.start_button.isEnabled()
        # the window's display clock drives the page (here: the test ticks it)
        qtbot.waitUntil(lambda: (page.display_tick(), page.records_seen >= 5)[1],
                        timeout=10000)
        # a live edit of the particle count reaches the tracker on the next step
        form = page.param_form
        new = dataclasses.replace(form.params, n_particles=90, map_adjust_p=0.1)
        form.set_params(new)
        with qtbot.waitSignal(page.run.params_changed, timeout=2000):
            form.params_changed.emit(new)
        qtbot.waitUntil(lambda: (page.display_tick(), page.records_seen >= 30)[1],
                        timeout=10000)
    page.display_tick()  # the last steps of the run still reach the paths
    assert page.records_seen == 41
    assert len(page.est_path) == len(page.true_path) == len(page.errors_m) == 41
    assert page.particles_item.data.shape[0] == 90  # the new particle count was applied
    assert float(np.sqrt(np.mean(np.square(page.errors_m)))) < 3.0
    assert "Finished" in page.status_label.text()
    assert page.start_button.isEnabled()
    assert not page.stop_button.isEnabled()
    page.grab().save(str(Path(page._layout_dir) / "beacons_page.png"))


def test_stop_ends_the_run(qtbot, page: BeaconsPage) -> None:  # type: ignore[no-untyped-def]
    page.steps_spin.setValue(100000)
    page.fps_spin.setValue(50.0)
    page.start_button.click()
    qtbot.waitUntil(lambda: (page.display_tick(), page.records_seen >= 2)[1], timeout=10000)
    with qtbot.waitSignal(page.run.finished, timeout=10000):
        page.stop_button.click()
    assert not page.run.is_running
    assert page.status_label.text().startswith("Stopped")


def test_layout_editing_import_export(page: BeaconsPage, tmp_path: Path) -> None:
    assert page.beacon_layout() == PAPER_LAYOUT
    page._targets["A"].setPos((3.0, 4.0))  # what a mouse drag does
    bid = page.add_beacon()
    assert bid == "E"
    assert page.beacon_layout()["A"] == (3.0, 4.0)
    out = tmp_path / "lay.csv"
    page.export_layout(out)
    page.set_layout(PAPER_LAYOUT)
    page.import_layout(out)
    assert page.beacon_layout()["E"] == (0.0, 8.0)
    assert len(page.beacon_layout()) == 5
    assert "layout=" in page.source_spec()
    page.import_layout(tmp_path / "missing.json")
    assert "import failed" in page.status_label.text()
    page.remove_last_beacon()
    assert "E" not in page.beacon_layout()


def test_ellipse_points_radii() -> None:
    pts = ellipse_points(np.array([1.0, 2.0]), np.diag([4.0, 1.0]), n_sigma=1.0, n=4)
    np.testing.assert_allclose(np.abs(pts - [1.0, 2.0]).max(axis=0), [2.0, 1.0], atol=1e-9)


def _free_udp_port() -> int:
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_page_shows_the_input_counters_of_a_live_udp_run(qtbot, page: BeaconsPage) -> None:  # type: ignore[no-untyped-def]
    import json
    import socket

    from app.pages.beacons import input_text

    assert page.input_label.text() == "No run yet."
    port = _free_udp_port()
    with qtbot.waitSignal(page.run.started, timeout=30_000):
        page.run.start(f"beacons-udp:port={port},heartbeat=0.2", "beacon-slam",
                       page.param_form.params, realtime=True, page="Beacons")

    def dg(t: float) -> bytes:
        return json.dumps({"timestamp_s": t, "ranges_m": {"A": 5.0 + t, "B": 6.0, "C": 7.0,
                                                         "D": 8.0}}).encode()

    sent = [dg(0.1 * i) for i in range(6)]
    sent += [b"{not json", dg(0.2), b'{"timestamp_s": 2.0}']  # malformed, late, no ranges_m
    sent += [dg(1.0 + 0.1 * i) for i in range(3)]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        for d in sent:
            tx.sendto(d, ("127.0.0.1", port))

    def shown() -> str:
        page.display_tick()
        return page.input_label.text()

    qtbot.waitUntil(lambda: shown().startswith("12 datagrams received"), timeout=20_000)
    text = page.input_label.text()
    assert text.splitlines()[:2] == [
        "12 datagrams received: 40 readings in 10 steps",
        "rejected: 2 malformed, 0 unknown ids, 0 duplicates, 1 out of order",
    ]
    assert "clock: sender" in text
    assert text.splitlines()[-1] == "last rejected: udp: malformed datagram (no 'ranges_m')"
    with qtbot.waitSignal(page.run.finished, timeout=10_000):
        page.stop()
    page.display_tick()
    after = page.input_label.text().splitlines()  # the run's counters stay after Stop
    assert after[:2] == text.splitlines()[:2]
    assert after[-1] == text.splitlines()[-1]
    # the simulator has no input to count; the next run starts from its own counters
    assert input_text(None, "beacons").startswith("Simulator")
    page.steps_spin.setValue(10)
    page.fps_spin.setValue(100.0)
    with qtbot.waitSignal(page.run.finished, timeout=20_000):
        page.start_button.click()
    page.display_tick()
    assert page.input_label.text().startswith("Simulator")
