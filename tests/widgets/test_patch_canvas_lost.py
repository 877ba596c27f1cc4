"""The presenter canvas never draws a LOST tracker's held box like a lock: dashed, in the
alarm colour, without its patches."""

from __future__ import annotations

import numpy as np

from widgets.patch_canvas import PatchCanvas

BOX = (40.0, 20.0, 60.0, 100.0)
PATCH = (50.0, 30.0, 40.0, 30.0)


def _edge_colours(canvas: PatchCanvas, box: tuple[float, float, float, float]) -> np.ndarray:
    """RGB of the pixels along the left edge of ``box`` (widget coordinates)."""
    img = canvas.grab().toImage()
    a = canvas.to_widget(box[0], box[1] + 0.2 * box[3])
    b = canvas.to_widget(box[0], box[1] + 0.8 * box[3])
    x = round(a.x())
    cols = [img.pixelColor(x, y) for y in range(round(a.y()), round(b.y()))]
    return np.array([(c.red(), c.green(), c.blue()) for c in cols], dtype=np.int32)


def test_lost_box_is_dashed_red_and_its_patches_are_not_drawn(qtbot) -> None:  # type: ignore[no-untyped-def]
    canvas = PatchCanvas()
    qtbot.addWidget(canvas)
    canvas.resize(320, 240)
    canvas.set_image(np.full((160, 160, 3), 90, np.uint8))
    boxes = [(BOX, "presenter"), (PATCH, "head")]
    canvas.set_live(boxes, None, None, None, None)
    locked = _edge_colours(canvas, BOX)
    assert (locked[:, 1] > locked[:, 0] + 60).all()  # solid green while tracking
    assert (_edge_colours(canvas, PATCH) != 90).any()
    canvas.set_live(boxes, None, None, None, None, lost=True)
    lost = _edge_colours(canvas, BOX)
    red = lost[:, 0] > lost[:, 1] + 60
    assert red.any()
    assert not red.all()  # dashed: gaps show the picture
    assert not (lost[:, 1] > lost[:, 0] + 60).any()  # nothing green is left
    assert (_edge_colours(canvas, PATCH) == 90).all()  # the patches are gone
