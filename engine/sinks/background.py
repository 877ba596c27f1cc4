"""A sink on its own thread: slow work (disk) off the engine thread.

:class:`BackgroundSink` wraps another sink: ``on_record`` only queues the record (bounded;
the engine never waits) and a worker thread calls the inner sink in order. When the queue is
full the record is dropped and counted (health WARNING with the count: a recording then has
a gap, and says so). An exception of the inner sink on the worker disables it (health
FAILED with the one-line reason); tracking goes on.
"""

from __future__ import annotations

import collections
import threading

from engine.pipeline import RunInfo, SinkBase, SinkHealth, SinkLevel, one_line
from engine.records import FrameRecord
from engine.sinks import SinkSpec

_STOP = object()


class BackgroundSink(SinkBase):
    """Runs ``inner`` (a :class:`engine.pipeline.Sink`) on a worker thread."""

    def __init__(self, inner: SinkBase, max_queue: int = 64) -> None:
        self.inner = inner
        self.name = str(getattr(inner, "name", "sink"))
        self.max_queue = max(1, int(max_queue))
        self._q: collections.deque[object] = collections.deque()
        self._cond = threading.Condition()
        self._thread: threading.Thread | None = None
        self.dropped = 0
        self.error = ""

    def open(self, run: RunInfo) -> None:
        self.inner.open(run)
        self._thread = threading.Thread(target=self._work, name=f"sink-{self.name}",
                                        daemon=True)
        self._thread.start()

    def on_record(self, record: FrameRecord) -> None:
        if self.error:
            return
        with self._cond:
            if len(self._q) >= self.max_queue:
                self.dropped += 1
                return
            self._q.append(record)
            self._cond.notify()

    def on_fault(self, message: str) -> None:
        with self._cond:
            self._q.append(("fault", message))
            self._cond.notify()

    def close(self, timeout_s: float = 30.0) -> None:
        """Finish the queued records, then close the inner sink (on the caller's thread)."""
        with self._cond:
            self._q.append(_STOP)
            self._cond.notify()
        if self._thread is not None:
            self._thread.join(timeout_s)
            self._thread = None
        self.inner.close()

    def _work(self) -> None:
        while True:
            with self._cond:
                while not self._q:
                    self._cond.wait()
                item = self._q.popleft()
            if item is _STOP:
                return
            if self.error:
                continue
            try:
                if isinstance(item, tuple):
                    self.inner.on_fault(str(item[1]))
                else:
                    assert isinstance(item, FrameRecord)
                    self.inner.on_record(item)
            except Exception as exc:
                self.error = one_line(exc)

    def health(self) -> SinkHealth:
        if self.error:
            return SinkHealth(self.name, SinkLevel.FAILED, self.error)
        h = self.inner.health()
        if self.dropped and h.level in (SinkLevel.OK, SinkLevel.WAITING):
            return SinkHealth(h.name, SinkLevel.WARNING,
                              f"{self.dropped} records dropped (the worker fell behind)",
                              h.targets, h.latency, {**h.counters, "dropped": self.dropped})
        return h


SINKS = (SinkSpec("background", "runs another sink on its own thread (bounded queue)",
                  BackgroundSink),)
