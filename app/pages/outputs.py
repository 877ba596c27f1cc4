"""The Outputs page: FreeD and OpenTrackIO targets, lens mapping, delays, studio frame.

Edits build a new frozen :class:`engine.outputs.sender.OutputConfig`; "Apply" swaps it in
(an invalid value keeps the last valid configuration and says why). Sockets bind to
127.0.0.1 unless the operator enters another bind address; the page says which address
each target is bound to.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QRadioButton,
    QScrollArea,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from app.pages import PageSpec
from app.pages._outputs_state import controller
from engine.errors import StudioTrackError
from engine.outputs import opentrackio as ot
from engine.outputs.sender import OutputConfig, TargetSpec
from engine.outputs.studio_frame import StudioFrame
from widgets.param_form import ParamForm


def _port_box(value: int) -> QSpinBox:
    s = QSpinBox()
    s.setRange(1, 65535)
    s.setValue(value)
    return s


class OutputsPage(QWidget):
    """Target, lens, delay and studio-frame settings for the pose outputs."""

    def __init__(self, ctx: Any) -> None:
        super().__init__()
        self.ctx = ctx
        self.ctrl = controller(ctx)
        cfg = self.ctrl.config
        freed_t = next((t for t in cfg.targets if t.protocol == "freed"), None)
        otio_t = next((t for t in cfg.targets if t.protocol == "opentrackio"), None)

        # -- sending + network
        self.send_box = QCheckBox("Send poses to the targets below")
        self.send_box.setObjectName("outputs_send")
        self.send_box.setChecked(self.ctrl.enabled)
        self.send_box.toggled.connect(self._on_send_toggled)
        self.bind_edit = QLineEdit(freed_t.bind_host or "" if freed_t else "")
        self.bind_edit.setPlaceholderText("automatic: 127.0.0.1 for loopback targets")
        self.bind_edit.setToolTip("Local address the output sockets bind to. Leave empty to "
                                  "bind to 127.0.0.1 (loopback only) for loopback targets, "
                                  "0.0.0.0 for targets on the network.")
        self.bind_label = QLabel()
        self.bind_label.setObjectName("outputs_bind")
        self.bind_label.setWordWrap(True)
        net = QGroupBox("Sending")
        nf = QFormLayout(net)
        nf.addRow(self.send_box)
        nf.addRow("Bind address", self.bind_edit)
        nf.addRow(self.bind_label)

        # -- FreeD
        self.freed_on = QCheckBox("FreeD D1 (UDP)")
        self.freed_on.setChecked(freed_t is not None)
        self.freed_host = QLineEdit(freed_t.host if freed_t else "127.0.0.1")
        self.freed_host.setToolTip("Unicast, broadcast (x.x.x.255) or multicast address")
        self.freed_port = _port_box(freed_t.port if freed_t else 40000)
        self.freed_form = ParamForm(cfg.freed)
        fg = QGroupBox("FreeD")
        ff = QFormLayout(fg)
        ff.addRow(self.freed_on)
        ff.addRow("Host", self.freed_host)
        ff.addRow("Port", self.freed_port)
        ff.addRow(self.freed_form)

        # -- OpenTrackIO
        self.otio_on = QCheckBox("OpenTrackIO 1.0 (UDP)")
        self.otio_on.setChecked(otio_t is not None)
        self.otio_host = QLineEdit(otio_t.host if otio_t else "127.0.0.1")
        self.otio_port = _port_box(otio_t.port if otio_t else ot.DEFAULT_PORT)
        self.otio_enc = QComboBox()
        self.otio_enc.addItems(["json", "cbor"])
        self.otio_enc.setCurrentText(otio_t.encoding if otio_t else "json")
        self.otio_source = QSpinBox()
        self.otio_source.setRange(1, 200)
        self.otio_source.setValue(cfg.opentrackio_source_number)
        self.sensor_w = QDoubleSpinBox()
        self.sensor_w.setRange(1.0, 100.0)
        self.sensor_w.setDecimals(2)
        self.sensor_w.setSuffix(" mm")
        self.sensor_w.setValue(cfg.lens.sensor_width_mm)
        self.sensor_w.setToolTip("Sensor width: converts focal length px -> mm (both outputs)")
        mc = QPushButton("Use multicast 239.135.1.N:55555")
        mc.clicked.connect(self._use_multicast)
        og = QGroupBox("OpenTrackIO")
        of = QFormLayout(og)
        of.addRow(self.otio_on)
        of.addRow("Host", self.otio_host)
        of.addRow("Port", self.otio_port)
        of.addRow(mc)
        of.addRow("Encoding", self.otio_enc)
        of.addRow("Source number", self.otio_source)
        of.addRow("Sensor width", self.sensor_w)

        # -- delays
        self.delay_form = ParamForm(cfg.delays)
        dg = QGroupBox("Delay compensation (ms, per axis; negative = predict ahead)")
        QVBoxLayout(dg).addWidget(self.delay_form)

        # -- studio frame
        self.frame_identity = QRadioButton("Identity (tracker world is the studio, z up)")
        self.frame_points = QRadioButton("From three floor points (world metres)")
        self.frame_identity.setChecked(True)
        self.points: list[list[QDoubleSpinBox]] = []
        grid = QGridLayout()
        defaults = ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
        for r, (label, vals) in enumerate(zip(("Origin", "On +X", "+Y side"), defaults,
                                               strict=True)):
            grid.addWidget(QLabel(label), r, 0)
            row = []
            for c, v in enumerate(vals):
                s = QDoubleSpinBox()
                s.setRange(-1000.0, 1000.0)
                s.setDecimals(3)
                s.setValue(v)
                grid.addWidget(s, r, c + 1)
                row.append(s)
            self.points.append(row)
        sg = QGroupBox("Studio frame")
        sl = QVBoxLayout(sg)
        sl.addWidget(self.frame_identity)
        sl.addWidget(self.frame_points)
        sl.addLayout(grid)

        # -- apply
        self.apply_button = QPushButton("Apply")
        self.apply_button.setObjectName("outputs_apply")
        self.apply_button.clicked.connect(self.apply)
        self.error_label = QLabel()
        self.error_label.setObjectName("param_error")
        self.error_label.setStyleSheet("color: #e05050")
        self.error_label.setWordWrap(True)
        buttons = QHBoxLayout()
        buttons.addWidget(self.error_label, 1)
        buttons.addWidget(self.apply_button)

        left = QVBoxLayout()
        left.addWidget(net)
        left.addWidget(fg)
        left.addWidget(og)
        left.addStretch(1)
        right = QVBoxLayout()
        right.addWidget(dg)
        right.addWidget(sg)
        right.addStretch(1)
        cols = QHBoxLayout()
        cols.addLayout(left, 1)
        cols.addLayout(right, 1)
        inner = QWidget()
        v = QVBoxLayout(inner)
        v.addLayout(cols)
        v.addLayout(buttons)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(inner)
        scroll.setFrameShape(QScrollArea.Shape.NoFrame)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(0, 0, 0, 0)
        outer.addWidget(scroll)
        self.ctrl.enabled_changed.connect(self.send_box.setChecked)
        self._show_bind(cfg)

    # ------------------------------------------------------------------ actions
    def _use_multicast(self) -> None:
        self.otio_host.setText(ot.default_multicast_group(self.otio_source.value()))
        self.otio_port.setValue(ot.DEFAULT_PORT)
        self.otio_on.setChecked(True)

    def build_config(self) -> OutputConfig:
        """The configuration the page shows; raises StudioTrackError when invalid."""
        bind = self.bind_edit.text().strip() or None
        targets = []
        if self.freed_on.isChecked():
            targets.append(TargetSpec("freed", self.freed_host.text().strip(),
                                      self.freed_port.value(), "json", bind))
        if self.otio_on.isChecked():
            targets.append(TargetSpec("opentrackio", self.otio_host.text().strip(),
                                      self.otio_port.value(), self.otio_enc.currentText(),
                                      bind))
        if self.frame_points.isChecked():
            p = [[s.value() for s in row] for row in self.points]
            studio = StudioFrame.from_floor_points(*p)
        else:
            studio = StudioFrame()
        base = self.ctrl.config
        return replace(
            base,
            targets=tuple(targets),
            freed=self.freed_form.params or base.freed,
            opentrackio_source_number=self.otio_source.value(),
            lens=replace(base.lens, sensor_width_mm=self.sensor_w.value()),
            delays=self.delay_form.params or base.delays,
            studio=studio,
        )

    def apply(self) -> bool:
        try:
            cfg = self.build_config()
        except StudioTrackError as exc:
            self.error_label.setText(f"Not applied: {exc}")
            return False
        self.ctrl.apply(cfg)
        self.error_label.setText("")
        self._show_bind(cfg)
        self.ctx.log.info("outputs: configuration applied")
        return True

    def _on_send_toggled(self, on: bool) -> None:
        if on and not self.apply():
            self.send_box.setChecked(False)
            return
        self.ctrl.set_enabled(on)

    def _show_bind(self, cfg: OutputConfig) -> None:
        if not cfg.targets:
            self.bind_label.setText("No targets enabled.")
            return
        lines = [f"{t.name} → bound to {t.effective_bind}"
                 + (" (loopback only)" if t.effective_bind.startswith("127.") else "")
                 for t in cfg.targets]
        self.bind_label.setText("\n".join(lines))
        self.bind_label.setAlignment(Qt.AlignmentFlag.AlignLeft)


PAGE = PageSpec(title="Outputs", order=50, factory=OutputsPage,
                tooltip="FreeD / OpenTrackIO targets, lens mapping, delays, studio frame")
