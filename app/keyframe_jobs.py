"""Engine-thread jobs of the Keyframes page: record a sweep, fuse depth, run SBA.

One ``QThread`` per job runs a plain engine function with ``should_stop`` polling
``isInterruptionRequested()`` (never ``terminate()``); progress records (frozen dataclasses or
tuples) and the result cross to the GUI thread through queued signals.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QObject, QThread, Signal

from app.run_owner import _THREADS
from engine.pipeline import one_line


class JobThread(QThread):
    """Runs ``fn(should_stop, progress)`` on its own thread."""

    progressed = Signal(object)
    succeeded = Signal(object)
    failed = Signal(str)

    def __init__(
        self,
        fn: Callable[[Callable[[], bool], Callable[[Any], None]], Any],
        parent: QObject | None = None,
    ) -> None:
        super().__init__(parent)
        self._fn = fn
        _THREADS.append(self)  # seen by the tests' dangling-thread check
        self.finished.connect(self._forget)

    def _forget(self) -> None:
        if self in _THREADS:
            _THREADS.remove(self)

    def run(self) -> None:
        try:
            result = self._fn(self.isInterruptionRequested, self.progressed.emit)
        except Exception as exc:
            self.failed.emit(one_line(exc))
            return
        self.succeeded.emit(result)

    def cancel(self, wait_ms: int = 10000) -> None:
        self.requestInterruption()
        self.wait(wait_ms)
