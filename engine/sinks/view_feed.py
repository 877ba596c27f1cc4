"""The 3D view feed: the latest camera pose handed to a viewer from the sink's own thread.

The viewer (viser, in the app) may be slow or blocked on its clients; the engine thread
only stores the newest pose, and a feed thread calls ``publish(T_world_cam, intrinsics)``
at most ``rate_hz`` times a second. A ``publish`` that raises disables the feed (FAILED in
its health); tracking never notices.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from engine.camera import Intrinsics
from engine.pipeline import RunInfo, SinkBase, SinkHealth, SinkLevel, one_line
from engine.records import FrameRecord
from engine.sinks import SinkSpec

Publish = Callable[[np.ndarray, Intrinsics | None], Any]


class ViewFeedSink(SinkBase):
    """Feeds the newest ``T_world_cam`` to ``publish`` (at most ``rate_hz``)."""

    name = "3D view"

    def __init__(self, publish: Publish, rate_hz: float = 20.0) -> None:
        self.publish = publish
        self.period_s = 1.0 / max(rate_hz, 0.1)
        self._cond = threading.Condition()
        self._latest: tuple[np.ndarray, Intrinsics | None] | None = None
        self._stop = False
        self._thread: threading.Thread | None = None
        self.published = 0
        self.error = ""

    def open(self, run: RunInfo) -> None:
        self._stop = False
        self._thread = threading.Thread(target=self._run, name="view-feed", daemon=True)
        self._thread.start()

    def on_record(self, record: FrameRecord) -> None:
        T = record.result.T_world_cam
        if T is None:
            return
        with self._cond:
            self._latest = (T, record.frame.intrinsics)
            self._cond.notify()

    def close(self) -> None:
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(2.0)
            self._thread = None

    def _run(self) -> None:
        while True:
            with self._cond:
                while self._latest is None and not self._stop:
                    self._cond.wait()
                if self._stop:
                    return
                item, self._latest = self._latest, None
            assert item is not None
            try:
                self.publish(*item)
                self.published += 1
            except Exception as exc:
                self.error = one_line(exc)
                return
            time.sleep(self.period_s)

    def health(self) -> SinkHealth:
        if self.error:
            return SinkHealth(self.name, SinkLevel.FAILED, self.error)
        level = SinkLevel.OK if self.published else SinkLevel.WAITING
        return SinkHealth(self.name, level, counters={"published": self.published})


SINKS = (SinkSpec("3d-view", "moves the 3D view's live camera with the tracked pose",
                  ViewFeedSink),)
