"""Outputs and Operations pages: config edits, live sending from the engine, failure → LOST."""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest

from app.context import AppContext
from app.engine_bridge import EngineBridge
from app.pages._outputs_state import controller
from app.pages.operations import OperationsPage
from app.pages.outputs import OutputsPage
from engine.outputs import freed as fd
from engine.outputs import opentrackio as ot
from tests.app.fakes import create_fake, open_fake

SHOTS = os.environ.get("STUDIOTRACK_SCREENSHOTS")  # folder to save page screenshots in


@pytest.fixture
def ctx(qtbot, tmp_path):  # type: ignore[no-untyped-def]
    from PySide6.QtCore import QSettings

    bridge = EngineBridge(open_source=open_fake, create_tracker=create_fake)
    c = AppContext(
        bridge=bridge, settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat)
    )
    yield c
    bridge.stop()
    controller(c).shutdown()


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
    assert "bound to 127.0.0.1 (loopback only)" in outputs.bind_label.text()
    outputs.send_box.setChecked(True)
    ctrl = controller(ctx)
    assert ctrl.enabled
    with qtbot.waitSignal(ctx.bridge.finished, timeout=10_000):
        ctx.bridge.start("fake:20", "fake")
    assert ctrl.outputs.flush()
    st = ctrl.stats()
    assert [t.packets_sent for t in st.targets] == [20, 20]
    pkt = rx_f.recv(64)
    assert fd.decode_d1(pkt).camera_id == 1
    sample = ot.decode_datagrams([rx_o.recv(4096)])[0]
    assert sample["tracker"]["status"] == "DEGRADED"  # the fake's frame 0
    ops.refresh()
    assert ops.table.rowCount() == 2
    assert ops.table.item(0, 3).text() == "20"
    assert ops.values["frames"].text() == "20"
    assert ops.values["p50"].text().endswith("ms")
    if SHOTS:
        ops.resize(1000, 620)
        outputs.resize(1000, 700)
        ops.grab().save(str(Path(SHOTS) / "operations.png"))
        outputs.grab().save(str(Path(SHOTS) / "outputs.png"))
    # An engine exception mid-show: the last pose is re-sent flagged LOST.
    with qtbot.waitSignal(ctx.bridge.finished, timeout=10_000):
        ctx.bridge.start("fake:20", "explode")
    assert ctrl.outputs.flush()
    last = None
    rx_o.settimeout(0.5)
    try:
        while True:
            last = rx_o.recv(4096)
    except TimeoutError:
        pass
    assert ot.decode_datagrams([last])[0]["tracker"]["status"] == "LOST"
    rx_f.close()
    rx_o.close()


def test_invalid_edit_keeps_last_valid_config(qtbot, ctx):
    page = OutputsPage(ctx)
    qtbot.addWidget(page)
    before = controller(ctx).config
    page.frame_points.setChecked(True)  # three identical points: degenerate
    for row in page.points:
        for s in row:
            s.setValue(1.0)
    assert not page.apply()
    assert "coincide" in page.error_label.text() or "collinear" in page.error_label.text()
    assert controller(ctx).config == before
    page.points[1][0].setValue(3.0)
    page.points[2][1].setValue(2.0)
    assert page.apply()
    assert controller(ctx).config.studio.matrix[0, 3] == 1.0
