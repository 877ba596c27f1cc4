"""The main window: page navigation on the left, pages in the middle, log dock, status bar.

Pages come from :func:`app.pages.discover_pages` (one module per page); a page whose factory
raises is replaced by a placeholder showing the error, so one broken page never takes the
window down. Engine failures and logged warnings/errors appear in the status bar.
"""

from __future__ import annotations

import collections
import math
import time
import traceback

from PySide6.QtCore import QByteArray, QSize, Qt, QTimer, Slot
from PySide6.QtGui import QAction, QCloseEvent, QKeySequence
from PySide6.QtWidgets import (
    QFrame,
    QHBoxLayout,
    QLabel,
    QListWidget,
    QListWidgetItem,
    QMainWindow,
    QScrollArea,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from app.context import AppContext
from app.icons import page_icon
from app.pages import PageSpec, discover_pages
from app.pages._base import DISPLAY_HZ
from app.status import header_state
from widgets.log_panel import LogDock, LogEntry, LogLevel
from widgets.status_header import StatusHeader

#: the display clock's period (ms)
DISPLAY_PERIOD_MS = round(1000 / DISPLAY_HZ)
#: a record ticks the display if the last tick is at least this many periods old (a 60 Hz
#: source draws every other record at DISPLAY_HZ 30)
RECORD_TICK_GAP = 0.75
#: after a record's tick the timer waits this many periods (records keep the beat)
RECORD_TIMER_HOLD = 1.5

#: the header is refreshed every this many display ticks (10 Hz at 30 Hz)
HEADER_EVERY = 3

DEFAULT_SIZE = (1600, 960)
STATUS_STYLES = {
    LogLevel.ERROR: "color: #ff6b6b; font-weight: bold;",
    LogLevel.WARNING: "color: #f0b429;",
    LogLevel.INFO: "",
    LogLevel.DEBUG: "",
}


def _error_page(title: str, message: str) -> QWidget:
    page = QWidget()
    layout = QVBoxLayout(page)
    label = QLabel(f"<h3>The {title} page could not be built</h3><pre>{message}</pre>")
    label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
    label.setWordWrap(True)
    layout.addWidget(label)
    layout.addStretch(1)
    return page


class MainWindow(QMainWindow):
    """StudioTrack operator window."""

    def __init__(
        self,
        ctx: AppContext,
        pages: list[PageSpec] | None = None,
        *,
        restore_geometry: bool = True,
    ) -> None:
        super().__init__()
        self.ctx = ctx
        self.setObjectName("main_window")
        self.setWindowTitle("StudioTrack")

        # status bar first: page factories may already log errors
        self.status_label = QLabel()
        self.engine_label = QLabel("Engine idle")
        self.engine_label.setObjectName("engine_label")
        self.statusBar().addWidget(self.status_label, 1)
        self.statusBar().addPermanentWidget(self.engine_label)
        ctx.log.entry_added.connect(self._on_log_entry)

        self.nav = QListWidget()
        self.nav.setObjectName("page_nav")
        self.nav.setIconSize(QSize(18, 18))
        self.nav.setFixedWidth(150)
        self.stack = QStackedWidget()
        self.pages: dict[str, QWidget] = {}
        for spec in pages if pages is not None else discover_pages():
            self._add_page(spec)
        self.nav.currentRowChanged.connect(self.stack.setCurrentIndex)
        if self.nav.count():
            self.nav.setCurrentRow(0)

        self.header = StatusHeader()
        right = QWidget()
        col = QVBoxLayout(right)
        col.setContentsMargins(4, 4, 4, 0)
        col.setSpacing(2)
        col.addWidget(self.header)
        col.addWidget(self.stack, 1)
        central = QWidget()
        row = QHBoxLayout(central)
        row.setContentsMargins(0, 0, 0, 0)
        row.setSpacing(0)
        row.addWidget(self.nav)
        row.addWidget(right, 1)
        self.setCentralWidget(central)

        self.log_dock = LogDock(ctx.log, self)
        self.addDockWidget(Qt.DockWidgetArea.BottomDockWidgetArea, self.log_dock)
        self.resizeDocks([self.log_dock], [120], Qt.Orientation.Vertical)

        self._make_actions()
        from app.project_actions import install as install_project_actions

        self.project_actions = install_project_actions(self)  # File > New/Open/Save (issue 4)
        # one display clock for the whole window: the header and the visible page draw on it
        # (hidden pages cost nothing); the engine never waits for it
        # A record arriving ticks it at once (at most DISPLAY_HZ, ``record_ready``): the
        # window draws in the engine's idle time right after a frame, not at a random phase
        # where its drawing holds the interpreter lock during the next frame's tracking; the
        # timer ticks when no record comes (stopped, stalled source)
        self.display_timer = QTimer(self)
        self.display_timer.setInterval(DISPLAY_PERIOD_MS)
        self.display_timer.timeout.connect(self._on_display_timer)
        self._ticks = 0
        self._last_tick = self._last_tick_end = 0.0
        ctx.run.record_ready.connect(self._on_record_ready)
        self._record_retry = QTimer(self)  # a record that came too soon, drawn a bit later
        self._record_retry.setSingleShot(True)
        self._record_retry.timeout.connect(
            lambda: self._on_record_ready() if ctx.run.record_waiting() else None)
        #: GUI thread time per display tick (ms, last 600): what drawing costs
        self.tick_ms: collections.deque[float] = collections.deque(maxlen=600)
        self.display_timer.start()
        ctx.run.started.connect(self._on_started)
        ctx.run.failed.connect(self._on_failed)
        ctx.run.finished.connect(self._on_finished)
        self.nav.currentRowChanged.connect(lambda _row: self.display_tick(force_header=True))
        self.geometry_restored = False
        if restore_geometry:
            self._restore_geometry()
        else:
            self.resize(*DEFAULT_SIZE)

    # ------------------------------------------------------------------- pages
    def _add_page(self, spec: PageSpec) -> None:
        try:
            widget = spec.factory(self.ctx)
        except Exception as exc:
            message = f"{type(exc).__name__}: {exc}"
            self.ctx.log.error(f"page {spec.title!r}: {message}")
            widget = _error_page(spec.title, traceback.format_exc())
        widget.setObjectName(widget.objectName() or f"page_{spec.title.lower()}")
        item = QListWidgetItem(page_icon(spec.title), spec.title)
        if spec.tooltip:
            item.setToolTip(spec.tooltip)
        item.setSizeHint(QSize(140, 34))
        self.nav.addItem(item)
        # A page larger than the screen scrolls instead of forcing the window's minimum size.
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setFrameShape(QFrame.Shape.NoFrame)
        scroll.setWidget(widget)
        self.stack.addWidget(scroll)
        self.pages[spec.title] = widget

    def page(self, title: str) -> QWidget:
        return self.pages[title]

    def current_page(self) -> QWidget | None:
        scroll = self.stack.currentWidget()
        return scroll.widget() if isinstance(scroll, QScrollArea) else None

    @Slot()
    def _on_display_timer(self) -> None:
        if self.display_timer.interval() != DISPLAY_PERIOD_MS:
            self.display_timer.setInterval(DISPLAY_PERIOD_MS)
        self.display_tick()

    @Slot()
    def _on_record_ready(self) -> None:
        """A new record: tick now unless the last tick began under ``RECORD_TICK_GAP``
        display periods ago, or ended less than its own duration ago (a page slower than the
        display rate leaves the event loop half its time; the timer takes the record); the
        timer then waits ``RECORD_TIMER_HOLD`` periods for the next record."""
        now = time.perf_counter()
        wait_s = max(self._last_tick + RECORD_TICK_GAP * DISPLAY_PERIOD_MS / 1e3 - now,
                     self._last_tick_end + (self.tick_ms[-1] / 1e3 if self.tick_ms else 0.0)
                     - now)
        if wait_s > 0.0:  # too soon: this record is drawn at the earliest allowed moment
            if not self._record_retry.isActive():
                self._record_retry.start(max(1, math.ceil(wait_s * 1e3)))
            return
        self.display_tick()
        self.display_timer.start(round(RECORD_TIMER_HOLD * DISPLAY_PERIOD_MS))

    @Slot()
    def display_tick(self, force_header: bool = False) -> None:
        """The display clock: engine events to the log, the header, the shown page."""
        t0 = time.perf_counter()
        self._last_tick = t0
        try:
            self._display_tick(force_header)
        finally:
            self._last_tick_end = time.perf_counter()
            self.tick_ms.append((self._last_tick_end - t0) * 1000.0)

    def _display_tick(self, force_header: bool) -> None:
        run = self.ctx.run
        run.poll()
        run.take_latest()  # the display takes the newest record; skipped ones count as drops
        self._ticks += 1
        if force_header or self._ticks % HEADER_EVERY == 0:
            self.header.set_state(header_state(run))
            if run.is_running and run.run_info is None:
                self.engine_label.setText("Engine starting…")
        page = self.current_page()
        tick = getattr(page, "display_tick", None)
        if callable(tick) and page is not None and page.isVisible():
            try:
                tick()
            except Exception as exc:  # a page's drawing bug must not stop the clock
                self.ctx.log.error(f"page drawing failed: {type(exc).__name__}: {exc}")

    def show_page(self, title: str) -> None:
        self.nav.setCurrentRow(list(self.pages).index(title))

    def _make_actions(self) -> None:
        toggle_log = self.log_dock.toggleViewAction()
        toggle_log.setShortcut(QKeySequence("Ctrl+L"))
        quit_action = QAction("Quit", self)
        quit_action.setShortcut(QKeySequence.StandardKey.Quit)
        quit_action.triggered.connect(self.close)
        view_menu = self.menuBar().addMenu("&View")
        view_menu.addAction(toggle_log)
        file_menu = self.menuBar().addMenu("&File")
        file_menu.addAction(quit_action)
        # File before View in the bar
        self.menuBar().clear()
        self.menuBar().addMenu(file_menu)
        self.menuBar().addMenu(view_menu)

    # ------------------------------------------------------------- status bar
    def show_status(self, message: str, level: LogLevel = LogLevel.INFO) -> None:
        self.status_label.setStyleSheet(STATUS_STYLES[level])
        self.status_label.setText(message)
        self.status_label.setToolTip(message)

    def status_text(self) -> str:
        return self.status_label.text()

    @Slot(object)
    def _on_log_entry(self, entry: object) -> None:
        assert isinstance(entry, LogEntry)
        if entry.level >= LogLevel.INFO:
            self.show_status(entry.message, entry.level)

    @Slot(object)
    def _on_started(self, info: object) -> None:
        run = self.ctx.run
        name = getattr(info, "tracker_name", "")
        src = getattr(info, "source_name", "")
        self.engine_label.setText(f"Engine running · {name} · {src}")
        self.header.set_state(header_state(run))

    @Slot(str)
    def _on_failed(self, message: str) -> None:
        self.show_status(message, LogLevel.ERROR)
        self.header.set_state(header_state(self.ctx.run))

    @Slot(object)
    def _on_finished(self, _status: object) -> None:
        self.engine_label.setText("Engine idle")
        self.header.set_state(header_state(self.ctx.run))

    # ----------------------------------------------------------- persistence
    def _restore_geometry(self) -> None:
        geometry = self.ctx.settings.value("window/geometry")
        state = self.ctx.settings.value("window/state")
        if isinstance(geometry, QByteArray | bytes) and self.restoreGeometry(geometry):
            self.geometry_restored = True
            if isinstance(state, QByteArray | bytes):
                self.restoreState(state)
        else:
            self.resize(*DEFAULT_SIZE)

    def closeEvent(self, event: QCloseEvent) -> None:
        if not self.project_actions.confirm_close():  # unsaved project: Save/Discard/Cancel
            event.ignore()
            return
        self.display_timer.stop()
        for page in self.pages.values():  # pages with engine jobs or servers stop them
            stop = getattr(page, "shutdown", None)
            if callable(stop):
                stop()
        self.ctx.settings.setValue("window/geometry", self.saveGeometry())
        self.ctx.settings.setValue("window/state", self.saveState())
        self.ctx.shutdown()
        super().closeEvent(event)
