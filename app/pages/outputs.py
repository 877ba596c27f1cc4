"""The Outputs page: FreeD and OpenTrackIO targets, lens mapping, delays, studio frame.

Apply model: "Send poses" switches sending on/off immediately; every other edit is *pending*
until "Apply" (a "changes pending" indicator says so; "Revert" reloads what is in force).
Apply builds a new frozen :class:`engine.outputs.sender.OutputConfig`; an invalid value keeps
the last valid configuration and says why. Sockets bind to 127.0.0.1 (loopback only) unless
the operator enters another bind address; the page says what the bind address means, and shows
each target's live status (off / waiting / sending N Hz / error).
"""

from __future__ import annotations

from dataclasses import fields, replace
from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QAbstractSpinBox,
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
    QSizePolicy,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from app.pages import PageSpec
from app.pages._base import Page
from engine.errors import StudioTrackError
from engine.outputs import opentrackio as ot
from engine.outputs.clock import parse_rate, rate_name
from engine.outputs.sender import OutputConfig, TargetSpec
from engine.outputs.studio_frame import StudioFrame
from widgets.param_form import ParamForm

STATUS_MS = 500
#: the output rates the operator can pick ("source": the source's frame rate)
RATE_CHOICES = ("source", "23.976", "24", "25", "29.97", "30", "50", "59.94", "60")
FIELD_W = 110  # numeric editors keep a compact, fixed width
HOST_W = 130
POINT_W = 96
ERROR_COLOR = "#e05050"
OK_COLOR = "#4caf50"
PENDING_COLOR = "#e0a030"
MUTED_COLOR = "#9aa0a6"
DEFAULT_POINTS = ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))


def _port_box(value: int) -> QSpinBox:
    s = QSpinBox()
    s.setRange(1, 65535)
    s.setValue(value)
    s.setFixedWidth(FIELD_W - 20)
    return s


def _form(parent: QWidget) -> QFormLayout:
    """A form laid out like every other on the page: right-aligned labels, compact fields."""
    f = QFormLayout(parent)
    f.setLabelAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
    f.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.FieldsStayAtSizeHint)
    f.setVerticalSpacing(4)
    return f


def _compact(form: ParamForm) -> None:
    """Fixed-width editors in a ParamForm (they would otherwise stretch across the column)."""
    for f in fields(form.params) if form.params is not None else ():
        try:
            w = form.editor(f.name)
        except KeyError:
            continue
        if isinstance(w, QAbstractSpinBox | QComboBox):
            w.setFixedWidth(FIELD_W)


def bind_meaning(address: str) -> str:
    """What a bind address means for the operator, in one line."""
    if address.startswith("127.") or address == "localhost":
        return (f"{address} — loopback only; choose another address to send to the "
                "network")
    if address in ("0.0.0.0", ""):
        return "0.0.0.0 — all interfaces: packets can leave this machine"
    return f"{address} — sends from this interface only"


def _loopback_host(host: str) -> bool:
    return host == "localhost" or host.startswith("127.")


class OutputsPage(Page):
    """Target, lens, delay and studio-frame settings for the pose outputs."""

    refresh_interval_s = STATUS_MS / 1000.0

    def __init__(self, ctx: Any) -> None:
        super().__init__(ctx)
        self.run = ctx.run
        self._applying = False
        self._shown: OutputConfig | None = None
        cfg = self.run.outputs_config

        # -- header: send switch, apply model -------------------------------------------
        self.send_box = QCheckBox("Send poses")
        self.send_box.setObjectName("outputs_send")
        self.send_box.setToolTip("Takes effect immediately. Turning it on applies pending "
                                 "changes first.")
        self.send_box.setStyleSheet("font-weight: bold")
        self.send_box.setChecked(self.run.outputs_enabled)
        self.send_box.toggled.connect(self._on_send_toggled)
        self.send_state = QLabel()
        self.send_state.setObjectName("outputs_send_state")
        self.pending_label = QLabel()
        self.pending_label.setObjectName("outputs_pending")
        self.error_label = QLabel()
        self.error_label.setObjectName("param_error")
        self.error_label.setStyleSheet(f"color: {ERROR_COLOR}")
        self.error_label.setWordWrap(True)
        self.error_label.setSizePolicy(QSizePolicy.Policy.Ignored,
                                       QSizePolicy.Policy.Preferred)
        self.revert_button = QPushButton("Revert")
        self.revert_button.setObjectName("outputs_revert")
        self.revert_button.setToolTip("Discard pending changes; show the settings in force")
        self.revert_button.clicked.connect(self.revert)
        self.apply_button = QPushButton("Apply")
        self.apply_button.setObjectName("outputs_apply")
        self.apply_button.setToolTip("Put the pending changes in force (while sending too)")
        self.apply_button.setDefault(True)
        self.apply_button.clicked.connect(self.apply)
        header = QHBoxLayout()
        header.addWidget(self.send_box)
        header.addWidget(self.send_state)
        header.addSpacing(16)
        header.addWidget(self.error_label, 1)
        header.addWidget(self.pending_label)
        header.addWidget(self.revert_button)
        header.addWidget(self.apply_button)

        # -- targets ---------------------------------------------------------------------
        self.freed_on = QCheckBox("FreeD D1")
        self.freed_host = QLineEdit()
        self.freed_host.setFixedWidth(HOST_W)
        self.freed_host.setToolTip("Unicast, broadcast (x.x.x.255) or multicast address")
        self.freed_port = _port_box(40000)
        self.freed_status = QLabel()
        self.freed_status.setObjectName("outputs_status_freed")
        self.otio_on = QCheckBox("OpenTrackIO 1.0")
        self.otio_host = QLineEdit()
        self.otio_host.setFixedWidth(HOST_W)
        self.otio_host.setToolTip("Unicast or multicast address (default group "
                                  "239.135.1.<source number>)")
        self.otio_port = _port_box(ot.DEFAULT_PORT)
        self.otio_enc = QComboBox()
        self.otio_enc.addItems(["json", "cbor"])
        self.otio_enc.setToolTip("Payload encoding")
        self.otio_status = QLabel()
        self.otio_status.setObjectName("outputs_status_opentrackio")
        for lab in (self.freed_status, self.otio_status):
            # a long error message must not widen the page (full text in the tooltip)
            lab.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
            lab.setMinimumWidth(120)
        mc = QPushButton("Multicast")
        mc.setToolTip(f"Use the OpenTrackIO default 239.135.1.<source number>:{ot.DEFAULT_PORT}")
        mc.clicked.connect(self._use_multicast)
        self.bind_edit = QLineEdit()
        self.bind_edit.setFixedWidth(HOST_W)
        self.bind_edit.setPlaceholderText("automatic")
        self.bind_edit.setToolTip("Local address the output sockets bind to. Empty: 127.0.0.1 "
                                  "(loopback only) for loopback targets, 0.0.0.0 for targets "
                                  "on the network.")
        self.bind_label = QLabel()
        self.bind_label.setObjectName("outputs_bind")
        self.bind_label.setWordWrap(True)
        self.bind_label.setStyleSheet(f"color: {MUTED_COLOR}")
        tg = QGroupBox("Targets (UDP)")
        grid = QGridLayout(tg)
        grid.setVerticalSpacing(4)
        for c, text in enumerate(("", "Host", "Port", "", "Status")):
            h = QLabel(text)
            h.setStyleSheet(f"color: {MUTED_COLOR}")
            grid.addWidget(h, 0, c)
        grid.addWidget(self.freed_on, 1, 0)
        grid.addWidget(self.freed_host, 1, 1)
        grid.addWidget(self.freed_port, 1, 2)
        grid.addWidget(self.freed_status, 1, 4)
        grid.addWidget(self.otio_on, 2, 0)
        grid.addWidget(self.otio_host, 2, 1)
        grid.addWidget(self.otio_port, 2, 2)
        enc = QHBoxLayout()
        enc.addWidget(self.otio_enc)
        enc.addWidget(mc)
        grid.addLayout(enc, 2, 3)
        grid.addWidget(self.otio_status, 2, 4)
        grid.addWidget(QLabel("Bind address"), 3, 0)
        grid.addWidget(self.bind_edit, 3, 1)
        grid.addWidget(self.bind_label, 4, 0, 1, 5)
        grid.setColumnStretch(4, 1)

        # -- camera id and lens mapping --------------------------------------------------
        self.freed_form = ParamForm(cfg.freed)
        self.freed_form.title.setVisible(False)
        self.freed_form.defaults_button.setVisible(False)
        _compact(self.freed_form)
        self.otio_source = QSpinBox()
        self.otio_source.setRange(1, 200)
        self.otio_source.setFixedWidth(FIELD_W)
        self.otio_source.setToolTip("OpenTrackIO source number (also the multicast group)")
        self.sensor_w = QDoubleSpinBox()
        self.sensor_w.setRange(1.0, 100.0)
        self.sensor_w.setDecimals(2)
        self.sensor_w.setSuffix(" mm")
        self.sensor_w.setFixedWidth(FIELD_W)
        self.sensor_w.setToolTip("Sensor width: converts focal length px -> mm (both outputs)")
        self.rate_box = QComboBox()
        self.rate_box.setObjectName("outputs_rate")
        self.rate_box.addItems(list(RATE_CHOICES))
        self.rate_box.setFixedWidth(FIELD_W)
        self.rate_box.setToolTip("Packets leave at this video rate from the output clock "
                                 "(Hz), whatever the tracker's rate; 'source': the source's "
                                 "frame rate")
        lg = QGroupBox("Camera id and lens mapping")
        lv = QHBoxLayout(lg)
        fw = QWidget()
        fl = _form(fw)
        fl.setContentsMargins(0, 0, 0, 0)
        fl.addRow(QLabel("<b>FreeD</b>"))
        fl.addRow(self.freed_form)
        ow = QWidget()
        olay = _form(ow)
        olay.setContentsMargins(0, 0, 0, 0)
        olay.addRow(QLabel("<b>OpenTrackIO</b>"))
        olay.addRow("source number", self.otio_source)
        olay.addRow(QLabel("<b>Both</b>"))
        olay.addRow("sensor width", self.sensor_w)
        olay.addRow("output rate", self.rate_box)
        lv.addWidget(fw, 0, Qt.AlignmentFlag.AlignTop)
        lv.addSpacing(12)
        lv.addWidget(ow, 0, Qt.AlignmentFlag.AlignTop)
        lv.addStretch(1)

        # -- delays ----------------------------------------------------------------------
        self.delay_form = ParamForm(cfg.delays)
        self.delay_form.title.setText("Positive = output lags the tracked pose; "
                                      "negative = predict ahead.")
        _compact(self.delay_form)
        dg = QGroupBox("Delay compensation (per axis)")
        QVBoxLayout(dg).addWidget(self.delay_form)

        # -- studio frame ----------------------------------------------------------------
        self.frame_identity = QRadioButton("Identity (tracker world is the studio, z up)")
        self.frame_points = QRadioButton("From three floor points (world metres)")
        self.points: list[list[QDoubleSpinBox]] = []
        pgrid = QGridLayout()
        pgrid.setVerticalSpacing(4)
        for c, axis in enumerate("xyz"):
            h = QLabel(axis)
            h.setStyleSheet(f"color: {MUTED_COLOR}")
            pgrid.addWidget(h, 0, c + 1, Qt.AlignmentFlag.AlignHCenter)
        for r, (label, vals) in enumerate(zip(("origin", "on +X", "+Y side"), DEFAULT_POINTS,
                                               strict=True)):
            lab = QLabel(label)
            lab.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
            pgrid.addWidget(lab, r + 1, 0)
            row = []
            for c, v in enumerate(vals):
                s = QDoubleSpinBox()
                s.setRange(-1000.0, 1000.0)
                s.setDecimals(3)
                s.setSuffix(" m")
                s.setValue(v)
                s.setFixedWidth(POINT_W)
                pgrid.addWidget(s, r + 1, c + 1)
                row.append(s)
            self.points.append(row)
        pgrid.setColumnStretch(4, 1)
        self.frame_identity.toggled.connect(self._sync_points_enabled)
        sg = QGroupBox("Studio frame")
        sl = QVBoxLayout(sg)
        sl.setSpacing(4)
        sl.addWidget(self.frame_identity)
        sl.addWidget(self.frame_points)
        sl.addLayout(pgrid)

        left = QVBoxLayout()
        left.addWidget(tg)
        left.addWidget(lg)
        left.addStretch(1)
        right = QVBoxLayout()
        right.addWidget(dg)
        right.addWidget(sg)
        right.addStretch(1)
        cols = QHBoxLayout()
        cols.addLayout(left, 3)
        cols.addLayout(right, 2)
        outer = QVBoxLayout(self)
        outer.addLayout(header)
        outer.addLayout(cols, 1)

        self.load(cfg)
        for w in (self.freed_on, self.otio_on, self.frame_identity, self.frame_points):
            w.toggled.connect(self._update_pending)
        for e in (self.freed_host, self.otio_host, self.bind_edit):
            e.textChanged.connect(self._update_pending)
        for s in (self.freed_port, self.otio_port, self.otio_source):
            s.valueChanged.connect(self._update_pending)
        self.sensor_w.valueChanged.connect(self._update_pending)
        self.rate_box.currentTextChanged.connect(self._update_pending)
        for row in self.points:
            for s in row:
                s.valueChanged.connect(self._update_pending)
        self.otio_enc.currentTextChanged.connect(self._update_pending)
        for f in (self.freed_form, self.delay_form):
            f.params_changed.connect(self._update_pending)
            f.edit_rejected.connect(self._update_pending)
        self.run.outputs_changed.connect(self._on_outputs_changed)
        self._update_pending()
        self.refresh_status()

    # ------------------------------------------------------------------ state
    def load(self, cfg: OutputConfig) -> None:
        """Show ``cfg`` in every editor (discarding pending edits)."""
        self._shown = cfg
        freed_t = next((t for t in cfg.targets if t.protocol == "freed"), None)
        otio_t = next((t for t in cfg.targets if t.protocol == "opentrackio"), None)
        bind = next((t.bind_host for t in cfg.targets if t.bind_host), None)
        self.bind_edit.setText(bind or "")
        self.freed_on.setChecked(freed_t is not None)
        if freed_t is not None:
            self.freed_host.setText(freed_t.host)
            self.freed_port.setValue(freed_t.port)
        elif not self.freed_host.text():
            self.freed_host.setText("127.0.0.1")
        self.otio_on.setChecked(otio_t is not None)
        if otio_t is not None:
            self.otio_host.setText(otio_t.host)
            self.otio_port.setValue(otio_t.port)
            self.otio_enc.setCurrentText(otio_t.encoding)
        elif not self.otio_host.text():
            self.otio_host.setText("127.0.0.1")
        self.otio_source.setValue(cfg.opentrackio_source_number)
        self.sensor_w.setValue(cfg.lens.sensor_width_mm)
        self.rate_box.setCurrentText("source" if cfg.rate_hz is None else rate_name(cfg.rate_hz))
        self.freed_form.set_params(cfg.freed)
        self.delay_form.set_params(cfg.delays)
        if cfg.studio == StudioFrame():
            self.frame_identity.setChecked(True)
        else:
            self.frame_points.setChecked(True)
        self._sync_points_enabled()

    @property
    def pending(self) -> bool:
        """True when the editors differ from the configuration in force."""
        if self.freed_form.errors or self.delay_form.errors:
            return True
        try:
            return self.build_config() != self.run.outputs_config
        except StudioTrackError:
            return True

    def _update_pending(self, *_: Any) -> None:
        pending = self.pending
        self.pending_label.setText("● changes pending — not in force until Apply"
                                   if pending else "✓ all changes applied")
        self.pending_label.setStyleSheet(f"color: {PENDING_COLOR if pending else MUTED_COLOR}")
        self.apply_button.setEnabled(pending)
        self.revert_button.setEnabled(pending)
        self._show_bind(self._preview_config())

    def _preview_config(self) -> OutputConfig:
        try:
            return self.build_config()
        except StudioTrackError:
            return self.run.outputs_config

    def _sync_points_enabled(self, *_: Any) -> None:
        on = self.frame_points.isChecked()
        for row in self.points:
            for s in row:
                s.setEnabled(on)

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
        base = self.run.outputs_config
        return replace(
            base,
            targets=tuple(targets),
            freed=self.freed_form.params or base.freed,
            opentrackio_source_number=self.otio_source.value(),
            lens=replace(base.lens, sensor_width_mm=self.sensor_w.value()),
            delays=self.delay_form.params or base.delays,
            studio=studio,
            rate_hz=(None if self.rate_box.currentText() == "source"
                     else parse_rate(self.rate_box.currentText())),
        )

    def apply(self) -> bool:
        errors = {**self.freed_form.errors, **self.delay_form.errors}
        try:
            if errors:
                name, why = next(iter(errors.items()))
                raise StudioTrackError(f"{name}: {why}")
            cfg = self.build_config()
        except StudioTrackError as exc:
            self.error_label.setText(f"Not applied: {exc}")
            self.error_label.setToolTip(str(exc))
            self._update_pending()
            return False
        previous = self.run.outputs_config
        try:
            self._applying = True
            self.run.apply_outputs(cfg)  # refuses a target that cannot be reached at all
        except StudioTrackError as exc:
            self.error_label.setText(f"Not applied: {exc}")
            self.error_label.setToolTip(str(exc))
            self.ctx.log.error(f"outputs not applied: {exc}")
            self._update_pending()
            return False
        finally:
            self._applying = False
        self._shown = cfg
        proj = self.ctx.project
        if proj is not None and cfg.studio != previous.studio:  # the operator changed it
            proj.studio_frame = None if cfg.studio == StudioFrame() else cfg.studio
            proj.mark_dirty()
            self.ctx.log.info("studio frame saved in the project (unsaved until File > Save)")
        self.error_label.setText("")
        self.ctx.log.info("outputs: configuration applied")
        return True

    def revert(self) -> None:
        self.load(self.run.outputs_config)
        self.error_label.setText("")
        self._update_pending()

    def _on_send_toggled(self, on: bool) -> None:
        if on and self.pending and not self.apply():
            self.send_box.setChecked(False)
            return
        try:
            self.run.set_outputs_enabled(on)
        except StudioTrackError as exc:
            self.error_label.setText(f"Not switched on: {exc}")
            self.ctx.log.error(f"outputs not switched on: {exc}")
            self.send_box.setChecked(False)
        self.refresh_status()

    def _on_outputs_changed(self) -> None:
        if not self._applying and self._shown != self.run.outputs_config:
            self.load(self.run.outputs_config)  # changed elsewhere: show what is in force
        if self.send_box.isChecked() != self.run.outputs_enabled:
            self.send_box.blockSignals(True)
            self.send_box.setChecked(self.run.outputs_enabled)
            self.send_box.blockSignals(False)
        self._update_pending()
        self.refresh_status()

    def refresh(self) -> None:
        self.refresh_status()

    # ------------------------------------------------------------------ read-outs
    def _show_bind(self, cfg: OutputConfig) -> None:
        if not cfg.targets:
            self.bind_label.setText("No target enabled.")
            return
        binds = {t.effective_bind for t in cfg.targets}
        if len(binds) == 1:
            self.bind_label.setText("Binds to " + bind_meaning(binds.pop()))
        else:
            self.bind_label.setText("\n".join(
                f"{t.protocol} binds to {bind_meaning(t.effective_bind)}"
                for t in cfg.targets))
        unreachable = [t.host for t in cfg.targets
                       if t.effective_bind.startswith("127.") and not _loopback_host(t.host)]
        if unreachable:
            self.bind_label.setText(self.bind_label.text() + "\n⚠ " + ", ".join(unreachable)
                                    + " cannot be reached from a loopback bind address")
        self.bind_label.setAlignment(Qt.AlignmentFlag.AlignLeft)

    def refresh_status(self) -> None:
        """Per-target status: off / armed / waiting for poses / sending N Hz / FAILING."""
        st = self.run.output_stats() if self.run.is_running else None
        by_protocol = {t.protocol: t for t in st.targets} if st is not None else {}
        applied = {t.protocol for t in self.run.outputs_config.targets}
        for proto, label in (("freed", self.freed_status), ("opentrackio", self.otio_status)):
            t = by_protocol.get(proto)
            if proto not in applied:
                text, color, tip = "off (target disabled)", MUTED_COLOR, ""
            elif not self.run.outputs_enabled:
                text, color, tip = "off (sending is off)", MUTED_COLOR, ""
            elif st is None or t is None:
                text, color, tip = "armed (no run)", PENDING_COLOR, \
                    "sends when a run starts on any page"
            elif t.failing:
                # green only while packets leave without error
                text, color, tip = f"FAILING ×{t.errors}: {t.last_error}", ERROR_COLOR, \
                    f"{t.errors} failed sends; last: {t.last_error}"
            elif t.rate_hz >= 0.5:
                text, color = f"sending {t.rate_hz:.0f} Hz", OK_COLOR
                tip = f"{t.packets_sent} packets to {t.address}"
                if t.errors:
                    text += f" · {t.errors} errors"
                    tip += f"; last error: {t.last_error}"
            else:
                text, color, tip = "waiting for poses", PENDING_COLOR, \
                    f"{t.packets_sent} packets sent so far"
            label.setText(text)
            label.setToolTip(tip)
            label.setStyleSheet(f"color: {color}")
        if not self.run.outputs_enabled:
            self.send_state.setText("off — nothing is sent")
            self.send_state.setStyleSheet(f"color: {MUTED_COLOR}")
        elif st is None:
            self.send_state.setText("on — armed, sends while a run is active")
            self.send_state.setStyleSheet(f"color: {PENDING_COLOR}")
        else:
            n = len(st.targets)
            rate = (f" at {st.rate_hz:.3f} Hz (output clock)" if st.clocked
                    else " per tracked frame")
            self.send_state.setText(f"on — {n} target{'s' if n != 1 else ''}{rate}")
            self.send_state.setStyleSheet(f"color: {OK_COLOR}")


PAGES = (
    PageSpec(title="Outputs", order=50, factory=OutputsPage,
             tooltip="FreeD / OpenTrackIO targets, lens mapping, delays, studio frame"),
)
