"""Fixtures for app tests: an isolated AppContext, a main window that always stops its engine."""

from __future__ import annotations

import socket
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

#: a small built-in studio: fast to render and to track in tests
SMALL_STUDIO = "synthetic:frames=100000,width=160,height=120,presenter=1,path=rail"
REAL_TRACKER = "opencv-odometry"


@pytest.fixture
def udp_rx() -> Iterator[Callable[[], socket.socket]]:
    """Factory of loopback UDP receivers (127.0.0.1, a port the OS picks, 2 s timeout), all
    closed at teardown, also when the test fails or skips (an unclosed socket collected in a
    later test fails that test with a ResourceWarning)."""
    socks: list[socket.socket] = []

    def make() -> socket.socket:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        socks.append(s)
        s.bind(("127.0.0.1", 0))
        s.settimeout(2.0)
        return s

    yield make
    for s in socks:
        s.close()


@pytest.fixture
def settings_path(tmp_path: Path) -> Path:
    return tmp_path / "settings.ini"


@pytest.fixture
def ctx(qtbot, settings_path: Path) -> Iterator[object]:  # type: ignore[no-untyped-def]
    from PySide6.QtCore import QSettings

    from app.context import AppContext
    from app.main import configure_pyqtgraph

    configure_pyqtgraph()
    context = AppContext(settings=QSettings(str(settings_path), QSettings.Format.IniFormat))
    yield context
    context.run.stop()


@pytest.fixture
def window(qtbot, ctx):  # type: ignore[no-untyped-def]
    from app.main_window import MainWindow

    win = MainWindow(ctx)
    qtbot.addWidget(win)
    win.show()
    yield win
    ctx.run.stop()


@pytest.fixture
def live(window):  # type: ignore[no-untyped-def]
    page = window.page("Live")
    page.realtime_check.setChecked(False)
    return page
