"""The status header shown above every page: is the show healthy, readable across a room.

A big state box (TRACKING green, DEGRADED amber, LOST and ERROR red, STOPPED grey,
STARTING/INITIALIZING/RELOCALIZING blue), the tracker and source with the latest reason,
frames/s against the target rate with a "falling behind" warning, end-to-end latency, one
chip per output target (green only while packets leave without error), and the timecode
slot. LOST, ERROR and a failing output flash the border (an alarm). The widget shows a
:class:`HeaderState`; what it says is decided by the app (``app.status.header_state``).
"""

from __future__ import annotations

from dataclasses import dataclass

from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QPainter, QPaintEvent, QPalette
from PySide6.QtWidgets import QFrame, QHBoxLayout, QLabel, QSizePolicy, QVBoxLayout, QWidget

STATE_COLOURS = {
    "TRACKING": "#1f9d55",
    "DEGRADED": "#d99a00",
    "LOST": "#d63031",
    "ERROR": "#d63031",
    "STOPPED": "#4a505b",
    "STARTING": "#3d6fd6",
    "INITIALIZING": "#3d6fd6",
    "RELOCALIZING": "#3d6fd6",
}
LEVEL_COLOURS = {"ok": "#1f9d55", "waiting": "#8a6d1f", "alarm": "#d63031", "off": "#3a3f48"}
ALARM_COLOUR = "#ff4d4f"
MESSAGE_COLOUR = "#b9bec7"
ALARM_MESSAGE_COLOUR = "#ff8a8a"
FLASH_MS = 400


@dataclass(frozen=True, slots=True)
class HeaderTarget:
    """One output chip: ``level`` is ok | waiting | alarm | off."""

    name: str
    level: str
    text: str
    tooltip: str = ""


@dataclass(frozen=True, slots=True)
class HeaderState:
    state: str  # one of STATE_COLOURS
    title: str  # tracker · source
    message: str = ""  # why (LOST reason, engine error), or what runs
    fps_text: str = "–"
    behind: bool = False
    latency_text: str = "–"
    targets: tuple[HeaderTarget, ...] = ()
    timecode: str = ""
    alarm: bool = False


IDLE = HeaderState("STOPPED", "no run", "press Start on a page to track")


def _restyle(widget: QWidget, css: str) -> None:
    """Set a style sheet only when it changes: each set re-polishes the widget and its
    children (the header updates 10 times a second, its styles rarely)."""
    if widget.styleSheet() != css:
        widget.setStyleSheet(css)


def _retext(label: QLabel, text: str) -> None:
    if label.text() != text:
        label.setText(text)


def _label(name: str, text: str = "", *, mono: bool = False) -> QLabel:
    lab = QLabel(text)
    lab.setObjectName(name)
    if mono:
        lab.setStyleSheet("font-family: monospace; font-size: 9pt;")
    return lab


class _ElidedLabel(QLabel):
    """One line that elides with "…" when it does not fit (``text()`` stays the whole
    text): at the end, or in the middle (``mode``) so that a reason's end stays readable."""

    def __init__(self, mode: Qt.TextElideMode = Qt.TextElideMode.ElideRight) -> None:
        super().__init__()
        self.elide_mode = mode

    def paintEvent(self, event: QPaintEvent) -> None:
        painter = QPainter(self)
        rect = self.contentsRect()
        painter.setFont(self.font())
        painter.setPen(self.palette().color(QPalette.ColorRole.WindowText))
        text = self.fontMetrics().elidedText(self.text(), self.elide_mode, rect.width())
        painter.drawText(rect, Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter, text)
        painter.end()


class StatusHeader(QFrame):
    """A strip ~60 px high across the window (see the module docstring)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setObjectName("status_header")
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self._state = IDLE
        self._flash_on = False
        self.state_label = QLabel("STOPPED")
        self.state_label.setObjectName("header_state")
        self.state_label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.state_label.setMinimumWidth(160)
        self.state_label.setFixedHeight(46)
        self.title_label = _ElidedLabel()
        self.title_label.setObjectName("header_title")
        self.title_label.setStyleSheet("font-weight: bold; font-size: 12pt; color: #e6e9ee;")
        # "OUTPUT FAILING: freed:192.0.2.1:40000: Invalid argument": what fails and why
        self.message_label = _ElidedLabel(Qt.TextElideMode.ElideMiddle)
        self.message_label.setObjectName("header_message")
        self.message_label.setStyleSheet(f"color: {MESSAGE_COLOUR};")
        for lab in (self.title_label, self.message_label):
            lab.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        mid = QVBoxLayout()
        mid.setSpacing(0)
        mid.addWidget(self.title_label)
        mid.addWidget(self.message_label)
        self.fps_label = _label("header_fps", "–", mono=True)
        self.latency_label = _label("header_latency", "–", mono=True)
        self.timecode_label = _label("header_timecode", "TC –")
        # read across the room like the state box: bright, bold, fixed-width digits
        self.timecode_label.setStyleSheet("font-family: monospace; font-size: 13pt; "
                                          "font-weight: bold; color: #e6e9ee;")
        nums = QVBoxLayout()
        nums.setSpacing(0)
        nums.addWidget(self.fps_label)
        nums.addWidget(self.latency_label)
        self.targets_box = QHBoxLayout()
        self.targets_box.setSpacing(4)
        self.targets_box.addStretch(1)
        self.target_labels: list[QLabel] = []
        self._target_texts: list[str] = []
        # one-line chips above the timecode: the reason line keeps the width it needs to be
        # read whole at 1280 px (an output failure's target and reason)
        right = QVBoxLayout()
        right.setSpacing(2)
        right.addLayout(self.targets_box)
        right.addWidget(self.timecode_label, 0, Qt.AlignmentFlag.AlignRight)
        row = QHBoxLayout(self)
        row.setContentsMargins(8, 4, 8, 4)
        row.setSpacing(8)
        row.addWidget(self.state_label)
        row.addLayout(mid, 1)
        row.addLayout(nums)
        row.addLayout(right)
        self.setFixedHeight(58)
        self._flash = QTimer(self)
        self._flash.setInterval(FLASH_MS)
        self._flash.timeout.connect(self._toggle_flash)
        self._apply_frame()
        self.set_state(IDLE)

    # ------------------------------------------------------------------ api
    @property
    def state(self) -> HeaderState:
        return self._state

    def set_state(self, st: HeaderState) -> None:
        """Show ``st`` (cheap when nothing changed)."""
        if st == self._state and self.state_label.text() == st.state:
            return
        self._state = st
        colour = STATE_COLOURS.get(st.state, "#4a505b")
        _retext(self.state_label, st.state)
        _restyle(self.state_label,
                 f"background: {colour}; color: white; font-size: 19pt; font-weight: 800; "
                 "border-radius: 5px; padding: 0 10px;")
        self.state_label.setAccessibleName(f"tracking state {st.state}")
        _retext(self.title_label, st.title)
        self.title_label.setToolTip(st.title)
        _retext(self.message_label, st.message)
        self.message_label.setToolTip(st.message)
        _restyle(self.message_label,  # an alarm's reason reads as one
                 f"color: {ALARM_MESSAGE_COLOUR}; font-weight: bold;" if st.alarm
                 else f"color: {MESSAGE_COLOUR};")
        fps_colour = "#ffb020" if st.behind else "#e6e9ee"
        _retext(self.fps_label, st.fps_text + ("  falling behind" if st.behind else ""))
        _restyle(self.fps_label, f"font-family: monospace; font-size: 9pt; color: {fps_colour};"
                 + (" font-weight: bold;" if st.behind else ""))
        _retext(self.latency_label, st.latency_text)
        _retext(self.timecode_label, f"TC {st.timecode}" if st.timecode else "TC –")
        self.timecode_label.setToolTip("timecode of the latest record" if st.timecode
                                       else "no timecode on this source")
        self._set_targets(st.targets)
        if st.alarm and not self._flash.isActive():
            self._flash.start()
        elif not st.alarm and self._flash.isActive():
            self._flash.stop()
            self._flash_on = False
        self._apply_frame()

    def target_texts(self) -> list[str]:
        """``"name\nstate"`` of each chip shown (the chip reads them on one line)."""
        return list(self._target_texts)

    # ------------------------------------------------------------ internals
    def _set_targets(self, targets: tuple[HeaderTarget, ...]) -> None:
        self._target_texts = [f"{t.name}\n{t.text}" for t in targets]
        while len(self.target_labels) < len(targets):
            lab = QLabel()
            lab.setObjectName("header_target")
            self.targets_box.addWidget(lab)
            self.target_labels.append(lab)
        for i, lab in enumerate(self.target_labels):
            if i >= len(targets):
                lab.setVisible(False)
                continue
            t = targets[i]
            lab.setVisible(True)
            _retext(lab, f"{t.name} {t.text}")
            lab.setToolTip(t.tooltip or t.text)
            lab.setProperty("level", t.level)
            _restyle(lab, f"background: {LEVEL_COLOURS.get(t.level, '#3a3f48')}; color: white; "
                     "border-radius: 3px; padding: 1px 6px; font-size: 9pt; font-weight: bold;")

    def _toggle_flash(self) -> None:
        self._flash_on = not self._flash_on
        self._apply_frame()

    def _apply_frame(self) -> None:
        border = ALARM_COLOUR if (self._state.alarm and self._flash_on) else "#2b2f37"
        width = 3 if self._state.alarm else 1
        _restyle(self, f"QFrame#status_header {{ background: #1b1d22; border: {width}px "
                       f"solid {border}; border-radius: 4px; }}")

    @property
    def flashing(self) -> bool:
        return self._flash.isActive()
