"""Frames made ahead on a worker thread, as a camera exposes the next frame while the
tracker works on this one.

A generated source (the built-in studio) renders each frame in a numba kernel that releases
the GIL; made on the consumer's thread, the render and the tracker take turns and a real-time
run spends most of each frame period rendering. :func:`read_ahead` makes frame ``i + 1``
(up to ``depth`` frames) on its own thread while the consumer handles frame ``i``, so the
source behaves like a camera: every frame is made (none skipped), in order, and a frame's
``capture_mono_s`` is the moment it is handed out (when a camera's frame would arrive), not
when it was rendered ahead of time.

The worker stops when the consumer closes the iterator (or drops it); an exception of
``make`` reaches the consumer at the frame that raised it.

Example::

    for frame in read_ahead(studio.frame, 300):
        tracker.track(frame)
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

from engine.frames import Frame
from engine.realtime import lower_priority

#: how often a blocked worker looks whether the consumer has gone (s)
_POLL_S = 0.05
#: how long closing waits for the frame being made (s); the daemon worker is left after it
_JOIN_S = 5.0


@dataclass(frozen=True, slots=True)
class _Failed:
    exc: BaseException


_END = object()


def read_ahead(make: Callable[[int], Frame], count: int, *, depth: int = 1,
               name: str = "source-ahead", nice: int = 0) -> Iterator[Frame]:
    """``make(0) ... make(count - 1)``, each made on a worker thread up to ``depth`` frames
    before the consumer asks for it (``depth`` 0: on the caller's thread). ``nice`` > 0: the
    worker runs that many nice levels below the process
    (:func:`engine.realtime.lower_priority`)."""
    if depth <= 0:
        for i in range(count):
            yield make(i)
        return
    items: queue.Queue[object] = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def put(item: object) -> bool:
        while not stop.is_set():
            try:
                items.put(item, timeout=_POLL_S)
                return True
            except queue.Full:
                continue
        return False

    def work() -> None:
        lower_priority(nice)
        try:
            for i in range(count):
                if stop.is_set() or not put(make(i)):
                    return
        except BaseException as exc:  # handed to the consumer, raised there
            put(_Failed(exc))
            return
        put(_END)

    worker = threading.Thread(target=work, name=name, daemon=True)
    worker.start()
    try:
        while True:
            item = items.get()
            if item is _END:
                return
            if isinstance(item, _Failed):
                raise item.exc
            assert isinstance(item, Frame)
            yield replace(item, capture_mono_s=time.monotonic())
    finally:
        stop.set()
        deadline = time.monotonic() + _JOIN_S
        while worker.is_alive() and time.monotonic() < deadline:
            with contextlib.suppress(queue.Empty):  # a blocked worker sees ``stop`` soon
                items.get_nowait()
            worker.join(_POLL_S)
