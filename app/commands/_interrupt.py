"""Clean stops on SIGINT / SIGTERM for long CLI runs (``track``, ``record``, ``sweep``...).

``with StopSignals() as stop: run(..., should_stop=stop)``: the first Ctrl-C (or SIGTERM)
only sets a flag that the engine loop polls once per frame, so the run ends after the
current frame and the command writes what was done, flagged partial. A second signal aborts
at once (``KeyboardInterrupt``: the CLI prints ``studiotrack: interrupted``). The previous
handlers are put back on exit; outside the main thread nothing is installed.
"""

from __future__ import annotations

import signal
import threading
from types import FrameType
from typing import Any

from engine.progress import log

SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: exit codes of a run a signal stopped (the shell's 128 + signal number)
EXIT_CODES = {"SIGINT": 130, "SIGTERM": 143}


class StopSignals:
    """A ``should_stop`` callable that turns true after SIGINT/SIGTERM."""

    def __init__(self, what: str = "the run") -> None:
        self.what = what
        self.signal_name: str | None = None
        self._old: dict[int, Any] = {}

    def __call__(self) -> bool:
        return self.signal_name is not None

    @property
    def reason(self) -> str:
        return f"interrupted by {self.signal_name}" if self.signal_name else ""

    @property
    def exit_code(self) -> int:
        return EXIT_CODES.get(self.signal_name or "", 0)

    def _handle(self, signum: int, _frame: FrameType | None) -> None:
        name = signal.Signals(signum).name
        if self.signal_name is not None:
            raise KeyboardInterrupt  # second signal: abort now
        self.signal_name = name
        log(f"{name}: stopping {self.what} after this frame and saving what was done "
            "(again to abort without saving)")

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            for sig in SIGNALS:
                self._old[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old.clear()
