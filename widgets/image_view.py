"""Live image with tracker overlays (pyqtgraph, row-major images).

Overlays, all in pixel coordinates of the image:
- points coloured by weight, green (used, weight 1) to red (rejected, weight 0), as in
  Tykkälä 2014 Fig. 15; drawn as a few colour buckets, each one line-segment path (a short
  thick dash per point: a numpy-built path, ~10x cheaper to set than scatter symbols);
- boxes with labels (tracker boxes solid, the ground-truth box dashed white);
- polylines; a crosshair.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pyqtgraph as pg
from numpy.typing import NDArray
from PySide6.QtCore import QRectF, Qt
from PySide6.QtGui import QColor, QPen
from PySide6.QtWidgets import QGraphicsRectItem, QWidget

from engine.trackers.base import Overlay

#: number of colour buckets between red (weight 0) and green (weight 1)
N_WEIGHT_BUCKETS = 8
BOX_COLOURS = ("#ffd24c", "#4cc3ff", "#ff7ad9", "#9dff4c")
POLYLINE_COLOUR = "#4cc3ff"
CROSSHAIR_COLOUR = "#ffd24c"
POINT_SIZE_PX = 2


def weight_colour(w: float) -> QColor:
    """Green for weight 1, amber in between, red for weight 0."""
    w = float(np.clip(w, 0.0, 1.0))
    # through amber rather than muddy brown: red -> amber -> green
    if w < 0.5:
        r, g = 255, int(70 + 2 * w * (200 - 70))
    else:
        r, g = int(255 - 2 * (w - 0.5) * (255 - 46)), int(200 + 2 * (w - 0.5) * (215 - 200))
    return QColor(r, g, 60 if w >= 0.5 else 70)


def bucket_weights(weights: NDArray[np.floating], n: int = N_WEIGHT_BUCKETS) -> NDArray[np.intp]:
    """Bucket index 0 (red, w=0) .. n-1 (green, w=1) of each weight."""
    w = np.nan_to_num(np.asarray(weights, dtype=np.float32), nan=0.0)
    return np.clip((np.clip(w, 0.0, 1.0) * n).astype(np.intp), 0, n - 1)


def bgr_to_rgb(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    if image.ndim == 3 and image.shape[2] == 3:
        import cv2

        return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))  # releases the GIL
    return np.ascontiguousarray(image)


class ImageView(pg.GraphicsLayoutWidget):
    """An image with overlays; aspect locked, y down, zoom with the mouse wheel."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setMinimumSize(320, 240)
        self.ci.setContentsMargins(0, 0, 0, 0)
        self.view: pg.ViewBox = self.addViewBox(lockAspect=True, invertY=True, enableMenu=False)
        self.view.setDefaultPadding(0.0)
        self.image_item = pg.ImageItem(axisOrder="row-major")
        self.view.addItem(self.image_item)
        self._image: NDArray[np.uint8] | None = None
        self._shape: tuple[int, ...] | None = None

        self._point_items: list[pg.PlotCurveItem] = []
        self._point_counts = [0] * N_WEIGHT_BUCKETS
        for b in range(N_WEIGHT_BUCKETS):
            colour = weight_colour((b + 0.5) / N_WEIGHT_BUCKETS)
            pen = pg.mkPen(colour, width=POINT_SIZE_PX + 1)
            pen.setCosmetic(True)
            pen.setCapStyle(Qt.PenCapStyle.FlatCap)
            item = pg.PlotCurveItem(pen=pen, connect="pairs", skipFiniteCheck=True)
            item.setZValue(10)
            self.view.addItem(item)
            self._point_items.append(item)
        self._boxes: list[tuple[QGraphicsRectItem, pg.TextItem]] = []
        self._polylines: list[pg.PlotCurveItem] = []
        self.crosshair = pg.PlotCurveItem(pen=pg.mkPen(CROSSHAIR_COLOUR, width=2), connect="pairs")
        self.crosshair.setZValue(30)
        self.view.addItem(self.crosshair)
        self.info = pg.TextItem(color="#e6e9ee", anchor=(0, 0), fill=pg.mkBrush(0, 0, 0, 140))
        self.info.setZValue(40)
        self.info.setVisible(False)
        self.view.addItem(self.info)
        self.placeholder = pg.TextItem("no image", color="#8a93a3", anchor=(0.5, 0.5))
        self.view.addItem(self.placeholder)
        self.placeholder.setPos(320, 240)
        self.view.setRange(QRectF(0, 0, 640, 480), padding=0)

    # ------------------------------------------------------------------ image
    @property
    def image_rgb(self) -> NDArray[np.uint8] | None:
        """The RGB image currently shown (None before the first frame)."""
        return self._image

    def set_image(self, image_bgr: NDArray[np.uint8] | None) -> None:
        if image_bgr is None:
            return
        rgb = bgr_to_rgb(image_bgr)
        self._image = rgb
        if rgb.dtype == np.uint8:
            # no levels: pyqtgraph wraps the bytes in a QImage as they are (levels (0, 255)
            # would rescale every pixel, ~1.5 ms a frame on the GUI thread for nothing)
            self.image_item.setImage(rgb, autoLevels=False, levels=None)
        else:
            self.image_item.setImage(rgb, autoLevels=True)
        if rgb.shape[:2] != (self._shape or (0, 0))[:2]:
            self._shape = rgb.shape
            h, w = rgb.shape[:2]
            self.view.setRange(QRectF(0, 0, w, h), padding=0)
        self.placeholder.setVisible(False)

    def clear_image(self, text: str = "no image") -> None:
        """No image and no overlay (e.g. a new run before its first frame)."""
        self._image = None
        self.image_item.clear()
        self.set_overlay(None)
        self.set_info("")
        self.placeholder.setText(text)
        self.placeholder.setVisible(True)
        if self._shape is not None:
            h, w = self._shape[:2]
            self.placeholder.setPos(w / 2, h / 2)

    def set_info(self, text: str) -> None:
        self.info.setText(text)
        self.info.setPos(4, 4)
        self.info.setVisible(bool(text))

    # --------------------------------------------------------------- overlays
    def set_points(
        self, points_uv: NDArray[np.floating] | None, weights: NDArray[np.floating] | None
    ) -> None:
        """Points (N, 2) coloured by weight in [0, 1] (all green when weights are None)."""
        empty = np.zeros(0)
        if points_uv is None or len(points_uv) == 0:
            for b, item in enumerate(self._point_items):
                if self._point_counts[b]:
                    item.setData(x=empty, y=empty)
                self._point_counts[b] = 0
            return
        uv = np.asarray(points_uv, dtype=np.float64).reshape(-1, 2)
        uv = uv[np.isfinite(uv).all(axis=1)]
        if weights is None:
            buckets = np.full(len(uv), N_WEIGHT_BUCKETS - 1)
        else:
            buckets = bucket_weights(np.asarray(weights).reshape(-1)[: len(uv)])
        half = 0.5 * POINT_SIZE_PX
        for b, item in enumerate(self._point_items):
            sel = uv[buckets == b]
            n = len(sel)
            if n == 0 and self._point_counts[b] == 0:
                continue
            # each point: a dash from u - half to u + half at v (drawn with connect="pairs")
            x = np.empty(2 * n)
            x[0::2] = sel[:, 0] - half
            x[1::2] = sel[:, 0] + half
            y = np.repeat(sel[:, 1], 2)
            item.setData(x=x, y=y)
            self._point_counts[b] = n

    def point_counts(self) -> list[int]:
        """Points drawn per weight bucket (red first) - for tests and the legend."""
        return list(self._point_counts)

    def set_boxes(
        self,
        boxes_xywh: Sequence[tuple[float, float, float, float]],
        labels: Sequence[str] = (),
        gt_box_xywh: tuple[float, float, float, float] | None = None,
    ) -> None:
        """Tracker boxes with labels; the ground-truth box dashed white, labelled GT."""
        wanted: list[tuple[tuple[float, float, float, float], str, QPen, str]] = []
        for i, box in enumerate(boxes_xywh):
            colour = BOX_COLOURS[i % len(BOX_COLOURS)]
            label = labels[i] if i < len(labels) else ""
            wanted.append((box, label, pg.mkPen(colour, width=2), colour))
        if gt_box_xywh is not None:
            pen = pg.mkPen("#ffffff", width=1.5, style=Qt.PenStyle.DashLine)
            wanted.append((gt_box_xywh, "GT", pen, "#ffffff"))
        while len(self._boxes) < len(wanted):
            rect = QGraphicsRectItem()
            rect.setZValue(20)
            text = pg.TextItem(anchor=(0, 1), fill=pg.mkBrush(0, 0, 0, 150))
            text.setZValue(21)
            self.view.addItem(rect)
            self.view.addItem(text)
            self._boxes.append((rect, text))
        for i, (rect, text) in enumerate(self._boxes):
            if i >= len(wanted):
                rect.setVisible(False)
                text.setVisible(False)
                continue
            (x, y, w, h), label, pen, colour = wanted[i]
            pen.setCosmetic(True)
            rect.setPen(pen)
            rect.setRect(QRectF(x, y, w, h))
            rect.setVisible(True)
            text.setText(label, color=colour)
            text.setPos(x, y)
            text.setVisible(bool(label))

    def visible_boxes(self) -> int:
        return sum(1 for rect, _ in self._boxes if rect.isVisible())

    def set_polylines(self, polylines_uv: Sequence[NDArray[np.floating]]) -> None:
        while len(self._polylines) < len(polylines_uv):
            item = pg.PlotCurveItem(pen=pg.mkPen(POLYLINE_COLOUR, width=2))
            item.setZValue(15)
            self.view.addItem(item)
            self._polylines.append(item)
        for i, item in enumerate(self._polylines):
            if i < len(polylines_uv):
                uv = np.asarray(polylines_uv[i], dtype=np.float64).reshape(-1, 2)
                item.setData(uv[:, 0], uv[:, 1])
                item.setVisible(True)
            else:
                item.setVisible(False)

    def set_crosshair(self, uv: tuple[float, float] | None, size_px: float = 14.0) -> None:
        if uv is None:
            self.crosshair.setVisible(False)
            return
        u, v = uv
        s = size_px
        self.crosshair.setData(np.array([u - s, u + s, u, u]), np.array([v, v, v - s, v + s]))
        self.crosshair.setVisible(True)

    def set_overlay(
        self,
        overlay: Overlay | None,
        gt_box_xywh: tuple[float, float, float, float] | None = None,
    ) -> None:
        """Draw everything an :class:`Overlay` asks for (clears what it does not have)."""
        if overlay is None:
            overlay = Overlay()
        self.set_points(overlay.points_uv, overlay.point_weights)
        self.set_boxes(overlay.boxes_xywh, overlay.box_labels, gt_box_xywh)
        self.set_polylines(overlay.polylines_uv)
        self.set_crosshair(overlay.crosshair_uv)
