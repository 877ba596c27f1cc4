"""Tracking-status light: a coloured lamp with the state's name.

TRACKING green, DEGRADED amber, RELOCALIZING blue, LOST red, INITIALIZING and idle grey.
"""

from __future__ import annotations

from PySide6.QtCore import QRectF, QSize, Qt
from PySide6.QtGui import QBrush, QColor, QFont, QPainter, QPaintEvent, QPen, QRadialGradient
from PySide6.QtWidgets import QSizePolicy, QWidget

from engine.trackers.base import TrackState

STATE_COLOURS: dict[TrackState | None, str] = {
    TrackState.TRACKING: "#2ecc71",
    TrackState.DEGRADED: "#f0b429",
    TrackState.RELOCALIZING: "#3d8bfd",
    TrackState.LOST: "#ff4d4f",
    TrackState.INITIALIZING: "#8a93a3",
    None: "#5a606b",
}


class StatusLight(QWidget):
    """A lamp + label for a :class:`TrackState` (``None`` means idle)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._state: TrackState | None = None
        self._text = "IDLE"
        self.setSizePolicy(QSizePolicy.Policy.Fixed, QSizePolicy.Policy.Fixed)
        self.setToolTip("Tracking state of the last processed frame")
        self._font = QFont(self.font())
        self._font.setBold(True)
        self._font.setPointSize(11)

    @property
    def state(self) -> TrackState | None:
        return self._state

    @property
    def text(self) -> str:
        return self._text

    def colour(self) -> QColor:
        return QColor(STATE_COLOURS[self._state])

    def set_state(self, state: TrackState | None, text: str | None = None) -> None:
        """Show ``state`` (``None``: idle) with its name or ``text``."""
        label = text if text is not None else (state.value if state is not None else "IDLE")
        if state is self._state and label == self._text:
            return
        self._state = state
        self._text = label
        self.setAccessibleName(f"tracking state {label}")
        self.update()

    def sizeHint(self) -> QSize:
        return QSize(190, 34)

    def paintEvent(self, event: QPaintEvent) -> None:
        painter = QPainter(self)
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        rect = QRectF(self.rect()).adjusted(1, 1, -1, -1)
        colour = self.colour()
        painter.setPen(QPen(colour.darker(160), 1))
        painter.setBrush(QColor(colour.red(), colour.green(), colour.blue(), 40))
        painter.drawRoundedRect(rect, 6, 6)
        d = rect.height() - 12
        lamp = QRectF(rect.left() + 8, rect.top() + 6, d, d)
        grad = QRadialGradient(lamp.center(), d / 2)
        grad.setColorAt(0.0, colour.lighter(150))
        grad.setColorAt(1.0, colour)
        painter.setPen(Qt.PenStyle.NoPen)
        painter.setBrush(QBrush(grad))
        painter.drawEllipse(lamp)
        painter.setPen(QColor("#f2f4f7"))
        painter.setFont(self._font)
        text_rect = rect.adjusted(lamp.width() + 16, 0, -6, 0)
        painter.drawText(
            text_rect, Qt.AlignmentFlag.AlignVCenter | Qt.AlignmentFlag.AlignLeft, self._text
        )
        painter.end()
