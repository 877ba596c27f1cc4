"""What the screenshot scripts share (``screenshots_onair.py``, ``screenshots_presenter.py``):
the operator window on a throw-away settings file, an event pump, a wait and a shot at
1280x800 and 1920x1080. Scripts, run from the repository root (offscreen)."""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

SIZES = ((1280, 800), (1920, 1080))


def open_window() -> tuple[Any, Any]:
    """The application, its context and main window, shown (settings in a temporary file)."""
    from PySide6.QtCore import QSettings

    from app.context import AppContext
    from app.main import create_application
    from app.main_window import MainWindow

    create_application()
    tmp = tempfile.mkdtemp(prefix="studiotrack_shots_")
    ctx = AppContext(settings=QSettings(f"{tmp}/s.ini", QSettings.Format.IniFormat))
    win = MainWindow(ctx, restore_geometry=False)
    win.show()
    return ctx, win


def pump(seconds: float) -> None:
    """Run the Qt event loop for ``seconds``."""
    from PySide6.QtCore import QEventLoop, QTimer

    loop = QEventLoop()
    QTimer.singleShot(round(seconds * 1000), loop.quit)
    loop.exec()


def wait(cond: Callable[[], object], timeout: float = 90.0, step: float = 0.1) -> bool:
    """Pump events until ``cond()`` is true (True) or ``timeout`` seconds pass (False)."""
    t = time.monotonic()
    while time.monotonic() - t < timeout:
        if cond():
            return True
        pump(step)
    return False


def shoot(win: Any, out: Path, name: str, page: str | None = None) -> None:
    """``out/NAME_WxH.png`` of the whole window at each of :data:`SIZES` (``page`` shown)."""
    for w, h in SIZES:
        win.resize(w, h)
        if page is not None:
            win.show_page(page)
        pump(0.4)
        win.display_tick(force_header=True)
        pump(0.2)
        win.grab().save(str(out / f"{name}_{w}x{h}.png"))
