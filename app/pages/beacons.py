"""The Beacons page: range-beacon camera tracking (Yang 2007) on the built-in simulator.

- Layout editor: the beacons are draggable targets on the map (the simulator's truth and the
  operator's layout that the tracker takes its quadrants/bearings from); add/remove, import
  and export as JSON or CSV.
- Start/Stop runs ``beacons:...`` through ``beacon-slam`` via the window's run owner
  (``ctx.run``: outputs and the status header follow it). Parameter edits (particle count,
  sigmas, Map Adjustment p) are sent as ``SetParams`` and apply on the next step.
- Live map: true vs estimated camera path (every step, from the run's history), particle
  cloud, estimated beacons with 2-sigma ellipses (of the step drawn); error over time. The
  page draws on the window's display clock while shown.
"""

from __future__ import annotations

import math
import string
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, Slot
from PySide6.QtWidgets import (
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QScrollArea,
    QSpinBox,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from app.pages import PageSpec
from app.pages._base import Page
from widgets.plot_grid import GridLines

ELLIPSE_SIGMA = 2.0
BEACON_COLOR = (255, 200, 60)
EST_COLOR = (80, 200, 255)
TRUE_COLOR = (230, 230, 230)
EST_BEACON_COLOR = (255, 90, 90)


def ellipse_points(mean: np.ndarray, cov: np.ndarray, n_sigma: float = ELLIPSE_SIGMA,
                   n: int = 48) -> np.ndarray:
    """(n + 1, 2) points of the n-sigma ellipse of a 2x2 covariance (closed curve)."""
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    vals = np.sqrt(np.clip(vals, 0.0, None))
    t = np.linspace(0.0, 2.0 * math.pi, n + 1)
    circle = np.stack([np.cos(t), np.sin(t)], axis=1)
    return mean[None, :] + n_sigma * (circle * vals[None, :]) @ vecs.T


class BeaconsPage(Page):
    """Layout editor, simulator controls, live map and error plot for ``beacon-slam``."""

    follows_trackers = ("beacon-slam",)

    def __init__(self, ctx: Any, parent: QWidget | None = None) -> None:
        super().__init__(ctx, parent)
        from engine.beacons.params import BeaconFilterParams
        from engine.beacons.simulator import PAPER_LAYOUT
        from widgets.param_form import ParamForm

        self.setObjectName("page_beacons")
        self.run = ctx.run
        self._layout_dir = Path(tempfile.mkdtemp(prefix="studiotrack_beacons_"))
        self._targets: dict[str, pg.TargetItem] = {}
        self._pending: list[Any] = []
        self._latest: Any | None = None
        self.true_path: list[tuple[float, float]] = []
        self.est_path: list[tuple[float, float]] = []
        self.errors_m: list[float] = []
        self.records_seen = 0

        # ---- map
        self.map_plot = pg.PlotWidget()
        self.map_plot.setAspectLocked(True)
        GridLines(self.map_plot.getPlotItem())  # cheap to repaint (widgets.plot_grid)
        self.map_plot.setLabel("bottom", "x (m)")
        self.map_plot.setLabel("left", "y (m)")
        self.map_plot.addLegend(offset=(8, 8))
        self.particles_item = pg.ScatterPlotItem(
            size=3, pen=None, brush=pg.mkBrush(120, 170, 255, 90), name="particles"
        )
        self.true_item = pg.PlotDataItem(
            pen=pg.mkPen(TRUE_COLOR, width=2, style=pg.QtCore.Qt.PenStyle.DashLine),
            name="true path",
        )
        self.est_item = pg.PlotDataItem(pen=pg.mkPen(EST_COLOR, width=2), name="estimated path")
        self.cam_item = pg.ScatterPlotItem(size=12, symbol="o", pen=pg.mkPen("w"),
                                           brush=pg.mkBrush(*EST_COLOR), name="camera estimate")
        self.est_beacons_item = pg.ScatterPlotItem(
            size=12, symbol="x", pen=pg.mkPen(EST_BEACON_COLOR, width=2),
            brush=pg.mkBrush(*EST_BEACON_COLOR), name="estimated beacons (2σ)"
        )
        for item in (self.particles_item, self.true_item, self.est_item, self.cam_item,
                     self.est_beacons_item):
            self.map_plot.addItem(item)
        self.ellipse_items: list[pg.PlotCurveItem] = []

        # ---- error over time
        self.err_plot = pg.PlotWidget()
        GridLines(self.err_plot.getPlotItem())
        self.err_plot.setLabel("bottom", "time step")
        self.err_plot.setLabel("left", "position error (m)")
        self.err_plot.getAxis("left").enableAutoSIPrefix(False)
        # whole steps before a run (not 0.1 ... 0.9); auto-range takes over with data
        self.err_plot.getViewBox().setRange(
            xRange=(0.0, 120.0), yRange=(0.0, 1.0), padding=0.0, disableAutoRange=False
        )
        self.err_item = self.err_plot.plot(pen=pg.mkPen(EST_COLOR, width=2))

        # ---- controls
        self.start_button = QPushButton("Start")
        self.start_button.setObjectName("beacons_start")
        self.start_button.setToolTip("Simulate the layout and track it with beacon-slam")
        self.stop_button = QPushButton("Stop")
        self.stop_button.setObjectName("beacons_stop")
        self.stop_button.setEnabled(False)
        self.status_label = QLabel("Stopped. Drag the beacons, then Start.")
        self.status_label.setObjectName("beacons_status")
        self.status_label.setWordWrap(True)
        self.input_label = QLabel(input_text(None, ""))
        self.input_label.setObjectName("beacons_input")
        self.input_label.setWordWrap(True)
        self.input_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.input_label.setToolTip(
            "What the run's input delivered and what it rejected, with the reason for the "
            "newest rejection (the counters of `track --json`'s \"input\")"
        )
        self._input_stats: Mapping[str, object] | None = None
        self._input_kind = ""
        self._input_epoch = -1

        self.steps_spin = QSpinBox()
        self.steps_spin.setRange(10, 100000)
        self.steps_spin.setValue(120)
        self.steps_spin.setToolTip("time steps of the simulated camera path (the paper: 120)")
        self.fps_spin = QDoubleSpinBox()
        self.fps_spin.setRange(1.0, 1000.0)
        self.fps_spin.setValue(20.0)
        self.fps_spin.setSuffix(" steps/s")
        self.fps_spin.setToolTip("playback rate of the simulator")
        self.noise_spin = self._dspin(0.0, 5.0, 0.1, 0.05, " m", "range noise std")
        self.dropout_spin = self._dspin(0.0, 0.9, 0.0, 0.05, "",
                                        "probability a reading is missing")
        self.outlier_spin = self._dspin(0.0, 0.9, 0.0, 0.05, "",
                                        "probability a reading is an outlier")
        self.seed_spin = QSpinBox()
        self.seed_spin.setRange(0, 1_000_000)
        self.seed_spin.setToolTip("simulator seed")
        sim_box = QGroupBox("Simulator")
        sim_form = QFormLayout(sim_box)
        sim_form.addRow("steps", self.steps_spin)
        sim_form.addRow("rate", self.fps_spin)
        sim_form.addRow("range noise", self.noise_spin)
        sim_form.addRow("dropout prob.", self.dropout_spin)
        sim_form.addRow("outlier prob.", self.outlier_spin)
        sim_form.addRow("seed", self.seed_spin)

        self.add_button = QPushButton("Add")
        self.add_button.setToolTip("Add a beacon at the map centre")
        self.remove_button = QPushButton("Remove")
        self.remove_button.setToolTip("Remove the last beacon")
        self.import_button = QPushButton("Import…")
        self.import_button.setToolTip("Load a layout (.json or .csv: id,x_m,y_m)")
        self.export_button = QPushButton("Export…")
        self.export_button.setToolTip("Save the layout (.json or .csv)")
        self.paper_button = QPushButton("Paper")
        self.paper_button.setToolTip("The paper's layout: A(10,10) B(22,0) C(-12,-16) D(5,15)")
        layout_box = QGroupBox("Beacon layout (drag on the map)")
        lb = QVBoxLayout(layout_box)
        row1 = QHBoxLayout()
        for b in (self.add_button, self.remove_button, self.paper_button):
            row1.addWidget(b)
        row2 = QHBoxLayout()
        for b in (self.import_button, self.export_button):
            row2.addWidget(b)
        self.layout_label = QLabel()
        self.layout_label.setWordWrap(True)
        lb.addLayout(row1)
        lb.addLayout(row2)
        lb.addWidget(self.layout_label)

        self.param_form = ParamForm(BeaconFilterParams())
        params_box = QGroupBox("beacon-slam (applies next step)")
        QVBoxLayout(params_box).addWidget(self.param_form)

        side = QWidget()
        sl = QVBoxLayout(side)
        sl.setContentsMargins(0, 0, 0, 0)
        buttons = QHBoxLayout()
        buttons.addWidget(self.start_button)
        buttons.addWidget(self.stop_button)
        sl.addLayout(buttons)
        sl.addWidget(self.status_label)
        input_box = QGroupBox("Input")
        QVBoxLayout(input_box).addWidget(self.input_label)
        sl.addWidget(input_box)
        sl.addWidget(layout_box)
        sl.addWidget(sim_box)
        sl.addWidget(params_box)
        sl.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(side)
        scroll.setMinimumWidth(330)
        scroll.setMaximumWidth(420)

        plots = QSplitter(pg.QtCore.Qt.Orientation.Vertical)
        plots.addWidget(self.map_plot)
        plots.addWidget(self.err_plot)
        plots.setSizes([560, 180])
        split = QSplitter(pg.QtCore.Qt.Orientation.Horizontal)
        split.addWidget(plots)
        split.addWidget(scroll)
        split.setStretchFactor(0, 1)
        split.setSizes([900, 360])
        root = QVBoxLayout(self)
        root.setContentsMargins(8, 8, 8, 4)
        root.addWidget(split)

        # ---- wiring
        self.start_button.clicked.connect(self.start)
        self.stop_button.clicked.connect(self.stop)
        self.add_button.clicked.connect(self.add_beacon)
        self.remove_button.clicked.connect(self.remove_last_beacon)
        self.paper_button.clicked.connect(lambda: self.set_layout(PAPER_LAYOUT))
        self.import_button.clicked.connect(self._import_dialog)
        self.export_button.clicked.connect(self._export_dialog)
        self.param_form.params_changed.connect(self._on_params)
        self.run.failed.connect(self._on_failed)
        self.run.started.connect(lambda _i: self._update_buttons())
        self.run.finished.connect(self._on_finished)
        self.set_layout(PAPER_LAYOUT)
        self._update_buttons()

    @staticmethod
    def _dspin(lo: float, hi: float, value: float, step: float, suffix: str, tip: str
               ) -> QDoubleSpinBox:
        s = QDoubleSpinBox()
        s.setRange(lo, hi)
        s.setSingleStep(step)
        s.setDecimals(2)
        s.setValue(value)
        s.setSuffix(suffix)
        s.setToolTip(tip)
        return s

    # ------------------------------------------------------------------ layout editor
    def beacon_layout(self) -> dict[str, tuple[float, float]]:
        """The beacon layout shown on the map, {id: (x, y)} in metres."""
        out = {}
        for bid, t in self._targets.items():
            p = t.pos()
            out[bid] = (round(float(p.x()), 3), round(float(p.y()), 3))
        return out

    def set_layout(self, layout: dict[str, Any]) -> None:
        for t in self._targets.values():
            self.map_plot.removeItem(t)
        self._targets.clear()
        for bid, (x, y) in layout.items():
            self._add_target(str(bid), float(x), float(y))
        self._layout_changed()
        self.fit_view()

    def fit_view(self) -> None:
        """Show every beacon, the start and the paths (TargetItems do not auto-range)."""
        pts = [(0.0, 0.0), *self.beacon_layout().values(), *self.true_path, *self.est_path]
        xy = np.asarray(pts, dtype=np.float64)
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        pad = 0.08 * float(max(hi[0] - lo[0], hi[1] - lo[1], 1.0)) + 1.0
        self.map_plot.setRange(xRange=(lo[0] - pad, hi[0] + pad),
                               yRange=(lo[1] - pad, hi[1] + pad), padding=0.0)

    def _add_target(self, bid: str, x: float, y: float) -> None:
        t = pg.TargetItem(
            pos=(x, y), size=16, symbol="t1", movable=True,
            pen=pg.mkPen(BEACON_COLOR, width=2), brush=pg.mkBrush(*BEACON_COLOR, 120),
            label=bid, labelOpts={"color": BEACON_COLOR, "offset": (10, -10)},
        )
        t.setToolTip(f"beacon {bid}: drag to move")
        t.sigPositionChangeFinished.connect(lambda *_: self._layout_changed())
        self.map_plot.addItem(t)
        self._targets[bid] = t

    def add_beacon(self) -> str:
        used = set(self._targets)
        bid = next((c for c in string.ascii_uppercase if c not in used), f"B{len(used)}")
        self._add_target(bid, 0.0, 8.0)
        self._layout_changed()
        self.fit_view()
        return bid

    def remove_last_beacon(self) -> None:
        if len(self._targets) <= 1:
            return
        bid = list(self._targets)[-1]
        self.map_plot.removeItem(self._targets.pop(bid))
        self._layout_changed()

    def _layout_changed(self) -> None:
        # no-break space inside a beacon's coordinates: the label wraps between beacons only
        text = "   ".join(
            f"{k}\u00a0({x:.1f},\u00a0{y:.1f})" for k, (x, y) in self.beacon_layout().items()
        )
        suffix = " — applies at the next Start" if self._running_here() else ""
        self.layout_label.setText(text + suffix)

    def import_layout(self, path: str | Path) -> None:
        from engine.beacons.io import load_layout
        from engine.errors import StudioTrackError

        try:
            self.set_layout(load_layout(path))
        except StudioTrackError as exc:
            self._report(f"import failed: {exc}", error=True)
            return
        self._report(f"beacon layout imported from {path}")

    def export_layout(self, path: str | Path) -> None:
        from engine.beacons.io import save_layout

        try:
            save_layout(path, self.beacon_layout())
        except OSError as exc:
            self._report(f"export failed: {path}: {exc.strerror}", error=True)
            return
        self._report(f"beacon layout exported to {path}")

    def _import_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Import beacon layout", "",
                                              "Layouts (*.json *.csv)")
        if path:
            self.import_layout(path)

    def _export_dialog(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Export beacon layout", "beacons.json",
                                              "Layouts (*.json *.csv)")
        if path:
            self.export_layout(path)

    def _report(self, msg: str, error: bool = False) -> None:
        self.status_label.setText(msg)
        log = getattr(self.ctx, "log", None)
        if log is not None:
            (log.error if error else log.info)(msg)

    # ------------------------------------------------------------------ run control
    def source_spec(self) -> str:
        """The ``beacons:`` spec of the current layout and simulator settings."""
        from engine.beacons.io import save_layout

        path = self._layout_dir / "layout.json"
        save_layout(path, self.beacon_layout())
        return (
            f"beacons:layout={path},steps={self.steps_spin.value()},"
            f"noise={self.noise_spin.value():g},dropout={self.dropout_spin.value():g},"
            f"outliers={self.outlier_spin.value():g},seed={self.seed_spin.value()},"
            f"fps={self.fps_spin.value():g}"
        )

    def _running_here(self) -> bool:
        return self.run.is_running and self.follows(self.run.run_info)

    def _update_buttons(self) -> None:
        running = self.run.is_running
        self.start_button.setEnabled(not running)
        self.start_button.setToolTip("Simulate the layout and track it with beacon-slam"
                                     if not running else "A run is active: stop it first")
        self.stop_button.setEnabled(running)

    @Slot()
    def start(self) -> None:
        if self.run.is_running:
            self._report("a run is active: stop it first", error=True)
            return
        self.true_path.clear()
        self.est_path.clear()
        self.errors_m.clear()
        self.records_seen = 0
        self._latest = None
        self.fit_view()
        self.run.start(self.source_spec(), "beacon-slam", self.param_form.params,
                       realtime=True, page="Beacons")
        self._update_buttons()
        self.status_label.setText("Running…")

    @Slot()
    def stop(self) -> None:
        self.run.stop()

    @Slot(object)
    def _on_params(self, params: Any) -> None:
        if self._running_here():
            self.run.set_params(params)  # SetParams: applies on the next step

    def _follow_input(self) -> None:
        """A new beacon run: its own counters from now on (never the last run's)."""
        info = self.run.run_info
        if self._input_epoch != self._epoch and info is not None and self.follows(info):
            self._input_epoch = self._epoch
            self._input_stats = None
            self._input_kind = _input_kind(info.source_spec)
            self.input_label.setText(input_text(None, self._input_kind))

    def run_changed(self, info: Any) -> None:
        self._follow_input()

    def add_samples(self, samples: list[Any], missed: int) -> None:
        from engine.sources.beacons import BeaconTruth, RangeReadings

        self._follow_input()
        for smp in samples:
            readings = smp.payload(RangeReadings)
            if readings is not None and readings.input_stats is not None:
                self._input_stats = readings.input_stats  # cumulative: the newest says all
            if smp.T_world_cam is None:
                continue
            est = (float(smp.T_world_cam[0, 3]), float(smp.T_world_cam[1, 3]))
            self.est_path.append(est)
            truth = smp.payload(BeaconTruth)
            gt = truth.gt_xy if truth is not None else None
            if gt is not None:
                self.true_path.append(gt)
                self.errors_m.append(math.hypot(est[0] - gt[0], est[1] - gt[1]))
            self.records_seen += 1
        if samples:
            self.input_label.setText(input_text(self._input_stats, self._input_kind))

    @Slot(str)
    def _on_failed(self, msg: str) -> None:
        req = self.run.request
        if req is not None and req.page == "Beacons":
            self._report(f"beacon run failed: {msg}", error=True)
        self._update_buttons()

    @Slot(object)
    def _on_finished(self, status: Any) -> None:
        self.run_ended(status)

    def run_stalled(self, message: str) -> None:
        self.status_label.setText(f"LOST: {message} — the estimate shown is not live")

    def run_faulted(self, status: Any) -> None:
        error = getattr(status, "error", None) or self.run.last_error or "engine error"
        # the engine already logged it: the page only says so
        self.status_label.setText(f"ERROR: {error} — not tracking; press Stop")
        self._update_buttons()

    def run_ended(self, status: Any) -> None:
        self._update_buttons()
        if self._latest is not None or self.errors_m:
            self._redraw_paths()
            if self.run.last_error is None or self.run.stopped_by_user:
                self.status_label.setText(self._summary("Finished" if not
                                                         self.run.stopped_by_user else
                                                         "Stopped"))
        self._latest = None
        self._layout_changed()

    def _summary(self, prefix: str) -> str:
        if not self.errors_m:
            return prefix
        rec = self._latest
        from engine.sources.beacons import BeaconTruth
        from engine.trackers.beacon_slam import BeaconDetails

        ex = rec.result.details_as(BeaconDetails) if rec is not None else None
        e = np.asarray(self.errors_m)
        rmse = math.sqrt(float(np.mean(e**2)))
        text = f"{prefix}: step {len(e) - 1}, error {e[-1]:.2f} m, RMSE {rmse:.2f} m"
        if ex is not None:
            text += f", ESS {ex.ess:.0f}/{ex.n_particles}"
        truth = rec.frame.payload(BeaconTruth) if rec is not None else None
        gt_b = truth.gt_beacons if truth is not None else None
        if gt_b and ex is not None:
            errs = [float(np.hypot(*(np.asarray(b) - gt_b[i])))
                    for i, b in zip(ex.beacon_ids, ex.beacons_xy, strict=True)
                    if i in gt_b and np.all(np.isfinite(b))]
            if errs:
                text += f", beacon error {np.mean(errs):.2f} m"
        if ex is not None and ex.outlier_ids:
            text += f", outliers now: {', '.join(ex.outlier_ids)}"
        return text

    # ------------------------------------------------------------------ drawing
    def draw(self, record: Any) -> None:
        self._latest = record
        self._redraw()

    def _redraw_paths(self) -> None:
        if self.true_path:
            tp = np.asarray(self.true_path)
            self.true_item.setData(tp[:, 0], tp[:, 1])
        if self.est_path:
            ep = np.asarray(self.est_path)
            self.est_item.setData(ep[:, 0], ep[:, 1])
            self.cam_item.setData([ep[-1, 0]], [ep[-1, 1]])
        if self.errors_m:
            self.err_item.setData(np.arange(len(self.errors_m)), np.asarray(self.errors_m))

    @Slot()
    def _redraw(self) -> None:
        self._redraw_paths()
        rec = self._latest
        if rec is None:
            return
        from engine.trackers.beacon_slam import BeaconDetails

        ex = rec.result.details_as(BeaconDetails)
        parts = ex.particles_xy if ex is not None else None
        if parts is not None:
            self.particles_item.setData(parts[:, 0], parts[:, 1])
        b_xy = ex.beacons_xy if ex is not None else None
        b_cov = ex.beacons_cov if ex is not None else None
        if b_xy is not None and b_cov is not None:
            ok = np.all(np.isfinite(b_xy), axis=1)
            self.est_beacons_item.setData(b_xy[ok, 0], b_xy[ok, 1])
            while len(self.ellipse_items) < len(b_xy):
                item = pg.PlotCurveItem(pen=pg.mkPen(EST_BEACON_COLOR, width=1))
                self.map_plot.addItem(item)
                self.ellipse_items.append(item)
            for k, item in enumerate(self.ellipse_items):
                if k < len(b_xy) and ok[k] and np.all(np.isfinite(b_cov[k])):
                    pts = ellipse_points(b_xy[k], b_cov[k])
                    item.setData(pts[:, 0], pts[:, 1])
                else:
                    item.setData([], [])
        if self._running_here():
            self.status_label.setText(self._summary(f"Running ({rec.result.state.value})"))


def _input_kind(source_spec: str) -> str:
    kind = source_spec.split(":", 1)[0].strip()
    return kind if kind in ("beacons", "beacons-csv", "beacons-udp") else "other"


def input_text(stats: Mapping[str, object] | None, kind: str) -> str:
    """The input counters of a beacon run, as the CLI reports them in ``--json``'s "input"."""
    if not kind:
        return "No run yet."
    if stats is None:
        if kind == "beacons":
            return "Simulator: readings are generated, no input to count."
        return "Nothing received yet."
    def n(key: str) -> int:
        v = stats.get(key, 0)
        return int(v) if isinstance(v, int | float) else 0
    unit = "datagrams" if kind == "beacons-udp" else "lines"
    lines = [f"{n('lines')} {unit} received: {n('readings')} readings in {n('steps')} steps"]
    names = stats.get("unknown_id_names") or ()
    unknown = f"{n('unknown_ids')} unknown ids"
    if names and isinstance(names, list | tuple):
        unknown += f" ({', '.join(str(x) for x in list(names)[:5])})"
    lines.append(f"rejected: {n('malformed')} malformed, {unknown}, "
                 f"{n('duplicates')} duplicates, {n('out_of_order')} out of order")
    if kind == "beacons-udp":
        clock = str(stats.get("clock") or "not yet")
        extra = f"; {n('ignored_timestamps')} sender timestamps ignored" \
            if n("ignored_timestamps") else ""
        lines.append(f"{n('heartbeats')} heartbeats (nothing received); clock: {clock}{extra}")
    last = str(stats.get("last_error") or "")
    if last:
        lines.append(f"last rejected: {last}")
    return "\n".join(lines)


def _factory(ctx: Any) -> QWidget:
    return BeaconsPage(ctx)


PAGES = (
    PageSpec(
        title="Beacons",
        order=60,
        factory=_factory,
        tooltip="Range-beacon camera tracking (particle-filter SLAM with Map Adjustment)",
        trackers=("beacon-slam",),
    ),
)
