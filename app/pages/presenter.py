"""The Presenter page: VR-TV presenter tracking, from model set-up to robot-camera control.

Set-up (paper Sec. III-B, Fig. 4): take a reference image from the source, drag the main
region, drag two or more patches inside it (move / resize in Edit mode, Delete removes the
selected patch, names are edited in the list); each patch's 10x10 hue-saturation histogram
(+ the brightness bins of hue-less pixels) is shown. Degenerate selections get a one-line
message. Models are saved as model.json + reference.png in the project (or a session folder).

Two views (paper Fig. 2): a source with a second camera (``synthetic:views=2``, ``twoview:``)
shows its picture beside the frontal one; the Floor tab takes its frame, four floor marks are
clicked on it and their floor coordinates (m) typed in, with the robot's floor position; the
calibration is saved in the studio project and given to the tracker, which then reports the
presenter's floor position, height and distance d, and sends the talent output. A second
camera that zooms takes the lens file (the project's, or the source's own) and the zoom /
focus encoders at the marks: the calibration is then a camera model (engine.floor) that
follows the encoders the camera reports each frame.

Live: Start runs ``presenter`` through the window's run owner (``ctx.run``: the outputs,
the robot-camera control sink and the status header follow it; a run of another page must be
stopped first). Boxes or a cross-hair over the video, the particle cloud, the colour
likelihood with its Pmin / Pref lines, x / y raw vs jitter-filtered, the state light, the
control errors (eq. 7-8) and the UDP target are shown, every number from the frame drawn.
Every parameter edit is sent as ``SetParams`` and applies on the next frame. The page draws
on the window's display clock while shown; after Stop the live read-outs clear.
"""

from __future__ import annotations

import collections
import dataclasses
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QRectF, QSize, Qt, Slot
from PySide6.QtGui import QColor, QPainter
from PySide6.QtWidgets import (
    QButtonGroup,
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFrame,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QRadioButton,
    QScrollArea,
    QSpinBox,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from app.pages import PageSpec
from app.pages._base import Page
from engine.results import TrackState
from widgets.param_form import ParamForm
from widgets.patch_canvas import PATCH_COLOURS, PatchCanvas
from widgets.plot_grid import GridLines
from widgets.status_light import StatusLight

CELL_PX = 9
AXIS_PX = 14  # room for the saturation axis label
HISTORY = 300
DEFAULT_SOURCE = "synthetic:frames=3000,seed=3,presenter=1,path=static"


class HistogramTile(QWidget):
    """One patch's N x N hue-saturation histogram (cell colour = bin colour, square size =
    weight) and, below, its N brightness bins for hue-less pixels; axes labelled."""

    def __init__(self, name: str, hist: np.ndarray, n_bins: int, colour: str,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.name = name
        self.hist = np.asarray(hist, dtype=np.float64)
        self.n = n_bins
        self.colour = QColor(colour)
        self.setToolTip(f"{name}: hue (across) x saturation (up) histogram; bottom row: "
                        "brightness of the pixels without a hue (grey, black, white)")
        self.setFixedSize(self.sizeHint())

    def sizeHint(self) -> QSize:
        return QSize(CELL_PX * self.n + 8 + AXIS_PX, CELL_PX * (self.n + 1) + 24 + 2 * 12)

    def paintEvent(self, _ev: object) -> None:
        p = QPainter(self)
        n, c = self.n, float(CELL_PX)
        font = p.font()
        font.setBold(True)
        p.setFont(font)
        p.setPen(self.colour.lighter(130))
        p.drawText(QRectF(0, 0, self.width(), 14), Qt.AlignmentFlag.AlignLeft, self.name)
        small = p.font()
        small.setBold(False)
        small.setPointSizeF(max(small.pointSizeF() - 1.5, 6.5))
        p.setFont(small)
        p.setPen(QColor("#aab2bf"))
        p.drawText(QRectF(AXIS_PX, 14, n * c + 4, 12), Qt.AlignmentFlag.AlignLeft,
                   "hue →")
        p.save()  # the saturation axis, written upwards beside the grid
        p.translate(AXIS_PX - 3, 28 + n * c)
        p.rotate(-90)
        p.drawText(QRectF(0, -11, n * c, 11), Qt.AlignmentFlag.AlignLeft,
                   "saturation →")
        p.restore()
        p.drawText(QRectF(AXIS_PX, 28 + (n + 1) * c + 6, n * c + 4, 12),
                   Qt.AlignmentFlag.AlignLeft, "brightness →")
        p.translate(AXIS_PX - 4, 12)
        top = 16.0
        hs = self.hist[: n * n].reshape(n, n)  # [hue bin, sat bin]
        grey = self.hist[n * n:]
        vmax = max(float(self.hist.max()), 1e-9)
        for hb in range(n):
            for sb in range(n):
                col = QColor.fromHsvF((hb + 0.5) / n, (sb + 0.5) / n, 1.0)
                x, y = 4 + hb * c, top + (n - 1 - sb) * c  # saturation grows upwards
                p.fillRect(QRectF(x, y, c - 1, c - 1), col.darker(350))
                frac = float(np.sqrt(hs[hb, sb] / vmax))
                if frac > 0.02:
                    d = (c - 1) * frac
                    p.fillRect(QRectF(x + (c - 1 - d) / 2, y + (c - 1 - d) / 2, d, d), col)
        y = top + n * c + 4
        for vb in range(n):
            col = QColor.fromHsvF(0.0, 0.0, (vb + 0.5) / n)
            x = 4 + vb * c
            p.fillRect(QRectF(x, y, c - 1, c - 1), QColor("#202328"))
            frac = float(np.sqrt(grey[vb] / vmax))
            if frac > 0.02:
                d = (c - 1) * frac
                p.fillRect(QRectF(x + (c - 1 - d) / 2, y + (c - 1 - d) / 2, d, d), col)
        p.end()


class PresenterPage(Page):
    follows_trackers = ("presenter",)

    def __init__(self, ctx: Any) -> None:
        super().__init__(ctx)
        from engine.presenter.params import PresenterParams

        self.run = ctx.run
        self.reference: np.ndarray | None = None
        self.model: Any = None
        self.latest: Any = None
        self._session_dir: Path | None = None
        self.hist_p: collections.deque[tuple[float, float, float]] = collections.deque(
            maxlen=HISTORY)
        self.hist_xy: collections.deque[tuple[float, ...]] = collections.deque(maxlen=HISTORY)
        self._frames = 0

        # ---------------------------------------------------------- set-up controls
        self.source_edit = QLineEdit(DEFAULT_SOURCE)
        self.source_edit.setToolTip("Source spec (synthetic:..., camera:N, a folder or video)")
        self.take_button = QPushButton("Take reference")
        self.take_button.setToolTip("Grab the current frame of the source as the reference")
        self.take_button.clicked.connect(self.take_reference)
        self.canvas = PatchCanvas()
        # the second (overhead) camera: its picture, the tracked box, the floor marks
        self.over_canvas = PatchCanvas()
        self.over_canvas.placeholder = ("No second view: a source with an overhead camera "
                                        "(synthetic:...,views=2 or twoview:...) shows it here")
        self.over_canvas.set_mode("floor")
        self.over_canvas.setMinimumSize(240, 180)
        self.over_canvas.setToolTip("Second (overhead) camera. In the Floor tab, click four "
                                    "floor marks here and type their floor coordinates")
        self.over_canvas.floor_point_added.connect(self._on_floor_point)
        self.floor_calib: Any = None
        self.over_reference: np.ndarray | None = None
        self.mode_group = QButtonGroup(self)
        self.mode_buttons: dict[str, QPushButton] = {}
        mode_row = QHBoxLayout()
        for mode, text, tip in (
            ("main", "Main region", "Drag the rectangle enclosing the presenter"),
            ("patch", "Add patch", "Drag a patch inside the main region (head, torso, legs...)"),
            ("edit", "Edit", "Drag a rectangle to move it, its corner handle to resize it"),
        ):
            b = QPushButton(text)
            b.setCheckable(True)
            b.setToolTip(tip)
            self.mode_group.addButton(b)
            self.mode_buttons[mode] = b
            b.clicked.connect(lambda _=False, m=mode: self.canvas.set_mode(m))
            mode_row.addWidget(b)
        self.mode_buttons["main"].setChecked(True)
        self.delete_button = QPushButton("Delete patch")
        self.delete_button.clicked.connect(self.canvas.delete_selected)
        self.auto_button = QPushButton("Split 3")
        self.auto_button.setToolTip("Split the main region into head / torso / legs bands")
        self.auto_button.clicked.connect(self.auto_split)
        mode_row.addWidget(self.delete_button)
        mode_row.addWidget(self.auto_button)
        mode_row.addStretch(1)

        self.patch_list = QListWidget()
        self.patch_list.setMaximumHeight(80)
        self.patch_list.setToolTip("Patches; double-click a name to rename it")
        self.patch_list.itemChanged.connect(self._on_item_renamed)
        self.patch_list.currentRowChanged.connect(self._on_list_selected)
        self.hist_box = QWidget()
        self.hist_layout = QHBoxLayout(self.hist_box)
        self.hist_layout.setContentsMargins(0, 0, 0, 0)
        self.hist_layout.addStretch(1)
        self.message = QLabel("Take a reference image, then drag the main region and "
                              "two or more patches.")
        self.message.setWordWrap(True)
        self.save_button = QPushButton("Save model")
        self.save_button.clicked.connect(self.save_model)
        self.load_button = QPushButton("Load model")
        self.load_button.clicked.connect(self.load_model_dialog)
        self.start_button = QPushButton("Start tracking")
        self.start_button.setObjectName("primary")
        self.start_button.clicked.connect(self.start_tracking)
        self.stop_button = QPushButton("Stop")
        self.stop_button.setObjectName("presenter_stop")
        self.stop_button.clicked.connect(self.stop_tracking)
        self.realtime_check = QCheckBox("Real time")
        self.realtime_check.setChecked(True)
        self.realtime_check.setToolTip("Pace recorded sources at their frame rate")

        self.canvas.rects_changed.connect(self._on_rects_changed)
        self.canvas.selection_changed.connect(self._on_canvas_selected)
        self._build_floor_tab()

        # ---------------------------------------------------------- live controls
        self.form = ParamForm(PresenterParams())
        self.form.params_changed.connect(self._on_params)
        self.form.edit_rejected.connect(lambda msg: self._say(msg, "error"))
        self.boxes_radio = QRadioButton("Boxes")
        self.cross_radio = QRadioButton("Cross-hair")
        self.boxes_radio.setChecked(True)
        self.particles_check = QCheckBox("Particle cloud")
        self.particles_check.setChecked(True)
        self.light = StatusLight()
        self.readout = QLabel("Not tracking.")
        self.readout.setObjectName("readout")
        self.readout.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.readout.setWordWrap(True)  # a narrow panel wraps, never clips a number
        self.control_label = QLabel("Robot-camera control: shown while tracking.")
        self.control_label.setToolTip(
            "e_f: framing error of the presenter in the image (px); e_d: distance error from "
            "the overhead view (m); v: velocity command sent to the robot camera (eq. 7-8)"
        )
        self.control_label.setWordWrap(True)

        self.p_plot = pg.PlotWidget(title="Colour likelihood")
        self.p_plot.setLogMode(y=True)
        self.p_plot.setYRange(-6, 0)  # log10 decades until data arrive (no crowded minor ticks)
        self.p_plot.addLegend(offset=(-5, 5), labelTextSize="8pt", colCount=3)
        self.p_plot.setToolTip("P(z_col|s_t): colour likelihood of the best particle (log "
                               "scale); below Pmin the presenter counts as lost; Pref: at "
                               "model time")
        self.p_curve = self.p_plot.plot(pen=pg.mkPen("#2ecc71", width=2), name="P")
        self.pmin_curve = self.p_plot.plot(pen=pg.mkPen("#ff4d4f", style=Qt.PenStyle.DashLine),
                                           name="Pmin")
        self.pref_curve = self.p_plot.plot(pen=pg.mkPen("#4cc3ff", style=Qt.PenStyle.DashLine),
                                           name="Pref")
        self.z_plot = pg.PlotWidget(title="Loss test z")
        self.z_plot.addLegend(offset=(5, 5), labelTextSize="8pt", colCount=2)
        self.z_plot.setToolTip("z: the patches' colour distance from the model, 0 = the "
                               "presenter's own level, 1 = the most presenter-like "
                               "background; LOST while z is above the threshold")
        self.z_curve = self.z_plot.plot(pen=pg.mkPen("#2ecc71", width=2), name="z")
        self.z_over = self.z_plot.plot(pen=pg.mkPen("#b28dff", width=1), name="z overhead")
        # the threshold is named in the title (a third legend entry does not fit a narrow plot)
        self.zmax_curve = self.z_plot.plot(pen=pg.mkPen("#ff4d4f", style=Qt.PenStyle.DashLine))
        self.z_plot.setYRange(-0.5, 1.5)
        self.xy_plot = pg.PlotWidget(title="Image position")
        self.xy_plot.addLegend(offset=(-5, 5), labelTextSize="8pt", colCount=2)
        self.xy_plot.setToolTip("Presenter x, y in the image: raw particle-filter estimate vs "
                                "the jitter-filtered one sent to the outputs")
        self.x_raw = self.xy_plot.plot(pen=pg.mkPen("#4cc3ff", width=1), name="x raw")
        self.x_f = self.xy_plot.plot(pen=pg.mkPen("#ffd24c", width=2), name="x filtered")
        self.y_raw = self.xy_plot.plot(pen=pg.mkPen("#ff7ad9", width=1), name="y raw")
        self.y_f = self.xy_plot.plot(pen=pg.mkPen("#9dff4c", width=2), name="y filtered")
        self.d_plot = pg.PlotWidget(title="Floor distance")
        self.d_plot.setToolTip("Presenter distance d from the second (overhead) view, "
                               "needs the four floor points")
        self.d_curve = self.d_plot.plot(pen=pg.mkPen("#ff8c42", width=2))
        for plot, left_label in ((self.p_plot, "P"), (self.z_plot, "z"),
                                 (self.xy_plot, "x, y (px)"), (self.d_plot, "d (m)")):
            plot.setMinimumHeight(120)
            plot.setMinimumWidth(200)
            plot.setLabel("left", left_label)
            plot.setLabel("bottom", "frame (last 300)")
            GridLines(plot)  # cheap to repaint (widgets.plot_grid)
            for side in ("left", "bottom"):
                plot.getAxis(side).enableAutoSIPrefix(False)

        # ---------------------------------------------------------- layout
        left = QWidget()
        lv = QVBoxLayout(left)
        src_row = QHBoxLayout()
        src_row.addWidget(QLabel("Source"))
        src_row.addWidget(self.source_edit, 1)
        src_row.addWidget(self.take_button)
        lv.addLayout(src_row)
        lv.addLayout(mode_row)
        views = QSplitter(Qt.Orientation.Horizontal)
        views.addWidget(self.canvas)
        views.addWidget(self.over_canvas)
        views.setStretchFactor(0, 3)
        views.setStretchFactor(1, 2)
        lv.addWidget(views, 1)
        disp = QHBoxLayout()
        disp.addWidget(self.boxes_radio)
        disp.addWidget(self.cross_radio)
        disp.addWidget(self.particles_check)
        disp.addStretch(1)
        disp.addWidget(self.realtime_check)
        disp.addWidget(self.start_button)
        disp.addWidget(self.stop_button)
        lv.addLayout(disp)
        lv.addWidget(self.message)

        model_box = QGroupBox("Model")
        mg = QGridLayout(model_box)
        self.model_hint = QLabel("No patches yet: press “Add patch” and drag head, torso and "
                                 "legs on the reference image; their colour histograms then "
                                 "appear above.")
        self.model_hint.setWordWrap(True)
        self.model_hint.setObjectName("readout_caption")
        mg.addWidget(self.model_hint, 3, 0, 1, 2)
        mg.addWidget(self.patch_list, 0, 0, 1, 2)
        mg.addWidget(self.save_button, 1, 0)
        mg.addWidget(self.load_button, 1, 1)
        hist_scroll = QScrollArea()
        hist_scroll.setWidget(self.hist_box)
        hist_scroll.setWidgetResizable(True)
        hist_scroll.setMinimumHeight(CELL_PX * 11 + 44)
        mg.addWidget(hist_scroll, 2, 0, 1, 2)

        live_box = QGroupBox("Live")
        lg = QVBoxLayout(live_box)
        lg.addWidget(self.light)
        lg.addWidget(self.readout)
        lg.addWidget(self.control_label)

        form_scroll = QScrollArea()
        form_scroll.setWidget(self.form)
        form_scroll.setWidgetResizable(True)
        form_scroll.setFrameShape(QFrame.Shape.NoFrame)
        # Live state always visible; model and parameters share the rest as tabs, so the
        # parameter list is not squeezed to two rows under the model at 1280 x 800
        self.side_tabs = QTabWidget()
        self.side_tabs.addTab(model_box, "Model")
        self.side_tabs.addTab(form_scroll, "Parameters")
        # the floor form scrolls too: its height (table, robot, lens rows) must not set the
        # page's minimum (at 1280 x 800 it pushed the plots' axes below the window)
        floor_scroll = QScrollArea()
        floor_scroll.setWidget(self.floor_box)
        floor_scroll.setWidgetResizable(True)
        floor_scroll.setFrameShape(QFrame.Shape.NoFrame)
        self.side_tabs.addTab(floor_scroll, "Floor")
        model_box.setTitle("")
        model_box.setStyleSheet("QGroupBox { border: none; margin-top: 0; padding-top: 0; }")
        right = QWidget()
        rv = QVBoxLayout(right)
        rv.addWidget(live_box)
        rv.addWidget(self.side_tabs, 1)
        right.setMinimumWidth(430)  # readouts on one line each, the floor form unclipped

        plots = QWidget()
        pv = QHBoxLayout(plots)
        pv.setContentsMargins(0, 0, 0, 0)
        pv.addWidget(self.p_plot)
        pv.addWidget(self.z_plot)
        pv.addWidget(self.xy_plot)
        pv.addWidget(self.d_plot)

        centre = QSplitter(Qt.Orientation.Vertical)
        centre.addWidget(left)
        centre.addWidget(plots)
        centre.setStretchFactor(0, 4)
        centre.setStretchFactor(1, 1)
        centre.setSizes([600, 240])
        split = QSplitter(Qt.Orientation.Horizontal)
        split.addWidget(centre)
        split.addWidget(right)
        split.setStretchFactor(0, 3)
        split.setStretchFactor(1, 1)
        split.setSizes([1100, 380])
        outer = QVBoxLayout(self)
        outer.setContentsMargins(6, 6, 6, 6)
        outer.addWidget(split)

        self._show_loss_plot()
        self.run.failed.connect(self._on_failed)
        self.run.started.connect(self._on_started)
        self.run.finished.connect(self._on_finished)
        # Start/Stop follow the run (a bright red Stop on an idle page misleads)
        self._update_buttons()

    # ------------------------------------------------------------------ messages
    def _say(self, text: str, level: str = "info") -> None:
        colour = {"info": "#b9bec7", "warning": "#f0b429", "error": "#ff4d4f"}[level]
        if text == self.message.text():
            return
        self.message.setText(text)
        self.message.setStyleSheet(f"color: {colour};")
        log = getattr(self.ctx, "log", None)
        if log is not None and hasattr(log, level):
            getattr(log, level)(f"Presenter: {text}")

    # ------------------------------------------------------------------ set-up
    @Slot()
    def take_reference(self) -> None:
        """The latest tracked frame if running, else the first frame of the source."""
        frame = None
        rec = self.run.latest()
        if rec is not None and self.follows(self.run.run_info):
            frame = rec.frame
        else:
            from engine.errors import StudioTrackError
            from engine.sources import open_source

            try:
                with open_source(self.source_edit.text()) as src:
                    frame = next(iter(src.frames()), None)
            except (StudioTrackError, OSError) as exc:
                self._say(f"cannot take a reference: {exc}", "error")
                return
        if frame is None or frame.color_bgr is None:
            self._say("the source gave no image", "error")
            return
        img = frame.color_bgr
        if img.ndim == 2:
            img = np.repeat(img[..., None], 3, axis=2)
        self.set_reference(np.array(img))
        from engine.floor import OverheadView

        over = frame.payload(OverheadView)
        if over is not None:
            self.set_overhead(np.array(over.color_bgr), over.floor_calibration,
                              over.lens_encoders)
        else:
            # this source has no second view: another source's picture is not left standing
            self.over_reference = None
            self._source_lens = None
            self.over_canvas.set_image(None)
            self.over_canvas.set_floor_points([])

    def set_reference(self, image_bgr: np.ndarray) -> None:
        self.reference = image_bgr
        self.canvas.set_image(image_bgr)
        self._on_rects_changed()
        h, w = image_bgr.shape[:2]
        self._say(f"reference {w}x{h} taken: drag the main region, then two or more patches")

    @Slot()
    def auto_split(self) -> None:
        from engine.presenter.model import auto_patches

        if self.canvas.main is None:
            self._say("draw the main region first", "error")
            return
        self.canvas.set_model(self.canvas.main,
                              [(p.name, p.xywh) for p in auto_patches(self.canvas.main, 3)])

    def build_model(self) -> Any:
        """Validate the drawn selection and build the model; None (with a message) if bad."""
        from engine.presenter import PresenterError
        from engine.presenter.model import PatchSpec, build_model

        if self.reference is None:
            self._say("take a reference image first", "error")
            return None
        if self.canvas.main is None:
            self._say("no main region: drag a rectangle around the presenter", "error")
            return None
        p = self.form.params
        try:
            model = build_model(self.reference, self.canvas.main,
                                [PatchSpec(r.name, r.xywh) for r in self.canvas.patches],
                                n_bins=p.n_bins, grey_world=p.grey_world)
        except PresenterError as exc:
            self._say(str(exc), "error")
            return None
        if model.warnings:
            self._say("; ".join(model.warnings), "warning")
        else:
            self._say(f"model OK: {len(model.patches)} patches", "info")
        return model

    def _refresh_list(self) -> None:
        self.patch_list.blockSignals(True)
        self.patch_list.clear()
        for i, r in enumerate(self.canvas.patches):
            item = QListWidgetItem(r.name)
            item.setFlags(item.flags() | Qt.ItemFlag.ItemIsEditable)
            item.setForeground(QColor(PATCH_COLOURS[i % len(PATCH_COLOURS)]))
            self.patch_list.addItem(item)
        if 0 <= self.canvas.selected < self.patch_list.count():
            self.patch_list.setCurrentRow(self.canvas.selected)
        self.patch_list.blockSignals(False)
        self.model_hint.setVisible(self.patch_list.count() == 0)

    def _refresh_histograms(self, model: Any) -> None:
        while self.hist_layout.count() > 1:
            item = self.hist_layout.takeAt(0)
            w = item.widget() if item is not None else None
            if w is not None:
                w.setParent(None)  # type: ignore[call-overload]
                w.deleteLater()
        if model is None:
            return
        for i, (spec, hist) in enumerate(zip(model.patches, model.hists, strict=True)):
            tile = HistogramTile(spec.name, hist, model.n_bins,
                                 PATCH_COLOURS[i % len(PATCH_COLOURS)])
            self.hist_layout.insertWidget(self.hist_layout.count() - 1, tile,
                                          alignment=Qt.AlignmentFlag.AlignTop)

    @Slot()
    def _on_rects_changed(self) -> None:
        self._refresh_list()
        if self.reference is None or self.canvas.main is None or not self.canvas.patches:
            self.model = None
            self._refresh_histograms(None)
            return
        self.model = self.build_model()
        if self.model is None:
            # still show what the valid patches look like
            self._refresh_histograms(self._partial_model())
        else:
            self._refresh_histograms(self.model)

    def _partial_model(self) -> Any:
        """Histograms of the drawn patches even when the selection is not yet valid."""
        from types import SimpleNamespace

        from engine.presenter.model import patch_histograms

        if self.reference is None:
            return None
        p = self.form.params
        named = patch_histograms(self.reference, [(r.name, r.xywh) for r in self.canvas.patches],
                                 p.n_bins, grey_world=p.grey_world)
        return SimpleNamespace(patches=[SimpleNamespace(name=n) for n, _ in named],
                               hists=[h for _, h in named], n_bins=p.n_bins)

    @Slot(QListWidgetItem)
    def _on_item_renamed(self, item: QListWidgetItem) -> None:
        row = self.patch_list.row(item)
        name = item.text().strip()
        if 0 <= row < len(self.canvas.patches) and name:
            self.canvas.rename(row, name)

    @Slot(int)
    def _on_list_selected(self, row: int) -> None:
        self.canvas.select(row)

    @Slot(int)
    def _on_canvas_selected(self, idx: int) -> None:
        self.patch_list.blockSignals(True)
        self.patch_list.setCurrentRow(idx if idx >= 0 else -1)
        self.patch_list.blockSignals(False)

    # ------------------------------------------------------------------ two views
    def _build_floor_tab(self) -> None:
        """The floor calibration of the second view: four marks, the robot, the lens."""
        self.floor_box = QWidget()
        fv = QVBoxLayout(self.floor_box)
        intro = QLabel("Floor calibration of the overhead camera: take its frame, click four "
                       "floor marks on it (right picture), type where they are on the floor "
                       "(metres, studio floor frame) and the robot's floor position.")
        intro.setWordWrap(True)
        intro.setObjectName("readout_caption")
        fv.addWidget(intro)
        row = QHBoxLayout()
        self.take_over_button = QPushButton("Take overhead frame")
        self.take_over_button.setToolTip("The source's second view at its first frame")
        self.take_over_button.clicked.connect(self.take_overhead)
        self.clear_floor_button = QPushButton("Clear marks")
        self.clear_floor_button.clicked.connect(self.clear_floor_points)
        row.addWidget(self.take_over_button)
        row.addWidget(self.clear_floor_button)
        fv.addLayout(row)
        self.floor_table = QTableWidget(4, 4)
        self.floor_table.setHorizontalHeaderLabels(["u (px)", "v (px)", "floor x (m)",
                                                    "floor y (m)"])
        self.floor_table.setVerticalHeaderLabels([f"F{k + 1}" for k in range(4)])
        self.floor_table.setToolTip("u, v: where the mark is in the overhead picture (click "
                                    "it); floor x, y: where it is on the studio floor")
        self.floor_table.horizontalHeader().setStretchLastSection(True)
        self.floor_table.setMinimumHeight(150)
        for r in range(4):
            for c in range(4):
                self.floor_table.setItem(r, c, QTableWidgetItem(""))
        fv.addWidget(self.floor_table)
        grid = QGridLayout()
        self.robot_x = QDoubleSpinBox()
        self.robot_y = QDoubleSpinBox()
        for box in (self.robot_x, self.robot_y):
            box.setRange(-100.0, 100.0)
            box.setDecimals(3)
            box.setSingleStep(0.1)
            box.setSuffix(" m")
        self.focal = QDoubleSpinBox()
        self.focal.setRange(0.0, 20000.0)
        self.focal.setDecimals(1)
        self.focal.setSuffix(" px")
        self.focal.setSpecialValueText("solve")
        self.focal.setToolTip("The overhead camera's focal length; 0 = solve it from the four "
                              "marks (not possible for a camera looking straight down)")
        grid.addWidget(QLabel("robot floor x"), 0, 0)
        grid.addWidget(self.robot_x, 0, 1)
        grid.addWidget(QLabel("robot floor y"), 1, 0)
        grid.addWidget(self.robot_y, 1, 1)
        grid.addWidget(QLabel("focal length"), 2, 0)
        grid.addWidget(self.focal, 2, 1)
        self.floor_lens = QComboBox()
        for text, key in (("none: fixed homography", "none"),
                          ("the project's lens file", "project"),
                          ("the source's lens file", "source")):
            self.floor_lens.addItem(text, key)
        self.floor_lens.setToolTip(
            "A camera that zooms: K and distortion from a lens file at its zoom/focus "
            "encoders, the pose from the four marks (PnP), so that zooming keeps d; 'none' "
            "keeps a fixed homography (right only at the zoom the marks were clicked at)")
        self.floor_zoom = QSpinBox()
        self.floor_focus = QSpinBox()
        for box in (self.floor_zoom, self.floor_focus):
            box.setRange(0, 2**31 - 1)
            box.setToolTip("the overhead camera's encoder counts when the marks were taken "
                           "(filled from the taken frame where the camera reports them)")
            box.setMinimumWidth(70)  # not as wide as 2^31 - 1: the form fits a narrow tab
        grid.addWidget(QLabel("lens"), 3, 0)
        grid.addWidget(self.floor_lens, 3, 1)
        grid.addWidget(QLabel("zoom / focus (marks)"), 4, 0)
        enc_row = QHBoxLayout()
        enc_row.addWidget(self.floor_zoom)
        enc_row.addWidget(self.floor_focus)
        grid.addLayout(enc_row, 4, 1)
        self._source_lens: Any = None  # the taken frame's calibration's lens, if any
        fv.addLayout(grid)
        self.floor_save_button = QPushButton("Calibrate and save to project")
        self.floor_save_button.setToolTip("Compute the floor homography and keep it in the "
                                          "studio project (File > Save writes it); the "
                                          "tracker uses it from the next Start")
        self.floor_save_button.clicked.connect(self.save_floor_calibration)
        fv.addWidget(self.floor_save_button)
        self.floor_status = QLabel("No floor calibration.")
        self.floor_status.setWordWrap(True)
        self.floor_status.setObjectName("readout")
        fv.addWidget(self.floor_status)
        fv.addStretch(1)

    def _show_loss_plot(self) -> None:
        """The plot of the loss test the parameters select (contrast z or likelihood P)."""
        contrast = self.form.params.loss_test == "contrast"
        self.z_plot.setVisible(contrast)
        self.p_plot.setVisible(not contrast)

    @Slot()
    def take_overhead(self) -> None:
        """The second view of the source's first frame (and a source's own calibration)."""
        from engine.errors import StudioTrackError
        from engine.floor import OverheadView
        from engine.sources import open_source

        try:
            with open_source(self.source_edit.text()) as src:
                frame = next(iter(src.frames()), None)
        except (StudioTrackError, OSError) as exc:
            self._say(f"cannot take the overhead frame: {exc}", "error")
            return
        over = None if frame is None else frame.payload(OverheadView)
        if over is None:
            self._say("this source has no second view (try synthetic:...,views=2 or "
                      "twoview:front=...,over=...)", "warning")
            return
        self.set_overhead(np.array(over.color_bgr), over.floor_calibration,
                          over.lens_encoders)

    def set_overhead(self, image_bgr: np.ndarray, calib: Any = None,
                     encoders: Any = None) -> None:
        self.over_reference = image_bgr
        self.over_canvas.set_image(image_bgr)
        if encoders is not None:  # the camera reports its lens encoders at this frame
            self.floor_zoom.setValue(int(encoders.zoom_raw))
            self.floor_focus.setValue(int(encoders.focus_raw))
        if calib is not None and getattr(calib, "lens", None) is not None:
            self._source_lens = calib.lens
        if calib is not None and len(calib.image_points_px) == 4 and self.floor_calib is None:
            # the source knows its calibration (built-in studio): show it as the marks
            self._fill_floor(calib)
        h, w = image_bgr.shape[:2]
        self._say(f"overhead frame {w}x{h} taken: click four floor marks on it")

    def _fill_floor(self, calib: Any) -> None:
        self.over_canvas.set_floor_points(list(calib.image_points_px))
        for r, ((u, v), (x, y)) in enumerate(zip(calib.image_points_px, calib.floor_points_m,
                                                  strict=True)):
            for c, val in enumerate((u, v, x, y)):
                self.floor_table.item(r, c).setText(f"{val:.3f}" if c >= 2 else f"{val:.1f}")
        self.robot_x.setValue(calib.robot_floor_xy_m[0])
        self.robot_y.setValue(calib.robot_floor_xy_m[1])
        self.focal.setValue(calib.f_px or 0.0)
        if getattr(calib, "has_lens_model", False):
            self.floor_lens.setCurrentIndex(self.floor_lens.findData(
                "project" if calib.lens_from_project else "source"))
            self.floor_zoom.setValue(int(calib.encoders_raw[0]))
            self.floor_focus.setValue(int(calib.encoders_raw[1]))

    @Slot()
    def clear_floor_points(self) -> None:
        self.over_canvas.set_floor_points([])
        for r in range(4):
            for c in range(2):
                self.floor_table.item(r, c).setText("")

    @Slot(float, float)
    def _on_floor_point(self, x: float, y: float) -> None:
        n = len(self.over_canvas.floor_points)
        self.floor_table.item(n - 1, 0).setText(f"{x:.1f}")
        self.floor_table.item(n - 1, 1).setText(f"{y:.1f}")
        self._say(f"floor mark F{n} at ({x:.0f}, {y:.0f}) px"
                  + (" - type the four marks' floor coordinates, then Calibrate"
                     if n == 4 else ""))

    def _floor_table_values(self) -> tuple[list[tuple[float, float]], list[tuple[float, float]]]:
        img, flo = [], []
        for r in range(4):
            vals = []
            for c in range(4):
                text = self.floor_table.item(r, c).text().strip()
                try:
                    vals.append(float(text))
                except ValueError:
                    what = ("click it on the overhead picture" if c < 2 else
                            "type its floor coordinate in metres")
                    header = ("u (px)", "v (px)", "floor x (m)", "floor y (m)")[c]
                    raise ValueError(f"F{r + 1}: {header} is missing ({what})") from None
            img.append((vals[0], vals[1]))
            flo.append((vals[2], vals[3]))
        return img, flo

    @Slot()
    def save_floor_calibration(self) -> Any:
        """Calibrate from the table; keep it in the project (and for the next run)."""
        from engine.errors import CalibrationError
        from engine.floor import calibrate_floor

        try:
            img, flo = self._floor_table_values()
        except ValueError as exc:
            self._say(f"floor calibration: {exc}", "error")
            return None
        wh = None
        if self.over_reference is not None:
            wh = (self.over_reference.shape[1], self.over_reference.shape[0])
        choice = self.floor_lens.currentData()
        lens = None
        if choice == "project":
            lens = getattr(getattr(self.ctx, "project", None), "lens", None)
            if lens is None or not lens.complete:
                self._say("floor calibration: the project has no complete lens file (Lens "
                          "page), choose 'none' or the source's", "error")
                return None
        elif choice == "source":
            lens = self._source_lens
            if lens is None:
                self._say("floor calibration: the source's second view has no lens file "
                          "(try synthetic:...,views=2,over_zoom=sweep), choose 'none'",
                          "error")
                return None
        try:
            calib = calibrate_floor(img, flo, (self.robot_x.value(), self.robot_y.value()), wh,
                                    self.focal.value() or None, lens=lens,
                                    encoders_raw=(self.floor_zoom.value(),
                                                  self.floor_focus.value()),
                                    lens_from_project=choice == "project")
        except CalibrationError as exc:
            self._say(str(exc), "error")
            return None
        self.floor_calib = calib
        model = calib.camera_at()
        if model is not None:
            T = model[1]
            C = -T[:3, :3].T @ T[:3, 3]
            where = (f"camera at ({C[0]:.2f}, {C[1]:.2f}) m, {C[2]:.2f} m above the floor "
                     f"(lens model, marks reprojected to {calib.pnp_rms_px:.2f} px at zoom "
                     f"{calib.encoders_raw[0]}, focus {calib.encoders_raw[1]})")
        elif (P := calib.camera()) is not None:
            C = -np.linalg.solve(P[:, :3], P[:, 3])
            where = f"camera at ({C[0]:.2f}, {C[1]:.2f}) m, {C[2]:.2f} m above the floor"
        else:
            where = "camera not recovered (floor positions from the feet only)"
        edit = getattr(self.ctx, "edit_project", None)
        if edit is not None:
            edit(lambda proj: setattr(proj, "floor_calibration", calib))
            saved = "kept in the project (File > Save writes it)"
        else:
            saved = "kept for this session (open or create a project to save it)"
        self.floor_status.setText(f"Floor calibration OK: {where}; {saved}.")
        self._say("floor calibration computed", "info")
        return calib

    def _floor_for_run(self) -> str:
        """A floor.json for the tracker: this page's calibration, else the project's."""
        from engine.floor import save_floor_calibration

        calib = self.floor_calib
        project = getattr(self.ctx, "project", None)
        if calib is None and project is not None:
            calib = getattr(project, "floor_calibration", None)
        if calib is None:
            return ""
        path = self.model_dir().parent / "floor.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        save_floor_calibration(path, calib)
        return str(path)

    # ------------------------------------------------------------------ persistence
    def model_dir(self) -> Path:
        """``<project>/presenter/frontal`` if a project is open, else a session folder."""
        project = getattr(self.ctx, "project", None)
        root = getattr(project, "folder", None) or getattr(project, "path", None)
        if root is not None:
            return Path(root) / "presenter" / "frontal"
        if self._session_dir is None:
            self._session_dir = Path(tempfile.mkdtemp(prefix="studiotrack-presenter-"))
        return self._session_dir / "frontal"

    @Slot()
    def save_model(self) -> Path | None:
        from engine.presenter.model import save_model

        model = self.build_model()
        if model is None or self.reference is None:
            return None
        path = save_model(self.model_dir(), model, self.reference)
        self._say(f"model saved to {path}")
        return path

    @Slot()
    def load_model_dialog(self) -> None:
        from PySide6.QtWidgets import QFileDialog

        folder = QFileDialog.getExistingDirectory(self, "Presenter model folder",
                                                  str(self.model_dir()))
        if folder:
            self.load_model_from(Path(folder))

    def load_model_from(self, folder: Path) -> None:
        from engine.presenter import PresenterError
        from engine.presenter.model import load_model

        try:
            model, img = load_model(folder)
        except PresenterError as exc:
            self._say(str(exc), "error")
            return
        self.set_reference(img)
        self.canvas.set_model(model.main_xywh, [(p.name, p.xywh) for p in model.patches])

    # ------------------------------------------------------------------ tracking
    @Slot()
    def start_tracking(self) -> bool:
        if self.run.is_running:
            self._say("a run is active: stop it first", "warning")
            return False
        path = self.save_model()
        if path is None:
            return False
        params = dataclasses.replace(self.form.params, model_path=str(path.parent),
                                     floor_path=self._floor_for_run())
        self.form.set_params(params)
        self.hist_p.clear()
        self.hist_xy.clear()
        self._frames = 0
        self.canvas.show_model = False
        self.run.start(self.source_edit.text(), "presenter", params,
                       realtime=self.realtime_check.isChecked(), page="Presenter")
        self._update_buttons()
        return True

    @Slot()
    def stop_tracking(self) -> None:
        self.run.stop()

    def _update_buttons(self) -> None:
        running = self.run.is_running
        self.start_button.setEnabled(not running)
        self.start_button.setToolTip("Save the model and track it" if not running else
                                     "A run is active: stop it first")
        self.stop_button.setEnabled(running)

    @Slot(object)
    def _on_started(self, info: Any) -> None:
        self._update_buttons()
        if self.follows(info):
            self._say("tracking started", "info")

    @Slot(str)
    def _on_failed(self, message: str) -> None:
        self._update_buttons()
        req = self.run.request
        if req is not None and req.page == "Presenter":
            self._say(f"tracking failed: {message}", "error")

    @Slot(object)
    def _on_finished(self, status: Any) -> None:
        self.run_ended(status)

    def run_ended(self, status: Any) -> None:
        """Nothing stale after Stop: the light, read-outs and live overlay clear."""
        self.latest = None
        self.canvas.show_model = True
        self.canvas.set_live([], None, None, None, None)
        self.over_canvas.set_live([], None, None, None, None)
        # the model is drawn on its own reference again, not on the run's last frame
        if self.reference is not None:
            self.canvas.set_image(self.reference)
        if self.over_reference is not None:
            self.over_canvas.set_image(self.over_reference)
        self.light.set_state(None, "STOPPED")
        self.readout.setText("Not tracking.")
        self.control_label.setText("Robot-camera control: shown while tracking.")
        if self.message.text() == "tracking started":  # said at Start: not true any more
            self.message.setText("tracking stopped")
            self.message.setStyleSheet("color: #b9bec7;")
        self.canvas.update()
        self._update_buttons()

    def run_stalled(self, message: str) -> None:
        """No record for a while: LOST (as the header says); the box is not live."""
        self.light.set_state(TrackState.LOST, "LOST · engine stalled")
        self.readout.setText(f"⚠ {message}: the box shown is the last one, not live")

    def run_faulted(self, status: Any) -> None:
        """The engine raised: ERROR; the held box goes (it is not live), the reason shows."""
        error = getattr(status, "error", None) or self.run.last_error or "engine error"
        self.canvas.set_live([], None, None, None, None)
        self.over_canvas.set_live([], None, None, None, None)
        self.light.set_state(None, "ERROR")
        self.readout.setText(f"⚠ {error}\nnot tracking: the outputs hold the last position "
                             "flagged LOST — press Stop")
        self._update_buttons()

    def run_changed(self, info: Any) -> None:
        self._update_buttons()

    @Slot(object)
    def _on_params(self, params: Any) -> None:
        self._show_loss_plot()
        info = self.run.run_info
        if self.run.is_running and self.follows(info):
            self.run.set_params(params)
        if self.reference is not None and self.canvas.main is not None:
            self._on_rects_changed()

    def add_samples(self, samples: list[Any], missed: int) -> None:
        from engine.trackers.presenter import PresenterDetails

        for smp in samples:
            self._frames += 1
            ex = smp.details if isinstance(smp.details, PresenterDetails) else None
            if ex is None:
                continue
            self.hist_p.append((max(ex.p_col, 1e-12), max(ex.p_min, 1e-12),
                                max(ex.p_ref, 1e-12)))
            raw, filt = ex.raw_xyh, ex.filtered_xyh
            d = ex.d_m
            self.hist_xy.append((raw[0], filt[0], raw[1], filt[1],
                                 float("nan") if d is None else d, ex.loss_z,
                                 float("nan") if ex.overhead_loss_z is None
                                 else ex.overhead_loss_z))

    @Slot()
    def redraw(self) -> None:
        """Draw now (tests, screenshots): what the display clock would draw."""
        self.display_tick()

    def draw(self, rec: Any) -> None:
        from engine.trackers.presenter import PresenterDetails

        self.latest = rec
        res = rec.result
        self.canvas.set_image(rec.frame.color_bgr)
        ov = res.overlay
        boxes: list[tuple[Any, str]] = []
        cross = None
        ex = res.details_as(PresenterDetails)
        if ov is not None:
            if self.boxes_radio.isChecked():
                boxes = list(zip(ov.boxes_xywh, ov.box_labels, strict=False))
            else:
                cross = ov.crosshair_uv
        parts = weights = None
        if ov is not None and self.particles_check.isChecked():
            parts, weights = ov.points_uv, ov.point_weights
        target = None
        cmd = ex.control if ex is not None else None
        if cmd is not None:
            target = (cmd.target_x_px, cmd.target_y_px)
        self.canvas.set_live(boxes, cross, parts, weights, target,
                             lost=res.state is TrackState.LOST)
        self._draw_overhead(rec, ex)
        self.light.set_state(res.state)
        st = self.run.status()
        fps = st.fps if st is not None else rec.fps
        if ex is not None:
            self.readout.setText(self._readout(ex, res, fps))
        elif res.message:
            self.readout.setText(res.message)
        if cmd is not None:
            p = self.form.params
            udp = (f"UDP -> {p.control_host}:{p.control_port}" if p.control_udp
                   else "UDP off")
            robot = next((h for h in (st.sinks if st is not None else ())
                          if h.name == "robot camera"), None)
            if robot is not None and robot.level.is_bad:
                udp += f" FAILING: {robot.message}"
            ed = "-" if cmd.e_d_m is None else f"{cmd.e_d_m:+.2f} m"
            self.control_label.setText(
                f"e_f = [{cmd.e_f_px[0]:+.1f}, {cmd.e_f_px[1]:+.1f}] px   e_d = {ed}\n"
                f"v = [{cmd.v_x_px_s:+.0f}, {cmd.v_y_px_s:+.0f}] px/s, "
                f"{cmd.v_d_m_s:+.2f} m/s   {udp}")
        if self.hist_p:
            arr = np.asarray(self.hist_p)
            t = np.arange(len(arr))
            self.p_curve.setData(t, arr[:, 0])
            self.pmin_curve.setData(t, arr[:, 1])
            self.pref_curve.setData(t, arr[:, 2])
            xy = np.asarray(self.hist_xy)
            self.x_raw.setData(t, xy[:, 0])
            self.x_f.setData(t, xy[:, 1])
            self.y_raw.setData(t, xy[:, 2])
            self.y_f.setData(t, xy[:, 3])
            ok = np.isfinite(xy[:, 4])
            self.d_curve.setData(t[ok], xy[ok, 4])
            ok5 = np.isfinite(xy[:, 5])
            self.z_curve.setData(t[ok5], xy[ok5, 5])
            okz = np.isfinite(xy[:, 6])
            self.z_over.setData(t[okz], xy[okz, 6])
            thr = self.form.params.loss_contrast
            self.zmax_curve.setData([t[0], t[-1]], [thr, thr])
            # short: a long title widens the plot beyond its slot
            self.z_plot.setTitle(f"Loss z, LOST > {thr:.2f}")
            self.d_plot.setTitle("Floor distance d" if ok.any() else "d: no second view")


    def _readout(self, ex: Any, res: Any, fps: float) -> str:
        """The numbers of the drawn frame: the loss test the tracker runs, the views, d."""
        p = self.form.params
        if p.loss_test == "contrast":
            z = "-" if not np.isfinite(ex.loss_z) else f"{ex.loss_z:.2f}"
            test = f"contrast z {z} (LOST above {p.loss_contrast:.2f})"
        else:
            test = f"P {ex.p_col:.3g}   Pref {ex.p_ref:.3g}   Pmin {ex.p_min:.3g}"
        lines = [f"{res.state.value}: {test}"]
        if ex.overhead_state is not None:
            lines.append(f"frontal {ex.frontal_state}   overhead {ex.overhead_state}")
        if ex.floor_xy_m is not None:
            h = "-" if ex.height_m is None else f"{ex.height_m:.2f} m"
            d = "-" if ex.d_m is None else f"{ex.d_m:.2f} m"
            # d on its own line: on one with the floor position it wrapped between "d" and
            # its value in the panel's width at 1280x800
            lines.append(f"d {d} from the robot")
            lines.append(f"floor ({ex.floor_xy_m[0]:+.2f}, {ex.floor_xy_m[1]:+.2f}) m   "
                         f"height {h}")
        lines.append(f"particles {ex.n_particles}   lost frames {ex.lost_frames}")
        lines.append(f"jitter lag {ex.lag_s:.2f} s   {fps:.0f} fps")
        return "\n".join(lines)

    def _draw_overhead(self, rec: Any, ex: Any) -> None:
        from engine.floor import OverheadView

        over = rec.frame.payload(OverheadView)
        if over is None:
            return
        self.over_canvas.set_image(over.color_bgr)
        boxes = []
        if ex is not None and ex.overhead_box_xywh is not None:
            label = f"presenter {ex.overhead_state}"  # short: the picture is narrow
            boxes.append((ex.overhead_box_xywh, label))
        self.over_canvas.set_live(boxes, None, None, None, None)


def _factory(ctx: Any) -> QWidget:
    return PresenterPage(ctx)


PAGES = (
    PageSpec(
        title="Presenter",
        order=20,
        factory=_factory,
        tooltip="Presenter tracking (VR-TV multi-patch particle filter): model set-up, live "
        "tuning, loss handling, robot-camera control",
        trackers=("presenter",),
    ),
)
