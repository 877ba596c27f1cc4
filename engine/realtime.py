"""Real-time helpers of the air path: where a thread's time goes, and its OS priority.

A thread of the air path (the engine, the output sender) that is late was either *runnable
but not running* (another process or thread had the CPU: the OS run queue), or *blocked*:
asleep past its deadline, or waiting for the interpreter lock (the GIL) while another Python
thread holds it. Python cannot see the GIL wait directly, but Linux counts the run-queue
wait per thread (``/proc/thread-self/schedstat``, second field); so over an interval

- ``wall = cpu + run_queue + blocked`` (CPU: :func:`time.thread_time`), and for a thread
  that does not sleep or do I/O in that interval, ``blocked`` is the GIL wait.

:func:`run_queue_s` reads that counter (NaN where the kernel does not provide it).

:func:`raise_priority` asks, best effort, for a higher OS priority for the calling thread:
a real-time class (``SCHED_FIFO``) for a thread that only wakes briefly (the sender), a
lower nice value for one that computes (the engine). Neither is an error when refused (CI
and an ordinary operator account usually cannot): the :class:`PriorityGrant` says what was
granted, and the caller reports it.
"""

from __future__ import annotations

import gc
import math
import os
import sys
import threading
from dataclasses import dataclass

_SCHEDSTAT = "/proc/thread-self/schedstat"

#: the interpreter's thread switch interval while a show is on (Python's default: 5 ms). A
#: thread that wants the GIL waits at least this long when another runs Python code (the
#: window drawing, the tracker's Python parts): it bounds the sender's and the engine's
#: wait for each hand-over
AIR_SWITCH_INTERVAL_S = 0.001


def use_air_switch_interval() -> float:
    """Lower the interpreter's switch interval to :data:`AIR_SWITCH_INTERVAL_S` (never
    raises it); returns the interval in force."""
    if sys.getswitchinterval() > AIR_SWITCH_INTERVAL_S:
        sys.setswitchinterval(AIR_SWITCH_INTERVAL_S)
    return sys.getswitchinterval()


def run_queue_s() -> float:
    """Seconds the calling thread has waited runnable for a CPU since it started (Linux);
    NaN when the kernel does not say."""
    try:
        with open(_SCHEDSTAT, "rb") as f:
            fields = f.read().split()
        return int(fields[1]) * 1e-9
    except (OSError, IndexError, ValueError):
        return math.nan


@dataclass(frozen=True, slots=True)
class PriorityGrant:
    """What :func:`raise_priority` obtained for one thread."""

    role: str  # "sender" | "engine" | ...
    thread_id: int  # the OS thread id
    asked: str  # e.g. "SCHED_FIFO 10" or "nice -5"
    granted: str  # what is in force now: "SCHED_FIFO 10", "nice -5" or "unchanged"
    reason: str = ""  # why not (one line), "" when granted

    @property
    def ok(self) -> bool:
        return not self.reason

    def to_json_dict(self) -> dict[str, object]:
        return {"thread_id": self.thread_id, "asked": self.asked, "granted": self.granted,
                "reason": self.reason}

    def line(self) -> str:
        """One log line."""
        if self.ok:
            return f"{self.role} thread priority: {self.granted}"
        return (f"{self.role} thread priority: {self.asked} refused ({self.reason}); "
                f"runs {self.granted}")


def raise_priority(role: str, *, fifo: int = 0, nice: int = 0) -> PriorityGrant:
    """Raise the calling thread's OS priority, best effort (never raises).

    ``fifo`` > 0: ask for ``SCHED_FIFO`` at that priority (1..99), falling back to
    ``nice`` when refused; else ``nice`` < 0: ask for that nice value (a thread already
    at or above it is left as it is). On Linux both apply to the calling thread only (its
    native id), not to the whole process.
    """
    tid = threading.get_native_id()
    want_fifo = fifo > 0 and hasattr(os, "sched_setscheduler") and sys.platform == "linux"
    asked = f"SCHED_FIFO {fifo}" if want_fifo else (f"nice {nice}" if nice < 0 else "none")
    reasons: list[str] = []
    if want_fifo:
        try:
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(int(fifo)))
            return PriorityGrant(role, tid, asked, f"SCHED_FIFO {fifo}")
        except (OSError, ValueError) as exc:
            reasons.append(f"SCHED_FIFO: {_why(exc)}")
    if nice < 0 and sys.platform == "linux" and hasattr(os, "setpriority"):
        try:
            now = os.getpriority(os.PRIO_PROCESS, tid)
            if now > nice:  # never lowers a thread already above it
                os.setpriority(os.PRIO_PROCESS, tid, int(nice))
            granted = f"nice {min(now, nice)}"
            return PriorityGrant(role, tid, asked, granted, "; ".join(reasons))
        except (OSError, ValueError) as exc:
            reasons.append(f"nice {nice}: {_why(exc)}")
    elif nice < 0:
        reasons.append(f"nice {nice}: not on this platform")
    if not reasons and asked == "none":
        return PriorityGrant(role, tid, asked, "unchanged")
    if not reasons:
        reasons.append("not on this platform")
    return PriorityGrant(role, tid, asked, "unchanged", "; ".join(reasons))


_heap_lock = threading.Lock()
_heap_holders = 0


def freeze_heap() -> int:
    """Move every object alive now into the permanent generation (:func:`gc.freeze`) until
    the matching :func:`thaw_heap`; returns how many objects are frozen.

    Python's full (generation 2) collection holds the interpreter lock while it scans every
    tracked object: over the operator window's ~200 000 objects that is 30-110 ms, during
    which no thread of the air path runs (the sender misses slots). Frozen for a show, a full
    collection scans only what the show itself made. Nothing is collected first (that would
    be such a collection, at Start): garbage frozen with the rest is reclaimed after the
    thaw. Shows may overlap: the heap thaws when the last one ends.
    """
    global _heap_holders
    with _heap_lock:
        _heap_holders += 1
        gc.freeze()
        return gc.get_freeze_count()


def thaw_heap() -> None:
    """End one :func:`freeze_heap`; the last one unfreezes (the objects are collected as
    usual again, so nothing that died during the show is kept)."""
    global _heap_holders
    with _heap_lock:
        _heap_holders = max(0, _heap_holders - 1)
        if _heap_holders == 0:
            gc.unfreeze()


def _why(exc: BaseException) -> str:
    return getattr(exc, "strerror", None) or str(exc) or type(exc).__name__


def background_priority(fallback_nice: int = 10) -> str:
    """Make the calling thread a background one: it runs only on a core no other thread
    wants (Linux ``SCHED_IDLE``: a waking thread of the normal class preempts it at once,
    where a niced thread still holds the core for up to a scheduler slice, ~3 ms); where
    that is refused, ``fallback_nice`` nice levels kinder (:func:`lower_priority`). Always
    permitted (a thread may lower itself), never raises; returns what is in force:
    ``"SCHED_IDLE"``, ``"nice N"`` or ``"unchanged"``."""
    if sys.platform == "linux" and hasattr(os, "SCHED_IDLE"):
        try:
            os.sched_setscheduler(threading.get_native_id(), os.SCHED_IDLE, os.sched_param(0))
            return "SCHED_IDLE"
        except (OSError, ValueError):
            pass
    now = lower_priority(fallback_nice)
    return "unchanged" if now is None else f"nice {now}"


def lower_priority(by: int) -> int | None:
    """Make the calling thread ``by`` nice levels kinder to the others (Linux: this
    thread only; always permitted); returns its nice value now, None where not possible."""
    if by <= 0 or sys.platform != "linux" or not hasattr(os, "setpriority"):
        return None
    tid = threading.get_native_id()
    try:
        now = os.getpriority(os.PRIO_PROCESS, tid)
        os.setpriority(os.PRIO_PROCESS, tid, min(19, now + int(by)))
        return os.getpriority(os.PRIO_PROCESS, tid)
    except OSError:
        return None
