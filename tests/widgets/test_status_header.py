"""The status header: a title or reason too long for the strip ends in "…" (the whole text
stays the label's text and tooltip); an alarm's message shows in the alarm colour."""

from __future__ import annotations

from widgets.status_header import (
    ALARM_MESSAGE_COLOUR,
    MESSAGE_COLOUR,
    HeaderState,
    HeaderTarget,
    StatusHeader,
)

LONG = "beacon-slam · beacon simulator (4 beacons, 100000 steps, layout from the project)"


def test_long_title_keeps_its_text_and_an_alarm_message_is_in_the_alarm_colour(qtbot) -> None:  # type: ignore[no-untyped-def]
    header = StatusHeader()
    qtbot.addWidget(header)
    header.resize(700, 58)
    header.show()
    qtbot.waitExposed(header)
    message = "OUTPUT FAILING: freed:192.0.2.1:40000: Invalid argument"
    header.set_state(HeaderState("TRACKING", LONG, message, alarm=True,
                                 targets=(HeaderTarget("freed", "alarm", "FAILING"),)))
    lab = header.title_label
    assert lab.text() == LONG
    assert lab.toolTip() == LONG
    assert lab.fontMetrics().horizontalAdvance(LONG) > lab.contentsRect().width()
    assert lab.grab().width() <= lab.width()  # painted elided, the strip keeps its size
    assert header.message_label.text() == message
    assert ALARM_MESSAGE_COLOUR in header.message_label.styleSheet()
    header.set_state(HeaderState("TRACKING", "dense · studio", "all good"))
    assert header.message_label.text() == "all good"
    assert MESSAGE_COLOUR in header.message_label.styleSheet()
    assert ALARM_MESSAGE_COLOUR not in header.message_label.styleSheet()
