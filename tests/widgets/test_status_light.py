from __future__ import annotations

import pytest
from PySide6.QtGui import QColor

from engine.trackers.base import TrackState
from widgets.status_light import StatusLight


@pytest.mark.parametrize(
    ("state", "colour"),
    [
        (TrackState.TRACKING, "#2ecc71"),
        (TrackState.DEGRADED, "#f0b429"),
        (TrackState.RELOCALIZING, "#3d8bfd"),
        (TrackState.LOST, "#ff4d4f"),
        (None, "#5a606b"),
    ],
)
def test_colours_and_text(qtbot, state, colour) -> None:  # type: ignore[no-untyped-def]
    light = StatusLight()
    qtbot.addWidget(light)
    light.set_state(state)
    assert light.colour() == QColor(colour)
    assert light.text == (state.value if state else "IDLE")
    image = light.grab().toImage()
    lamp = image.pixelColor(8 + (image.height() - 12) // 2 + 2, image.height() // 2)
    # the lamp is painted in (a lighter shade of) the state's colour
    assert abs(lamp.hue() - QColor(colour).hue()) <= 12 or state is None


def test_custom_text(qtbot) -> None:  # type: ignore[no-untyped-def]
    light = StatusLight()
    qtbot.addWidget(light)
    light.set_state(None, "ERROR")
    assert light.text == "ERROR"
    assert light.state is None
