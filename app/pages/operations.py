"""The Operations page: is the show healthy? Everything live, refreshed twice a second.

Tracker frames/s, processing latency p50/p95 (last 600 frames), tracking state, output rate
per target with its bind address and last send error, dropped samples, and the process's CPU
and memory (psutil). Data arrival (``result_ready``) only appends numbers; a QTimer redraws.
"""

from __future__ import annotations

import time
from collections import deque
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import (
    QAbstractItemView,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from app.pages import PageSpec
from app.pages._outputs_state import controller

REFRESH_MS = 500
HISTORY = 240  # samples of the rate/memory plots (2 minutes at 2 Hz)
COLUMNS = ("Target", "Bound to", "Rate (Hz)", "Packets", "Errors", "Last send error")


class OperationsPage(QWidget):
    """Live health read-outs for the operator."""

    def __init__(self, ctx: Any) -> None:
        super().__init__()
        import psutil

        self.ctx = ctx
        self.ctrl = controller(ctx)
        self._proc = psutil.Process()
        self._proc.cpu_percent(None)  # first call primes the counter
        self._cpu_t = time.monotonic()
        self._cpu = float("nan")
        self.values: dict[str, QLabel] = {}

        eng = QGroupBox("Engine")
        g = QGridLayout(eng)
        items = [
            ("state", "Tracking state", "state of the last tracked frame"),
            ("fps", "Tracker frames/s", "engine loop rate (EMA)"),
            ("p50", "Latency p50", "median processing time per frame, last 600 frames"),
            ("p95", "Latency p95", "95th percentile processing time, last 600 frames"),
            ("frames", "Frames this run", "frames tracked since the run started"),
            ("cpu", "CPU (process)", "StudioTrack process CPU, % of one core"),
            ("rss", "Memory (RSS)", "resident memory of the process"),
            ("threads", "Threads", "threads in the process"),
        ]
        for i, (key, cap, tip) in enumerate(items):
            c = QLabel(cap)
            c.setToolTip(tip)
            v = QLabel("–")
            v.setObjectName(f"ops_{key}")
            v.setToolTip(tip)
            v.setStyleSheet("font-weight: bold")
            g.addWidget(c, i // 2, (i % 2) * 2)
            g.addWidget(v, i // 2, (i % 2) * 2 + 1)
            self.values[key] = v
        g.setRowStretch(len(items) // 2, 1)

        out = QGroupBox("Outputs")
        ol = QVBoxLayout(out)
        self.sender_label = QLabel("Outputs off (enable them on the Outputs page)")
        self.sender_label.setObjectName("ops_sender")
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setObjectName("ops_targets")
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        self.table.verticalHeader().setVisible(False)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        header = self.table.horizontalHeader()
        for col in range(len(COLUMNS) - 1):
            header.setSectionResizeMode(col, QHeaderView.ResizeMode.ResizeToContents)
        header.setSectionResizeMode(len(COLUMNS) - 1, QHeaderView.ResizeMode.Stretch)
        ol.addWidget(self.sender_label)
        ol.addWidget(self.table)

        self.plot = pg.PlotWidget()
        self.plot.setObjectName("ops_plot")
        self.plot.setLabel("left", "frames/s")
        self.plot.setLabel("bottom", "seconds ago")
        self.plot.addLegend(offset=(5, 5))
        self.plot.showGrid(x=True, y=True, alpha=0.2)
        self.fps_curve = self.plot.plot(pen=pg.mkPen("#4caf50", width=2), name="tracker fps")
        self.rate_curve = self.plot.plot(pen=pg.mkPen("#2196f3", width=2), name="output Hz")
        self.fps_hist: deque[float] = deque(maxlen=HISTORY)
        self.rate_hist: deque[float] = deque(maxlen=HISTORY)

        top = QHBoxLayout()
        top.addWidget(eng, 1)
        top.addWidget(self.plot, 1)
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addWidget(out, 1)

        self.timer = QTimer(self)
        self.timer.setInterval(REFRESH_MS)
        self.timer.timeout.connect(self.refresh)
        self.timer.start()
        self.refresh()

    def refresh(self) -> None:
        c = self.ctrl
        running = bool(getattr(self.ctx.bridge, "is_running", False))
        v = self.values
        v["state"].setText(c.last_state)
        v["fps"].setText(f"{c.fps:.1f}" if c.frames else "–")
        if c.process_ms:
            a = np.fromiter(c.process_ms, dtype=np.float64)
            v["p50"].setText(f"{np.percentile(a, 50):.1f} ms")
            v["p95"].setText(f"{np.percentile(a, 95):.1f} ms")
        v["frames"].setText(str(c.frames))
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
        st = c.stats()
        rate = 0.0
        if st is None:
            self.sender_label.setText("Outputs off (enable them on the Outputs page)")
            self.table.setRowCount(0)
        else:
            self.sender_label.setText(
                f"Samples submitted {st.submitted}, dropped (queue full) {st.dropped}, "
                f"skipped (no pose yet) {st.skipped_no_pose}, encode errors {st.encode_errors}; "
                f"queue→sent latency p50 {st.latency_p50_ms:.2f} ms, "
                f"p95 {st.latency_p95_ms:.2f} ms"
                + (f" – {st.last_encode_error}" if st.last_encode_error else ""))
            self.table.setRowCount(len(st.targets))
            for r, t in enumerate(st.targets):
                cells = (t.name, t.bind, f"{t.rate_hz:.1f}", str(t.packets_sent),
                         str(t.errors), t.last_error or "–")
                for col, text in enumerate(cells):
                    item = QTableWidgetItem(text)
                    if col == 4 and t.errors:
                        item.setForeground(pg.mkColor("#e05050"))
                    self.table.setItem(r, col, item)
            rate = max((t.rate_hz for t in st.targets), default=0.0)
        self.fps_hist.append(c.fps if running else 0.0)
        self.rate_hist.append(rate)
        x = -np.arange(len(self.fps_hist))[::-1] * REFRESH_MS / 1000.0
        self.fps_curve.setData(x, np.fromiter(self.fps_hist, dtype=np.float64))
        self.rate_curve.setData(x, np.fromiter(self.rate_hist, dtype=np.float64))


PAGE = PageSpec(title="Operations", order=60, factory=OperationsPage,
                tooltip="Live health: frames/s, latency, output rates, errors, CPU, memory")
