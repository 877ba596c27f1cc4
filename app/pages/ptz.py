"""The PTZ page: pan-tilt camera target tracking (Gaspar 2009) and its calibration workflow.

Tabs:
- Calibration points (sec. 3.1): click an image point, type its world x, y, z in the table
  (or import a CSV), Solve DLT; the residual of every point is shown and outliers are
  highlighted in red; coplanar or too few points give a one-line message.
- Lens lines (sec. 3.3): click points along world-straight lines (New line starts another)
  or accept proposed lines (chessboard rows, LSD chains); Estimate fits the inverse radial
  model; Preview shows the undistorted image with the corrected lines overlaid.
- Calibration into the project: "Save head to project" (the DLT at the image's motor angles,
  head_from_dlt), "Save distortion to project" (the line-based model), "Calibrate from the
  simulator" (the whole chain on ptz-sim views: lines, marker DLTs at four poses, head); the
  Live tab's "calibrated chain" mode then tracks with only that calibration.
- Live (sec. 4-6): ``ptz-sim`` through the ``ptz`` tracker, run by the window's run owner;
  the head is the simulated one, the loopback VISCA-over-IP camera (real bytes, finite speed,
  position back by FreeD; its state is the header's HEAD chip) or, in the calibrated chain, a
  head without encoder seen through a distorting lens
  (outputs and the status header follow it; the simulated head obeys the tracker's commands
  through the pipeline's head sink);
  video with the evolving snake (grey) and final contour (blue), measured centre and
  predicted position; top view and height (estimate vs truth), model probabilities and
  estimated omega over time (the paper's Fig. 6), position/velocity/acceleration with
  2-sigma bands. The plots take every frame from the run's history; the page draws on the
  window's display clock while shown.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, Slot
from PySide6.QtGui import QBrush, QColor
from PySide6.QtWidgets import (
    QComboBox,
    QFileDialog,
    QFrame,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QScrollArea,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from app.pages import PageSpec
from app.pages._base import Page
from engine.shared_data import shared_data_dir
from widgets.plot_grid import GridLines

HISTORY = 3000
MODEL_COLOURS = [(230, 230, 230), (255, 90, 90), (90, 200, 255), (255, 200, 60),
                 (160, 255, 120), (220, 120, 255)]
AXIS_COLOURS = [(255, 90, 90), (120, 230, 120), (90, 160, 255)]
OUTLIER_BG = QColor(170, 40, 40)


def _axes(plot: Any, bottom: str, left: str) -> None:
    """Axis labels with units; no SI prefixes (the units are in the labels)."""
    plot.setLabel("bottom", bottom)
    plot.setLabel("left", left)
    for side in ("bottom", "left"):
        plot.getAxis(side).enableAutoSIPrefix(False)
    GridLines(plot)  # cheap to repaint (widgets.plot_grid)


class ClickImage(pg.PlotWidget):
    """An image (row-major, y down) whose left clicks report image coordinates."""

    def __init__(self, on_click: Any, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setAspectLocked(True)
        self.invertY(True)
        self.image_item = pg.ImageItem(axisOrder="row-major")
        self.addItem(self.image_item)
        self.setLabel("bottom", "u (px)")
        self.setLabel("left", "v (px)")
        self._on_click = on_click
        self.scene().sigMouseClicked.connect(self._clicked)

    def set_image_bgr(self, img: np.ndarray) -> None:
        rgb = img[..., ::-1] if img.ndim == 3 else img
        self.image_item.setImage(np.ascontiguousarray(rgb), autoLevels=False, levels=(0, 255))
        self.autoRange()

    def _clicked(self, ev: Any) -> None:
        if ev.button() != Qt.MouseButton.LeftButton or self.image_item.image is None:
            return
        p = self.plotItem.vb.mapSceneToView(ev.scenePos())
        self._on_click(float(p.x()), float(p.y()))


class CalibPointsPanel(QWidget):
    """DLT point entry: image clicks + typed world coordinates, residuals and outliers."""

    COLS = ("u px", "v px", "x m", "y m", "z m", "residual px")

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.image: np.ndarray | None = None
        self.result: Any = None
        self.outliers = np.zeros(0, dtype=bool)
        self.view = ClickImage(self.add_image_point)
        self.scatter = pg.ScatterPlotItem(size=11, pen=pg.mkPen("k"),
                                          brush=pg.mkBrush(80, 220, 80))
        self.reproj = pg.ScatterPlotItem(size=9, symbol="x", pen=pg.mkPen(255, 220, 0, width=2))
        self.view.addItem(self.scatter)
        self.view.addItem(self.reproj)
        self.table = QTableWidget(0, len(self.COLS))
        self.table.setObjectName("ptz_points_table")
        self.table.setHorizontalHeaderLabels(list(self.COLS))
        self.table.itemChanged.connect(self._edited)
        self.status = QLabel("Click image points, type their world x, y, z, then Solve DLT.")
        self.status.setObjectName("ptz_dlt_status")
        self.status.setWordWrap(True)
        btns = QHBoxLayout()
        self.solve_button = QPushButton("Solve DLT")
        self.solve_button.setObjectName("ptz_solve_dlt")
        for text, slot in (("Load image…", self._load_image), ("Import CSV…", self._import),
                           ("Export CSV…", self._export), ("Remove selected", self._remove)):
            b = QPushButton(text)
            b.clicked.connect(slot)
            btns.addWidget(b)
        self.solve_button.clicked.connect(self.solve)
        btns.addWidget(self.solve_button)
        self.save_head_button = QPushButton("Save head to project")
        self.save_head_button.setObjectName("ptz_save_head")
        self.save_head_button.setToolTip("head geometry from this DLT (taken at motor pan/tilt "
                                         "0/0, optical centre 4 cm ahead of the rotation "
                                         "centre) into the studio project")
        btns.addWidget(self.save_head_button)
        self.save_frame_button = QPushButton("Studio frame from DLT")
        self.save_frame_button.setObjectName("ptz_save_studio_frame")
        self.save_frame_button.setToolTip("the calibration points' frame (x right, y away, z "
                                          "up, metres) becomes the studio frame of the "
                                          "outputs, saved in the project")
        btns.addWidget(self.save_frame_button)
        right = QWidget()
        rl = QVBoxLayout(right)
        rl.addWidget(self.table, 1)
        rl.addLayout(btns)
        rl.addWidget(self.status)
        split = QSplitter()
        split.addWidget(self.view)
        split.addWidget(right)
        split.setSizes([600, 500])
        lay = QVBoxLayout(self)
        lay.addWidget(split)

    def set_image(self, img: np.ndarray) -> None:
        self.image = img
        self.view.set_image_bgr(img)

    # -------------------------------------------------------------- point table
    def add_image_point(self, u: float, v: float, xyz: tuple[float, float, float] | None = None
                        ) -> int:
        if self.image is not None:
            h, w = self.image.shape[:2]
            if not (0 <= u < w and 0 <= v < h):
                return -1
        r = self.table.rowCount()
        self.table.blockSignals(True)
        self.table.insertRow(r)
        vals = [f"{u:.2f}", f"{v:.2f}"] + ([f"{c:g}" for c in xyz] if xyz else ["", "", ""])
        for c, text in enumerate([*vals, ""]):
            it = QTableWidgetItem(text)
            if c == 5:
                it.setFlags(it.flags() & ~Qt.ItemFlag.ItemIsEditable)
            self.table.setItem(r, c, it)
        self.table.blockSignals(False)
        self._refresh_markers()
        return r

    def rows(self) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """Complete rows: world (N, 3), pixels (N, 2) and their table row indices."""
        X, uv, idx = [], [], []
        for r in range(self.table.rowCount()):
            try:
                vals = [float(self.table.item(r, c).text()) for c in range(5)]
            except (AttributeError, ValueError):
                continue
            uv.append(vals[:2])
            X.append(vals[2:5])
            idx.append(r)
        return np.asarray(X, float).reshape(-1, 3), np.asarray(uv, float).reshape(-1, 2), idx

    def _edited(self, _item: QTableWidgetItem) -> None:
        self._refresh_markers()

    def _refresh_markers(self) -> None:
        pts = []
        for r in range(self.table.rowCount()):
            try:
                pts.append((float(self.table.item(r, 0).text()),
                            float(self.table.item(r, 1).text())))
            except (AttributeError, ValueError):
                pts.append((np.nan, np.nan))
        brushes = []
        for r in range(len(pts)):
            out = r < len(self.outliers) and self.outliers[r]
            brushes.append(pg.mkBrush(230, 50, 50) if out else pg.mkBrush(80, 220, 80))
        a = np.asarray(pts, float).reshape(-1, 2)
        self.scatter.setData(x=a[:, 0], y=a[:, 1], brush=brushes)

    def _remove(self) -> None:
        for r in sorted({i.row() for i in self.table.selectedIndexes()}, reverse=True):
            self.table.removeRow(r)
        self.outliers = np.zeros(0, dtype=bool)
        self._refresh_markers()

    @Slot()
    def solve(self) -> None:
        from engine.errors import CalibrationError
        from engine.ptz.dlt import calibrate_dlt, outlier_mask, project_P

        X, uv, idx = self.rows()
        self.outliers = np.zeros(self.table.rowCount(), dtype=bool)
        self.table.blockSignals(True)
        for r in range(self.table.rowCount()):
            self.table.item(r, 5).setText("")
            for c in range(6):
                self.table.item(r, c).setBackground(QBrush())
        self.table.blockSignals(False)
        try:
            res = calibrate_dlt(X, uv)
        except CalibrationError as exc:
            self.result = None
            self.status.setText(f"⚠ {exc}")
            self.reproj.setData(x=[], y=[])
            self._refresh_markers()
            return
        self.result = res
        out = outlier_mask(res.residuals_px)
        self.table.blockSignals(True)
        for k, r in enumerate(idx):
            self.table.item(r, 5).setText(f"{res.residuals_px[k]:.2f}")
            if out[k]:
                self.outliers[r] = True
                for c in range(6):
                    self.table.item(r, c).setBackground(OUTLIER_BG)
        self.table.blockSignals(False)
        proj = project_P(res.P, X)
        self.reproj.setData(x=proj[:, 0], y=proj[:, 1])
        self._refresh_markers()
        d = res.decomposition
        c = d.camera_centre_world
        self.status.setText(
            f"{len(X)} points, RMSE {res.rmse_px:.2f} px, {int(out.sum())} outlier(s). "
            f"αu {d.alpha_u:.1f}  αv {d.alpha_v:.1f}  u0 {d.u0:.1f}  v0 {d.v0:.1f}  "
            f"centre ({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f}) m  skew {d.skew_deg:.2f}°"
        )

    def _load_image(self) -> None:
        import cv2

        path, _ = QFileDialog.getOpenFileName(self, "Calibration image", "",
                                              "Images (*.png *.jpg *.bmp)")
        if path:
            img = cv2.imread(path)
            if img is not None:
                self.set_image(img)

    def _import(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Points CSV (x,y,z,u,v)", "", "CSV (*.csv)")
        if path:
            self.import_csv(Path(path))

    def import_csv(self, path: Path) -> None:
        from engine.errors import CalibrationError
        from engine.ptz.dlt import load_points_csv

        try:
            X, uv = load_points_csv(path)
        except CalibrationError as exc:
            self.status.setText(f"⚠ {exc}")
            return
        for x, m in zip(X, uv, strict=True):
            self.add_image_point(float(m[0]), float(m[1]), (float(x[0]), float(x[1]),
                                                            float(x[2])))
        self.status.setText(f"imported {len(X)} point(s) from {path.name}")

    def _export(self) -> None:
        from engine.ptz.dlt import save_points_csv

        path, _ = QFileDialog.getSaveFileName(self, "Points CSV", "points.csv", "CSV (*.csv)")
        if path:
            X, uv, _ = self.rows()
            save_points_csv(path, X, uv)


class LinesPanel(QWidget):
    """Line-based distortion: click/propose lines, estimate, preview undistorted."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.image: np.ndarray | None = None
        self.lines: list[list[tuple[float, float]]] = [[]]
        self.fit: Any = None
        self.preview = False
        self.view = ClickImage(self.add_point)
        self.curves: list[pg.PlotDataItem] = []
        self.status = QLabel("Click points along lines straight in the world, or Propose.")
        self.status.setObjectName("ptz_lines_status")
        self.status.setWordWrap(True)
        btns = QHBoxLayout()
        for text, slot in (("New line", self.new_line), ("Propose (chessboard)",
                                                         self.propose_chessboard),
                           ("Propose (edges)", self.propose_edges), ("Clear", self.clear),
                           ("Estimate", self.estimate), ("Preview undistorted",
                                                         self.toggle_preview)):
            b = QPushButton(text)
            b.clicked.connect(slot)
            btns.addWidget(b)
        self.save_button = QPushButton("Save distortion to project")
        self.save_button.setObjectName("ptz_save_distortion")
        btns.addWidget(self.save_button)
        lay = QVBoxLayout(self)
        lay.addWidget(self.view, 1)
        lay.addLayout(btns)
        lay.addWidget(self.status)

    def set_image(self, img: np.ndarray) -> None:
        self.image = img
        self.fit = None
        self.preview = False
        self.view.set_image_bgr(img)
        self._draw()

    def add_point(self, u: float, v: float) -> None:
        if self.preview:
            return
        self.lines[-1].append((u, v))
        self._draw()

    def new_line(self) -> None:
        if self.lines[-1]:
            self.lines.append([])

    def clear(self) -> None:
        self.lines = [[]]
        self.fit = None
        self._draw()

    def _gray(self) -> np.ndarray | None:
        import cv2

        if self.image is None:
            return None
        return cv2.cvtColor(self.image, cv2.COLOR_BGR2GRAY) if self.image.ndim == 3 else self.image

    def _accept(self, found: list[np.ndarray], what: str) -> None:
        self.lines = [ln for ln in self.lines if ln] + [[tuple(p) for p in f] for f in found]
        self.lines.append([])
        self.status.setText(f"{len(found)} {what} line(s) proposed; Clear to discard")
        self._draw()

    def propose_chessboard(self) -> None:
        from engine.ptz.distortion import propose_lines_chessboard

        g = self._gray()
        if g is not None:
            self._accept(propose_lines_chessboard(g, (9, 6)), "chessboard")

    def propose_edges(self) -> None:
        from engine.ptz.distortion import propose_lines_edges

        g = self._gray()
        if g is not None:
            self._accept(propose_lines_edges(g), "edge")

    def estimate(self) -> None:
        from engine.errors import CalibrationError
        from engine.ptz.distortion import estimate_radial_from_lines

        if self.image is None:
            return
        lines = [np.asarray(ln, float) for ln in self.lines if len(ln) >= 3]
        try:
            self.fit = estimate_radial_from_lines(
                lines, (self.image.shape[1], self.image.shape[0]))
        except CalibrationError as exc:
            self.status.setText(f"⚠ {exc}")
            return
        m = self.fit.model
        self.status.setText(
            f"{len(lines)} lines: k3 {m.k[0]:+.4f}  k5 {m.k[1]:+.4f}  "
            f"centre ({m.centre_px[0]:.1f}, {m.centre_px[1]:.1f}) px  "
            f"straightness {self.fit.rms_before_px:.2f} → "
            f"{self.fit.rms_after_px:.2f} px RMS"
        )

    def toggle_preview(self) -> None:
        if self.fit is None or self.image is None:
            self.status.setText("Estimate first")
            return
        self.preview = not self.preview
        img = self.fit.model.undistort_image(self.image) if self.preview else self.image
        self.view.set_image_bgr(img)
        self._draw()

    def _draw(self) -> None:
        for c in self.curves:
            self.view.removeItem(c)
        self.curves = []
        for i, ln in enumerate(self.lines):
            if not ln:
                continue
            a = np.asarray(ln, float)
            if self.preview and self.fit is not None:
                a = self.fit.model.undistort_px(a)
            col = MODEL_COLOURS[1 + i % (len(MODEL_COLOURS) - 1)]
            c = pg.PlotDataItem(a[:, 0], a[:, 1], pen=pg.mkPen(col, width=2), symbol="o",
                                symbolSize=5, symbolBrush=col)
            self.view.addItem(c)
            self.curves.append(c)


class LivePanel(QWidget):
    """Runs ptz-sim through the ptz tracker; video, trajectories, Fig. 6 and error bands."""

    def __init__(self, ctx: Any, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        from engine.trackers.ptz import PtzParams
        from widgets.param_form import ParamForm

        self.ctx = ctx
        self.run = ctx.run
        self.run.started.connect(lambda _i: self.update_buttons())
        self.run.finished.connect(lambda _s: self.run_ended())
        self.run.failed.connect(self._on_failed)
        self._latest: Any = None
        self.t: list[float] = []
        self.est: list[np.ndarray] = []
        self.sig: list[np.ndarray] = []
        self.truth: list[np.ndarray] = []
        self.probs: list[np.ndarray] = []
        self.omega: list[float] = []
        self.omega_true: list[float] = []
        self.form = ParamForm(PtzParams().with_preset("ptz-sim"))
        self.form.params_changed.connect(self._on_params)
        self.start_button = QPushButton("Start (ptz-sim)")
        self.start_button.setObjectName("ptz_start")
        self.stop_button = QPushButton("Stop")
        self.stop_button.setObjectName("ptz_stop")
        self.stop_button.setEnabled(False)  # enabled while the engine runs
        self.start_button.setToolTip("Run the simulated pan-tilt studio with the ptz tracker")
        self.start_button.clicked.connect(self.start)
        self.head_combo = QComboBox()
        self.head_combo.setObjectName("ptz_head_mode")
        for text, key in HEAD_MODES:
            self.head_combo.addItem(text, key)
        self.head_combo.setToolTip("what drives the camera: the simulated stepping head, the "
                                   "loopback VISCA-over-IP camera (real bytes, position back "
                                   "by FreeD), or the calibrated chain (the project's "
                                   "calibration only, head without encoder)")
        self.calib_button = QPushButton("Calibrate from the simulator → project")
        self.calib_button.setObjectName("ptz_calibrate_sim")
        self.calib_button.setToolTip("run the whole chain on ptz-sim views (board lines, "
                                     "marker DLTs at four poses) and save it in the project")
        self.calib_button.clicked.connect(self.calibrate_from_sim)
        self.stop_button.clicked.connect(self.stop)
        self.readout = QLabel("")
        self.readout.setObjectName("ptz_readout")
        self.readout.setWordWrap(True)

        self.video = ClickImage(lambda u, v: None)
        self.snake_items = [pg.PlotDataItem(pen=pg.mkPen(200, 200, 200, 120)) for _ in range(5)]
        self.final_contour = pg.PlotDataItem(pen=pg.mkPen(60, 140, 255, width=2))
        self.centre = pg.ScatterPlotItem(size=12, symbol="+", pen=pg.mkPen(0, 255, 0, width=2))
        self.pred = pg.ScatterPlotItem(size=12, symbol="o", pen=pg.mkPen(255, 220, 0, width=2),
                                       brush=None)
        for it in (*self.snake_items, self.final_contour, self.centre, self.pred):
            self.video.addItem(it)

        # the video keeps its aspect: no axes, no padding, and its pane is sized to the
        # image's aspect at the row's height (_fit_video)
        self.video.hideAxis("left")
        self.video.hideAxis("bottom")
        self.video.getViewBox().setDefaultPadding(0.0)
        self.plots = pg.GraphicsLayoutWidget()  # beside the video: top view, height, Fig. 6
        self.kin = pg.GraphicsLayoutWidget()  # below: position, velocity, acceleration
        # short titles (they must fit a 1280 px window) + axis labels carrying the units
        self.top = self.plots.addPlot(0, 0, title="Top view")
        self.top.setAspectLocked(True)
        _axes(self.top, "x (m)", "y (m)")
        self.top_truth = self.top.plot(pen=pg.mkPen(230, 230, 230, width=5))
        self.top_est = self.top.plot(pen=pg.mkPen(255, 90, 90, width=1.5))
        self.zplot = self.plots.addPlot(0, 1, title="Height")
        _axes(self.zplot, "time (s)", "z (m)")
        self.z_truth = self.zplot.plot(pen=pg.mkPen(230, 230, 230))
        self.z_est = self.zplot.plot(pen=pg.mkPen(255, 90, 90, width=2))
        self.pplot = self.plots.addPlot(1, 0, title="Models (Fig. 6 l.)")
        _axes(self.pplot, "time (s)", "p")
        self.pplot.setYRange(0, 1.02)
        self.pplot.addLegend(offset=(5, 5))
        self.p_curves: list[Any] = []
        self.wplot = self.plots.addPlot(1, 1, title="Turn rate (Fig. 6 r.)")
        _axes(self.wplot, "time (s)", "ω (rad/s)")
        self.w_est = self.wplot.plot(pen=pg.mkPen(90, 160, 255, width=2))
        self.w_true = self.wplot.plot(pen=pg.mkPen(255, 90, 90))
        self.kin_plots = []
        self.kin_items: list[list[tuple[Any, Any, Any, Any]]] = []
        for k, (title, unit) in enumerate((("Position ±2σ", "m"), ("Velocity ±2σ", "m/s"),
                                            ("Acceleration ±2σ", "m/s²"))):
            pl = self.kin.addPlot(0, k, title=title)
            _axes(pl, "time (s)", f"x y z ({unit})")
            items = []
            for a in range(3):
                col = AXIS_COLOURS[a]
                lo = pl.plot(pen=pg.mkPen(*col, 0))
                hi = pl.plot(pen=pg.mkPen(*col, 0))
                fill = pg.FillBetweenItem(lo, hi, brush=pg.mkBrush(*col, 50))
                pl.addItem(fill)
                est = pl.plot(pen=pg.mkPen(col, width=2))
                tru = pl.plot(pen=pg.mkPen(col, width=1, style=Qt.PenStyle.DashLine))
                items.append((lo, hi, est, tru))
            self.kin_plots.append(pl)
            self.kin_items.append(items)
        self.kin.addLabel(
            "top/height: red est., white truth<br>turn rate: blue est., red truth<br>"
            "x red · y green · z blue<br>solid: est. · dashed: truth",
            0, 3, color="#9aa3b2", size="9pt",
        )

        left = QWidget()
        ll = QVBoxLayout(left)
        row = QHBoxLayout()
        row.addWidget(self.start_button)
        row.addWidget(self.stop_button)
        ll.addLayout(row)
        ll.addWidget(self.head_combo)
        ll.addWidget(self.calib_button)
        ll.addWidget(self.readout)
        form_scroll = QScrollArea()  # a long form scrolls, not the page
        form_scroll.setWidgetResizable(True)
        form_scroll.setFrameShape(QFrame.Shape.NoFrame)
        form_scroll.setWidget(self.form)
        ll.addWidget(form_scroll, 1)
        left.setMinimumWidth(300)  # combo boxes and 5-decimal spin boxes stay readable
        self.readout.setText(
            "Idle. Start runs the simulated pan-tilt studio (ptz-sim): the camera follows the "
            "red target."
        )
        self.video_row = QSplitter()
        self.video_row.addWidget(self.video)
        self.video_row.addWidget(self.plots)
        self.right = QSplitter(Qt.Orientation.Vertical)
        self.right.addWidget(self.video_row)
        self.right.addWidget(self.kin)
        self.right.setSizes([600, 400])
        split = QSplitter()
        split.addWidget(left)
        split.addWidget(self.right)
        split.setSizes([310, 900])
        split.setCollapsible(0, False)
        lay = QVBoxLayout(self)
        lay.addWidget(split)
        self.update_buttons()

    def _fit_video(self) -> None:
        """Size the video's pane to its image's aspect: as wide as the plots beside it
        (``SIDE_MIN_PX``) and the kinematics row below (30 % of the height) leave room for,
        the row's height following; the operator's handle drags hold until the next
        resize."""
        img = self.video.image_item.image
        h_img, w_img = (img.shape[:2] if img is not None else (480, 640))
        aspect = w_img / max(h_img, 1)
        W, H = self.right.width(), self.right.height()
        below = max(KIN_MIN_PX, int(0.3 * H))
        w = max(160, min(W - SIDE_MIN_PX, int((H - below) * aspect)))
        h = int(w / aspect)
        self.right.setSizes([h, max(H - h, 1)])
        self.video_row.setSizes([w, max(W - w, 1)])

    def resizeEvent(self, event: Any) -> None:
        super().resizeEvent(event)
        self._fit_video()

    def start(self, spec: str = "ptz-sim:duration=60,period=50", realtime: bool = True) -> None:
        if self.run.is_running:
            self.readout.setText("A run is active: stop it first.")
            return
        from app.run_owner import RunRequest

        spec = spec if isinstance(spec, str) else "ptz-sim:duration=60,period=50"
        mode = self.head_combo.currentData()
        factory = None
        if mode == "visca":
            spec += ",head=visca"
        elif mode == "calibrated":
            proj = self.ctx.project
            cal = getattr(proj, "ptz", None)
            if cal is None or cal.head is None:
                self.readout.setText("⚠ the project has no pan-tilt calibration with a head: "
                                     "save one (DLT tab or Calibrate from the simulator)")
                return
            spec += CHAIN_OPTIONS
            params = self.form.params

            def factory(c: Any = cal, p: Any = params) -> Any:
                from engine.trackers.ptz import PtzTracker

                return PtzTracker(p, calibration=c)
        self.clear_history()
        self.run.start(RunRequest(spec, "ptz", self.form.params, realtime=realtime,
                                  page="PTZ", tracker_factory=factory))
        self.update_buttons()

    def calibrate_from_sim(self) -> None:
        """The whole chain on ptz-sim views (sec. 3.1-3.3) into the project."""
        from engine.errors import CalibrationError
        from engine.ptz.sim import CircleScenario, PtzSimSource
        from engine.ptz.sim_calibration import calibrate_sim

        sc = CircleScenario(markers=True, distortion_k3=CHAIN_K3, encoder=False)
        try:
            cal, rep = calibrate_sim(PtzSimSource(sc))
        except CalibrationError as exc:
            self.readout.setText(f"⚠ {exc}")
            return
        save_ptz(self.ctx, cal, f"chain from the simulator: {rep['lines']} lines, "
                 f"straightness {rep['straightness_before_px']:.2f} → "
                 f"{rep['straightness_after_px']:.2f} px, {rep['dlt_views']} DLT views")
        self.readout.setText("Calibration saved in the project (unsaved until File > Save). "
                             "Choose 'calibrated chain' and Start.")
        idx = self.head_combo.findData("calibrated")
        self.head_combo.setCurrentIndex(idx)

    def stop(self) -> None:
        self.run.stop()

    def clear_history(self) -> None:
        for lst in (self.t, self.est, self.sig, self.truth, self.probs, self.omega,
                    self.omega_true):
            lst.clear()

    def update_buttons(self) -> None:
        running = self.run.is_running
        self.start_button.setEnabled(not running)
        self.stop_button.setEnabled(running)

    def _on_params(self, params: Any) -> None:
        info = self.run.run_info
        if self.run.is_running and info is not None and info.tracker_name == "ptz":
            self.run.set_params(params)

    def run_faulted(self, status: Any) -> None:
        """The engine raised: the live markers go (not live), the read-out says why."""
        self._latest = None
        for it in (*self.snake_items, self.final_contour):
            it.setData([], [])
        self.centre.setData([], [])
        self.pred.setData([], [])
        error = getattr(status, "error", None) or self.run.last_error or "engine error"
        self.readout.setText(f"⚠ ERROR: {error} — the head holds; press Stop")
        self.update_buttons()

    def run_ended(self) -> None:
        """Nothing stale after Stop: the live markers and the read-out clear."""
        self._latest = None
        for it in (*self.snake_items, self.final_contour):
            it.setData([], [])
        self.centre.setData([], [])
        self.pred.setData([], [])
        req = self.run.request
        if req is None or req.page != "PTZ":
            # another page's run: the read-out stays about this page's own last run (its
            # frame count is not this page's)
            self.update_buttons()
            return
        err = self.run.last_error
        st = self.run.status()
        frames = st.frames if st is not None else len(self.t)
        self.readout.setText(f"⚠ {err}" if err and not self.run.stopped_by_user else
                             f"Stopped after {frames} frames ({len(self.t)} with a target "
                             "estimate).")
        self.update_buttons()

    def add_samples(self, samples: list[Any], missed: int) -> None:
        from engine.ptz.sim import PtzTargetTruth
        from engine.trackers.ptz import PtzDetails

        for smp in samples:
            ex = smp.details if isinstance(smp.details, PtzDetails) else None
            if ex is None or ex.target_xyz is None:
                continue
            x = np.concatenate([ex.target_xyz, ex.target_vel, ex.target_acc])
            order = np.array([0, 3, 6, 1, 4, 7, 2, 5, 8])
            sig = np.sqrt(np.clip(np.diag(ex.target_cov)[order], 0, None))
            fe = smp.payload(PtzTargetTruth)
            nan3 = (np.nan, np.nan, np.nan)
            tru = np.concatenate([fe.xyz_world if fe else nan3, fe.vel_world if fe else nan3,
                                  fe.acc_world if fe else nan3])
            self.t.append(smp.timestamp_s)
            self.est.append(x)
            self.sig.append(sig)
            self.truth.append(tru)
            self.probs.append(np.asarray(ex.model_probs))
            self.omega.append(float(ex.omega_rad_s or 0.0))
            self.omega_true.append(float(fe.omega_rad_s) if fe else np.nan)
            if not self.p_curves and ex.omegas is not None:
                for j, w in enumerate(ex.omegas):
                    self.p_curves.append(self.pplot.plot(
                        pen=pg.mkPen(MODEL_COLOURS[j % len(MODEL_COLOURS)], width=2),
                        name=f"p{j + 1} ω={w:.3f}"))
        if len(self.t) > HISTORY:
            for lst in (self.t, self.est, self.sig, self.truth, self.probs, self.omega,
                        self.omega_true):
                del lst[: len(lst) - HISTORY]

    @Slot(str)
    def _on_failed(self, msg: str) -> None:
        req = self.run.request
        if req is not None and req.page == "PTZ":
            self.readout.setText(f"⚠ {msg}")
        self.update_buttons()

    def redraw(self) -> None:
        """Draw the newest record now (tests, screenshots)."""
        rec = self.run.latest()
        if rec is not None:
            self.draw(rec)

    def draw(self, rec: Any) -> None:
        self._latest = rec
        if rec.frame.color_bgr is not None:
            self.video.image_item.setImage(np.ascontiguousarray(rec.frame.color_bgr[..., ::-1]),
                                           autoLevels=False, levels=(0, 255))
        ov = rec.result.overlay
        polys = list(ov.polylines_uv) if ov is not None else []
        for i, it in enumerate(self.snake_items):
            if i < len(polys) - 1:
                it.setData(polys[i][:, 0], polys[i][:, 1])
            else:
                it.setData([], [])
        if polys:
            self.final_contour.setData(polys[-1][:, 0], polys[-1][:, 1])
        if ov is not None and ov.crosshair_uv is not None:
            self.centre.setData([ov.crosshair_uv[0]], [ov.crosshair_uv[1]])
        det = rec.result.details
        pu = getattr(det, "predicted_uv", None)
        self.pred.setData(*(([pu[0]], [pu[1]]) if pu else ([], [])))
        if not self.t:
            return
        t = np.asarray(self.t)
        E = np.asarray(self.est)
        S = np.asarray(self.sig)
        T = np.asarray(self.truth)
        self.top_truth.setData(T[:, 0], T[:, 1])
        self.top_est.setData(E[:, 0], E[:, 1])
        self.z_truth.setData(t, T[:, 2])
        self.z_est.setData(t, E[:, 2])
        Pm = np.asarray(self.probs)
        for j, c in enumerate(self.p_curves):
            c.setData(t, Pm[:, j])
        self.w_est.setData(t, np.asarray(self.omega))
        self.w_true.setData(t, np.asarray(self.omega_true))
        for k, items in enumerate(self.kin_items):
            for a, (lo, hi, est, tru) in enumerate(items):
                i = 3 * k + a
                lo.setData(t, E[:, i] - 2 * S[:, i])
                hi.setData(t, E[:, i] + 2 * S[:, i])
                est.setData(t, E[:, i])
                tru.setData(t, T[:, i])
        ex = rec.result.details
        err = float(np.linalg.norm(E[-1, :3] - T[-1, :3]))
        meas = getattr(ex, "measurement", None)
        self.readout.setText(
            f"{rec.result.state.value}  t={t[-1]:.1f} s  d={meas[2]:.2f} m  " if meas else
            f"{rec.result.state.value}  t={t[-1]:.1f} s  "
        )
        self.readout.setText(
            self.readout.text() + f"pos err {err * 100:.1f} cm  ω̂={self.omega[-1]:.3f} rad/s  "
            f"pan/tilt {_deg_pair(getattr(ex, 'pan_tilt_deg', None))} "
            f"({getattr(ex, 'pan_tilt_source', '–')})  "
            f"resets {getattr(ex, 'resets', '–')}  "
            f"{1000.0 / max(rec.process_ms, 1e-3):.0f} updates/s"
        )


HEAD_MODES = (("Head: simulated motors", "sim"),
              ("Head: loopback VISCA camera", "visca"),
              ("Head: calibrated chain (project)", "calibrated"))
CHAIN_K3 = 0.12
#: the Live tab's layout: the plots beside the video keep this width, the row below this
#: height (the video takes the rest at its image's aspect)
SIDE_MIN_PX = 430
KIN_MIN_PX = 180
CHAIN_OPTIONS = f",markers=1,distortion={CHAIN_K3},encoder=0"


def save_ptz(ctx: Any, cal: Any, what: str) -> None:
    """Put a pan-tilt calibration into the project (a new one when none is open)."""
    ctx.edit_project(lambda proj: setattr(proj, "ptz", cal))
    ctx.log.info(f"PTZ calibration: {what}")


def _deg_pair(value: Any) -> str:
    try:
        pan, tilt = (float(v) for v in value)
    except (TypeError, ValueError):
        return "–"
    return f"{pan:.1f}° / {tilt:.1f}°"


class PtzPage(Page):
    follows_trackers = ("ptz",)

    def __init__(self, ctx: Any, parent: QWidget | None = None) -> None:
        super().__init__(ctx, parent)
        self.setObjectName("page_ptz")
        self.tabs = QTabWidget()
        self.points = CalibPointsPanel()
        self.lines = LinesPanel()
        self.live = LivePanel(ctx)
        self.tabs.addTab(self.live, "Live")
        self.tabs.addTab(self.points, "Calibration points (DLT)")
        self.tabs.addTab(self.lines, "Lens lines")
        lay = QGridLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        lay.addWidget(self.tabs, 0, 0)
        self.points.save_head_button.clicked.connect(self.save_head)
        self.points.save_frame_button.clicked.connect(self.save_studio_frame)
        self.lines.save_button.clicked.connect(self.save_distortion)
        self._load_defaults()

    def _calibration(self) -> Any:
        from engine.ptz.calibration import PtzCalibration

        proj = self.ctx.project
        cal = getattr(proj, "ptz", None)
        return cal if cal is not None else PtzCalibration(head=None)

    def save_head(self) -> None:
        import dataclasses

        from engine.ptz.calibration import DltPose
        from engine.ptz.kinematics import head_from_dlt

        res = self.points.result
        if res is None:
            self.points.status.setText("⚠ Solve the DLT first")
            return
        head = head_from_dlt(res.decomposition, np.array([0.0, 0.0, 0.04]), 0.0, 0.0)
        cal = dataclasses.replace(self._calibration(), head=head, dlt_poses=(
            DltPose(0.0, 0.0, res.rmse_px, len(res.residuals_px)),))
        if self.points.image is not None:  # the lens sample from this DLT needs it
            h, w = self.points.image.shape[:2]
            cal = dataclasses.replace(cal, image_size=(w, h))
        save_ptz(self.ctx, cal, f"head from the DLT (RMSE {res.rmse_px:.2f} px)")
        self.points.status.setText(self.points.status.text() + "  — saved to the project")

    def save_studio_frame(self) -> None:
        """The DLT's world as the studio frame (the pan-tilt tracker's world is the DLT
        camera's: ``T_world_cam`` identity), into the project and the outputs in force."""
        from engine.errors import StudioTrackError
        from engine.outputs.studio_frame import StudioFrame

        res = self.points.result
        if res is None:
            self.points.status.setText("⚠ Solve the DLT first")
            return
        d = res.decomposition
        try:
            frame = StudioFrame.from_dlt(np.eye(4), d.R_cam_world, d.t_cam_world)
        except StudioTrackError as exc:
            self.points.status.setText(f"⚠ {exc}")
            return
        self.ctx.edit_project(lambda proj: setattr(proj, "studio_frame", frame))
        o = frame.matrix[:3, 3]
        self.ctx.log.info(f"studio frame from the DLT: origin ({o[0]:.3f}, {o[1]:.3f}, "
                          f"{o[2]:.3f}) m in the tracker's world")
        self.points.status.setText(self.points.status.text()
                                   + "  — studio frame saved to the project")

    def save_distortion(self) -> None:
        import dataclasses

        fit = self.lines.fit
        if fit is None or self.lines.image is None:
            self.lines.status.setText("⚠ Estimate first")
            return
        h, w = self.lines.image.shape[:2]
        cal = dataclasses.replace(self._calibration(), radial=fit.model, image_size=(w, h))
        ks = ", ".join(f"{k:+.4f}" for k in fit.model.k)
        save_ptz(self.ctx, cal, f"line-based distortion k ({ks})")
        self.lines.status.setText(self.lines.status.text() + "  — saved to the project")

    def _load_defaults(self) -> None:
        import cv2

        from engine.ptz.sim import CircleScenario, PtzSimSource

        frame = next(iter(PtzSimSource(CircleScenario(duration_s=0.1)).frames()))
        self.points.set_image(np.ascontiguousarray(frame.color_bgr))
        self.live.video.set_image_bgr(np.ascontiguousarray(frame.color_bgr))
        radial = shared_data_dir() / "opencv_samples" / "lines_distortion" / "calib_radial.jpg"
        img = cv2.imread(str(radial)) if radial.exists() else None
        self.lines.set_image(img if img is not None else np.ascontiguousarray(frame.color_bgr))

    # the page base calls these; the Live tab draws them (calibration tabs need no clock)
    def run_changed(self, info: Any) -> None:
        self.live.update_buttons()

    def run_faulted(self, status: Any) -> None:
        self.live.run_faulted(status)

    def run_stalled(self, message: str) -> None:
        self.live.readout.setText(f"⚠ LOST: {message} — the markers shown are not live")

    def add_samples(self, samples: list[Any], missed: int) -> None:
        self.live.add_samples(samples, missed)

    def draw(self, record: Any) -> None:
        if self.tabs.currentWidget() is self.live:
            self.live.draw(record)


def _factory(ctx: Any) -> QWidget:
    return PtzPage(ctx)


PAGES = (
    PageSpec(title="PTZ", order=80, factory=_factory, trackers=("ptz",),
             tooltip="pan-tilt camera target tracking (Gaspar 2009): calibration + live"),
)
