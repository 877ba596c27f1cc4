"""The newest-frame policy of live sources: grab on a thread, hand out only the newest frame.

A live camera keeps delivering at its own rate whatever the tracker does. If the tracker is
slower, queued frames would make the output ever later; so a grabber thread reads the
device continuously and keeps only the newest item, and :meth:`NewestGrabber.take` returns
it together with the number of items nobody took since the previous take (the frames the
engine skipped). The operator sees the rate of skipped frames ("skipping N frames/s").

The thread only reads: it never blocks on the consumer. An exception in ``grab`` is kept and
re-raised by the next :meth:`take`, after the items that arrived before it.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

T = TypeVar("T")

#: window of the skipped-frames rate
RATE_WINDOW_S = 1.0


@dataclass(frozen=True, slots=True)
class Grabbed(Generic[T]):
    """One item handed to the consumer."""

    item: T
    #: arrival count of this item (1 = first item grabbed)
    seq: int
    #: items that arrived after the previous take and were dropped for this one
    skipped: int
    #: ``time.monotonic()`` when the grab returned (the capture time on the host clock)
    arrival_s: float


class NewestGrabber(Generic[T]):
    """Run ``grab()`` on a daemon thread; keep the newest result; count the dropped ones.

    ``grab`` blocks until the device delivers (or raises); returning ``None`` means "nothing
    this time" (a timeout) and is not counted as a frame.
    """

    def __init__(self, grab: Callable[[], T | None], name: str = "grabber") -> None:
        self._grab = grab
        self._name = name
        self._cond = threading.Condition()
        self._latest: tuple[T, int, float] | None = None
        self._arrived = 0
        self._taken_seq = 0
        self._error: BaseException | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._skip_times: deque[tuple[float, int]] = deque()
        self.total_skipped = 0

    def start(self) -> None:
        if self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                item = self._grab()
            except BaseException as exc:  # handed to the consumer by take()
                with self._cond:
                    self._error = exc
                    self._cond.notify_all()
                return
            if item is None:
                continue
            now = time.monotonic()
            with self._cond:
                self._arrived += 1
                self._latest = (item, self._arrived, now)
                self._cond.notify_all()

    def take(self, timeout_s: float) -> Grabbed[T] | None:
        """The newest item not yet taken, waiting up to ``timeout_s``; None on timeout.

        Raises what ``grab`` raised once no newer item is waiting.
        """
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while self._latest is None or self._latest[1] <= self._taken_seq:
                if self._error is not None:
                    err, self._error = self._error, None
                    raise err
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._cond.wait(left)
            item, seq, arrival = self._latest
            skipped = seq - self._taken_seq - 1
            self._taken_seq = seq
            if skipped:
                self.total_skipped += skipped
                self._skip_times.append((arrival, skipped))
            return Grabbed(item=item, seq=seq, skipped=skipped, arrival_s=arrival)

    def skipped_per_s(self, now_s: float | None = None) -> float:
        """Frames skipped over the last :data:`RATE_WINDOW_S` seconds, per second."""
        now = time.monotonic() if now_s is None else now_s
        with self._cond:
            while self._skip_times and self._skip_times[0][0] < now - RATE_WINDOW_S:
                self._skip_times.popleft()
            return sum(n for _, n in self._skip_times) / RATE_WINDOW_S

    def stop(self, join_timeout_s: float = 2.0) -> None:
        """Ask the thread to end and wait for it (the current ``grab`` must return first)."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join(join_timeout_s)
        with self._cond:
            self._latest = None
            self._error = None
            self._taken_seq = self._arrived

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()
