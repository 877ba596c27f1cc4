"""Live pose plots (x, y, z, pan, tilt, roll vs time, ground truth dashed) and residual plots.

Data arrive per frame through ``append`` (cheap: a few numbers into a ring buffer); curves are
redrawn only by ``redraw()``, which the page calls from its display timer (STYLE.md: display
separate from arrival).

Drawing stays cheap at any run length: the view ranges move in steps (time in whole
:data:`TIME_STEP_S` pages, values only when the data leave the range or shrink well inside
it), so the axes are re-laid out a few times a minute instead of on every redraw, and the
grid is two light line items in the plot instead of pyqtgraph's axis-drawn grid (which
re-plays across the whole plot whenever a curve changes: ~8 ms per axis per redraw
offscreen). A plot the operator zoomed (mouse wheel on y) keeps the operator's range.

Ground truth and the estimate usually live in different world frames (odometry starts at the
identity). The plots therefore show ground truth aligned at the first frame that has both:
``T_align = T_est0 @ inv(T_gt0)``, ``T_gt_shown = T_align @ T_gt``. The "error vs GT"
curve is the translation distance after that alignment (drift, not ATE: ATE aligns the whole
trajectory, see ``engine.evaluation``).
"""

from __future__ import annotations

import math

import numpy as np
import pyqtgraph as pg
from numpy.typing import NDArray
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QWidget

from engine.geometry import pan_tilt_roll_deg
from widgets.plot_grid import GridLines

EST_COLOURS = ("#ff6b6b", "#51cf66", "#4dabf7", "#ff6b6b", "#51cf66", "#4dabf7")
GT_COLOUR = "#e6e9ee"
#: smallest y span shown per unit: a still camera's sub-millimetre jitter stays a flat line
#: instead of being stretched over the whole plot (with ticks like "5e-05")
MIN_SPAN = {"m": 0.05, "°": 1.0, "mm": 5.0}
#: the time axis shows whole pages of this many seconds (it moves once per page)
TIME_STEP_S = 10.0
#: a value range is kept while the data span at least this fraction of it
SHRINK_BELOW = 0.3
#: padding around the data when a value range is chosen (fraction of the data span)
Y_PAD = 0.15
POSE_CHANNELS = (
    ("x", "m"),
    ("y", "m"),
    ("z", "m"),
    ("pan", "°"),
    ("tilt", "°"),
    ("roll", "°"),
)


class RingBuffer:
    """Fixed-capacity time series: ``t`` (N,) and ``values`` (N, k), oldest first."""

    def __init__(self, capacity: int, n_channels: int) -> None:
        self.capacity = capacity
        self._t = np.full(capacity, np.nan)
        self._v = np.full((capacity, n_channels), np.nan)
        self._n = 0  # samples written in total

    def clear(self) -> None:
        self._t[:] = np.nan
        self._v[:] = np.nan
        self._n = 0

    def append(self, t: float, values: NDArray[np.float64] | list[float]) -> None:
        i = self._n % self.capacity
        self._t[i] = t
        self._v[i] = values
        self._n += 1

    def __len__(self) -> int:
        return min(self._n, self.capacity)

    @property
    def total(self) -> int:
        return self._n

    def data(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(t, values) in time order (copies)."""
        if self._n <= self.capacity:
            return self._t[: self._n].copy(), self._v[: self._n].copy()
        i = self._n % self.capacity
        return np.roll(self._t, -i), np.roll(self._v, -i, axis=0)


def pose_channels(T_world_cam: NDArray[np.float64] | None) -> NDArray[np.float64]:
    """x, y, z (m) and pan, tilt, roll (deg) of a pose; NaN when there is none."""
    if T_world_cam is None:
        return np.full(6, np.nan)
    T = np.asarray(T_world_cam, dtype=np.float64)
    if not np.all(np.isfinite(T)):
        return np.full(6, np.nan)
    pan, tilt, roll = pan_tilt_roll_deg(T[:3, :3])
    return np.array([T[0, 3], T[1, 3], T[2, 3], pan, tilt, roll])


def time_range(t0: float, t1: float, step_s: float = TIME_STEP_S) -> tuple[float, float]:
    """Whole pages of ``step_s`` covering [t0, t1] (at least one page from ``t0``'s)."""
    lo = math.floor(t0 / step_s) * step_s
    hi = max(lo + step_s, (math.floor(t1 / step_s) + 1) * step_s)
    return lo, hi


def value_range(lo: float, hi: float, current: tuple[float, float] | None,
                min_span: float = 0.0) -> tuple[float, float] | None:
    """The y range for data in [lo, hi]: ``current`` while it holds the data and is not
    much larger (hysteresis), else the data padded; None when there is nothing finite."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return None
    span = max(hi - lo, min_span)
    if span <= 0.0:  # a flat line without a unit span: a tenth of its value around it
        span = 0.2 * abs(lo) or 1.0
    if current is not None:
        c0, c1 = current
        inside = c0 <= lo and hi <= c1
        if inside and (span >= SHRINK_BELOW * (c1 - c0) or (c1 - c0) <= 1.0001 * min_span):
            return current
    mid = 0.5 * (lo + hi)
    half = 0.5 * span * (1.0 + 2.0 * Y_PAD)
    return mid - half, mid + half


class RangeFollower:
    """Moves one plot's view in steps (see the module docstring); stops following y once
    the operator zooms it, until :meth:`reset`."""

    def __init__(self, plot: pg.PlotItem, *, min_span: float = 0.0, follow_x: bool = True,
                 follow_y: bool = True) -> None:
        self.plot = plot
        self.min_span = min_span
        self.follow_x = follow_x
        self.follow_y = follow_y
        self.user_y = False
        vb = plot.getViewBox()
        vb.enableAutoRange(x=False, y=False)
        vb.sigRangeChangedManually.connect(self._manual)

    def _manual(self, mask: object) -> None:
        self.user_y = True

    def reset(self) -> None:
        self.user_y = False

    def update(self, t: NDArray[np.float64], values: NDArray[np.float64]) -> None:
        vb = self.plot.getViewBox()
        (cx0, cx1), (cy0, cy1) = vb.viewRange()
        ok = np.isfinite(values)
        x_new = y_new = None
        if self.follow_x and len(t):
            rng = time_range(float(t[0]), float(t[-1]))
            if rng != (cx0, cx1):
                x_new = rng
        if self.follow_y and not self.user_y and ok.any():
            v = values[ok]
            rng_y = value_range(float(v.min()), float(v.max()), (cy0, cy1), self.min_span)
            if rng_y is not None and rng_y != (cy0, cy1):
                y_new = rng_y
        if x_new is not None or y_new is not None:
            vb.setRange(xRange=x_new, yRange=y_new, padding=0.0, disableAutoRange=True)


def _style_plot(plot: pg.PlotItem, name: str, unit: str, show_time: bool) -> GridLines:
    grid = GridLines(plot)
    plot.setMenuEnabled(False)
    plot.hideButtons()
    left = plot.getAxis("left")
    left.enableAutoSIPrefix(False)
    left.setWidth(64)
    plot.setLabel("left", f"{name} ({unit})")
    if unit in MIN_SPAN:
        plot.getViewBox().setLimits(minYRange=MIN_SPAN[unit])
    bottom = plot.getAxis("bottom")
    bottom.enableAutoSIPrefix(False)
    # before data arrive show 0-10 s: the default 0-1 range puts "0.20.40.60.8" on a narrow
    # plot; auto-range stays on and takes over with the first samples
    plot.getViewBox().setRange(xRange=(0.0, TIME_STEP_S), padding=0.0)
    if show_time:
        plot.setLabel("bottom", "time (s)")
    else:  # x-linked rows above the bottom one: the time values would only repeat
        bottom.setStyle(showValues=False)
        bottom.setHeight(6)
    plot.setMouseEnabled(x=False, y=True)
    return grid


class PosePlots(pg.GraphicsLayoutWidget):
    """Six plots in a 3×2 grid: x/y/z (m) left, pan/tilt/roll (deg) right."""

    def __init__(self, capacity: int = 1800, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setMinimumSize(360, 300)
        self.est = RingBuffer(capacity, 6)
        self.gt = RingBuffer(capacity, 6)
        self.err = RingBuffer(capacity, 1)
        self.align_gt = True
        self._T_align: NDArray[np.float64] | None = None
        self._t0: float | None = None
        self._last_t: float | None = None
        self.has_gt = False
        self.plots: list[pg.PlotItem] = []
        self.grids: list[GridLines] = []
        self.est_curves: list[pg.PlotCurveItem] = []
        self.gt_curves: list[pg.PlotCurveItem] = []
        for row in range(3):
            for col in range(2):
                k = col * 3 + row
                name, unit = POSE_CHANNELS[k]
                plot = self.addPlot(row=row, col=col)
                self.grids.append(_style_plot(plot, name, unit, show_time=row == 2))
                gt = pg.PlotCurveItem(
                    pen=pg.mkPen(GT_COLOUR, width=1.2, style=Qt.PenStyle.DashLine),
                    connect="finite",
                    name="ground truth",
                )
                est = pg.PlotCurveItem(
                    pen=pg.mkPen(EST_COLOURS[k], width=1.6), connect="finite", name="estimate"
                )
                plot.addItem(gt)
                plot.addItem(est)
                self.plots.append(plot)
                self.est_curves.append(est)
                self.gt_curves.append(gt)
        # reorder to channel order x, y, z, pan, tilt, roll
        order = [0, 2, 4, 1, 3, 5]
        self.plots = [self.plots[i] for i in order]
        self.est_curves = [self.est_curves[i] for i in order]
        self.gt_curves = [self.gt_curves[i] for i in order]
        for plot in self.plots[1:]:
            plot.setXLink(self.plots[0])
        # the top plot moves the shared time axis; every plot follows its own values
        self.followers = [RangeFollower(p, min_span=MIN_SPAN.get(POSE_CHANNELS[k][1], 0.0),
                                        follow_x=k == 0)
                          for k, p in enumerate(self.plots)]
        self.no_data: list[pg.TextItem] = []
        for plot in self.plots:
            text = pg.TextItem("no pose yet", color="#6b717c", anchor=(0.5, 0.5))
            plot.addItem(text, ignoreBounds=True)
            self.no_data.append(text)
        self.ci.setSpacing(2)
        self.redraw()

    # GraphicsLayoutWidget copies ci.clear() etc. onto the instance, so a method named
    # ``clear`` here would be shadowed: hence ``clear_data``.
    def clear_data(self) -> None:
        """Forget all samples (a new run)."""
        self.est.clear()
        self.gt.clear()
        self.err.clear()
        self._T_align = None
        self._t0 = None
        self._last_t = None
        self.has_gt = False
        for f in self.followers:
            f.reset()
        self.redraw()

    def append(
        self,
        t_s: float,
        T_est: NDArray[np.float64] | None,
        T_gt: NDArray[np.float64] | None = None,
    ) -> float | None:
        """Add one frame; returns the translation error vs aligned ground truth (m) or None."""
        if self._last_t is not None and t_s < self._last_t:
            self.clear_data()  # the source restarted (looping or a new run)
        if self._t0 is None:
            self._t0 = t_s
        self._last_t = t_s
        t = t_s - self._t0
        self.est.append(t, pose_channels(T_est))
        err: float | None = None
        if T_gt is not None and np.all(np.isfinite(T_gt)):
            T_gt = np.asarray(T_gt, dtype=np.float64)
            if self._T_align is None:
                self._T_align = (
                    T_est @ np.linalg.inv(T_gt)
                    if self.align_gt and T_est is not None
                    else np.eye(4)
                )
            T_shown = self._T_align @ T_gt
            self.gt.append(t, pose_channels(T_shown))
            self.has_gt = True
            if T_est is not None:
                err = float(np.linalg.norm(np.asarray(T_est)[:3, 3] - T_shown[:3, 3]))
        else:
            self.gt.append(t, np.full(6, np.nan))
        self.err.append(t, [err if err is not None else math.nan])
        return err

    def redraw(self) -> None:
        t, est = self.est.data()
        _, gt = self.gt.data()
        for k in range(6):
            if len(t):
                self.est_curves[k].setData(t, est[:, k])
            else:
                self.est_curves[k].clear()
            if self.has_gt and len(t):
                self.gt_curves[k].setData(t, gt[:, k])
            else:
                self.gt_curves[k].clear()
            has = bool(len(t)) and bool(np.any(np.isfinite(est[:, k])))
            if has:
                both = est[:, k] if not self.has_gt else np.concatenate([est[:, k], gt[:, k]])
                self.followers[k].update(t, both)
            if not has:  # e.g. a box tracker: say so instead of showing empty axes
                (x0, x1), (y0, y1) = self.plots[k].viewRange()
                self.no_data[k].setPos((x0 + x1) / 2, (y0 + y1) / 2)
            self.no_data[k].setVisible(not has)

    def curve_lengths(self) -> list[int]:
        """Points in each estimate curve (tests check the plots moved)."""
        return [0 if c.xData is None else len(c.xData) for c in self.est_curves]


class ResidualPlots(pg.GraphicsLayoutWidget):
    """Residual, inlier fraction (%) and translation error vs ground truth (mm) over time."""

    CHANNELS = (
        ("residual", "a.u.", "#ffa94d"),
        ("inliers", "%", "#51cf66"),
        ("GT error", "mm", "#ff6b6b"),
    )

    def __init__(self, capacity: int = 1800, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setMinimumSize(360, 140)
        self.data = RingBuffer(capacity, 3)
        self.plots: list[pg.PlotItem] = []
        self.grids: list[GridLines] = []
        self.curves: list[pg.PlotCurveItem] = []
        for col, (name, unit, colour) in enumerate(self.CHANNELS):
            plot = self.addPlot(row=0, col=col)
            self.grids.append(_style_plot(plot, name, unit, show_time=True))
            curve = pg.PlotCurveItem(pen=pg.mkPen(colour, width=1.6), connect="finite")
            plot.addItem(curve)
            self.plots.append(plot)
            self.curves.append(curve)
        self.plots[2].getViewBox().setLimits(yMin=0.0)  # a distance: never below zero
        self.followers = [RangeFollower(p, min_span=MIN_SPAN.get(unit, 0.0),
                                        follow_y=k != 1)
                          for k, (p, (_, unit, _)) in enumerate(zip(self.plots, self.CHANNELS,
                                                                     strict=True))]
        self.plots[1].setYRange(0, 100, padding=0.02)
        self.plots[1].setMouseEnabled(x=False, y=False)
        # no x-link: a tracker without residuals would pin the shared range to [0, 1]
        self.no_data: list[pg.TextItem] = []
        for plot in self.plots:
            text = pg.TextItem("no data", color="#6b717c", anchor=(0.5, 0.5))
            plot.addItem(text, ignoreBounds=True)
            self.no_data.append(text)
        self.ci.setSpacing(2)
        self._t0: float | None = None
        self._last_t: float | None = None

    def clear_data(self) -> None:
        """Forget all samples (a new run)."""
        self.data.clear()
        self._t0 = None
        self._last_t = None
        for f in self.followers:
            f.reset()
        self.redraw()

    def append(
        self,
        t_s: float,
        residual: float | None,
        inlier_fraction: float | None,
        error_m: float | None,
    ) -> None:
        def num(v: float | None, scale: float = 1.0) -> float:
            return math.nan if v is None or not math.isfinite(v) else float(v) * scale

        if self._last_t is not None and t_s < self._last_t:
            self.clear_data()
        if self._t0 is None:
            self._t0 = t_s
        self._last_t = t_s
        values = [num(residual), num(inlier_fraction, 100.0), num(error_m, 1000.0)]
        self.data.append(t_s - self._t0, values)

    def redraw(self) -> None:
        t, v = self.data.data()
        for k, curve in enumerate(self.curves):
            has = bool(len(t)) and bool(np.any(np.isfinite(v[:, k])))
            if has:
                curve.setData(t, v[:, k])
                ok = np.isfinite(v[:, k])
                self.followers[k].update(t[ok], v[:, k])
            else:
                curve.clear()
                (x0, x1), (y0, y1) = self.plots[k].viewRange()
                self.no_data[k].setPos((x0 + x1) / 2, (y0 + y1) / 2)
            self.no_data[k].setVisible(not has)

    def curve_lengths(self) -> list[int]:
        return [0 if c.xData is None else len(c.xData) for c in self.curves]
