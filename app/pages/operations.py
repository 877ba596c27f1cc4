"""The Operations page: is the show healthy? Everything live, refreshed twice a second.

Tracker frames/s against the target, tracker time p50/p95 and end-to-end latency
(capture -> packet on the wire), tracking state, frames dropped by the display, status and
output rate per target with its bind address and last send error (configured targets show
"off" while outputs are off; the output-rate curve is hidden then), held/LOST output slots,
and the process's CPU and memory (psutil). Everything is read from the run owner's status
on the window's display clock while the page is shown; after Stop the engine numbers clear.
"""

from __future__ import annotations

import time
from collections import deque
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QAbstractItemView,
    QGridLayout,
    QGroupBox,
    QHeaderView,
    QLabel,
    QSizePolicy,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
)

from app.pages import PageSpec
from app.pages._base import Page
from app.status import header_state
from widgets.plot_grid import GridLines

REFRESH_MS = 500
HISTORY = 240  # samples of the rate/memory plots (2 minutes at 2 Hz)
COLUMNS = ("Target", "Bound to", "Status", "Rate (Hz)", "Packets", "Errors", "Last send error")
COL = {name: i for i, name in enumerate(COLUMNS)}
#: starting widths (px) of the interactive columns; numbers are sized to their contents
#: "Target" takes the spare width; an error message is elided (full text in the tooltip)
COLUMN_WIDTHS = {"Bound to": 150, "Status": 130, "Last send error": 300}
ERROR_COLOR = "#e05050"
OK_COLOR = "#4caf50"
MUTED_COLOR = "#9aa0a6"


class OperationsPage(Page):
    """Live health read-outs for the operator."""

    refresh_interval_s = REFRESH_MS / 1000.0

    def __init__(self, ctx: Any) -> None:
        super().__init__(ctx)
        import psutil

        self.run = ctx.run
        self._proc = psutil.Process()
        self._proc.cpu_percent(None)  # first call primes the counter
        self._cpu_t = time.monotonic()
        self._cpu = float("nan")
        self.values: dict[str, QLabel] = {}

        eng = QGroupBox("Engine")
        g = QGridLayout(eng)
        g.setVerticalSpacing(2)
        g.setHorizontalSpacing(18)
        items = [
            ("state", "Tracking state", "what the status header says"),
            ("fps", "Tracker frames/s", "frames over the last second / the source's rate"),
            ("p50", "Tracker p50 / p95", "tracker time per frame, last 600 frames"),
            ("p95", "Capture→wire p95", "capture -> packet on the wire (outputs on), else "
             "capture -> tracker done; p95 / max of the last 600"),
            ("frames", "Frames this run", "frames tracked since the run started; dropped: "
             "records the display skipped (the engine never waits for it)"),
            ("cpu", "CPU (process)", "StudioTrack process CPU, % of one core"),
            ("rss", "Memory (RSS)", "resident memory of the process"),
            ("threads", "Threads", "threads in the process"),
        ]
        per_row = 4
        for i, (key, cap, tip) in enumerate(items):
            c = QLabel(cap)
            c.setToolTip(tip)
            c.setStyleSheet(f"color: {MUTED_COLOR}")
            v = QLabel("–")
            v.setObjectName(f"ops_{key}")
            v.setToolTip(tip)
            v.setStyleSheet("font-weight: bold; font-size: 15px")
            r, col = divmod(i, per_row)
            g.addWidget(c, 2 * r, col)
            g.addWidget(v, 2 * r + 1, col)
            self.values[key] = v
        for col in range(per_row):
            g.setColumnStretch(col, 1)
        eng.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Maximum)

        out = QGroupBox("Outputs")
        ol = QVBoxLayout(out)
        self.sender_label = QLabel("Outputs off (enable them on the Outputs page)")
        self.sender_label.setObjectName("ops_sender")
        # no word wrap: a wrapping label makes the page height-for-width, and the main
        # window's scroll area would then size it by the plot's (large) size hint
        self.sender_label.setSizePolicy(QSizePolicy.Policy.Ignored,
                                        QSizePolicy.Policy.Preferred)
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setObjectName("ops_targets")
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        self.table.verticalHeader().setVisible(False)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.NoSelection)
        self.table.setWordWrap(False)
        self.table.setTextElideMode(Qt.TextElideMode.ElideMiddle)
        header = self.table.horizontalHeader()
        header.setStretchLastSection(False)
        for name, col in COL.items():
            if name == "Target":
                header.setSectionResizeMode(col, QHeaderView.ResizeMode.Stretch)
            elif name in COLUMN_WIDTHS:
                header.setSectionResizeMode(col, QHeaderView.ResizeMode.Interactive)
                header.resizeSection(col, COLUMN_WIDTHS[name])
            else:
                header.setSectionResizeMode(col, QHeaderView.ResizeMode.ResizeToContents)
        self.table.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Maximum)
        ol.addWidget(self.sender_label)
        ol.addWidget(self.table)
        out.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Maximum)

        self.plot = pg.PlotWidget()
        self.plot.setObjectName("ops_plot")
        self.plot.setLabel("left", "frames/s")
        self.plot.setLabel("bottom", "seconds ago")
        self.plot.addLegend(offset=(5, 5))
        self.grid = GridLines(self.plot.getPlotItem())  # cheap to repaint
        self.fps_curve = self.plot.plot(pen=pg.mkPen("#4caf50", width=2), name="tracker fps")
        self.rate_curve = self.plot.plot(pen=pg.mkPen("#2196f3", width=2), name="output Hz")
        self.fps_hist: deque[float] = deque(maxlen=HISTORY)
        self.rate_hist: deque[float] = deque(maxlen=HISTORY)

        self.legend = self.plot.plotItem.legend
        self.plot.setMinimumHeight(180)
        self.plot.enableAutoRange(axis="y", enable=False)
        self.plot.setMouseEnabled(x=False, y=False)
        self.rate_off = pg.TextItem("output Hz: off", color=MUTED_COLOR, anchor=(1, 0))
        self.plot.addItem(self.rate_off, ignoreBounds=True)
        self._rate_shown = True

        layout = QVBoxLayout(self)
        layout.addWidget(eng)
        layout.addWidget(self.plot, 1)
        layout.addWidget(out)

        self.refresh()

    def refresh(self) -> None:
        run = self.run
        running = run.is_running
        v = self.values
        st = run.status() if running else None
        v["state"].setText(header_state(run).state)
        fps = st.fps if st is not None else 0.0
        if st is not None and st.frames:
            v["fps"].setText(f"{st.fps:.1f}" + (f" / {st.target_fps:.2f}" if st.target_fps
                                                 else ""))
            tm = st.tracker_ms
            v["p50"].setText("–" if tm is None else f"{tm.p50_ms:.1f} / {tm.p95_ms:.1f} ms")
            out = run.output_health()
            lat = out.latency if out is not None and out.latency is not None else \
                st.capture_to_done
            v["p95"].setText("–" if lat is None else f"{lat.p95_ms:.1f} / {lat.max_ms:.0f} ms")
            v["frames"].setText(f"{st.frames} (dropped {st.display_dropped})")
        else:  # nothing stale after Stop
            for key in ("fps", "p50", "p95"):
                v[key].setText("–")
            v["frames"].setText("–")
        try:
            now = time.monotonic()
            if now - self._cpu_t >= 0.25:  # a shorter interval would read ~0 %
                self._cpu = self._proc.cpu_percent(None)
                self._cpu_t = now
            v["cpu"].setText(f"{self._cpu:.0f} %" if self._cpu == self._cpu else "–")
            v["rss"].setText(f"{self._proc.memory_info().rss / 2**20:.0f} MB")
            v["threads"].setText(str(self._proc.num_threads()))
        except Exception as exc:  # psutil on an exotic platform: show, never crash
            v["cpu"].setText(type(exc).__name__)
        st_out = run.output_stats() if running and run.outputs_enabled else None
        rate = float("nan")
        cfg = run.outputs_config
        if st_out is None and run.outputs_enabled:
            self.sender_label.setText("Outputs armed — they send while a run is active. "
                                      "Configured targets:")
            rows = [(t.name, t.effective_bind, "armed (no run)", "–", "–", "–", "–", "")
                    for t in cfg.targets]
        elif st_out is None:
            self.sender_label.setText("Outputs off — nothing is sent (switch them on on the "
                                      "Outputs page). Configured targets:")
            # not bound to anything while off: say what it would bind to
            rows = [(t.name, f"{t.effective_bind} (when on)", "off", "–", "–", "–", "–", "")
                    for t in cfg.targets]
        else:
            st = st_out
            self.sender_label.setText(
                (f"Clocked at {st.rate_hz:.3f} Hz: {st.ticks} slots, {st.held_ticks} held, "
                 f"{st.lost_ticks} flagged LOST, {st.missed_ticks} missed; "
                 if st.clocked else f"Per record: {st.ticks} samples; ")
                + f"dropped (queue full) {st.dropped}, skipped (no pose yet) "
                f"{st.skipped_no_pose}, encode errors {st.encode_errors}"
                + (f" – {st.last_encode_error}" if st.last_encode_error else ""))
            rows = []
            for t in st.targets:
                if t.failing:
                    status = "error"
                elif t.rate_hz >= 0.5:
                    status = f"sending {t.rate_hz:.0f} Hz"
                else:
                    status = "waiting for poses"
                rows.append((t.name, t.bind, status, f"{t.rate_hz:.1f}", str(t.packets_sent),
                             str(t.errors), t.last_error or "–", t.last_error))
            rate = max((t.rate_hz for t in st.targets), default=0.0)
        self.sender_label.setToolTip(self.sender_label.text())
        self._fill_table(rows)
        self.fps_hist.append(fps if running else 0.0)
        self.rate_hist.append(rate)
        x = -np.arange(len(self.fps_hist))[::-1] * REFRESH_MS / 1000.0
        fps = np.fromiter(self.fps_hist, dtype=np.float64)
        rates = np.fromiter(self.rate_hist, dtype=np.float64)
        self.fps_curve.setData(x, fps)
        # Outputs off: no flat zero line -- the rate curve is hidden and the plot says "off".
        self._show_rate(st_out is not None)
        self.rate_curve.setData(x, rates, connect="finite")
        top = np.nanmax(np.concatenate([fps, rates, [0.0]]))
        self.plot.setYRange(0.0, max(10.0, float(top) * 1.15), padding=0)
        self.plot.setXRange(min(float(x[0]), -10.0), 0.0, padding=0.02)
        self.rate_off.setPos(0.0, max(10.0, float(top) * 1.15))

    def _show_rate(self, on: bool) -> None:
        if on == self._rate_shown:
            return
        self._rate_shown = on
        self.rate_curve.setVisible(on)
        self.rate_off.setVisible(not on)
        if on:
            self.legend.addItem(self.rate_curve, "output Hz")
        else:
            self.legend.removeItem(self.rate_curve)

    def _fill_table(self, rows: list[tuple[str, ...]]) -> None:
        self.table.setRowCount(len(rows))
        for r, row in enumerate(rows):
            *cells, tip = row
            for col, text in enumerate(cells):
                item = QTableWidgetItem(text)
                if col in (COL["Rate (Hz)"], COL["Packets"], COL["Errors"]):
                    item.setTextAlignment(Qt.AlignmentFlag.AlignRight
                                          | Qt.AlignmentFlag.AlignVCenter)
                if col == COL["Status"]:
                    color = (ERROR_COLOR if text == "error" else OK_COLOR
                             if text.startswith("sending") else MUTED_COLOR)
                    item.setForeground(pg.mkColor(color))
                if col == COL["Errors"] and text not in ("0", "–"):
                    item.setForeground(pg.mkColor(ERROR_COLOR))
                item.setToolTip(tip or text)
                self.table.setItem(r, col, item)
        # compact: exactly as tall as its rows (at least one empty row's worth)
        h = self.table.horizontalHeader().height() + 2 * self.table.frameWidth()
        h += sum(self.table.rowHeight(r) for r in range(len(rows))) or 24
        self.table.setFixedHeight(h + 2)

PAGES = (
    PageSpec(title="Operations", order=70, factory=OperationsPage,
             tooltip="Live health: frames/s, latency, output rates, errors, CPU, memory"),
)
