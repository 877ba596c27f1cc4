"""A one-line progress bar on stderr for long CLI jobs (plain lines when stderr is no TTY)."""

from __future__ import annotations

import sys
import time
from typing import TextIO

from engine.progress import log


class ProgressBar:
    """``[########............]  48/120 frames  1.6 s  (2 skipped)``, redrawn in place.

    ``total`` None (a live source captured for a time) draws a counter without a bar. When
    the stream is not a terminal, a plain line is printed at every tenth of the total (or
    every ``every`` items) so logs stay readable.
    """

    def __init__(self, total: int | None, unit: str = "frames", *, width: int = 30,
                 stream: TextIO | None = None, every: int = 30) -> None:
        self.total = total if total else None
        self.unit = unit
        self.width = width
        self._own_stream = stream is not None
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.every = max(1, (self.total // 10) if self.total else every)
        self._t0 = time.monotonic()
        self._last_draw = 0.0
        self._shown = False

    def text(self, n: int, extra: str = "") -> str:
        secs = time.monotonic() - self._t0
        if self.total:
            filled = min(self.width, round(self.width * n / self.total))
            bar = "[" + "#" * filled + "." * (self.width - filled) + "] "
            count = f"{n:>{len(str(self.total))}}/{self.total} {self.unit}"
        else:
            bar, count = "", f"{n} {self.unit}"
        return f"{bar}{count}  {secs:.1f} s" + (f"  ({extra})" if extra else "")

    def update(self, n: int, extra: str = "") -> None:
        now = time.monotonic()
        done = self.total is not None and n >= self.total
        if self.tty:
            if done or now - self._last_draw >= 0.1:
                self._last_draw = now
                self.stream.write("\r" + self.text(n, extra) + "\x1b[K")
                self.stream.flush()
                self._shown = True
        elif n % self.every == 0 or done:
            if self._own_stream:
                print(self.text(n, extra), file=self.stream, flush=True)
            else:  # a progress line like every other (engine.progress), not an error line
                log(self.text(n, extra))

    def close(self) -> None:
        if self.tty and self._shown:
            self.stream.write("\n")
            self.stream.flush()
