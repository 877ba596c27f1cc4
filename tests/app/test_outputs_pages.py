"""Outputs and Operations pages: config edits, live sending from the engine, failure → LOST,
a bad host refused at Apply with one line."""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest

from app.context import AppContext
from app.pages.operations import COL, OperationsPage
from app.pages.outputs import OutputsPage, bind_meaning
from engine.outputs import freed as fd
from engine.outputs import opentrackio as ot
from tests.app.fakes import create_fake, open_fake

SHOTS = os.environ.get("STUDIOTRACK_SCREENSHOTS")  # folder to save page screenshots in


@pytest.fixture
def ctx(qtbot, tmp_path):  # type: ignore[no-untyped-def]
    from PySide6.QtCore import QSettings

    from app.run_owner import RunOwner

    owner = RunOwner(open_source=open_fake, create_tracker=create_fake)
    c = AppContext(
        run=owner, settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat)
    )
    yield c
    owner.stop()


def _rx():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(2.0)
    return s


def test_pages_send_while_tracking_and_flag_lost_on_failure(qtbot, ctx):
    outputs = OutputsPage(ctx)
    ops = OperationsPage(ctx)
    qtbot.addWidget(outputs)
    qtbot.addWidget(ops)
    rx_f, rx_o = _rx(), _rx()
    outputs.freed_port.setValue(rx_f.getsockname()[1])
    outputs.otio_port.setValue(rx_o.getsockname()[1])
    outputs.otio_enc.setCurrentText("cbor")
    assert outputs.bind_label.text() == "Binds to " + bind_meaning("127.0.0.1")
    assert "loopback only; choose another address" in outputs.bind_label.text()
    # edits are pending until applied; the send switch applies them first
    assert outputs.pending
    assert outputs.apply_button.isEnabled()
    assert "changes pending" in outputs.pending_label.text()
    # sending is off: targets say so (they are not "bound" to anything yet)
    assert outputs.freed_status.text() == "off (sending is off)"
    ops.refresh()
    assert ops.table.rowCount() == 2
    assert ops.table.item(0, COL["Status"]).text() == "off"
    assert ops.table.item(0, COL["Bound to"]).text() == "127.0.0.1 (when on)"
    assert not ops.rate_curve.isVisible()
    assert ops.rate_off.isVisible()
    outputs.send_box.setChecked(True)
    assert not outputs.pending
    assert not outputs.apply_button.isEnabled()
    assert "all changes applied" in outputs.pending_label.text()
    run = ctx.run
    assert run.outputs_enabled
    outputs.refresh_status()
    assert outputs.freed_status.text() == "armed (no run)"
    # a headless-like run (not real time): one packet per tracked frame
    with qtbot.waitSignal(run.finished, timeout=10_000):
        run.start("fake:20", "fake", realtime=False)
    st = run.output_stats()
    assert [t.packets_sent for t in st.targets] == [20, 20]
    pkt = rx_f.recv(64)
    assert fd.decode_d1(pkt).camera_id == 1
    sample = ot.decode_datagrams([rx_o.recv(4096)])[0]
    assert sample["tracker"]["status"] == "DEGRADED"  # the fake's frame 0
    ops.refresh()
    assert ops.values["frames"].text() == "–"  # nothing stale after the run
    # a real-time run: clocked at the source's rate; the pages show it while it runs
    with qtbot.waitSignal(run.started, timeout=10_000):
        run.start("fake:1000000", "fake", realtime=True)
    qtbot.waitUntil(lambda: run.frames_received >= 10, timeout=10_000)
    ops.refresh()
    assert ops.table.rowCount() == 2
    assert int(ops.table.item(0, COL["Packets"]).text()) > 0
    assert ops.table.item(0, COL["Bound to"]).text() == "127.0.0.1"
    status = ops.table.item(0, COL["Status"]).text()
    assert status == "waiting for poses" or status.startswith("sending"), status
    assert ops.rate_curve.isVisible()
    assert not ops.rate_off.isVisible()
    assert "Clocked at 30.000 Hz" in ops.sender_label.text()
    outputs.refresh_status()
    assert outputs.send_state.text().startswith("on — 2 targets at 30.000 Hz")
    assert outputs.freed_status.text().startswith("sending")
    assert ops.values["frames"].text().startswith(str(run.frames_received)[:1])
    assert ops.values["p50"].text().endswith("ms")
    if SHOTS:
        ops.resize(1000, 620)
        outputs.resize(1000, 700)
        ops.grab().save(str(Path(SHOTS) / "operations.png"))
        outputs.grab().save(str(Path(SHOTS) / "outputs.png"))
    run.stop()
    # An engine exception mid-show: the last pose goes on flagged LOST until Stop.
    with qtbot.waitSignal(run.started, timeout=10_000):
        run.start("fake:20", "explode", realtime=True)
    qtbot.waitUntil(lambda: run.pipeline is not None and run.pipeline.status().error != "",
                    timeout=10_000)
    rx_o.settimeout(0.5)
    lost = []
    try:
        for _ in range(200):
            got = ot.decode_datagrams([rx_o.recv(4096)])[0]
            if got["tracker"]["status"] == "LOST":
                lost.append(got)
            if len(lost) >= 5:
                break
    except TimeoutError:
        pass
    run.stop()
    assert len(lost) >= 5  # at the output rate, not once
    rx_f.close()
    rx_o.close()


def test_bad_host_is_refused_at_apply_in_one_line(qtbot, ctx):
    page = OutputsPage(ctx)
    qtbot.addWidget(page)
    before = ctx.run.outputs_config
    page.freed_host.setText("no.such.host.invalid")
    assert not page.apply()
    text = page.error_label.text()
    assert text.startswith("Not applied: freed target 'no.such.host.invalid': cannot resolve")
    assert "\n" not in text
    assert ctx.run.outputs_config == before
    page.send_box.setChecked(True)  # switching on applies first: refused, stays off
    assert not ctx.run.outputs_enabled
    assert not page.send_box.isChecked()


def test_unreachable_target_is_an_alarm_never_a_silent_counter(qtbot, ctx, monkeypatch):
    import app.run_owner as run_owner
    from app.status import header_state

    page = OutputsPage(ctx)
    qtbot.addWidget(page)
    # the route goes away after Apply (simulated: the check at Apply is skipped); a socket
    # bound to loopback cannot reach a TEST-NET address, so every send fails locally
    monkeypatch.setattr(run_owner, "check_targets", lambda cfg: None)
    page.freed_host.setText("192.0.2.1")
    page.otio_on.setChecked(False)
    page.bind_edit.setText("127.0.0.1")
    assert page.apply()
    ctx.run.set_outputs_enabled(True)
    with qtbot.waitSignal(ctx.run.started, timeout=10_000):
        ctx.run.start("fake:1000000", "fake", realtime=True)
    try:
        qtbot.waitUntil(lambda: (h := ctx.run.output_health()) is not None
                        and h.level.name == "ALARM", timeout=10_000)
        head = header_state(ctx.run)
        page.refresh_status()
        status_text = page.freed_status.text()
    finally:
        ctx.run.stop()
    assert head.alarm
    [chip] = head.targets
    assert chip.level == "alarm"
    assert "FAILING" in chip.text
    # the header says in words what the render engine does not get, not only a red chip
    assert head.message.startswith("OUTPUT FAILING: freed:192.0.2.1:40000")
    assert "\n" not in head.message
    assert status_text.startswith("FAILING")


def test_invalid_edit_keeps_last_valid_config(qtbot, ctx):
    page = OutputsPage(ctx)
    qtbot.addWidget(page)
    before = ctx.run.outputs_config
    page.frame_points.setChecked(True)  # three identical points: degenerate
    for row in page.points:
        for s in row:
            s.setValue(1.0)
    assert not page.apply()
    assert "coincide" in page.error_label.text() or "collinear" in page.error_label.text()
    assert ctx.run.outputs_config == before
    page.points[1][0].setValue(3.0)
    page.points[2][1].setValue(2.0)
    assert page.apply()
    assert ctx.run.outputs_config.studio.matrix[0, 3] == 1.0


def test_apply_revert_and_pending_indicator(qtbot, ctx):
    page = OutputsPage(ctx)
    qtbot.addWidget(page)
    assert page.apply()
    assert not page.pending
    assert not page.revert_button.isEnabled()
    before = ctx.run.outputs_config
    page.freed_port.setValue(41234)
    assert page.pending
    assert page.revert_button.isEnabled()
    assert "changes pending" in page.pending_label.text()
    assert ctx.run.outputs_config == before  # nothing in force until Apply
    page.revert()
    assert page.freed_port.value() == before.targets[0].port
    assert not page.pending
    page.otio_on.setChecked(False)
    assert page.apply()
    assert [t.protocol for t in ctx.run.outputs_config.targets] == ["freed"]
    assert page.otio_status.text() == "off (target disabled)"
    page.freed_host.setText("192.0.2.1")
    page.bind_edit.setText("127.0.0.1")
    assert "192.0.2.1 cannot be reached from a loopback" in page.bind_label.text()
    page.bind_edit.setText("0.0.0.0")
    assert page.bind_label.text().startswith("Binds to 0.0.0.0 — all interfaces")


@pytest.mark.parametrize("size", [(1120, 620)])  # page area of a 1280x800 window
def test_pages_fit_a_1280x800_window_without_scrolling(qtbot, ctx, size):
    from PySide6.QtWidgets import QSpinBox

    for cls in (OutputsPage, OperationsPage):
        page = cls(ctx)
        qtbot.addWidget(page)
        hint = page.minimumSizeHint()
        assert hint.width() <= size[0], (cls.__name__, hint)
        assert hint.height() <= size[1], (cls.__name__, hint)
        layout = page.layout()
        if layout.hasHeightForWidth():
            assert layout.heightForWidth(size[0]) <= size[1], cls.__name__
    # numeric editors keep a compact width instead of stretching across the column
    page = OutputsPage(ctx)
    # worst case: changes pending, a long send error, a bind warning
    page.freed_host.setText("192.0.2.1")
    page.bind_edit.setText("127.0.0.1")
    page.freed_status.setText("error: " + "Network is unreachable " * 4)
    page.error_label.setText("Not applied: " + "x" * 300)
    assert page.pending
    assert page.minimumSizeHint().width() <= size[0]
    assert page.minimumSizeHint().height() <= size[1]
    qtbot.addWidget(page)
    page.resize(*size)
    page.show()
    for spin in page.findChildren(QSpinBox):
        assert spin.width() <= 160
