"""An image canvas for drawing a presenter model: main region + named patches (VR-TV Fig. 4).

Modes (``set_mode``):
- ``"main"``  a left-drag draws the main region (replaces the previous one);
- ``"patch"`` a left-drag draws a new patch (named ``patch N``, rename in the page's list);
- ``"edit"``  press inside a rectangle and drag to move it, press its bottom-right corner
              handle to resize it; the pressed patch becomes the selection (Delete removes it);
- ``"floor"`` each click adds a floor-calibration point (up to four).

The canvas also draws the live overlay (tracker boxes or a cross-hair, the particle cloud).
Coordinates exposed by the API are image pixels; mouse handling does its own press/move/
release bookkeeping (no reliance on ``buttons()`` of move events), so tests can drive it with
``QTest``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import (
    QBrush,
    QColor,
    QFont,
    QFontMetricsF,
    QImage,
    QKeyEvent,
    QMouseEvent,
    QPainter,
    QPen,
)
from PySide6.QtWidgets import QSizePolicy, QWidget

XYWH = tuple[float, float, float, float]
MAIN_COLOUR = QColor("#2ecc71")
LOST_COLOUR = QColor("#ff4d4f")
PATCH_COLOURS = ("#4cc3ff", "#ff7ad9", "#ffd24c", "#9dff4c", "#ff8c42", "#b28dff")
HANDLE_PX = 9.0
MIN_DRAG_PX = 3.0


@dataclass
class CanvasRect:
    name: str
    xywh: XYWH


class PatchCanvas(QWidget):
    """Shows a BGR image scaled to fit; draws and edits rectangles in image coordinates."""

    rects_changed = Signal()
    selection_changed = Signal(int)  # patch index, -1 for none / main region
    floor_point_added = Signal(float, float)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setMinimumSize(320, 240)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.setMouseTracking(False)
        self._qimage: QImage | None = None
        self._image_wh = (640, 480)
        self.mode = "main"
        self.main: XYWH | None = None
        self.patches: list[CanvasRect] = []
        self.selected = -1
        self.floor_points: list[tuple[float, float]] = []
        self._drag: dict[str, object] | None = None
        self._rubber: XYWH | None = None
        # live overlay
        self.overlay_boxes: list[tuple[XYWH, str]] = []
        self.overlay_lost = False
        self.crosshair: tuple[float, float] | None = None
        self.target: tuple[float, float] | None = None
        self.particles: NDArray[np.float32] | None = None
        self.particle_w: NDArray[np.float32] | None = None
        self.show_model = True
        #: what the canvas says while it has no image
        self.placeholder = "No reference image: press \u201cTake reference\u201d"

    # ---------------------------------------------------------------- image and mapping
    def set_image(self, image_bgr: NDArray[np.uint8] | None) -> None:
        if image_bgr is None:
            self._qimage = None
        else:
            img = np.ascontiguousarray(image_bgr[..., ::-1] if image_bgr.ndim == 3 else
                                       np.repeat(image_bgr[..., None], 3, axis=2))
            h, w = img.shape[:2]
            self._image_wh = (w, h)
            self._qimage = QImage(img.data, w, h, 3 * w, QImage.Format.Format_RGB888).copy()
        self.update()

    @property
    def image_wh(self) -> tuple[int, int]:
        return self._image_wh

    def _scale_offset(self) -> tuple[float, float, float]:
        w, h = self._image_wh
        s = min(self.width() / w, self.height() / h)
        return s, (self.width() - s * w) / 2.0, (self.height() - s * h) / 2.0

    def to_image(self, p: QPointF) -> tuple[float, float]:
        s, ox, oy = self._scale_offset()
        w, h = self._image_wh
        return (min(max((p.x() - ox) / s, 0.0), float(w)), min(max((p.y() - oy) / s, 0.0),
                                                              float(h)))

    def to_widget(self, x: float, y: float) -> QPointF:
        s, ox, oy = self._scale_offset()
        return QPointF(ox + s * x, oy + s * y)

    def _wrect(self, r: XYWH) -> QRectF:
        p = self.to_widget(r[0], r[1])
        s, _, _ = self._scale_offset()
        return QRectF(p.x(), p.y(), r[2] * s, r[3] * s)

    # ---------------------------------------------------------------- model editing API
    def set_mode(self, mode: str) -> None:
        if mode not in ("main", "patch", "edit", "floor"):
            raise ValueError(f"unknown canvas mode {mode!r}")
        self.mode = mode
        self.setCursor(Qt.CursorShape.SizeAllCursor if mode == "edit"
                       else Qt.CursorShape.CrossCursor)

    def set_model(self, main: XYWH | None, patches: list[tuple[str, XYWH]]) -> None:
        self.main = main
        self.patches = [CanvasRect(n, r) for n, r in patches]
        self.selected = -1
        self.rects_changed.emit()
        self.update()

    def clear_model(self) -> None:
        self.set_model(None, [])

    def set_floor_points(self, points: list[tuple[float, float]]) -> None:
        """Replace the floor marks (image px), e.g. from a saved calibration."""
        self.floor_points = [(float(x), float(y)) for x, y in points][:4]
        self.update()

    def delete_selected(self) -> bool:
        if 0 <= self.selected < len(self.patches):
            del self.patches[self.selected]
            self.selected = -1
            self.selection_changed.emit(-1)
            self.rects_changed.emit()
            self.update()
            return True
        return False

    def rename(self, index: int, name: str) -> None:
        self.patches[index].name = name
        self.rects_changed.emit()
        self.update()

    def select(self, index: int) -> None:
        self.selected = index
        self.update()

    def _new_patch_name(self) -> str:
        names = {p.name for p in self.patches}
        k = len(self.patches) + 1
        while f"patch {k}" in names:
            k += 1
        return f"patch {k}"

    # ---------------------------------------------------------------- mouse
    def _hit(self, x: float, y: float) -> tuple[str, int]:
        """('resize'|'move', index) of the rectangle under the point; index -1 = main."""
        s, _, _ = self._scale_offset()
        tol = HANDLE_PX / s
        cands: list[tuple[int, XYWH]] = [(i, p.xywh) for i, p in enumerate(self.patches)]
        cands.reverse()
        if self.main is not None:
            cands.append((-1, self.main))
        for i, (rx, ry, rw, rh) in cands:
            if abs(x - (rx + rw)) <= tol and abs(y - (ry + rh)) <= tol:
                return "resize", i
        for i, (rx, ry, rw, rh) in cands:
            if rx <= x <= rx + rw and ry <= y <= ry + rh:
                return "move", i
        return "", -2

    def mousePressEvent(self, ev: QMouseEvent) -> None:
        if ev.button() != Qt.MouseButton.LeftButton:
            return
        self.setFocus()
        x, y = self.to_image(ev.position())
        if self.mode == "floor":
            if len(self.floor_points) < 4:
                self.floor_points.append((x, y))
                self.floor_point_added.emit(x, y)
                self.update()
            return
        if self.mode == "edit":
            kind, idx = self._hit(x, y)
            if kind:
                rect = self.main if idx == -1 else self.patches[idx].xywh
                self._drag = {"kind": kind, "index": idx, "start": (x, y), "rect": rect}
                self.selected = idx
                self.selection_changed.emit(idx)
                self.update()
            return
        self._drag = {"kind": "draw", "start": (x, y)}
        self._rubber = (x, y, 0.0, 0.0)

    def mouseMoveEvent(self, ev: QMouseEvent) -> None:
        if self._drag is None:
            return
        x, y = self.to_image(ev.position())
        x0, y0 = self._drag["start"]  # type: ignore[misc]
        kind = self._drag["kind"]
        if kind == "draw":
            self._rubber = (min(x0, x), min(y0, y), abs(x - x0), abs(y - y0))
        else:
            rx, ry, rw, rh = self._drag["rect"]  # type: ignore[misc]
            if kind == "move":
                new = (rx + x - x0, ry + y - y0, rw, rh)
            else:
                new = (rx, ry, max(rw + x - x0, 2.0), max(rh + y - y0, 2.0))
            idx = int(self._drag["index"])  # type: ignore[call-overload]
            if idx == -1:
                self.main = new
            else:
                self.patches[idx].xywh = new
            self.rects_changed.emit()
        self.update()

    def mouseReleaseEvent(self, ev: QMouseEvent) -> None:
        if self._drag is None or ev.button() != Qt.MouseButton.LeftButton:
            return
        self.mouseMoveEvent(ev)
        kind = self._drag["kind"]
        self._drag = None
        if kind == "draw" and self._rubber is not None:
            r = self._rubber
            self._rubber = None
            s, _, _ = self._scale_offset()
            if r[2] * s >= MIN_DRAG_PX and r[3] * s >= MIN_DRAG_PX:
                if self.mode == "main":
                    self.main = r
                    self.selected = -1
                    self.selection_changed.emit(-1)
                else:
                    self.patches.append(CanvasRect(self._new_patch_name(), r))
                    self.selected = len(self.patches) - 1
                    self.selection_changed.emit(self.selected)
                self.rects_changed.emit()
        self.update()

    def keyPressEvent(self, ev: QKeyEvent) -> None:
        if ev.key() in (Qt.Key.Key_Delete, Qt.Key.Key_Backspace):
            self.delete_selected()
            return
        super().keyPressEvent(ev)

    # ---------------------------------------------------------------- live overlay
    def set_live(self, boxes: list[tuple[XYWH, str]], crosshair: tuple[float, float] | None,
                 particles: NDArray[np.float32] | None, weights: NDArray[np.float32] | None,
                 target: tuple[float, float] | None = None, lost: bool = False) -> None:
        """The live overlay; ``lost``: the boxes are the last estimate of a LOST tracker
        (drawn dashed in the alarm colour, the main box labelled so), never as a lock."""
        self.overlay_lost = lost
        self.overlay_boxes = boxes
        self.crosshair = crosshair
        self.particles = particles
        self.particle_w = weights
        self.target = target
        self.update()

    # ---------------------------------------------------------------- painting
    def paintEvent(self, _ev: object) -> None:
        p = QPainter(self)
        p.fillRect(self.rect(), QColor("#101215"))
        if self._qimage is not None:
            w, h = self._image_wh
            p.drawImage(self._wrect((0.0, 0.0, float(w), float(h))), self._qimage)
        else:
            p.setPen(QColor("#8a93a3"))
            p.drawText(QRectF(self.rect()).adjusted(12, 12, -12, -12),
                       Qt.AlignmentFlag.AlignCenter | Qt.TextFlag.TextWordWrap,
                       self.placeholder)
        if self.particles is not None and len(self.particles):
            s, ox, oy = self._scale_offset()
            wts = self.particle_w if self.particle_w is not None else np.ones(len(self.particles))
            p.setPen(Qt.PenStyle.NoPen)
            for (u, v), wt in zip(self.particles, wts, strict=False):
                c = QColor.fromHsvF(0.33 * float(np.clip(wt, 0, 1)), 0.9, 1.0)
                p.setBrush(QBrush(c))
                p.drawRect(QRectF(ox + s * u - 1.5, oy + s * v - 1.5, 3.0, 3.0))
        p.setBrush(Qt.BrushStyle.NoBrush)
        lost = self.overlay_lost
        for k, (box, label) in enumerate(self.overlay_boxes):
            if lost and k > 0:
                continue  # the patches of a lost box locate nothing: only the held box
            colour = (LOST_COLOUR if lost else MAIN_COLOUR if k == 0
                      else QColor(PATCH_COLOURS[(k - 1) % len(PATCH_COLOURS)]))
            p.setPen(QPen(colour, 2 if k == 0 else 1,
                          Qt.PenStyle.DashLine if lost else Qt.PenStyle.SolidLine))
            r = self._wrect(box)
            p.drawRect(r)
            if lost:
                label = f"{label}: LOST (last estimate)"
            # the presenter's label above the box, patch labels inside: never on top of
            # each other
            self._label(p, r.topLeft() + (QPointF(0, -2) if k == 0 else QPointF(2, 2)),
                        label, colour, above=k == 0)
        if self.crosshair is not None:
            c = self.to_widget(*self.crosshair)
            p.setPen(QPen(QColor("#ffd24c"), 2))
            p.drawLine(c + QPointF(-14, 0), c + QPointF(14, 0))
            p.drawLine(c + QPointF(0, -14), c + QPointF(0, 14))
        if self.target is not None:
            c = self.to_widget(*self.target)
            p.setPen(QPen(QColor("#ff4d4f"), 1, Qt.PenStyle.DashLine))
            p.drawEllipse(c, 8, 8)
        if self.show_model:
            if self.main is not None:
                pen = QPen(MAIN_COLOUR, 2, Qt.PenStyle.DashLine)
                p.setPen(pen)
                r = self._wrect(self.main)
                p.drawRect(r)
                self._label(p, r.topLeft() + QPointF(0, -2), "main region", MAIN_COLOUR,
                            above=True)
                self._handle(p, r, self.selected == -1 and self._drag is not None)
            for i, pr in enumerate(self.patches):
                colour = QColor(PATCH_COLOURS[i % len(PATCH_COLOURS)])
                p.setPen(QPen(colour, 3 if i == self.selected else 1.5))
                r = self._wrect(pr.xywh)
                p.drawRect(r)
                self._label(p, r.topLeft() + QPointF(2, 2), pr.name, colour)
                self._handle(p, r, i == self.selected)
        if self._rubber is not None:
            p.setPen(QPen(QColor("white"), 1, Qt.PenStyle.DotLine))
            p.drawRect(self._wrect(self._rubber))
        for k, (x, y) in enumerate(self.floor_points):
            c = self.to_widget(x, y)
            p.setPen(QPen(QColor("#ff8c42"), 2))
            p.drawEllipse(c, 5, 5)
            self._label(p, c + QPointF(7, -7), f"F{k + 1}", QColor("#ff8c42"), above=True)
        p.end()

    @staticmethod
    def _label(p: QPainter, at: QPointF, text: str, colour: QColor, above: bool = False) -> None:
        """Readable on any picture: bold text in the rectangle's colour on a dark chip
        (``at``: its top-left corner, or bottom-left with ``above``)."""
        font = QFont(p.font())
        font.setBold(True)
        font.setPointSizeF(max(font.pointSizeF(), 9.0))
        p.save()
        p.setFont(font)
        fm = QFontMetricsF(font)
        w, h = fm.horizontalAdvance(text) + 8.0, fm.height() + 2.0
        top = at.y() - h if above else at.y()
        chip = QRectF(at.x(), top, w, h)
        p.setPen(Qt.PenStyle.NoPen)
        p.setBrush(QColor(10, 12, 16, 200))
        p.drawRoundedRect(chip, 3.0, 3.0)
        p.setPen(colour.lighter(130))
        p.drawText(chip.adjusted(4.0, 0.0, 0.0, 0.0),
                   Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter, text)
        p.restore()

    @staticmethod
    def _handle(p: QPainter, r: QRectF, strong: bool) -> None:
        size = 7.0
        p.fillRect(QRectF(r.right() - size / 2, r.bottom() - size / 2, size, size),
                   QColor("white") if strong else QColor("#c0c4cc"))
