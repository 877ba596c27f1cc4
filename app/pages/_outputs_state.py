"""Pose-output state shared by the Outputs and Operations pages (one per AppContext).

The controller owns the :class:`engine.outputs.sender.OutputSet`. It feeds it from the
bridge's ``result_ready`` (the engine waits for the GUI to take each record, so every tracked
frame arrives; sending itself happens on the sender thread, so the GUI never waits for the
network). When the engine fails mid-show the last pose is re-sent flagged LOST.
"""

from __future__ import annotations

from collections import deque
from typing import Any

from PySide6.QtCore import QObject, Signal, Slot

from engine.outputs import OutputError
from engine.outputs.sender import OutputConfig, OutputSet, SenderStats, TargetSpec

DEFAULT_CONFIG = OutputConfig(
    targets=(
        TargetSpec("freed", "127.0.0.1", 40000),
        TargetSpec("opentrackio", "127.0.0.1", 55555, "json"),
    )
)


class OutputsController(QObject):
    """Holds the output configuration, the sender, and per-frame engine statistics."""

    config_changed = Signal(object)  # OutputConfig
    enabled_changed = Signal(bool)

    def __init__(self, ctx: Any) -> None:
        super().__init__(ctx if isinstance(ctx, QObject) else None)
        self.ctx = ctx
        self.config: OutputConfig = DEFAULT_CONFIG
        self.outputs: OutputSet | None = None
        self.process_ms: deque[float] = deque(maxlen=600)
        self.fps = 0.0
        self.frames = 0
        self.last_state = "–"
        ctx.bridge.result_ready.connect(self._on_record)
        ctx.bridge.failed.connect(self._on_failed)
        ctx.bridge.started.connect(self._on_started)

    @property
    def enabled(self) -> bool:
        return self.outputs is not None

    def set_enabled(self, on: bool) -> None:
        if on == self.enabled:
            return
        if on:
            self.outputs = OutputSet(self.config)
            self._log("info", "outputs on: " + ", ".join(
                f"{t.name} (bind {t.effective_bind})" for t in self.config.targets))
        else:
            assert self.outputs is not None
            self.outputs.close()
            self.outputs = None
            self._log("info", "outputs off")
        self.enabled_changed.emit(on)

    def apply(self, config: OutputConfig) -> None:
        if not isinstance(config, OutputConfig):
            raise OutputError("not an output configuration")
        self.config = config
        if self.outputs is not None:
            self.outputs.set_config(config)
        self.config_changed.emit(config)

    def stats(self) -> SenderStats | None:
        return self.outputs.stats() if self.outputs is not None else None

    def shutdown(self) -> None:
        if self.outputs is not None:
            self.outputs.close()
            self.outputs = None

    @Slot()
    def _on_started(self) -> None:
        self.process_ms.clear()
        self.frames = 0

    @Slot(object)
    def _on_record(self, record: Any) -> None:
        self.frames += 1
        self.process_ms.append(float(record.process_ms))
        self.fps = float(record.fps)
        self.last_state = record.result.state.value
        if self.outputs is not None:
            self.outputs.submit_record(record)

    @Slot(str)
    def _on_failed(self, message: str) -> None:
        if self.outputs is not None:
            self.outputs.mark_lost()
            self._log("warning", "engine failed: outputs hold the last pose, flagged LOST")
        self.last_state = "LOST"

    def _log(self, level: str, text: str) -> None:
        log = getattr(self.ctx, "log", None)
        fn = getattr(log, level, None)
        if callable(fn):
            fn(text)


def controller(ctx: Any) -> OutputsController:
    """The context's controller, created on first use."""
    c = getattr(ctx, "_outputs_controller", None)
    if c is None:
        c = OutputsController(ctx)
        ctx._outputs_controller = c  # the sender thread is a daemon; shutdown() closes it
    return c
