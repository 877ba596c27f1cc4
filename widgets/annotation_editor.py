"""Annotation editor for sparse bundle adjustment (Tykkälä 2014 sec. 6.1, Fig. 11).

Two keyframe panes side by side. Click a physical point in either pane: the point gets that
observation and the editor predicts where it appears in the other keyframes (current poses +
depth) and snaps the prediction by patch matching (:mod:`engine.keyframes.annotate`). The
suggestions show as dashed circles; Enter (or "Accept") confirms them, a click in a pane
corrects the observation there. A table lists the points with their views and reprojection error.

Panes: wheel zooms about the cursor, right- or middle-drag pans, a crosshair follows the
mouse and a magnifier (4x) shows the pixels around it. Keys: N new point, Enter accept
suggestions, Delete delete the selected point, Ctrl+Z / Ctrl+Shift+Z (Ctrl+Y) undo / redo,
F fit both views, [ and ] previous / next keyframe in the right pane.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import (
    QColor,
    QImage,
    QKeySequence,
    QMouseEvent,
    QPainter,
    QPen,
    QShortcut,
    QUndoCommand,
    QUndoStack,
    QWheelEvent,
)
from PySide6.QtWidgets import (
    QAbstractItemView,
    QComboBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from engine.project import AnnotatedPoint

POINT_COLOUR = QColor("#ff4d4d")
SELECTED_COLOUR = QColor("#ffd24c")
SUGGEST_COLOUR = QColor("#4cc3ff")


class KeyframePane(QWidget):
    """A grey keyframe image with zoom, pan, crosshair, magnifier and point markers."""

    clicked = Signal(float, float)  # image pixel (u, v)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setMinimumSize(240, 180)
        self.setMouseTracking(True)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self._img: QImage | None = None
        self._arr: np.ndarray | None = None
        self.scale = 1.0
        self.offset = QPointF(0.0, 0.0)  # widget position of image pixel (-0.5, -0.5)
        self._pan_from: QPointF | None = None
        self._mouse: QPointF | None = None
        self.markers: list[tuple[float, float, str, bool]] = []  # u, v, label, selected
        self.suggestions: list[tuple[float, float, str]] = []
        self.title = ""

    def set_image(self, gray: np.ndarray | None, title: str = "") -> None:
        self.title = title
        if gray is None:
            self._img = self._arr = None
        else:
            self._arr = np.ascontiguousarray(gray, dtype=np.uint8)
            h, w = self._arr.shape
            self._img = QImage(self._arr.data, w, h, w, QImage.Format.Format_Grayscale8)
        self.fit()

    def fit(self) -> None:
        if self._arr is None:
            return
        h, w = self._arr.shape
        self.scale = min(self.width() / w, self.height() / h)
        self.offset = QPointF(
            (self.width() - w * self.scale) / 2, (self.height() - h * self.scale) / 2
        )
        self.update()

    def resizeEvent(self, event: Any) -> None:
        self.fit()
        super().resizeEvent(event)

    def to_image(self, p: QPointF) -> tuple[float, float]:
        return (
            (p.x() - self.offset.x()) / self.scale - 0.5,
            (p.y() - self.offset.y()) / self.scale - 0.5,
        )

    def to_widget(self, u: float, v: float) -> QPointF:
        return QPointF(
            self.offset.x() + (u + 0.5) * self.scale, self.offset.y() + (v + 0.5) * self.scale
        )

    def zoom(self, factor: float, about: QPointF) -> None:
        u, v = self.to_image(about)
        self.scale = float(np.clip(self.scale * factor, 0.1, 40.0))
        w = self.to_widget(u, v)
        self.offset += about - w
        self.update()

    def wheelEvent(self, e: QWheelEvent) -> None:
        self.zoom(1.25 if e.angleDelta().y() > 0 else 0.8, e.position())

    def mousePressEvent(self, e: QMouseEvent) -> None:
        if e.button() in (Qt.MouseButton.RightButton, Qt.MouseButton.MiddleButton):
            self._pan_from = e.position()
        elif e.button() == Qt.MouseButton.LeftButton and self._arr is not None:
            u, v = self.to_image(e.position())
            h, w = self._arr.shape
            if -0.5 <= u < w - 0.5 and -0.5 <= v < h - 0.5:
                self.clicked.emit(u, v)

    def mouseMoveEvent(self, e: QMouseEvent) -> None:
        self._mouse = e.position()
        if self._pan_from is not None:
            self.offset += e.position() - self._pan_from
            self._pan_from = e.position()
        self.update()

    def mouseReleaseEvent(self, e: QMouseEvent) -> None:
        self._pan_from = None

    def leaveEvent(self, e: Any) -> None:
        self._mouse = None
        self.update()

    def paintEvent(self, e: Any) -> None:
        p = QPainter(self)
        p.fillRect(self.rect(), QColor("#202225"))
        if self._img is None:
            p.setPen(QColor("#aaaaaa"))
            p.drawText(self.rect(), Qt.AlignmentFlag.AlignCenter, "no keyframe")
            return
        h, w = self._arr.shape  # type: ignore[union-attr]
        target = QRectF(self.offset.x(), self.offset.y(), w * self.scale, h * self.scale)
        p.drawImage(target, self._img)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        for u, v, label, sel in self.markers:
            c = self.to_widget(u, v)
            p.setPen(QPen(SELECTED_COLOUR if sel else POINT_COLOUR, 2))
            p.drawEllipse(c, 6, 6)
            p.drawLine(c + QPointF(-9, 0), c + QPointF(-3, 0))
            p.drawLine(c + QPointF(3, 0), c + QPointF(9, 0))
            p.drawText(c + QPointF(8, -8), label)
        pen = QPen(SUGGEST_COLOUR, 2, Qt.PenStyle.DashLine)
        for u, v, label in self.suggestions:
            c = self.to_widget(u, v)
            p.setPen(pen)
            p.drawEllipse(c, 9, 9)
            p.drawText(c + QPointF(10, 14), label + "?")
        p.setPen(QColor("#dddddd"))
        p.drawText(QPointF(8, 16), self.title)
        if self._mouse is not None:
            m = self._mouse
            p.setPen(QPen(QColor(255, 210, 76, 140), 1))
            p.drawLine(QPointF(0, m.y()), QPointF(self.width(), m.y()))
            p.drawLine(QPointF(m.x(), 0), QPointF(m.x(), self.height()))
            u, v = self.to_image(m)
            # magnifier: 4x the pixels around the cursor, in the top-right corner
            r = 12
            src = QRectF(u + 0.5 - r, v + 0.5 - r, 2 * r, 2 * r)
            dst = QRectF(self.width() - 8 * r - 8, 8, 8 * r, 8 * r)
            p.drawImage(dst, self._img, src)
            p.setPen(QPen(SELECTED_COLOUR, 1))
            p.drawRect(dst)
            p.drawLine(dst.center() + QPointF(-6, 0), dst.center() + QPointF(6, 0))
            p.drawLine(dst.center() + QPointF(0, -6), dst.center() + QPointF(0, 6))
            p.drawText(QPointF(dst.left(), dst.bottom() + 14), f"u {u:.1f}  v {v:.1f}")
        p.end()


class _Edit(QUndoCommand):
    """Replace the whole point list (lists are small; simple and exact undo)."""

    def __init__(
        self,
        editor: AnnotationEditor,
        before: list[AnnotatedPoint],
        after: list[AnnotatedPoint],
        text: str,
    ) -> None:
        super().__init__(text)
        self.editor, self.before, self.after = editor, before, after

    def redo(self) -> None:
        self.editor._set_points(copy.deepcopy(self.after))

    def undo(self) -> None:
        self.editor._set_points(copy.deepcopy(self.before))


class AnnotationEditor(QWidget):
    """Editor of :class:`engine.project.AnnotatedPoint` s over a keyframe store."""

    points_changed = Signal()
    message = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.store: Any | None = None
        self.points: list[AnnotatedPoint] = []
        self.selected: int | None = None
        self.suggested: dict[int, tuple[float, float]] = {}  # kf id -> snapped uv
        self.errors_px: dict[int, float] = {}
        self.undo_stack = QUndoStack(self)
        self.left, self.right = KeyframePane(), KeyframePane()
        self.left.setObjectName("left_pane")
        self.right.setObjectName("right_pane")
        self.left_kf, self.right_kf = QComboBox(), QComboBox()
        self.left_kf.setToolTip("keyframe in the left pane")
        self.right_kf.setToolTip("keyframe in the right pane ([ and ] to step)")
        self.table = QTableWidget(0, 4)
        self.table.setHorizontalHeaderLabels(["point", "keyframes", "reproj. err (px)", "label"])
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.verticalHeader().setVisible(False)
        self.table.setMinimumWidth(260)
        hh = self.table.horizontalHeader()
        hh.setStretchLastSection(True)
        for c, w in enumerate((50, 80, 120)):
            self.table.setColumnWidth(c, w)
        self.status = QLabel("Click a point in either keyframe.")
        self.status.setWordWrap(True)
        b_new = QPushButton("New point (N)")
        b_accept = QPushButton("Accept suggestions (Enter)")
        b_del = QPushButton("Delete point (Del)")
        b_undo = QPushButton("Undo")
        b_redo = QPushButton("Redo")
        self.accept_button = b_accept
        b_new.clicked.connect(self.new_point)
        b_accept.clicked.connect(self.accept_suggestions)
        b_del.clicked.connect(self.delete_selected)
        b_undo.clicked.connect(self.undo_stack.undo)
        b_redo.clicked.connect(self.undo_stack.redo)

        panes = QSplitter()
        for combo, pane in ((self.left_kf, self.left), (self.right_kf, self.right)):
            box = QWidget()
            col = QVBoxLayout(box)
            col.setContentsMargins(0, 0, 0, 0)
            col.addWidget(combo)
            col.addWidget(pane, 1)
            panes.addWidget(box)
        side = QWidget()
        sc = QVBoxLayout(side)
        sc.setContentsMargins(0, 0, 0, 0)
        sc.addWidget(self.table, 1)
        for b in (b_new, b_accept, b_del):
            sc.addWidget(b)
        ur = QHBoxLayout()
        ur.addWidget(b_undo)
        ur.addWidget(b_redo)
        sc.addLayout(ur)
        left_col = QVBoxLayout()
        left_col.addWidget(panes, 1)
        left_col.addWidget(self.status)
        row = QHBoxLayout(self)
        row.addLayout(left_col, 1)
        row.addWidget(side)

        self.left_kf.currentIndexChanged.connect(lambda _i: self._show_panes())
        self.right_kf.currentIndexChanged.connect(lambda _i: self._show_panes())
        self.left.clicked.connect(lambda u, v: self.click(self._kf_id(self.left_kf), u, v))
        self.right.clicked.connect(lambda u, v: self.click(self._kf_id(self.right_kf), u, v))
        self.table.itemSelectionChanged.connect(self._on_table_selection)
        for keys, slot in (
            ("N", self.new_point),
            ("Return", self.accept_suggestions),
            ("Enter", self.accept_suggestions),
            ("Delete", self.delete_selected),
            ("Ctrl+Z", self.undo_stack.undo),
            ("Ctrl+Shift+Z", self.undo_stack.redo),
            ("Ctrl+Y", self.undo_stack.redo),
            ("F", self._fit),
            ("[", lambda: self._step(-1)),
            ("]", lambda: self._step(1)),
        ):
            sc_ = QShortcut(QKeySequence(keys), self)
            sc_.setContext(Qt.ShortcutContext.WidgetWithChildrenShortcut)
            sc_.activated.connect(slot)

    # ------------------------------------------------------------------ model
    def set_data(self, store: Any | None, points: list[AnnotatedPoint]) -> None:
        self.store = store
        self.undo_stack.clear()
        ids = [k.id for k in store.keyframes] if store is not None else []
        for combo, pick in ((self.left_kf, 0), (self.right_kf, -1)):
            combo.blockSignals(True)
            combo.clear()
            for i in ids:
                combo.addItem(f"keyframe {i}", i)
            if ids:
                combo.setCurrentIndex(pick % len(ids))
            combo.blockSignals(False)
        self._set_points(copy.deepcopy(points))
        self._show_panes()

    def set_keyframes(self, left_id: int, right_id: int) -> None:
        self.left_kf.setCurrentIndex(self.left_kf.findData(left_id))
        self.right_kf.setCurrentIndex(self.right_kf.findData(right_id))

    def set_errors(self, errors_px: dict[int, float]) -> None:
        self.errors_px = dict(errors_px)
        self._refresh()

    def _set_points(self, pts: list[AnnotatedPoint]) -> None:
        self.points = pts
        if self.selected is not None and all(p.id != self.selected for p in pts):
            self.selected = pts[-1].id if pts else None
        self.suggested = {}
        self._refresh()
        self.points_changed.emit()

    def _commit(self, after: list[AnnotatedPoint], text: str) -> None:
        self.undo_stack.push(_Edit(self, copy.deepcopy(self.points), copy.deepcopy(after), text))

    def _kf_id(self, combo: QComboBox) -> int | None:
        d = combo.currentData()
        return None if d is None else int(d)

    def point(self, pid: int | None) -> AnnotatedPoint | None:
        return next((p for p in self.points if p.id == pid), None)

    # ---------------------------------------------------------------- actions
    def new_point(self) -> None:
        self.selected = None
        self.suggested = {}
        self.status.setText("New point: click it in either keyframe.")
        self._refresh()

    def click(self, kf_id: int | None, u: float, v: float) -> None:
        """Set the selected point's observation in ``kf_id`` (a new point if none selected)
        and predict + snap it in the other keyframes."""
        if kf_id is None or self.store is None:
            return
        after = copy.deepcopy(self.points)
        pt = next((p for p in after if p.id == self.selected), None)
        if pt is None:
            pt = AnnotatedPoint(1 + max((p.id for p in after), default=-1))
            after.append(pt)
            self.selected = pt.id
        pt.observations_px[kf_id] = (float(u), float(v))
        self._commit(after, f"point {pt.id} in keyframe {kf_id}")
        self._suggest(pt.id, kf_id, (float(u), float(v)))

    def _suggest(self, pid: int, kf_id: int, uv: tuple[float, float]) -> None:
        """Predict the clicked point in every other keyframe (current poses + the clicked
        keyframe's depth) and snap it there by patch matching against the clicked keyframe
        (perspective-corrected by the local affine map of
        :func:`engine.keyframes.annotate.local_affine`).
        Matching straight against the click avoids the drift of chained matches."""
        from engine.keyframes.annotate import predict_and_snap

        assert self.store is not None
        pt = self.point(pid)
        assert pt is not None
        src = self.store.by_id(kf_id)
        self.suggested = {}
        missed = []
        for kf in self.store.keyframes:
            if kf.id == kf_id or kf.id in pt.observations_px:
                continue
            pred, snap = predict_and_snap(self.store.intrinsics, src, uv, kf)
            if pred.uv is None:
                continue
            if snap is not None and snap.ok:
                self.suggested[kf.id] = snap.uv
            else:
                missed.append(kf.id)
        self.status.setText(
            f"Point {pid}: {len(self.suggested)} suggestion(s) snapped"
            + (f"; no confident match in keyframe(s) {missed}" if missed else "")
            + ". Enter accepts, a click corrects."
        )
        self._refresh()

    def accept_suggestions(self) -> None:
        if self.selected is None or not self.suggested:
            return
        after = copy.deepcopy(self.points)
        pt = next(p for p in after if p.id == self.selected)
        for k, uv in self.suggested.items():
            pt.observations_px.setdefault(k, uv)
        n = len(self.suggested)
        self._commit(after, f"accept {n} suggestion(s) of point {pt.id}")
        self.status.setText(
            f"Point {pt.id}: accepted {n} suggestion(s), now in "
            f"{len(pt.observations_px)} keyframes."
        )

    def delete_selected(self) -> None:
        if self.selected is None:
            return
        pid = self.selected
        self._commit([p for p in self.points if p.id != pid], f"delete point {pid}")
        self.selected = None
        self._refresh()

    def _step(self, d: int) -> None:
        n = self.right_kf.count()
        if n:
            self.right_kf.setCurrentIndex((self.right_kf.currentIndex() + d) % n)

    def _fit(self) -> None:
        self.left.fit()
        self.right.fit()

    def _on_table_selection(self) -> None:
        rows = self.table.selectionModel().selectedRows()
        if rows:
            item = self.table.item(rows[0].row(), 0)
            self.selected = int(item.data(Qt.ItemDataRole.UserRole))
            self.suggested = {}
            self._draw_markers()

    # ---------------------------------------------------------------- display
    def _show_panes(self) -> None:
        for combo, pane in ((self.left_kf, self.left), (self.right_kf, self.right)):
            kid = self._kf_id(combo)
            if self.store is None or kid is None:
                pane.set_image(None)
            else:
                pane.set_image(self.store.by_id(kid).gray, f"keyframe {kid}")
        self._draw_markers()

    def _draw_markers(self) -> None:
        for combo, pane in ((self.left_kf, self.left), (self.right_kf, self.right)):
            kid = self._kf_id(combo)
            pane.markers = [
                (*p.observations_px[kid], str(p.id), p.id == self.selected)
                for p in self.points
                if kid is not None and kid in p.observations_px
            ]
            pane.suggestions = (
                [(*self.suggested[kid], str(self.selected))] if kid in self.suggested else []
            )
            pane.update()

    def _refresh(self) -> None:
        self.table.blockSignals(True)
        self.table.setRowCount(len(self.points))
        for r, p in enumerate(self.points):
            e = self.errors_px.get(p.id, math.nan)
            cells = [
                str(p.id),
                str(len(p.observations_px)),
                "-" if not math.isfinite(e) else f"{e:.2f}",
                p.label,
            ]
            for c, text in enumerate(cells):
                it = QTableWidgetItem(text)
                it.setData(Qt.ItemDataRole.UserRole, p.id)
                if c == 2 and math.isfinite(e) and e > 2.0:
                    it.setForeground(QColor("#ff6b6b"))
                self.table.setItem(r, c, it)
            if p.id == self.selected:
                self.table.selectRow(r)
        self.table.blockSignals(False)
        self._draw_markers()
