"""Application log: a thread-safe model and a dock that shows it with a level filter.

:class:`LogModel` keeps the last entries in memory and emits ``entry_added`` for each new one.
:meth:`LogModel.add` may be called from any thread: it hands the entry to the model's own
thread through a queued signal, so the widgets only ever run in the GUI thread.
:class:`QtLogHandler` forwards Python ``logging`` records into the model.
"""

from __future__ import annotations

import enum
import logging
import time
from collections import deque
from dataclasses import dataclass

from PySide6.QtCore import QObject, Qt, QThread, Signal, Slot
from PySide6.QtGui import QColor, QFont, QGuiApplication, QTextCharFormat, QTextCursor
from PySide6.QtWidgets import (
    QComboBox,
    QDockWidget,
    QHBoxLayout,
    QLabel,
    QPlainTextEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)


class LogLevel(enum.IntEnum):
    DEBUG = logging.DEBUG
    INFO = logging.INFO
    WARNING = logging.WARNING
    ERROR = logging.ERROR


LEVEL_COLOURS = {
    LogLevel.DEBUG: "#8a8f98",
    LogLevel.INFO: "#d4d7dd",
    LogLevel.WARNING: "#f0b429",
    LogLevel.ERROR: "#ff6b6b",
}


@dataclass(frozen=True, slots=True)
class LogEntry:
    time_s: float
    level: LogLevel
    message: str
    origin: str = "app"

    def format(self) -> str:
        stamp = time.strftime("%H:%M:%S", time.localtime(self.time_s))
        millis = int((self.time_s % 1.0) * 1000)
        return f"{stamp}.{millis:03d} {self.level.name:<7} [{self.origin}] {self.message}"


class LogModel(QObject):
    """The last ``capacity`` log entries; ``entry_added`` fires in the model's thread."""

    entry_added = Signal(object)  # LogEntry
    cleared = Signal()
    _posted = Signal(object)  # internal: crosses threads as a queued connection

    def __init__(self, capacity: int = 5000, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._entries: deque[LogEntry] = deque(maxlen=capacity)
        self._posted.connect(self._append, Qt.ConnectionType.QueuedConnection)

    def add(self, level: LogLevel | int, message: str, origin: str = "app",
            time_s: float | None = None) -> LogEntry:
        """Log one message (any thread); ``time_s`` (epoch seconds) when it happened, if not
        now (engine events carry their own time). Returns the entry."""
        entry = LogEntry(time.time() if time_s is None else float(time_s),
                         LogLevel(_nearest_level(int(level))), message, origin)
        if self.thread() is QThread.currentThread():
            self._append(entry)
        else:
            self._posted.emit(entry)
        return entry

    def debug(self, message: str, origin: str = "app", time_s: float | None = None) -> LogEntry:
        return self.add(LogLevel.DEBUG, message, origin, time_s)

    def info(self, message: str, origin: str = "app", time_s: float | None = None) -> LogEntry:
        return self.add(LogLevel.INFO, message, origin, time_s)

    def warning(self, message: str, origin: str = "app",
                time_s: float | None = None) -> LogEntry:
        return self.add(LogLevel.WARNING, message, origin, time_s)

    def error(self, message: str, origin: str = "app", time_s: float | None = None) -> LogEntry:
        return self.add(LogLevel.ERROR, message, origin, time_s)

    @Slot(object)
    def _append(self, entry: object) -> None:
        assert isinstance(entry, LogEntry)
        self._entries.append(entry)
        self.entry_added.emit(entry)

    def entries(self, min_level: LogLevel = LogLevel.DEBUG) -> list[LogEntry]:
        return [e for e in self._entries if e.level >= min_level]

    def text(self, min_level: LogLevel = LogLevel.DEBUG) -> str:
        return "\n".join(e.format() for e in self.entries(min_level))

    def clear(self) -> None:
        self._entries.clear()
        self.cleared.emit()


def _nearest_level(level: int) -> int:
    for lv in (LogLevel.ERROR, LogLevel.WARNING, LogLevel.INFO):
        if level >= lv:
            return lv
    return LogLevel.DEBUG


class QtLogHandler(logging.Handler):
    """Forwards Python logging records (any thread) into a :class:`LogModel`."""

    def __init__(self, model: LogModel, level: int = logging.INFO) -> None:
        super().__init__(level)
        self._model = model

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self._model.add(record.levelno, record.getMessage(), record.name)
        except Exception:  # pragma: no cover - logging must never raise
            self.handleError(record)


class LogView(QWidget):
    """Level filter, read-only text, copy-to-clipboard and clear."""

    def __init__(self, model: LogModel, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = model
        self.level_box = QComboBox()
        for lv in LogLevel:
            self.level_box.addItem(lv.name.title(), lv)
        self.level_box.setCurrentIndex(1)  # Info
        self.level_box.setToolTip("Show messages of this level and above")
        self.copy_button = QPushButton("Copy")
        self.copy_button.setToolTip("Copy the shown log lines to the clipboard")
        self.clear_button = QPushButton("Clear")
        self.text = QPlainTextEdit()
        self.text.setReadOnly(True)
        self.text.setMaximumBlockCount(model._entries.maxlen or 5000)
        mono = QFont("monospace")
        mono.setStyleHint(QFont.StyleHint.TypeWriter)
        self.text.setFont(mono)
        self.text.setLineWrapMode(QPlainTextEdit.LineWrapMode.NoWrap)

        bar = QHBoxLayout()
        bar.setContentsMargins(0, 0, 0, 0)
        bar.addWidget(QLabel("Level"))
        bar.addWidget(self.level_box)
        bar.addStretch(1)
        bar.addWidget(self.copy_button)
        bar.addWidget(self.clear_button)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(4, 2, 4, 4)
        layout.setSpacing(2)
        layout.addLayout(bar)
        layout.addWidget(self.text)

        self.level_box.currentIndexChanged.connect(self._refill)
        self.copy_button.clicked.connect(self.copy_to_clipboard)
        self.clear_button.clicked.connect(model.clear)
        model.entry_added.connect(self._on_entry)
        model.cleared.connect(self._refill)
        self._refill()

    @property
    def min_level(self) -> LogLevel:
        return LogLevel(self.level_box.currentData())

    def set_min_level(self, level: LogLevel) -> None:
        self.level_box.setCurrentIndex(list(LogLevel).index(level))

    def _write(self, entry: LogEntry) -> None:
        fmt = QTextCharFormat()
        fmt.setForeground(QColor(LEVEL_COLOURS[entry.level]))
        cursor = self.text.textCursor()
        cursor.movePosition(QTextCursor.MoveOperation.End)
        if not self.text.document().isEmpty():
            cursor.insertBlock()
        cursor.insertText(entry.format(), fmt)
        self.text.verticalScrollBar().setValue(self.text.verticalScrollBar().maximum())

    @Slot(object)
    def _on_entry(self, entry: object) -> None:
        assert isinstance(entry, LogEntry)
        if entry.level >= self.min_level:
            self._write(entry)

    @Slot()
    def _refill(self) -> None:
        self.text.clear()
        for entry in self.model.entries(self.min_level):
            self._write(entry)

    def shown_text(self) -> str:
        return self.model.text(self.min_level)

    @Slot()
    def copy_to_clipboard(self) -> None:
        QGuiApplication.clipboard().setText(self.shown_text())


class LogDock(QDockWidget):
    """The log view in a dock (bottom of the main window by default)."""

    def __init__(self, model: LogModel, parent: QWidget | None = None) -> None:
        super().__init__("Log", parent)
        self.setObjectName("log_dock")
        self.view = LogView(model)
        self.setWidget(self.view)
        self.setFeatures(
            QDockWidget.DockWidgetFeature.DockWidgetMovable
            | QDockWidget.DockWidgetFeature.DockWidgetFloatable
            | QDockWidget.DockWidgetFeature.DockWidgetClosable
        )
