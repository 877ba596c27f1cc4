"""The Lens page: the studio project's lens file, made one zoom/focus sample at a time.

- Samples table (zoom, focus, focal length mm/px, k1, k2, entrance pupil, rms, note);
  Delete removes the selected rows; Import/Export read and write lens JSON; "Fixed lens"
  makes a one-sample file from a ``camera.json``.
- Calibrate a sample: the encoder values it belongs to (typed, or "Use live encoders" from
  the running source's frames; "on air" uses the typed values for frames without
  encoders), chessboard views (image files, or - for the built-in studio's zoom lens -
  rendered views at those encoders), pattern and square size; Calibrate adds the sample
  (OpenCV, k1 k2; k3 and tangential fixed). "Sample from PTZ calibration" makes the sample
  from the project's pan-tilt calibration instead (the PTZ page's DLT and lens lines:
  :func:`engine.ptz.lens_sample.lens_sample_from_ptz`).
- Curves: the interpolated focal length and k1 over the zoom axis with the samples as dots
  and the live encoder as a line.
- Camera offset: the tracked point -> nodal point transform (metres, degrees) saved in the
  project and applied before every output; the project's studio frame (from the Outputs
  page's floor points or the PTZ page's DLT) is shown and can be reset.

Every change goes into ``ctx.project`` (unsaved until File > Save); a lens problem (missing
corner, unreadable file) is one line under the table and in the log.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QAbstractItemView,
    QCheckBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from app.pages import PageSpec
from app.pages._base import Page
from widgets.plot_grid import GridLines

COLUMNS = ("zoom", "focus", "f (mm)", "f (px)", "k1", "k2", "pupil (m)", "rms (px)", "note")


class LensPage(Page):
    """See the module docstring."""

    refresh_interval_s = 0.5

    def __init__(self, ctx: Any, parent: QWidget | None = None) -> None:
        super().__init__(ctx, parent)
        self.setObjectName("page_lens")
        self.views: list[np.ndarray] = []
        self.live_encoders: tuple[int, int] | None = None
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setObjectName("lens_samples")
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.
                                                           ResizeToContents)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.status = QLabel("")
        self.status.setObjectName("lens_status")
        self.status.setWordWrap(True)
        buttons = QHBoxLayout()
        for text, name, slot in (("Delete selected", "lens_delete", self.delete_selected),
                                 ("Import…", "lens_import", self._import),
                                 ("Export…", "lens_export", self._export),
                                 ("Fixed lens from camera.json…", "lens_fixed", self._fixed)):
            b = QPushButton(text)
            b.setObjectName(name)
            b.clicked.connect(slot)
            buttons.addWidget(b)
        left = QWidget()
        ll = QVBoxLayout(left)
        ll.addWidget(QLabel("<b>Lens file samples</b> (raw encoder counts)"))
        ll.addWidget(self.table, 1)
        ll.addLayout(buttons)
        ll.addWidget(self.status)
        ll.addWidget(self._calibrate_box())
        ll.addWidget(self._offset_box())

        self.plots = pg.GraphicsLayoutWidget()
        self.f_plot = self.plots.addPlot(0, 0, title="Focal length vs zoom")
        self.k_plot = self.plots.addPlot(1, 0, title="k1 vs zoom")
        for pl, unit in ((self.f_plot, "f (mm)"), (self.k_plot, "k1")):
            pl.setLabel("bottom", "zoom encoder (raw)")
            pl.setLabel("left", unit)
            GridLines(pl)  # cheap to repaint (widgets.plot_grid)
            for side in ("bottom", "left"):
                pl.getAxis(side).enableAutoSIPrefix(False)
        self.f_curve = self.f_plot.plot(pen=pg.mkPen(90, 170, 255, width=2))
        self.k_curve = self.k_plot.plot(pen=pg.mkPen(255, 170, 60, width=2))
        self.f_dots = pg.ScatterPlotItem(size=9, brush=pg.mkBrush(230, 230, 230))
        self.k_dots = pg.ScatterPlotItem(size=9, brush=pg.mkBrush(230, 230, 230))
        self.f_plot.addItem(self.f_dots)
        self.k_plot.addItem(self.k_dots)
        self.f_live = pg.InfiniteLine(angle=90, pen=pg.mkPen(80, 220, 80, width=1.5))
        self.k_live = pg.InfiniteLine(angle=90, pen=pg.mkPen(80, 220, 80, width=1.5))
        for pl, ln in ((self.f_plot, self.f_live), (self.k_plot, self.k_live)):
            pl.addItem(ln)
            ln.setVisible(False)
        split = QSplitter()
        split.addWidget(left)
        split.addWidget(self.plots)
        split.setSizes([640, 560])
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        lay.addWidget(split)
        ctx.project_changed.connect(lambda _p: (self.show_lens(), self.show_offsets()))
        self.show_lens()
        self.show_offsets()

    # ------------------------------------------------------------------ widgets
    def _calibrate_box(self) -> QGroupBox:
        box = QGroupBox("Calibrate one sample")
        form = QFormLayout(box)
        self.zoom_spin = QSpinBox()
        self.zoom_spin.setObjectName("lens_zoom")
        self.zoom_spin.setRange(0, 0xFFFFFF)
        self.focus_spin = QSpinBox()
        self.focus_spin.setObjectName("lens_focus")
        self.focus_spin.setRange(0, 0xFFFFFF)
        enc = QHBoxLayout()
        enc.addWidget(QLabel("zoom"))
        enc.addWidget(self.zoom_spin)
        enc.addWidget(QLabel("focus"))
        enc.addWidget(self.focus_spin)
        use_live = QPushButton("Use live encoders")
        use_live.setObjectName("lens_use_live")
        use_live.setToolTip("the zoom/focus encoders of the running source's latest frame")
        use_live.clicked.connect(self.use_live_encoders)
        enc.addWidget(use_live)
        self.typed_check = QCheckBox("on air")
        self.typed_check.setObjectName("lens_typed_on_air")
        self.typed_check.setToolTip("use these typed encoders for sources whose frames carry "
                                    "none (a camera without lens encoder); off: the lens "
                                    "file's first sample")
        self.typed_check.toggled.connect(self.apply_typed)
        self.zoom_spin.valueChanged.connect(lambda _v: self._typed_changed())
        self.focus_spin.valueChanged.connect(lambda _v: self._typed_changed())
        enc.addWidget(self.typed_check)
        form.addRow("Encoders", enc)
        self.pattern_edit = QLineEdit("9x6")
        self.square_spin = QDoubleSpinBox()
        self.square_spin.setDecimals(4)
        self.square_spin.setRange(0.001, 1.0)
        self.square_spin.setValue(0.05)
        self.square_spin.setSuffix(" m")
        self.pupil_spin = QDoubleSpinBox()
        self.pupil_spin.setDecimals(3)
        self.pupil_spin.setRange(-2.0, 2.0)
        self.pupil_spin.setSuffix(" m")
        self.pupil_spin.setToolTip("entrance pupil along the optical axis (+ towards the scene)")
        board = QHBoxLayout()
        board.addWidget(QLabel("pattern"))
        board.addWidget(self.pattern_edit)
        board.addWidget(QLabel("square"))
        board.addWidget(self.square_spin)
        board.addWidget(QLabel("pupil"))
        board.addWidget(self.pupil_spin)
        form.addRow("Board", board)
        views = QHBoxLayout()
        self.views_label = QLabel("0 views")
        self.views_label.setObjectName("lens_views")
        add = QPushButton("Add images…")
        add.clicked.connect(self._add_images)
        render = QPushButton("Render views (built-in zoom lens)")
        render.setObjectName("lens_render_views")
        render.setToolTip("chessboard views through the built-in studio's known zoom lens at "
                          "these encoders (the simulated studio has no board to film)")
        render.clicked.connect(self.render_views)
        clear = QPushButton("Clear")
        clear.clicked.connect(self.clear_views)
        for w in (self.views_label, add, render, clear):
            views.addWidget(w)
        form.addRow("Views", views)
        self.calibrate_button = QPushButton("Calibrate sample")
        self.calibrate_button.setObjectName("lens_calibrate")
        self.calibrate_button.clicked.connect(self.calibrate)
        self.from_ptz_button = QPushButton("Sample from PTZ calibration (DLT + lens lines)")
        self.from_ptz_button.setObjectName("lens_from_ptz")
        self.from_ptz_button.setToolTip(
            "a sample at these encoders from the project's pan-tilt calibration (PTZ page: "
            "Save head to project, Save distortion to project): focal length and principal "
            "point from the DLT, Brown-Conrady k1 k2 k3 p1 p2 fitted to the line-based model; "
            "lens lines alone keep the lens file's focal length at these encoders")
        self.from_ptz_button.clicked.connect(self.sample_from_ptz)
        make = QHBoxLayout()
        make.addWidget(self.calibrate_button)
        make.addWidget(self.from_ptz_button)
        form.addRow(make)
        return box

    def _offset_box(self) -> QGroupBox:
        box = QGroupBox("Camera offset (tracked point → nodal point) and studio frame")
        box.setToolTip("applied to the pose before every output (FreeD, OpenTrackIO): "
                       "T_world_nodal = T_world_tracked · T_tracked_nodal, then the studio "
                       "frame; axes of the tracked camera: x right, y down, z forward")
        form = QFormLayout(box)
        self.offset_spins: dict[str, QDoubleSpinBox] = {}
        rows = ((("x_m", "x"), ("y_m", "y"), ("z_m", "z")),
                (("pan_deg", "pan"), ("tilt_deg", "tilt"), ("roll_deg", "roll")))
        for label, row in zip(("Offset (m)", "Rotation (°)"), rows, strict=True):
            line = QHBoxLayout()
            for key, text in row:
                sp = QDoubleSpinBox()
                sp.setObjectName(f"lens_offset_{key}")
                metres = key.endswith("_m")
                sp.setDecimals(4 if metres else 2)
                limit = 10.0 if metres else 180.0
                sp.setRange(-limit, limit)
                sp.setSingleStep(0.005 if metres else 0.5)
                line.addWidget(QLabel(text))
                line.addWidget(sp, 1)
                self.offset_spins[key] = sp
            form.addRow(label, line)
        btns = QHBoxLayout()
        save = QPushButton("Save offset to project")
        save.setObjectName("lens_offset_save")
        save.clicked.connect(self.save_offset)
        reset = QPushButton("Studio frame: identity")
        reset.setObjectName("lens_studio_reset")
        reset.setToolTip("forget the project's studio frame (set one from three floor points "
                         "on the Outputs page, or from a DLT on the PTZ page)")
        reset.clicked.connect(self.reset_studio_frame)
        btns.addWidget(save)
        btns.addWidget(reset)
        form.addRow(btns)
        self.offset_status = QLabel("")
        self.offset_status.setObjectName("lens_offset_status")
        self.offset_status.setWordWrap(True)
        form.addRow(self.offset_status)
        return box

    # ------------------------------------------------------------------ project
    def _lens(self) -> Any:
        proj = self.ctx.project
        return None if proj is None else proj.lens

    def _set_lens(self, lens: Any, what: str) -> None:
        self.ctx.edit_project(lambda proj: setattr(proj, "lens", lens))
        self.show_lens()
        self.status.setText(f"{self.status.text()}<br>Last change: {what}.")
        self.ctx.log.info(f"lens: {what}")

    def show_offsets(self) -> None:
        """The project's nodal offset in the spin boxes, its studio frame in words."""
        proj = self.ctx.project
        off = getattr(proj, "nodal_offset", None)
        for key, sp in self.offset_spins.items():
            sp.blockSignals(True)
            sp.setValue(0.0 if off is None else float(getattr(off, key)))
            sp.blockSignals(False)
        sf = getattr(proj, "studio_frame", None)
        if sf is None:
            frame = "studio frame: the tracker's world (identity)"
        else:
            o = sf.matrix[:3, 3]
            frame = f"studio frame: origin at ({o[0]:.3f}, {o[1]:.3f}, {o[2]:.3f}) m"
        nodal = "no nodal offset" if off is None or off.is_identity else (
            f"nodal offset ({off.x_m:.4f}, {off.y_m:.4f}, {off.z_m:.4f}) m, "
            f"{off.pan_deg:.2f}/{off.tilt_deg:.2f}/{off.roll_deg:.2f}°")
        where = "in the project" if proj is not None else "no project yet"
        self.offset_status.setText(f"{nodal}; {frame} ({where})")

    def _edit_project(self, what: str, change: Any) -> None:
        self.ctx.edit_project(change)
        self.show_offsets()
        self.ctx.log.info(what)

    def save_offset(self) -> None:
        from engine.errors import StudioTrackError
        from engine.outputs.studio_frame import CameraOffset

        try:
            off = CameraOffset(**{k: float(sp.value()) for k, sp in self.offset_spins.items()})
        except StudioTrackError as exc:
            self.offset_status.setText(f"<span style='color:#ff8080'>{exc}</span>")
            return

        def change(p: Any) -> None:
            p.nodal_offset = None if off.is_identity else off

        self._edit_project(f"nodal offset saved in the project: {off.to_json_dict()}", change)

    def reset_studio_frame(self) -> None:
        proj = self.ctx.project
        if proj is None or proj.studio_frame is None:
            return

        def change(p: Any) -> None:
            p.studio_frame = None

        self._edit_project("studio frame reset to the tracker's world", change)
        # the outputs in force keep the old frame until told: identity now
        from dataclasses import replace

        from engine.outputs.studio_frame import StudioFrame

        self.ctx.run.apply_outputs(replace(self.ctx.run.outputs_config, studio=StudioFrame()))

    def show_lens(self) -> None:
        from engine.lens import LensError

        lens = self._lens()
        samples = [] if lens is None else list(lens.samples)
        self.table.setRowCount(len(samples))
        for r, s in enumerate(samples):
            vals = [str(s.zoom_raw), str(s.focus_raw), f"{lens.focal_length_mm(s.fx_px):.3f}",
                    f"{s.fx_px:.1f}", f"{s.k1:+.4f}", f"{s.k2:+.4f}",
                    f"{s.entrance_pupil_m:.3f}", "–" if s.rms_px is None else f"{s.rms_px:.3f}",
                    s.note]
            for c, text in enumerate(vals):
                it = QTableWidgetItem(text)
                if c < 8:
                    it.setTextAlignment(Qt.AlignmentFlag.AlignRight
                                        | Qt.AlignmentFlag.AlignVCenter)
                self.table.setItem(r, c, it)
        if lens is None:
            self.status.setText("No lens file in the project: calibrate a sample, import a "
                                "file, or make a fixed lens from camera.json.")
            for item in (self.f_curve, self.k_curve):
                item.setData([], [])
            self.f_dots.setData([], [])
            self.k_dots.setData([], [])
            return
        try:
            lens.check_complete()
        except LensError as exc:
            self.status.setText(f"<span style='color:#ff8080'>{exc}</span>")
            return
        z, f = lens.curve("focal_length_mm", 200)
        _, k1 = lens.curve("k1", 200)
        self.f_curve.setData(z, f)
        self.k_curve.setData(z, k1)
        fa = lens.focus_axis[0]
        pts = [s for s in samples if s.focus_raw == fa]
        self.f_dots.setData([s.zoom_raw for s in pts],
                            [lens.focal_length_mm(s.fx_px) for s in pts])
        self.k_dots.setData([s.zoom_raw for s in pts], [s.k1 for s in pts])
        self.status.setText(
            f"{lens.name}: {len(samples)} sample(s) on {len(lens.zoom_axis)} zoom x "
            f"{len(lens.focus_axis)} focus values, {lens.width}x{lens.height} px, sensor "
            f"{lens.sensor_width_mm:g} mm; used on air by runs of this project.")

    # --------------------------------------------------------------- actions
    def use_live_encoders(self) -> None:
        if self.live_encoders is None:
            self.status.setText("The running source reports no lens encoders (type them).")
            return
        self.zoom_spin.setValue(self.live_encoders[0])
        self.focus_spin.setValue(self.live_encoders[1])

    def _typed_changed(self) -> None:
        if self.typed_check.isChecked():
            self.apply_typed(True)

    def apply_typed(self, on: bool) -> None:
        """Typed encoders on air (frames without their own) or back to the first sample."""
        self.ctx.lens_typed = ((self.zoom_spin.value(), self.focus_spin.value()) if on
                               else None)
        self.ctx.apply_project_setup()

    def clear_views(self) -> None:
        self.views = []
        self.views_label.setText("0 views")

    def _add_images(self) -> None:
        files, _ = QFileDialog.getOpenFileNames(self, "Chessboard images", "",
                                                "Images (*.png *.jpg *.jpeg *.bmp *.tif)")
        self.add_image_files([Path(f) for f in files])

    def add_image_files(self, files: list[Path]) -> None:
        from engine.errors import CalibrationError
        from engine.ptz.chessboard import read_calibration_image

        for f in files:
            try:
                self.views.append(read_calibration_image(f))
            except CalibrationError as exc:
                self.ctx.log.warning(str(exc))
        self.views_label.setText(f"{len(self.views)} views")

    def render_views(self, n: int = 12) -> None:
        from engine.studio.chessboard_view import calibration_views, render_chessboard
        from engine.studio.zoom import studio_zoom_lens

        lens = self._lens()
        w, h = (lens.width, lens.height) if lens is not None and lens.samples else (640, 480)
        cam = studio_zoom_lens(w, h).intrinsics_at(self.zoom_spin.value(),
                                                   self.focus_spin.value())
        poses = calibration_views(cam, n, (9, 6), 0.05, fill=0.7,
                                  seed=7 + self.zoom_spin.value())
        self.pattern_edit.setText("9x6")
        self.square_spin.setValue(0.05)
        self.views += [render_chessboard(cam, T, (9, 6), 0.05) for T in poses]
        self.views_label.setText(f"{len(self.views)} views")

    def calibrate(self) -> None:
        from engine.errors import StudioTrackError
        from engine.lens import LensError, LensFile
        from engine.ptz.chessboard import lens_sample_from_chessboard, parse_pattern

        try:
            sample, res = lens_sample_from_chessboard(
                self.views, self.zoom_spin.value(), self.focus_spin.value(),
                parse_pattern(self.pattern_edit.text()), self.square_spin.value(),
                entrance_pupil_m=self.pupil_spin.value())
            lens = self._lens()
            w, h = res.intrinsics.width, res.intrinsics.height
            if lens is None:
                lens = LensFile(w, h, (), name="studio lens")
            elif (lens.width, lens.height) != (w, h):
                raise LensError(f"views are {w}x{h}, the lens file is {lens.width}x"
                                f"{lens.height}")
        except StudioTrackError as exc:
            self.status.setText(f"<span style='color:#ff8080'>{exc}</span>")
            self.ctx.log.warning(f"lens sample: {exc}")
            return
        self._set_lens(lens.with_sample(sample),
                       f"sample zoom {sample.zoom_raw} focus {sample.focus_raw}: f "
                       f"{sample.fx_px:.1f} px, k1 {sample.k1:+.4f}, rms {res.rms_px:.3f} px "
                       f"({len(res.used_images)} views)")
        self.clear_views()

    def sample_from_ptz(self) -> None:
        """A sample at the typed encoders from the project's DLT and line-based distortion
        (:func:`engine.ptz.lens_sample.lens_sample_from_ptz`)."""
        from engine.errors import StudioTrackError
        from engine.lens import LensFile
        from engine.ptz.lens_sample import lens_sample_from_ptz

        lens = self._lens()
        try:
            sample, rep = lens_sample_from_ptz(
                getattr(self.ctx.project, "ptz", None), self.zoom_spin.value(),
                self.focus_spin.value(), lens=lens, entrance_pupil_m=self.pupil_spin.value())
            if lens is None:
                w, h = rep["image_size"]
                lens = LensFile(w, h, (), name="studio lens")
        except StudioTrackError as exc:
            self.status.setText(f"<span style='color:#ff8080'>{exc}</span>")
            self.ctx.log.warning(str(exc))
            return
        fit = (f", Brown-Conrady fit {rep['fit_rms_px']:.2f} px rms / {rep['fit_max_px']:.2f} "
               "px max" if rep.get("distortion_from") else ", no distortion model")
        self._set_lens(lens.with_sample(sample),
                       f"sample zoom {sample.zoom_raw} focus {sample.focus_raw} from the PTZ "
                       f"calibration ({rep['intrinsics_from']}): f {sample.fx_px:.1f} px, "
                       f"k1 {sample.k1:+.4f}{fit}")

    def delete_selected(self) -> None:
        lens = self._lens()
        if lens is None:
            return
        rows = sorted({i.row() for i in self.table.selectedIndexes()})
        keys = [(lens.samples[r].zoom_raw, lens.samples[r].focus_raw) for r in rows
                if r < len(lens.samples)]
        for z, f in keys:
            lens = lens.without_sample(z, f)
        if keys:
            self._set_lens(lens, f"deleted {len(keys)} sample(s)")

    def _import(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Import lens file", "", "Lens (*.json)")
        if path:
            self.import_file(Path(path))

    def import_file(self, path: Path) -> None:
        from engine.lens import LensError, LensFile

        try:
            lens = LensFile.load(path, require_complete=False)
        except LensError as exc:
            self.status.setText(f"<span style='color:#ff8080'>{exc}</span>")
            self.ctx.log.warning(str(exc))
            return
        self._set_lens(lens, f"imported {path}")

    def _export(self) -> None:
        if self._lens() is None:
            return
        path, _ = QFileDialog.getSaveFileName(self, "Export lens file", "lens.json",
                                              "Lens (*.json)")
        if path:
            self.export_file(Path(path))

    def export_file(self, path: Path) -> None:
        lens = self._lens()
        if lens is None:
            return
        try:
            lens.save(path)
        except OSError as exc:
            self.ctx.log.warning(f"{path}: {exc.strerror or exc}")
            return
        self.ctx.log.info(f"lens file written to {path}")

    def _fixed(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "camera.json", "", "camera (*.json)")
        if not path:
            return
        from engine.camera import load_camera_json
        from engine.errors import CalibrationError
        from engine.lens import LensFile

        try:
            cam = load_camera_json(path)
        except CalibrationError as exc:
            self.status.setText(f"<span style='color:#ff8080'>{exc}</span>")
            return
        self._set_lens(LensFile.fixed(cam, note=str(path)), f"fixed lens from {path}")

    def showEvent(self, event: Any) -> None:
        # other pages change the project's set-up too (the PTZ page's DLT studio frame)
        self.show_lens()
        self.show_offsets()
        super().showEvent(event)

    # ------------------------------------------------------------- run view
    def draw(self, record: Any) -> None:
        from engine.lens import LensEncoders, LensState

        st = record.frame.payload(LensState)
        enc = record.frame.payload(LensEncoders)
        if st is not None:
            self.live_encoders = (st.zoom_raw, st.focus_raw)
        elif enc is not None:
            self.live_encoders = (enc.zoom_raw, enc.focus_raw)
        if self.live_encoders is not None:
            for ln in (self.f_live, self.k_live):
                ln.setValue(self.live_encoders[0])
                ln.setVisible(True)

    def run_ended(self, status: Any) -> None:
        for ln in (self.f_live, self.k_live):
            ln.setVisible(False)


PAGES = (
    PageSpec(title="Lens", order=75, factory=LensPage,
             tooltip="the project's lens file: samples over zoom/focus, curves, import/export"),
)
