"""A light grid for pyqtgraph plots that stays cheap to paint.

pyqtgraph's own grid (``PlotItem.showGrid``) is drawn by the axes across the whole plot, so
every curve update re-plays both axes over the plot area (~8 ms per axis per redraw,
offscreen, measured on the Live page's nine plots). :class:`GridLines` draws the same grid as
two line items inside the plot (major and minor ticks), recomputed only when the view range
or size changes.

Example::

    plot = pg.PlotItem()
    grid = GridLines(plot)   # instead of plot.showGrid(x=True, y=True)
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg

#: alpha (0..255) of the major and minor grid lines
GRID_ALPHA = (60, 25)
#: minor lines closer than this (px) are left out (a small plot stays readable)
MIN_MINOR_SPACING_PX = 12.0


def _level(ticks: list[tuple[float, list[float]]], level: int, span: float,
           length_px: float) -> np.ndarray:
    """The tick values of one level; a minor level too dense on screen gives none."""
    if level >= len(ticks):
        return np.zeros(0)
    spacing, values = ticks[level]
    if level > 0 and span > 0 and spacing / span * length_px < MIN_MINOR_SPACING_PX:
        return np.zeros(0)
    return np.asarray(values, dtype=np.float64)


class GridLines:
    """A light grid at the axes' tick positions, as two line items in the plot (cheap to
    paint), redrawn only when the view range or size changes."""

    def __init__(self, plot: pg.PlotItem, alpha: tuple[int, int] = GRID_ALPHA) -> None:
        self.plot = plot
        fg = pg.getConfigOption("foreground")
        self.items: list[pg.PlotCurveItem] = []
        for a in alpha:
            colour = pg.mkColor(fg)
            colour.setAlpha(a)
            pen = pg.mkPen(colour, width=1)
            pen.setCosmetic(True)
            item = pg.PlotCurveItem(pen=pen, connect="pairs", skipFiniteCheck=True)
            item.setZValue(-100)
            plot.addItem(item, ignoreBounds=True)
            self.items.append(item)
        vb = plot.getViewBox()
        # closures, not bound methods: the connections keep the grid alive with the plot
        vb.sigRangeChanged.connect(lambda *_: self.update())
        vb.sigResized.connect(lambda *_: self.update())
        self.update()

    def update(self) -> None:
        vb = self.plot.getViewBox()
        (x0, x1), (y0, y1) = vb.viewRange()
        w = max(vb.width(), 1.0)
        h = max(vb.height(), 1.0)
        xs = self.plot.getAxis("bottom").tickValues(x0, x1, w)
        ys = self.plot.getAxis("left").tickValues(y0, y1, h)
        for level, item in enumerate(self.items):
            vx = _level(xs, level, x1 - x0, w)
            vy = _level(ys, level, y1 - y0, h)
            px = np.empty(2 * (len(vx) + len(vy)))
            py = np.empty_like(px)
            n = 2 * len(vx)
            px[0:n:2] = vx
            px[1:n:2] = vx
            py[0:n:2] = y0
            py[1:n:2] = y1
            px[n::2] = x0
            px[n + 1::2] = x1
            py[n::2] = vy
            py[n + 1::2] = vy
            item.setData(px, py)
