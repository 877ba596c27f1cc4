"""The Live page: pick a source and a tracker, start/stop, watch the image, poses and quality.

Runs go through the window's run owner (``ctx.run``): outputs, recording and the status
header follow them. Arrival and display are separate (STYLE.md): the main window's display
clock calls this page only while it is shown; the plots take every frame's numbers from the
run's history, the image, overlay and read-outs are drawn from the newest record only, so
the state and the numbers shown are always those of one and the same frame. Overlays are
decimated to at most :data:`MAX_POINTS` points. After Stop every live read-out clears.
"""

from __future__ import annotations

import dataclasses
import statistics
import time
from collections import deque
from typing import Any

import numpy as np
from PySide6.QtCore import Qt, Slot
from PySide6.QtGui import QKeySequence, QShortcut
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFrame,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QScrollArea,
    QSizePolicy,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

import engine.trackers as trackers
from app.context import AppContext
from app.icons import icon
from app.pages import PageSpec
from app.pages._base import Page
from engine.frames import Frame
from engine.loop import FrameRecord
from engine.pipeline import RunInfo, RunStatus, TraceSample
from engine.results import TrackState
from engine.trackers.base import Overlay
from widgets.depth_view import VIEW_MODES, compose_view
from widgets.image_view import ImageView
from widgets.param_form import ParamForm
from widgets.pose_plots import PosePlots, ResidualPlots
from widgets.source_picker import SourceKind, SourcePicker
from widgets.status_light import StatusLight

DEFAULT_SOURCE = "synthetic:frames=100000,presenter=1,path=rail"
#: at most this many overlay points are drawn (evenly strided; the count shown is the full one)
MAX_POINTS = 1500
#: the pose and quality plots are redrawn at most this often (s; the image keeps the display
#: rate). Their painting holds the interpreter lock: at 4 Hz instead of 10 the window's CPU per
#: frame fell 15.0 -> 13.0-13.4 ms and the tracker's p95 in the window 22.4-23.4 ->
#: 20.3-21.0 ms (bench onair, 2 runs each, interleaved); a run's end draws its last samples
PLOT_INTERVAL_S = 0.25


def _readout(caption: str, tooltip: str) -> tuple[QLabel, QLabel]:
    cap = QLabel(caption)
    cap.setObjectName("readout_caption")
    val = QLabel("–")
    val.setObjectName("readout")
    val.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
    val.setToolTip(tooltip)
    cap.setToolTip(tooltip)
    return cap, val


def decimated(overlay: Overlay | None, max_points: int = MAX_POINTS) -> Overlay | None:
    """The overlay with at most ``max_points`` points (evenly strided), drawing bounded."""
    if overlay is None or overlay.points_uv is None or len(overlay.points_uv) <= max_points:
        return overlay
    step = int(np.ceil(len(overlay.points_uv) / max_points))
    w = overlay.point_weights
    return dataclasses.replace(
        overlay, points_uv=overlay.points_uv[::step],
        point_weights=None if w is None or len(w) != len(overlay.points_uv) else w[::step])


class LivePage(Page):
    """Source + tracker pickers, start/stop, live image, pose and residual plots, parameters."""

    def __init__(self, ctx: AppContext, parent: QWidget | None = None) -> None:
        super().__init__(ctx, parent)
        self.setObjectName("page_live")
        self.run = ctx.run
        self._latest: FrameRecord | None = None
        self._shown_frame: Frame | None = None  # the frame on screen (kept after Stop)
        self._latency_ms: deque[float] = deque(maxlen=120)
        self._params_by_tracker: dict[str, Any] = {}
        self._frames_shown = 0
        self._plots_due = 0.0
        self.samples_missed = 0  # frames pushed out of the run's history before drawn

        # ---- controls
        self.source_picker = SourcePicker()
        self.source_picker.set_spec(DEFAULT_SOURCE)
        self.source_picker.set_recent(ctx.recent_files())
        self.tracker_box = QComboBox()
        self.tracker_box.setMinimumWidth(120)
        self.tracker_box.setToolTip("Tracker to run")
        self._fill_trackers()
        self.realtime_check = QCheckBox("Real-time")
        self.realtime_check.setChecked(True)
        self.realtime_check.setToolTip(
            "Pace recorded sources to their nominal frame rate (off: as fast as possible)"
        )
        self.record_check = QCheckBox("Record session")
        self.record_check.setObjectName("record_check")
        self.record_check.setToolTip(
            "Record the run as a replayable session folder (frames, poses, outputs sent) in "
            "the project's sessions/ folder (or a temporary one without a project)"
        )
        self.start_button = QPushButton("Start")
        self.start_button.setObjectName("start_button")
        self.start_button.setToolTip("Start tracking (F5)")
        self.stop_button = QPushButton("Stop")
        self.stop_button.setObjectName("stop_button")
        self.stop_button.setToolTip("Stop tracking (Shift+F5)")
        self.stop_button.setEnabled(False)
        self.start_button.setIcon(icon("icons/start.svg"))
        self.stop_button.setIcon(icon("icons/stop.svg"))
        for b in (self.start_button, self.stop_button):
            b.setMinimumWidth(84)

        # Source on top (it takes the full width, so the studio options stay on one line
        # even at 1280 px); tracker and Start/Stop head the side panel, next to the state
        # light they change.
        top = QHBoxLayout()
        top.setSpacing(8)
        source_label = QLabel("Source")
        source_label.setObjectName("readout_caption")
        tracker_label = QLabel("Tracker")
        tracker_label.setObjectName("readout_caption")
        source_label.setMinimumHeight(self.source_picker.kind_box.sizeHint().height())
        top.addWidget(source_label, 0, Qt.AlignmentFlag.AlignTop)
        top.addWidget(self.source_picker, 1)

        run_box = QGroupBox("Run")
        run_grid = QGridLayout(run_box)
        run_grid.setHorizontalSpacing(8)
        run_grid.addWidget(tracker_label, 0, 0)
        run_grid.addWidget(self.tracker_box, 0, 1)
        run_grid.addWidget(self.realtime_check, 0, 2)
        run_grid.addWidget(self.record_check, 1, 0, 1, 3)
        buttons = QHBoxLayout()
        buttons.addWidget(self.start_button, 1)
        buttons.addWidget(self.stop_button, 1)
        run_grid.addLayout(buttons, 2, 0, 1, 3)
        run_grid.setColumnStretch(1, 1)

        # ---- views
        self.image_view = ImageView()
        self.image_view.setToolTip(
            "Live image. Points: green = used, red = rejected (weight); dashed box: ground truth"
        )
        self.view_box = QComboBox()
        for mode in VIEW_MODES:
            self.view_box.addItem(mode.capitalize(), mode)
        self.view_box.setToolTip(
            "Show the colour image, the depth image (false colour, near = red, far = blue, "
            "black = no depth) or both side by side"
        )
        self.view_box.currentIndexChanged.connect(self._on_view_mode)
        self.pose_plots = PosePlots()
        self.residual_plots = ResidualPlots()

        # ---- side panel: state, read-outs, parameters
        self.status_light = StatusLight()
        self.status_light.setMinimumWidth(220)
        readouts = QGridLayout()
        readouts.setHorizontalSpacing(10)
        readouts.setVerticalSpacing(2)
        specs = [
            ("fps", "frames/s", "Frames processed per second (smoothed)"),
            ("latency", "latency (ms)", "Tracker time per frame: last / p95 of the last 120"),
            ("frame", "frame", "Index of the frame shown / frames in the source"),
            ("skipped", "skipped", "Camera frames skipped before this one because the tracker "
             "is slower than the camera (live sources take only the newest frame); "
             "the rate over the last second"),
            ("residual", "residual", "Tracker residual of the last frame"),
            ("inliers", "inliers", "Fraction of points the tracker kept"),
            ("error", "error vs GT", "Translation error vs ground truth aligned at frame 0"),
            ("keyframe", "keyframe", "Keyframe in use"),
        ]
        self.readouts: dict[str, QLabel] = {}
        for row, (key, caption, tip) in enumerate(specs):
            cap, val = _readout(caption, tip)
            readouts.addWidget(cap, row, 0)
            readouts.addWidget(val, row, 1)
            self.readouts[key] = val
        self.fps_label = self.readouts["fps"]
        self.latency_label = self.readouts["latency"]
        self.error_label = QLabel()
        self.error_label.setObjectName("param_error")
        self.error_label.setWordWrap(True)
        self.error_label.setVisible(False)
        self.error_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)

        self.param_form = ParamForm()
        self.reset_button = QPushButton("Reset tracker")
        self.reset_button.setToolTip("Forget tracker state; the next frame re-initialises")
        self.reset_button.setEnabled(False)
        params_box = QGroupBox("Tracker parameters")
        pb_layout = QVBoxLayout(params_box)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setFrameShape(QFrame.Shape.NoFrame)
        scroll.setWidget(self.param_form)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        pb_layout.addWidget(scroll)
        pb_layout.addWidget(self.reset_button)

        state_box = QGroupBox("Tracking")
        sb_layout = QVBoxLayout(state_box)
        sb_layout.addWidget(self.status_light, 0, Qt.AlignmentFlag.AlignLeft)
        sb_layout.addLayout(readouts)
        sb_layout.addWidget(self.error_label)

        side = QWidget()
        side_layout = QVBoxLayout(side)
        side_layout.setContentsMargins(0, 0, 0, 0)
        side_layout.addWidget(run_box)
        side_layout.addWidget(state_box)
        side_layout.addWidget(params_box, 1)
        side.setMinimumWidth(270)
        side.setMaximumWidth(380)

        left = QSplitter(Qt.Orientation.Vertical)
        left.addWidget(self._titled("Camera view", self.image_view, self.view_box))
        left.addWidget(self._titled("Quality", self.residual_plots))
        left.setStretchFactor(0, 3)
        left.setStretchFactor(1, 1)
        left.setSizes([520, 190])
        self.main_split = QSplitter(Qt.Orientation.Horizontal)
        self.main_split.addWidget(left)
        self.main_split.addWidget(
            self._titled("Camera pose (solid: estimate, dashed: ground truth)", self.pose_plots)
        )
        self.main_split.addWidget(side)
        self.main_split.setStretchFactor(0, 5)
        self.main_split.setStretchFactor(1, 4)
        self.main_split.setStretchFactor(2, 0)
        self.main_split.setSizes([640, 520, 290])
        for i in range(3):
            self.main_split.setCollapsible(i, False)

        layout = QVBoxLayout(self)
        layout.setContentsMargins(8, 8, 8, 4)
        layout.setSpacing(6)
        layout.addLayout(top)
        layout.addWidget(self.main_split, 1)

        # ---- wiring
        self.start_button.clicked.connect(self.start)
        self.stop_button.clicked.connect(self.stop)
        self.reset_button.clicked.connect(self.run.reset_tracker)
        self.tracker_box.currentIndexChanged.connect(self._on_tracker_changed)
        self.param_form.params_changed.connect(self._on_params_edited)
        self.param_form.edit_rejected.connect(
            lambda msg: ctx.log.warning(f"parameter rejected: {msg}")
        )
        self.run.started.connect(self._on_started)
        self.run.failed.connect(self._on_failed)
        self.run.finished.connect(self._on_finished)
        self.run.params_changed.connect(self._on_params_sent)
        QShortcut(QKeySequence("F5"), self, self.start)
        QShortcut(QKeySequence("Shift+F5"), self, self.stop)
        self._on_tracker_changed()
        self._update_controls()

    @staticmethod
    def _titled(title: str, widget: QWidget, tool: QWidget | None = None) -> QWidget:
        box = QWidget()
        layout = QVBoxLayout(box)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(2)
        label = QLabel(title)
        label.setObjectName("readout_caption")
        if tool is None:
            layout.addWidget(label)
        else:
            head = QHBoxLayout()
            head.setContentsMargins(0, 0, 0, 0)
            head.addWidget(label)
            head.addStretch(1)
            head.addWidget(tool)
            layout.addLayout(head)
        layout.addWidget(widget, 1)
        widget.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        return box

    # ----------------------------------------------------------------- config
    def _fill_trackers(self) -> None:
        self.tracker_box.blockSignals(True)
        self.tracker_box.clear()
        try:
            specs = trackers.available_trackers()
            default = trackers.default_tracker_name() if specs else None
        except Exception as exc:  # a broken tracker module must not take the window down
            self.ctx.log.error(f"tracker registry: {type(exc).__name__}: {exc}")
            specs, default = {}, None
        for name, spec in specs.items():
            self.tracker_box.addItem(name, name)
            self.tracker_box.setItemData(
                self.tracker_box.count() - 1, spec.description, Qt.ItemDataRole.ToolTipRole
            )
        if default is not None:
            self.tracker_box.setCurrentIndex(self.tracker_box.findData(default))
        self.tracker_box.blockSignals(False)

    @property
    def tracker_name(self) -> str | None:
        data = self.tracker_box.currentData()
        return None if data is None else str(data)

    def configure(
        self,
        source: str | None = None,
        tracker: str | None = None,
        realtime: bool | None = None,
    ) -> None:
        """Pre-select a source spec, a tracker and pacing (used by ``studiotrack gui``)."""
        if source is not None:
            self.source_picker.set_spec(source)
        if tracker is not None:
            index = self.tracker_box.findData(tracker)
            if index < 0:
                self.ctx.log.error(f"unknown tracker {tracker!r}")
            else:
                self.tracker_box.setCurrentIndex(index)
        if realtime is not None:
            self.realtime_check.setChecked(realtime)

    @Slot()
    def _on_tracker_changed(self) -> None:
        name = self.tracker_name
        if name is None:
            self.param_form.set_params(None)
            return
        params = self._params_by_tracker.get(name)
        if params is None:
            try:
                params = trackers.get_spec(name).params_cls()
            except Exception as exc:
                self.ctx.log.error(f"tracker {name!r} parameters: {type(exc).__name__}: {exc}")
                params = None
        self.param_form.set_params(params)

    @Slot(object)
    def _on_params_edited(self, params: object) -> None:
        name = self.tracker_name
        if name is not None:
            self._params_by_tracker[name] = params
        info = self.run.run_info
        if self.run.is_running and info is not None and info.tracker_name == name:
            self.run.set_params(params)
            self.ctx.log.info(f"{name}: parameters applied from the next frame")

    # ---------------------------------------------------------------- control
    @Slot()
    def start(self) -> None:
        name = self.tracker_name
        if name is None:
            self.ctx.log.error("no tracker available")
            return
        spec = self.source_picker.spec()
        recorded = (SourceKind.FOLDER, SourceKind.VIDEO, SourceKind.BAG)
        if self.source_picker.kind in recorded and spec:
            self.ctx.add_recent_file(spec)
            self.source_picker.set_recent(self.ctx.recent_files())
        self._clear_live()
        self.status_light.set_state(None, "STARTING")
        record_dir = self.session_dir() if self.record_check.isChecked() else None
        if record_dir is not None:
            self.ctx.log.info(f"recording the session to {record_dir}")
        self.run.start(spec, name, self.param_form.params,
                       realtime=self.realtime_check.isChecked(), page="Live",
                       record_dir=record_dir)
        self._update_controls()

    @Slot()
    def stop(self) -> None:
        if self.run.is_running:
            self.run.stop()
        self._update_controls()

    def session_dir(self) -> str:
        """A new session folder: ``<project>/sessions/<time>`` or a temporary one."""
        import tempfile
        from pathlib import Path

        project = getattr(self.ctx, "project", None)
        root = getattr(project, "folder", None) or getattr(project, "path", None)
        base = (Path(root) / "sessions" if root is not None
                else Path(tempfile.gettempdir()) / "studiotrack_sessions")
        stamp = time.strftime("%Y%m%d-%H%M%S")
        out = base / stamp
        n = 1
        while out.exists():
            n += 1
            out = base / f"{stamp}-{n}"
        return str(out)

    def _update_controls(self) -> None:
        running = self.run.is_running
        self.start_button.setEnabled(not running)
        self.stop_button.setEnabled(running)
        self.reset_button.setEnabled(running)
        self.tracker_box.setEnabled(not running)
        self.realtime_check.setEnabled(not running)
        self.record_check.setEnabled(not running)
        self.source_picker.setEnabled(not running)
        req = self.run.request
        tip = "Stop tracking (Shift+F5)"
        if running and req is not None and req.page != "Live":
            tip = f"Stop the {req.tracker} run started on the {req.page} page (Shift+F5)"
        self.stop_button.setToolTip(tip)
        self.start_button.setToolTip("Start tracking (F5)" if not running else
                                     "A run is active: stop it first")

    def _clear_live(self) -> None:
        """Forget everything shown of a run (a new run starts, or the run ended)."""
        self._latest = None
        self._latency_ms.clear()
        self._frames_shown = 0
        self.error_label.setVisible(False)
        for v in self.readouts.values():
            v.setText("–")

    # ---------------------------------------------------------- run events
    @Slot(object)
    def _on_started(self, info: object) -> None:
        assert isinstance(info, RunInfo)
        self.status_light.set_state(None, "INITIALIZING")
        self._show_run_params(info.tracker_name, info.params)
        self._update_controls()

    def _show_run_params(self, tracker_name: str, params: object) -> None:
        """Keep the form in step with what the engine runs (another page may start it)."""
        index = self.tracker_box.findData(tracker_name)
        if index < 0:
            return
        if index != self.tracker_box.currentIndex():
            self.tracker_box.setCurrentIndex(index)  # reloads the form for that tracker
        if (
            params is not None
            and dataclasses.is_dataclass(params)
            and not isinstance(params, type)
        ):
            self._params_by_tracker[tracker_name] = params
            if params != self.param_form.params:
                self.param_form.set_params(params)

    @Slot(object)
    def _on_params_sent(self, params: object) -> None:
        info = self.run.run_info
        if info is not None and params is not self.param_form.params:
            self._show_run_params(info.tracker_name, params)

    @Slot(str)
    def _on_failed(self, message: str) -> None:
        self.error_label.setText(message)
        self.error_label.setToolTip(message)
        self.error_label.setVisible(True)
        self.status_light.set_state(None, "ERROR")
        self._update_controls()

    @Slot(object)
    def _on_finished(self, status: object) -> None:
        self.run_ended(status if isinstance(status, RunStatus) else None)

    # ------------------------------------------------------------- page hooks
    def run_changed(self, info: RunInfo | None) -> None:
        self.samples_missed = 0
        self.image_view.clear_image("waiting for the first frame")
        self._shown_frame = None
        self.pose_plots.clear_data()
        self.residual_plots.clear_data()
        self.pose_plots.redraw()
        self.residual_plots.redraw()
        self._clear_live()
        self._update_controls()

    def run_ended(self, status: RunStatus | None) -> None:
        """Nothing stale after Stop: read-outs clear, the overlay goes, the light says so."""
        error = self.run.last_error
        fault = status is not None and bool(status.error)
        if error and not self.run.stopped_by_user and not fault:
            self.status_light.set_state(None, "ERROR")
        else:
            self.status_light.set_state(None, "STOPPED")
        self._clear_live()
        # the samples since the last timed redraw (the run's last frames) are drawn now
        self.pose_plots.redraw()
        self.residual_plots.redraw()
        if error and not self.run.stopped_by_user:
            self.error_label.setText(error)
            self.error_label.setVisible(True)
        frames = status.frames if status is not None else 0
        # the frame on screen, not a draw count: this runs twice per run end (the finished
        # signal and the display clock), and the second call must not wipe the picture
        if self._shown_frame is None:
            self.image_view.clear_image(f"stopped after {frames} frames (none shown on this page)")
        else:
            self.image_view.set_overlay(None, None)
            self.image_view.set_info(f"stopped after {frames} frames: the last frame shown")
        self._update_controls()

    def run_stalled(self, message: str) -> None:
        """No record for a while: LOST (as the header says), the last frame marked not live."""
        self.status_light.set_state(TrackState.LOST, "LOST · engine stalled")
        self.image_view.set_info(f"{message}: the last frame, not live")

    def run_faulted(self, status: RunStatus | None) -> None:
        """The engine raised: ERROR, the reason, the last frame marked as not live."""
        error = (status.error if status is not None else None) or self.run.last_error or ""
        self.status_light.set_state(None, "ERROR")
        self.error_label.setText(error)
        self.error_label.setToolTip(error)
        self.error_label.setVisible(bool(error))
        for key in ("fps", "latency"):
            self.readouts[key].setText("–")
        self.image_view.set_overlay(None, None)
        self.image_view.set_info("engine error: the last frame before it, not live; "
                                 "outputs hold it flagged LOST — press Stop")
        self._update_controls()

    def follows(self, info: RunInfo | None) -> bool:
        return info is not None  # the Live page shows every run

    def add_samples(self, samples: list[TraceSample], missed: int) -> None:
        self.samples_missed += missed
        for s in samples:
            err = self.pose_plots.append(s.timestamp_s, s.T_world_cam, s.gt_T_world_cam)
            self.residual_plots.append(s.timestamp_s, s.residual, s.inlier_fraction, err)
            self._latency_ms.append(s.process_ms)
        now = time.monotonic()
        if now >= self._plots_due:
            self._plots_due = now + PLOT_INTERVAL_S
            self.pose_plots.redraw()
            self.residual_plots.redraw()

    def draw(self, record: FrameRecord) -> None:
        """Draw the newest record: image, its own overlay, its own state and numbers."""
        self._latest = record
        if record.frame.color_bgr is not None:
            self._shown_frame = record.frame  # a frame without a picture keeps the last one
        self._frames_shown += 1
        frame, result = record.frame, record.result
        self.image_view.set_image(compose_view(frame.color_bgr, frame.depth_m, self.view_mode))
        overlay = result.overlay
        if result.box_xywh is not None and (overlay is None or not overlay.boxes_xywh):
            base = overlay if overlay is not None else Overlay()
            overlay = Overlay(
                points_uv=base.points_uv,
                point_weights=base.point_weights,
                boxes_xywh=(result.box_xywh,),
                box_labels=(record.tracker_name,),
                polylines_uv=base.polylines_uv,
                crosshair_uv=base.crosshair_uv,
            )
        if overlay is not None and not result.state.is_good and overlay.points_uv is not None:
            # a rejected attempt's points were not used for the pose: never drawn "used"
            overlay = dataclasses.replace(
                overlay, point_weights=np.zeros(len(overlay.points_uv), np.float32))
        self.image_view.set_overlay(decimated(overlay), frame.gt_box_xywh)
        self.image_view.set_info(self._info_text(record))
        self.status_light.set_state(result.state, self._state_text(record))
        self._update_readouts(record)

    @Slot()
    def redraw(self) -> None:
        """Draw now (tests, screenshots): what the display clock would draw."""
        self.display_tick()
        self.pose_plots.redraw()
        self.residual_plots.redraw()

    @property
    def view_mode(self) -> str:
        return str(self.view_box.currentData())

    @Slot()
    def _on_view_mode(self) -> None:
        """Show the frame on screen in the new mode at once (also after Stop)."""
        frame = self._shown_frame
        if frame is not None:
            self.image_view.set_image(compose_view(frame.color_bgr, frame.depth_m,
                                                   self.view_mode))

    @staticmethod
    def _state_text(record: FrameRecord) -> str | None:
        """"LOST · camera disconnected" while a live source has no picture."""
        reason = record.frame.link_lost_reason
        return f"{record.result.state.value} · {reason}" if reason else None

    def _info_text(self, record: FrameRecord) -> str:
        frame, result = record.frame, record.result
        parts = [f"frame {frame.index}", f"t = {frame.timestamp_s:.2f} s"]
        if frame.link_lost_reason:
            parts.append(f"{frame.link_lost_reason}, reconnecting")
        if record.skipped_per_s > 0:
            parts.append(f"skipping {record.skipped_per_s:.0f} frames/s")
        ov = result.overlay
        if ov is not None and ov.points_uv is not None and len(ov.points_uv):
            n = len(ov.points_uv)
            if not result.state.is_good:
                parts.append(f"{n} points, attempt rejected ({result.state.value})")
            elif ov.point_weights is not None and len(ov.point_weights):
                used = float(np.mean(np.asarray(ov.point_weights) >= 0.5)) * 100.0
                parts.append(f"{n} points, {used:.0f} % used")
            else:
                parts.append(f"{n} points")
        if result.message:
            parts.append(result.message)
        return "  ·  ".join(parts)

    def _update_readouts(self, record: FrameRecord) -> None:
        result = record.result
        st = self.run.status()
        fps = st.fps if st is not None else record.fps
        self.readouts["fps"].setText(f"{fps:6.1f}")
        lat = list(self._latency_ms)
        p95 = float(np.percentile(lat, 95)) if len(lat) >= 2 else record.process_ms
        self.readouts["latency"].setText(f"{record.process_ms:6.1f} / {p95:.1f}")
        total = f" / {record.source_len}" if record.source_len else ""
        self.readouts["frame"].setText(f"{record.frame.index}{total}")
        self.readouts["skipped"].setText(
            f"{record.frame.skipped_before}  ({record.skipped_per_s:.0f}/s)"
        )
        self.readouts["residual"].setText(
            "–" if result.residual is None else f"{result.residual:.4g}"
        )
        inl = result.inlier_fraction
        self.readouts["inliers"].setText(
            "–" if inl is None else f"{100 * inl:.1f} %" if result.state.is_good
            else f"{100 * inl:.1f} % (rejected)"  # this frame's own, from the failing attempt
        )
        _, err = self.pose_plots.err.data()
        finite = err[np.isfinite(err[:, 0]), 0] if len(err) else np.empty(0)
        self.readouts["error"].setText(f"{1000 * finite[-1]:.1f} mm" if len(finite) else "–")
        self.readouts["keyframe"].setText(
            "–" if result.keyframe_id is None else str(result.keyframe_id)
        )

    def latency_median_ms(self) -> float | None:
        return statistics.median(self._latency_ms) if self._latency_ms else None


def _factory(ctx: AppContext) -> QWidget:
    return LivePage(ctx)


PAGES = (
    PageSpec(
        title="Live",
        order=0,
        factory=_factory,
        tooltip="Track a source live: image, pose, quality and tracker parameters",
    ),
)
