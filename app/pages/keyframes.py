"""Keyframes page: the operator's pre-show keyframe model workflow (Tykkälä 2014 sec. 6.1).

Record a sweep (incremental dense tracking adds keyframes, a live strip shows them), delete
or retake keyframes, append a second sweep; fuse depth (Fig. 10) with progress and cancel;
annotate points (the annotation editor) and run sparse bundle adjustment (Fig. 11) with
Apply / Revert; open the 3D view (viser on 127.0.0.1) and export PLY. Recording a sweep is a
run of the window's run owner (``ctx.run``: the status header, outputs and 3D view follow
it) with the sweep recorder as one of its sinks; fusion and SBA run on a job thread
(:class:`app.keyframe_jobs.JobThread`). Progress is drawn on the window's display clock
while the page is shown. The page keeps the latest results and the open project
(``ctx.project``, an :class:`engine.project.Project`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from PySide6.QtCore import QSize, Qt, QTimer, QUrl, Signal
from PySide6.QtGui import QDesktopServices, QIcon, QImage, QPixmap
from PySide6.QtWidgets import (
    QCheckBox,
    QFileDialog,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QListView,
    QListWidget,
    QListWidgetItem,
    QProgressBar,
    QPushButton,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from app.keyframe_jobs import JobThread
from app.pages import PageSpec
from app.pages._base import Page
from engine.keyframes.fusion import FusionParams
from engine.keyframes.sba import SBAParams
from engine.keyframes.sweep import SweepParams
from widgets.annotation_editor import AnnotationEditor
from widgets.param_form import ParamForm
from widgets.source_picker import SourcePicker

DEFAULT_SOURCE = "synthetic:frames=150,path=rail,cycle_s=10"


def _pixmap(gray: np.ndarray) -> QPixmap:
    g = np.ascontiguousarray(gray, dtype=np.uint8)
    h, w = g.shape
    return QPixmap.fromImage(QImage(g.data, w, h, w, QImage.Format.Format_Grayscale8).copy())


class KeyframesPage(Page):
    """Record / fuse / annotate / bundle-adjust / view the keyframe model."""

    job_finished = Signal(str)  # "record" | "fuse" | "sba" (tests wait on it)

    def __init__(self, ctx: Any, parent: QWidget | None = None) -> None:
        super().__init__(ctx, parent)
        self.job: JobThread | None = None
        self.sweep: Any | None = None  # the SweepRecorder sink of the sweep being recorded
        self._sweep_run = -1  # the run owner's epoch of that sweep
        self.job_kind = ""
        self.recording: Any | None = None  # last SweepRecording (frames kept for fusion)
        self.fusion: Any | None = None
        self.sba: Any | None = None
        self.sba_backup: Any | None = None  # store before Apply (for Revert)
        self.viewer: Any | None = None
        self._pending_progress: Any | None = None

        # ---- recording
        self.source = SourcePicker()
        self.source.set_spec(DEFAULT_SOURCE)
        self.sweep_form = ParamForm(SweepParams())
        self.record_button = QPushButton("Record sweep")
        self.record_button.setObjectName("record_button")
        self.stop_button = QPushButton("Stop")
        self.stop_button.setEnabled(False)
        self.append_box = QCheckBox("Append to the existing keyframes")
        self.state_label = QLabel("No sweep recorded.")
        self.state_label.setObjectName("sweep_state")
        self.state_label.setWordWrap(True)
        self.strip = QListWidget()
        self.strip.setObjectName("keyframe_strip")
        self.strip.setViewMode(QListView.ViewMode.IconMode)
        self.strip.setFlow(QListView.Flow.LeftToRight)
        self.strip.setWrapping(False)
        self.strip.setIconSize(QSize(128, 96))
        self.strip.setGridSize(QSize(170, 150))
        self.strip.setWordWrap(True)
        self.strip.setFixedHeight(172)
        self.strip.setMovement(QListView.Movement.Static)
        self.delete_button = QPushButton("Delete keyframe")
        self.retake_button = QPushButton("Retake (delete + append sweep)")
        self.record_button.clicked.connect(self.start_recording)
        self.stop_button.clicked.connect(self.stop_job)
        self.delete_button.clicked.connect(self.delete_selected_keyframe)
        self.retake_button.clicked.connect(self.retake_selected_keyframe)

        rec_box = QGroupBox("1. Record a sweep of the empty studio")
        rl = QVBoxLayout(rec_box)
        rl.addWidget(self.source)
        rl.addWidget(self.sweep_form)
        rl.addWidget(self.append_box)
        row = QHBoxLayout()
        row.addWidget(self.record_button)
        row.addWidget(self.stop_button)
        rl.addLayout(row)
        rl.addWidget(self.state_label)

        # ---- fusion
        self.fusion_form = ParamForm(FusionParams())
        self.fuse_button = QPushButton("Fuse depth")
        self.fuse_button.setObjectName("fuse_button")
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setEnabled(False)
        self.progress = QProgressBar()
        self.progress.setObjectName("job_progress")
        self.fusion_table = QTableWidget(0, 6)
        self.fusion_table.setHorizontalHeaderLabels(
            [
                "kf",
                "frames",
                "holes\nbefore",
                "holes\nafter",
                "noise mm\nbefore",
                "noise mm\nafter",
            ]
        )
        self.fusion_table.verticalHeader().setVisible(False)
        _fit_columns(self.fusion_table)
        self.fuse_button.clicked.connect(self.start_fusion)
        self.cancel_button.clicked.connect(self.stop_job)
        fus_box = QGroupBox("2. Depth map fusion (Fig. 10)")
        fl = QVBoxLayout(fus_box)
        fl.addWidget(self.fusion_form)
        row = QHBoxLayout()
        row.addWidget(self.fuse_button)
        row.addWidget(self.cancel_button)
        fl.addLayout(row)
        fl.addWidget(self.fusion_table)

        # ---- SBA
        self.sba_button = QPushButton("Run SBA")
        self.sba_button.setObjectName("sba_button")
        self.apply_button = QPushButton("Apply")
        self.revert_button = QPushButton("Revert")
        self.apply_button.setEnabled(False)
        self.revert_button.setEnabled(False)
        self.sba_label = QLabel("Annotate points (tab 'Annotate'), then run SBA.")
        self.sba_label.setObjectName("sba_label")
        self.sba_label.setWordWrap(True)
        # no pose prior by default: the prior pulls towards the current poses, i.e. towards
        # the very drift SBA should remove (a 2 cm / 0.5 deg prior kept ~half of an injected
        # 1-3 cm error); the operator spreads points over the drifted keyframes instead
        self.sba_form = ParamForm(SBAParams())
        self.sba_table = QTableWidget(0, 4)
        self.sba_table.setHorizontalHeaderLabels(
            ["kf", "moved\n(mm)", "turned\n(deg)", "RMSE before /\nafter (px)"]
        )
        self.sba_table.verticalHeader().setVisible(False)
        _fit_columns(self.sba_table)
        self.sba_button.clicked.connect(self.start_sba)
        self.apply_button.clicked.connect(self.apply_sba)
        self.revert_button.clicked.connect(self.revert_sba)
        sba_box = QGroupBox("3. Sparse bundle adjustment (Fig. 11)")
        sl = QVBoxLayout(sba_box)
        row = QHBoxLayout()
        for b in (self.sba_button, self.apply_button, self.revert_button):
            row.addWidget(b)
        sl.addWidget(self.sba_form)
        sl.addLayout(row)
        sl.addWidget(self.sba_label)
        sl.addWidget(self.sba_table)

        # ---- 3D view
        self.view_button = QPushButton("Open 3D view")
        self.view_label = QLabel("3D view not running.")
        self.view_label.setObjectName("view_label")
        self.export_cloud_button = QPushButton("Export cloud PLY...")
        self.export_mesh_button = QPushButton("Export mesh PLY...")
        self.view_button.clicked.connect(self.open_3d_view)
        self.export_cloud_button.clicked.connect(lambda: self.export_ply(mesh=False))
        self.export_mesh_button.clicked.connect(lambda: self.export_ply(mesh=True))
        view_box = QGroupBox("4. 3D studio")
        vl = QVBoxLayout(view_box)
        row = QHBoxLayout()
        for b in (self.view_button, self.export_cloud_button, self.export_mesh_button):
            row.addWidget(b)
        vl.addLayout(row)
        self.origin_pick = QCheckBox("A click on an annotated point sets the studio origin")
        self.origin_pick.setObjectName("view_origin_pick")
        self.origin_pick.setToolTip("the studio frame's origin moves to the clicked point "
                                    "(axes kept), into the project and the outputs")
        vl.addWidget(self.origin_pick)
        vl.addWidget(self.view_label)

        # ---- layout: controls left, strip + tabs right
        left = QWidget()
        ll = QVBoxLayout(left)
        ll.setContentsMargins(0, 0, 0, 0)
        ll.addWidget(rec_box)
        ll.addWidget(self.progress)
        ll.addStretch(1)
        left.setMinimumWidth(470)
        left.setMaximumWidth(520)
        self.editor = AnnotationEditor()
        self.editor.points_changed.connect(self._on_points_changed)
        refine = QWidget()
        rfl = QHBoxLayout(refine)
        rfl.addWidget(fus_box, 1)
        col = QVBoxLayout()
        col.addWidget(sba_box)
        col.addWidget(view_box)
        rfl.addLayout(col, 1)
        self.tabs = QTabWidget()
        self.tabs.addTab(refine, "Fuse && adjust")
        self.tabs.addTab(self.editor, "Annotate")
        right = QWidget()
        rl2 = QVBoxLayout(right)
        rl2.setContentsMargins(0, 0, 0, 0)
        strip_row = QHBoxLayout()
        strip_row.addWidget(QLabel("Keyframes"))
        strip_row.addStretch(1)
        strip_row.addWidget(self.delete_button)
        strip_row.addWidget(self.retake_button)
        rl2.addLayout(strip_row)
        rl2.addWidget(self.strip)
        rl2.addWidget(self.tabs, 1)
        split = QSplitter()
        split.addWidget(left)
        split.addWidget(right)
        split.setStretchFactor(1, 1)
        split.setSizes([480, 1000])
        lay = QVBoxLayout(self)
        lay.addWidget(split)

        # drawing is separate from arrival: the window's display clock draws the progress
        ctx.project_changed.connect(lambda _p: self.reload_project())
        ctx.run.finished.connect(self._on_run_finished)
        ctx.run.failed.connect(self._on_run_failed)
        ctx.run.started.connect(lambda _info: self._update_buttons())
        self.reload_project()
        self._update_buttons()

    # ------------------------------------------------------------------ project
    def project(self) -> Any:
        from engine.project import new_project

        if self.ctx.project is None:
            self.ctx.set_project(new_project())
        return self.ctx.project

    @property
    def store(self) -> Any | None:
        prj = self.ctx.project
        return None if prj is None else prj.keyframes

    def _set_store(self, store: Any, why: str) -> None:
        prj = self.project()
        prj.keyframes = store
        if store is not None and prj.intrinsics is None:
            prj.intrinsics = store.intrinsics
        prj.mark_dirty()
        self.ctx.log.info(f"Keyframes: {why}")
        self._rebuild_strip()
        self.editor.set_data(store, prj.annotations)
        self._update_viewer()
        self._update_buttons()

    def reload_project(self) -> None:
        prj = self.ctx.project
        self.recording = self.fusion = self.sba = self.sba_backup = None
        self._rebuild_strip()
        self.editor.set_data(
            None if prj is None else prj.keyframes, [] if prj is None else prj.annotations
        )
        self.state_label.setText(
            "No sweep recorded."
            if self.store is None
            else f"{len(self.store)} keyframes in the project."
        )
        self._update_buttons()

    def _on_points_changed(self) -> None:
        prj = self.ctx.project
        if prj is not None and prj.annotations is not self.editor.points:
            same = [p.to_json() for p in prj.annotations] == [
                p.to_json() for p in self.editor.points
            ]
            prj.annotations = self.editor.points
            if not same:  # showing the project's points is no change
                prj.mark_dirty()
        self._update_buttons()

    # ---------------------------------------------------------------- strip
    def _strip_item(self, kf_id: int, T: np.ndarray, thumb: np.ndarray, valid: float) -> None:
        x, y, z = T[:3, 3]
        it = QListWidgetItem(
            QIcon(_pixmap(thumb)),
            f"#{kf_id}  {100 * valid:.0f} % depth\n({x:+.2f}, {y:+.2f}, {z:+.2f}) m",
        )
        it.setData(Qt.ItemDataRole.UserRole, kf_id)
        it.setToolTip(
            f"keyframe {kf_id}: position {x:.3f}, {y:.3f}, {z:.3f} m; "
            f"{100 * valid:.1f} % of pixels with depth"
        )
        self.strip.addItem(it)

    def _rebuild_strip(self) -> None:
        from engine.keyframes.sweep import thumbnail

        self.strip.clear()
        if self.store is None:
            return
        for k in self.store.keyframes:
            self._strip_item(
                k.id, k.T_world_cam, thumbnail(k.gray), float(np.mean(np.asarray(k.depth_m) > 0))
            )

    def selected_keyframe(self) -> int | None:
        it = self.strip.currentItem()
        return None if it is None else int(it.data(Qt.ItemDataRole.UserRole))

    def select_keyframe(self, kf_id: int) -> None:
        for i in range(self.strip.count()):
            if self.strip.item(i).data(Qt.ItemDataRole.UserRole) == kf_id:
                self.strip.setCurrentRow(i)
                self.strip.scrollToItem(self.strip.item(i))

    def delete_selected_keyframe(self) -> None:
        kid = self.selected_keyframe()
        if kid is None or self.store is None:
            return
        if len(self.store) == 1:
            self.ctx.log.warning("Keyframes: the last keyframe cannot be deleted")
            return
        prj = self.project()
        for p in prj.annotations:
            p.observations_px.pop(kid, None)
        self._set_store(self.store.without(kid), f"deleted keyframe {kid}")

    def retake_selected_keyframe(self) -> None:
        self.delete_selected_keyframe()
        self.append_box.setChecked(True)
        self.start_recording()

    # ------------------------------------------------------------------ jobs
    def _start(self, kind: str, fn: Any) -> None:
        if self.job is not None:
            return
        self.job_kind = kind
        self.job = JobThread(fn, self)
        self.job.progressed.connect(self._on_progress)
        self.job.succeeded.connect(self._on_done)
        self.job.failed.connect(self._on_failed)
        self.job.finished.connect(self._on_thread_finished)
        self.progress.setRange(0, 0)
        self._update_buttons()
        self.job.start()

    def stop_job(self) -> None:
        if self.sweep is not None and self._recording_now():
            self.ctx.run.stop()
        elif self.job is not None:
            self.job.requestInterruption()

    def _recording_now(self) -> bool:
        return self.sweep is not None and self.ctx.run.is_running \
            and self.ctx.run.epoch == self._sweep_run

    def refresh(self) -> None:
        """The display clock: the sweep's newest keyframes and progress, a job's progress."""
        if self.sweep is not None:
            for k in self.sweep.take_new():
                self._strip_item(k.id, k.T_world_cam, k.thumbnail, k.valid_depth_fraction)
                self.strip.scrollToBottom()
            if self.sweep.progress is not None:
                self._pending_progress = self.sweep.progress
        self._draw_progress()

    def shutdown(self) -> None:
        if self.job is not None:
            self.job.cancel()
        if self.viewer is not None:
            self.viewer.stop()
            self.viewer = None

    def _on_progress(self, rec: Any) -> None:
        self._pending_progress = rec

    def _draw_progress(self) -> None:
        rec = self._pending_progress
        if rec is None:
            return
        self._pending_progress = None
        if self.job_kind == "record":
            total = rec.source_len
            self.progress.setRange(0, total if total else 0)
            self.progress.setValue(rec.frames)
            msg = (
                f"Recording: frame {rec.frame_index}, {rec.frames} processed, "
                f"{rec.keyframes} keyframes kept, {rec.lost_frames} lost. "
                f"Tracking: {rec.state}."
            )
            if rec.adding_paused:
                msg += " Track lost: keyframe adding is paused until it recovers."
            self.state_label.setText(msg)
            if self.viewer is not None and rec.T_world_cam is not None:
                self.viewer.set_live_camera(rec.T_world_cam)
        elif self.job_kind == "fuse":
            done, total = rec
            self.progress.setRange(0, max(1, total))
            self.progress.setValue(done)

    def _on_done(self, result: Any) -> None:
        kind = self.job_kind
        self._draw_progress()
        self._pending_progress = None
        if kind == "record":
            self.recording = result
            prior = (
                len(self.store) if (self.store is not None and self.append_box.isChecked()) else 0
            )
            self._set_store(result.store, f"sweep recorded: {len(result.store)} keyframes")
            self.state_label.setText(
                f"Sweep {'stopped' if result.stopped else 'done'}: {result.frames_processed} "
                f"frames, {len(result.store)} keyframes ({len(result.store) - prior} new), "
                f"{result.lost_frames} lost, {len(result.frames)} frames kept for fusion."
            )
        elif kind == "fuse":
            self.fusion = result
            if result.cancelled:
                self.ctx.log.warning("Fusion cancelled: keyframe depth unchanged")
            else:
                self._show_fusion(result)
                self._set_store(
                    self.store.with_depths(result.depth_m),
                    f"depth fused: holes {result.hole_fraction_before:.4f} -> "
                    f"{result.hole_fraction_after:.4f}",
                )
        elif kind == "sba":
            self.sba = result
            self._show_sba(result)
        self.progress.setRange(0, 1)
        self.progress.setValue(1)

    def _on_failed(self, message: str) -> None:
        self.ctx.log.error(f"Keyframes: {message}")
        if self.job_kind == "sba":
            self.sba_label.setText(message)
        else:
            self.state_label.setText(message)
        self.progress.setRange(0, 1)
        self.progress.setValue(0)

    def _on_thread_finished(self) -> None:
        kind = self.job_kind
        self._draw_progress()
        if self.job is not None:
            self.job.deleteLater()
        self.job = None
        self._update_buttons()
        self.job_finished.emit(kind)

    def _update_buttons(self) -> None:
        recording = self._recording_now()
        busy = self.job is not None or recording
        has_store = self.store is not None
        self.record_button.setEnabled(not busy and not self.ctx.run.is_running)
        self.record_button.setToolTip("" if not self.ctx.run.is_running or recording else
                                      "A run is active: stop it first")
        self.stop_button.setEnabled(recording)
        self.cancel_button.setEnabled(busy and self.job_kind == "fuse")
        self.fuse_button.setEnabled(not busy and has_store and self.recording is not None)
        self.fuse_button.setToolTip(
            ""
            if self.recording is not None
            else "record a sweep first: fusion uses its non-keyframe frames"
        )
        self.sba_button.setEnabled(not busy and has_store)
        self.delete_button.setEnabled(not busy and has_store)
        self.retake_button.setEnabled(not busy and has_store)
        self.append_box.setEnabled(has_store)

    # ------------------------------------------------------------- recording
    def start_recording(self) -> None:
        """Record a sweep as a run of the window's run owner, the sweep recorder its sink."""
        from engine.keyframes.sweep import SweepRecorder, sweep_tracker

        if self.ctx.run.is_running or self.job is not None:
            self.state_label.setText("A run is active: stop it first.")
            return
        params = self.sweep_form.params
        spec = self.source.spec()
        base = self.store if (self.append_box.isChecked() and self.store is not None) else None
        if base is None:
            self.strip.clear()
        self.state_label.setText(f"Opening {spec} ...")
        tracker = sweep_tracker(params, store=base)
        self.sweep = SweepRecorder(tracker, params, store=base)
        self.job_kind = "record"
        self._pending_progress = None
        self.progress.setRange(0, 0)
        self.ctx.run.start(spec, "dense", tracker_factory=lambda: tracker, sinks=(self.sweep,),
                           realtime=False, max_frames=params.max_frames or None,
                           page="Keyframes")
        self._sweep_run = self.ctx.run.epoch
        self._update_buttons()

    def _on_run_failed(self, message: str) -> None:
        if self.sweep is not None and self.ctx.run.epoch == self._sweep_run:
            self._on_failed(message)

    def _on_run_finished(self, status: Any) -> None:
        self._update_buttons()
        sweep = self.sweep
        if sweep is None or self.ctx.run.epoch != self._sweep_run:
            return
        self.sweep = None
        self.refresh()
        from engine.errors import StudioTrackError

        if status is None or (status.error and not self.ctx.run.stopped_by_user):
            self.job_kind = "record"
            self._on_failed(self.ctx.run.last_error or "the sweep run failed")
        else:
            try:
                result = sweep.recording(status.info.source_name if status.info else "source",
                                         stopped=self.ctx.run.stopped_by_user)
            except StudioTrackError as exc:
                self._on_failed(str(exc))
            else:
                self.job_kind = "record"
                self._on_done(result)
        self.progress.setRange(0, 1)
        self._update_buttons()
        self.job_finished.emit("record")

    # ---------------------------------------------------------------- fusion
    def start_fusion(self) -> None:
        from engine.keyframes.fusion import fuse_depth

        if self.recording is None or self.store is None:
            return
        store, frames, params = self.store, list(self.recording.frames), self.fusion_form.params

        def job(should_stop: Any, progress: Any) -> Any:
            return fuse_depth(
                store,
                frames,
                params,
                should_stop=should_stop,
                progress=lambda d, n: progress((d, n)),
            )

        self._start("fuse", job)

    def _show_fusion(self, res: Any) -> None:
        t = self.fusion_table
        t.setRowCount(len(res.stats))
        for r, s in enumerate(res.stats):
            vals = [
                str(s.kf_id),
                str(s.frames),
                f"{s.hole_fraction_before:.4f}",
                f"{s.hole_fraction_after:.4f}",
                f"{1e3 * s.noise_before_m:.1f}",
                f"{1e3 * s.noise_after_m:.1f}",
            ]
            for c, v in enumerate(vals):
                t.setItem(r, c, QTableWidgetItem(v))
        t.resizeColumnsToContents()

    # ------------------------------------------------------------------- SBA
    def start_sba(self) -> None:
        from engine.keyframes.sba import bundle_adjust_store

        if self.store is None:
            return
        store, pts = self.store, [p for p in self.editor.points]
        params = self.sba_form.params

        def job(should_stop: Any, progress: Any) -> Any:
            return bundle_adjust_store(store, pts, params)

        self.sba_label.setText("Running SBA ...")
        self._start("sba", job)

    def _show_sba(self, res: Any) -> None:
        moved = [v[0] for k, v in res.pose_change.items()]
        self.sba_label.setText(
            f"Reprojection RMSE {res.rmse_before_px:.2f} px -> {res.rmse_after_px:.2f} px "
            f"({len(res.X_world_after)} points, gauge keyframe {res.gauge_id} fixed, "
            f"largest move {1e3 * max(moved, default=0):.1f} mm, {res.seconds:.2f} s)."
            + (
                f" Not adjusted (no points): {list(res.unadjusted_ids)}."
                if res.unadjusted_ids
                else ""
            )
            + " Apply or Revert."
        )
        t = self.sba_table
        t.setRowCount(len(res.pose_change))
        for r, (k, (dm, dd)) in enumerate(sorted(res.pose_change.items())):
            vals = [
                str(k),
                f"{1e3 * dm:.1f}",
                f"{dd:.3f}",
                f"{res.keyframe_rmse_before_px.get(k, math.nan):.2f} / "
                f"{res.keyframe_rmse_after_px.get(k, math.nan):.2f}",
            ]
            for c, v in enumerate(vals):
                t.setItem(r, c, QTableWidgetItem(v))
        t.resizeColumnsToContents()
        self.editor.set_errors(res.point_rmse_after_px)
        self.apply_button.setEnabled(True)
        self.revert_button.setEnabled(False)

    def apply_sba(self) -> None:
        if self.sba is None or self.store is None:
            return
        self.sba_backup = (self.store, {p.id: p.X_world for p in self.editor.points})
        prj = self.project()
        for p in prj.annotations:
            if p.id in self.sba.X_world_after:
                p.X_world = self.sba.X_world_after[p.id].copy()
        self._set_store(self.store.with_poses(self.sba.T_world_cam_after), "SBA applied")
        self.editor.set_errors(self.sba.point_rmse_after_px)
        self.apply_button.setEnabled(False)
        self.revert_button.setEnabled(True)

    def revert_sba(self) -> None:
        if self.sba_backup is None:
            return
        store, X = self.sba_backup
        prj = self.project()
        for p in prj.annotations:
            p.X_world = X.get(p.id)
        self._set_store(store, "SBA reverted")
        self.sba_backup = None
        self.apply_button.setEnabled(self.sba is not None)
        self.revert_button.setEnabled(False)

    # --------------------------------------------------------------- 3D view
    def open_3d_view(self, open_browser: bool = True) -> None:
        from app.viewer3d import StudioViewer

        if self.viewer is None:
            self.viewer = StudioViewer(on_keyframe_clicked=self._on_frustum_clicked,
                                       on_point_clicked=self._on_point_clicked)
            self.viewer.follow(self.ctx.run)  # the live frustum follows every pose run
            self._update_viewer()
        self.view_label.setText(f"3D view at {self.viewer.url} (127.0.0.1 only)")
        if open_browser:
            QDesktopServices.openUrl(QUrl(self.viewer.url))

    def _on_frustum_clicked(self, kf_id: int) -> None:
        # called on viser's thread: hop to the GUI thread
        QTimer.singleShot(0, self, lambda: self.select_keyframe(kf_id))

    def _on_point_clicked(self, X_world: Any) -> None:
        # called on viser's thread: hop to the GUI thread
        QTimer.singleShot(0, self, lambda: self.set_studio_origin(X_world))

    def set_studio_origin(self, X_world: Any) -> None:
        """Move the project's studio origin to a world point (axes kept): the outputs follow."""
        if not self.origin_pick.isChecked():
            return
        from engine.errors import StudioTrackError
        from engine.outputs.studio_frame import StudioFrame

        proj = self.ctx.project
        if proj is None:
            self.ctx.log.warning("studio origin: open or create a project first")
            return
        try:
            proj.studio_frame = (proj.studio_frame or StudioFrame()).with_origin_at(X_world)
        except StudioTrackError as exc:
            self.ctx.log.warning(str(exc))
            return
        proj.mark_dirty()
        self.ctx.apply_project_setup()
        x, y, z = (float(v) for v in X_world)
        self.ctx.log.info(f"studio origin moved to the clicked point ({x:.3f}, {y:.3f}, "
                          f"{z:.3f}) m (unsaved until File > Save)")

    def _update_viewer(self) -> None:
        if self.viewer is None or self.store is None:
            return
        self.viewer.set_store(self.store)
        pts = [p.X_world for p in self.editor.points if p.X_world is not None]
        if pts:
            self.viewer.set_points(np.array(pts))

    def export_ply(self, mesh: bool, path: str | None = None) -> None:
        from app.viewer3d import export_cloud_ply, export_mesh_ply

        if self.store is None:
            return
        if path is None:
            path, _ = QFileDialog.getSaveFileName(self, "Export PLY", "", "PLY (*.ply)")
            if not path:
                return
        try:
            n = export_mesh_ply(self.store, path) if mesh else export_cloud_ply(self.store, path)
        except Exception as exc:
            self.ctx.log.error(f"Export {path}: {exc}")
            return
        self.ctx.log.info(f"Exported {n} {'triangles' if mesh else 'points'} to {path}")


def _factory(ctx: Any) -> QWidget:
    return KeyframesPage(ctx)


PAGES = (
    PageSpec(
        title="Keyframes",
        order=10,
        factory=_factory,
        tooltip="record, fuse, annotate and bundle-adjust the keyframe model",
    ),
)


def _fit_columns(table: QTableWidget) -> None:
    """Columns share the table's width (two-line headers), so no header is clipped."""
    table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
