"""QApplication start-up: theme, pyqtgraph options, the main window, and ``run_gui``."""

from __future__ import annotations

import logging
import signal
import sys
from pathlib import Path

from PySide6.QtCore import QTimer
from PySide6.QtGui import QColor, QFont, QPalette
from PySide6.QtWidgets import QApplication

from app.icons import icon

DEFAULT_SOURCE = "synthetic:frames=100000,presenter=1,path=rail"

_configured = False


def configure_pyqtgraph() -> None:
    """Global pyqtgraph options, set once before any plot is created."""
    global _configured
    if _configured:
        return
    import pyqtgraph as pg

    pg.setConfigOption("imageAxisOrder", "row-major")
    pg.setConfigOptions(background="#15171b", foreground="#b9bec7", antialias=False)
    _configured = True


STYLE_SHEET = """
QMainWindow, QWidget { font-size: 10pt; }
QListWidget#page_nav { background: #1b1d22; border: none; padding-top: 6px; font-size: 11pt; }
QListWidget#page_nav::item { padding-left: 12px; color: #c9ced6; }
QListWidget#page_nav::item:selected { background: #2b3a55; color: #ffffff;
    border-left: 3px solid #4c8dff; }
QGroupBox { border: 1px solid #343842; border-radius: 4px; margin-top: 14px; padding-top: 4px; }
QGroupBox::title { subcontrol-origin: margin; left: 8px; padding: 0 4px; color: #9aa3b2; }
QPushButton { padding: 4px 12px; border: 1px solid #444a55; border-radius: 3px;
    background: #2a2e36; }
QPushButton:hover { background: #343944; }
QPushButton:disabled { color: #6b717c; background: #23262c; }
QPushButton#start_button, QPushButton#beacons_start, QPushButton#ptz_start,
QPushButton#primary { background: #1f6b3a; border-color: #2a8a4c; color: white;
    font-weight: bold; }
QPushButton#start_button:disabled, QPushButton#beacons_start:disabled,
QPushButton#ptz_start:disabled, QPushButton#primary:disabled {
    background: #23302a; color: #6b7d70; }
QPushButton#stop_button, QPushButton#beacons_stop, QPushButton#ptz_stop,
QPushButton#presenter_stop { background: #7a2626; border-color: #9c3434; color: white;
    font-weight: bold; }
QPushButton#stop_button:disabled, QPushButton#beacons_stop:disabled,
QPushButton#ptz_stop:disabled, QPushButton#presenter_stop:disabled {
    background: #302424; color: #7d6b6b; }
QTabWidget::pane { border: 1px solid #343842; border-radius: 3px; }
QTabBar::tab { padding: 5px 12px; background: #23262c; color: #9aa3b2;
    border: 1px solid #343842; border-bottom: none; border-top-left-radius: 3px;
    border-top-right-radius: 3px; margin-right: 2px; }
QTabBar::tab:selected { background: #2b3a55; color: #ffffff; border-color: #4c8dff; }
QTabBar::tab:hover:!selected { background: #2a2e36; color: #dfe3ea; }
QStatusBar { background: #1b1d22; color: #c9ced6; }
QStatusBar QLabel { padding: 0 6px; }
QDockWidget::title { background: #1b1d22; padding: 4px; color: #9aa3b2; }
QLabel#readout { font-family: monospace; font-size: 11pt; color: #e6e9ee; }
QLabel#readout_caption { color: #8a93a3; font-size: 9pt; }
QLabel#param_error { color: #ff6b6b; }
QToolTip { background: #2a2e36; color: #e6e9ee; border: 1px solid #4c5260; }
"""


def dark_palette() -> QPalette:
    p = QPalette()
    base, window, text = QColor("#1e2026"), QColor("#24272e"), QColor("#dfe3ea")
    p.setColor(QPalette.ColorRole.Window, window)
    p.setColor(QPalette.ColorRole.WindowText, text)
    p.setColor(QPalette.ColorRole.Base, base)
    p.setColor(QPalette.ColorRole.AlternateBase, window)
    p.setColor(QPalette.ColorRole.ToolTipBase, window)
    p.setColor(QPalette.ColorRole.ToolTipText, text)
    p.setColor(QPalette.ColorRole.Text, text)
    p.setColor(QPalette.ColorRole.Button, QColor("#2a2e36"))
    p.setColor(QPalette.ColorRole.ButtonText, text)
    p.setColor(QPalette.ColorRole.BrightText, QColor("#ff6b6b"))
    p.setColor(QPalette.ColorRole.Highlight, QColor("#3d6fd6"))
    p.setColor(QPalette.ColorRole.HighlightedText, QColor("#ffffff"))
    p.setColor(QPalette.ColorRole.Link, QColor("#6aa1ff"))
    p.setColor(QPalette.ColorRole.PlaceholderText, QColor("#7b8290"))
    for role in (
        QPalette.ColorRole.Text,
        QPalette.ColorRole.ButtonText,
        QPalette.ColorRole.WindowText,
    ):
        p.setColor(QPalette.ColorGroup.Disabled, role, QColor("#6b717c"))
    return p


def apply_theme(app: QApplication) -> None:
    app.setStyle("Fusion")
    app.setPalette(dark_palette())
    font = QFont(app.font())
    font.setPointSize(10)
    app.setFont(font)
    app.setStyleSheet(STYLE_SHEET)


def create_application(argv: list[str] | None = None) -> QApplication:
    """The QApplication (reused if one exists), themed, with pyqtgraph configured."""
    existing = QApplication.instance()
    if isinstance(existing, QApplication):
        app = existing
    else:
        app = QApplication(argv if argv is not None else sys.argv[:1])
    app.setApplicationName("StudioTrack")
    app.setOrganizationName("StudioTrack")
    app.setApplicationDisplayName("StudioTrack")
    app.setWindowIcon(icon("studiotrack.svg"))
    apply_theme(app)
    configure_pyqtgraph()
    return app


def run_gui(
    source: str | None = None,
    tracker: str | None = None,
    quit_after: int | None = None,
    screenshot: str | Path | None = None,
    *,
    start: bool = True,
    realtime: bool | None = None,
) -> int:
    """Open the operator window, start tracking ``source`` and run the event loop.

    With ``quit_after`` the app stops after that many processed frames (or when the run ends
    or fails first), saves ``screenshot`` of the main window if given, and quits. Returns the
    process exit code: 0, or 1 when the engine failed before ``quit_after`` frames.
    """
    app = create_application()
    from app.context import AppContext
    from app.main_window import MainWindow
    from widgets.log_panel import QtLogHandler

    ctx = AppContext()
    handler = QtLogHandler(ctx.log)
    logging.getLogger().addHandler(handler)
    if logging.getLogger().level > logging.INFO:
        logging.getLogger().setLevel(logging.INFO)
    # pictures for docs and tests use the default size, not the operator's saved geometry
    window = MainWindow(ctx, restore_geometry=screenshot is None)
    live = window.pages.get("Live")
    configure = getattr(live, "configure", None)
    if callable(configure):
        configure(source=source or DEFAULT_SOURCE, tracker=tracker, realtime=realtime)
    window.show()

    outcome = {"rc": 0, "done": False}

    def finish(rc: int) -> None:
        if outcome["done"]:
            return
        outcome["done"] = True
        outcome["rc"] = rc
        # draw the latest record and take the picture while tracking still shows live
        window.display_tick(force_header=True)
        if screenshot is not None:
            path = Path(screenshot)
            path.parent.mkdir(parents=True, exist_ok=True)
            if not window.grab().save(str(path)):
                print(f"studiotrack: error: could not save screenshot {path}", file=sys.stderr)
                outcome["rc"] = 1
            else:
                print(f"screenshot saved to {path}", file=sys.stderr)
        ctx.run.stop()
        window.close()
        app.quit()

    if quit_after is not None:
        # the run's frame counter is polled (the engine never waits for the window)
        def poll() -> None:
            st = ctx.run.status()
            if ctx.run.is_running and st is not None and st.frames >= quit_after:
                finish(0)

        def on_failed(message: str) -> None:
            print(f"studiotrack: engine failed: {message}", file=sys.stderr)
            QTimer.singleShot(0, lambda: finish(1))

        def on_finished(_status: object) -> None:
            QTimer.singleShot(0, lambda: finish(outcome["rc"]))

        counter = QTimer(window)
        counter.setInterval(20)
        counter.timeout.connect(poll)
        counter.start()
        ctx.run.failed.connect(on_failed)
        ctx.run.finished.connect(on_finished)

    if start:
        start_fn = getattr(live, "start", None)
        if callable(start_fn):
            QTimer.singleShot(0, start_fn)

    # let Ctrl+C in the terminal close the window cleanly
    signal.signal(signal.SIGINT, lambda *_: QTimer.singleShot(0, window.close))
    heartbeat = QTimer()
    heartbeat.start(250)  # gives the Python interpreter a chance to run signal handlers
    heartbeat.timeout.connect(lambda: None)

    app.exec()
    logging.getLogger().removeHandler(handler)
    ctx.run.stop()
    return int(outcome["rc"])
