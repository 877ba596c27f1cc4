"""Frames made ahead on a worker thread, as a camera exposes the next frame while the
tracker works on this one.

A generated source (the built-in studio) renders each frame in a numba kernel that releases
the GIL; made on the consumer's thread, the render and the tracker take turns and a real-time
run spends most of each frame period rendering. :func:`read_ahead` makes frame ``i + 1``
(up to ``depth`` frames) on its own thread while the consumer handles frame ``i``, so the
source behaves like a camera: every frame is made (none skipped), in order, and a frame's
``capture_mono_s`` is the moment it is handed out (when a camera's frame would arrive), not
when it was rendered ahead of time.

A real-time consumer (the pipeline) says when it is done with a frame by calling the
iterator's ``consumer_idle()``; from the first such call on, the worker makes the next frame
only then (or when the consumer asks for a frame not made yet), so the render runs in the
consumer's idle time instead of beside its tracking of the frame just handed out (where its
Python parts took the interpreter lock from the tracker for a switch interval, 1 ms, every
frame). A consumer that never calls it (a headless run) keeps the free-running read-ahead.

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
from engine.realtime import background_priority

#: how often a blocked worker looks whether the consumer has gone (s)
_POLL_S = 0.05
#: how long closing waits for the frame being made (s); the daemon worker is left after it
_JOIN_S = 5.0


@dataclass(frozen=True, slots=True)
class _Failed:
    exc: BaseException


_END = object()


def read_ahead(make: Callable[[int], Frame], count: int, *, depth: int = 1,
               name: str = "source-ahead", background: bool = False) -> Iterator[Frame]:
    """``make(0) ... make(count - 1)``, each made on a worker thread up to ``depth`` frames
    before the consumer asks for it (``depth`` 0: on the caller's thread). ``background``:
    the worker runs only on a core nothing else wants
    (:func:`engine.realtime.background_priority`)."""
    if depth <= 0:
        return (make(i) for i in range(count))
    return ReadAhead(make, count, depth=depth, name=name, background=background)


class _Shared:
    """What the worker and the consumer share (the worker holds no reference to the
    :class:`ReadAhead`, so a dropped iterator is collected and stops it)."""

    def __init__(self, depth: int) -> None:
        self.items: queue.Queue[object] = queue.Queue(maxsize=depth)
        self.stop = threading.Event()
        self.cond = threading.Condition()
        #: gated (after the first consumer_idle): the worker makes frame i only once
        #: ``allowed >= i``; -1 = free-running
        self.allowed = -1

    def put(self, item: object) -> bool:
        while not self.stop.is_set():
            try:
                self.items.put(item, timeout=_POLL_S)
                return True
            except queue.Full:
                continue
        return False

    def allow(self, i: int) -> None:
        with self.cond:
            if i > self.allowed:
                self.allowed = i
                self.cond.notify_all()

    def wait_allowed(self, i: int) -> bool:
        """Wait until frame ``i`` may be made (at once while free-running); False when
        stopping."""
        with self.cond:
            while 0 <= self.allowed < i and not self.stop.is_set():
                self.cond.wait(_POLL_S)
        return not self.stop.is_set()


def _work(shared: _Shared, make: Callable[[int], Frame], count: int, background: bool) -> None:
    if background:
        background_priority()
    try:
        for i in range(count):
            if not shared.wait_allowed(i) or not shared.put(make(i)):
                return
    except BaseException as exc:  # handed to the consumer, raised there
        shared.put(_Failed(exc))
        return
    shared.put(_END)


class ReadAhead:
    """The iterator :func:`read_ahead` returns (see the module docstring)."""

    def __init__(self, make: Callable[[int], Frame], count: int, *, depth: int, name: str,
                 background: bool) -> None:
        self._shared = _Shared(depth)
        self._done = False
        self._taken = 0  # frames handed out
        self._worker = threading.Thread(target=_work, args=(self._shared, make, count,
                                                            background),
                                        name=name, daemon=True)
        self._worker.start()

    def __iter__(self) -> ReadAhead:
        return self

    def __next__(self) -> Frame:
        if self._done:
            raise StopIteration
        sh = self._shared
        if sh.allowed >= 0 and sh.items.empty():
            sh.allow(self._taken)  # asked before it was made: make it now
        item = sh.items.get()
        if item is _END:
            self.close()
            raise StopIteration
        if isinstance(item, _Failed):
            self.close()
            raise item.exc
        assert isinstance(item, Frame)
        self._taken += 1
        return replace(item, capture_mono_s=time.monotonic())

    def consumer_idle(self) -> None:
        """The consumer is done with the frame it took: make the next one now (and from now
        on only at such calls, or when a frame is asked for before it is made)."""
        self._shared.allow(self._taken)

    def close(self) -> None:
        """Stop the worker (waits up to ``_JOIN_S`` for the frame being made)."""
        if self._done:
            return
        self._done = True
        sh = self._shared
        sh.stop.set()
        deadline = time.monotonic() + _JOIN_S
        while self._worker.is_alive() and time.monotonic() < deadline:
            with contextlib.suppress(queue.Empty):  # a blocked worker sees ``stop`` soon
                sh.items.get_nowait()
            self._worker.join(_POLL_S)

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self._shared.stop.set()
