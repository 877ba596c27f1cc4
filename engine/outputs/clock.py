"""The output clock: pose packets leave at the video rate, not at the tracker's rate.

The render engine wants one pose per video frame whatever the tracker does. The clock has
one *slot* per output period ``P = 1 / rate_hz`` (23.976 ... 60 Hz, default the source's
rate); every slot sends exactly once:

- early, the moment a fresh tracked pose arrives inside the slot's window
  ``[due - P/2, due]`` (a tracker at the video rate is sent the moment it is done);
- or at ``due`` by the timer, with the newest pose there is (one that arrived before the
  window opened, the held one, or the last good one flagged LOST by the sender when the
  engine stalled or failed).

A slot fired early (a fresh pose at its window's start) followed by a held one at its due
time would leave a gap of ``P + P/2``; so a slot without a fresh pose fires by the timer at
``min(due, last send + max_gap)`` with ``max_gap = (1.5 - margin) P``: the gap between two
sends stays below 1.5 periods by ``margin`` P, room for the sender waking late (waiting for
the interpreter lock, the OS), and a held slot goes at most that much before its due time.

So the send rate is exactly ``rate_hz``, a late tracker frame is measured (latency, held
slots) instead of queued, and no burst follows a stall (slots the sender thread itself
slept through are counted as missed and skipped). A slow phase correction moves the slot
grid so that frames arriving at the same rate land in the middle of the window: each fresh
arrival shifts the grid by ``gain`` times its wrapped offset from the window centre,
clamped to 5 % of a period, so sends follow the frames without changing the rate.

The clock is pure (times are passed in) and single-threaded: the sender thread owns it.
"""

from __future__ import annotations

import math

from engine.outputs import OutputError

#: the gap between two sends stays this many periods below 1.5 (see the module docstring)
GAP_MARGIN_FRAC = 0.15

#: the video rates an operator can pick (Hz)
VIDEO_RATES_HZ = (24000 / 1001, 24.0, 25.0, 30000 / 1001, 30.0, 50.0, 60000 / 1001, 60.0)
RATE_NAMES = ("23.976", "24", "25", "29.97", "30", "50", "59.94", "60")


def parse_rate(text: str | float) -> float:
    """``"29.97"`` -> 30000/1001; any of :data:`RATE_NAMES` or a number in 1..240 Hz."""
    s = str(text).strip()
    if s in RATE_NAMES:
        return VIDEO_RATES_HZ[RATE_NAMES.index(s)]
    try:
        v = float(s)
    except ValueError:
        raise OutputError(f"output rate {text!r} is not a number "
                          f"(video rates: {', '.join(RATE_NAMES)})") from None
    if not math.isfinite(v) or not 1.0 <= v <= 240.0:
        raise OutputError(f"output rate {text!r} Hz is outside 1..240")
    for name, r in zip(RATE_NAMES, VIDEO_RATES_HZ, strict=True):
        if abs(v - float(name)) < 1e-9:
            return r
    return v


def rate_name(rate_hz: float) -> str:
    for name, r in zip(RATE_NAMES, VIDEO_RATES_HZ, strict=True):
        if abs(rate_hz - r) < 1e-6:
            return name
    return f"{rate_hz:g}"


class OutputClock:
    """Slot scheduling for one output rate (see the module docstring)."""

    def __init__(self, rate_hz: float, *, window_frac: float = 0.5, gain: float = 0.1,
                 gap_margin_frac: float = GAP_MARGIN_FRAC) -> None:
        if not math.isfinite(rate_hz) or rate_hz <= 0:
            raise OutputError(f"output rate {rate_hz!r} Hz must be positive")
        self.rate_hz = float(rate_hz)
        self.period_s = 1.0 / self.rate_hz
        self.window_s = window_frac * self.period_s
        self.gain = gain
        #: the longest a held slot waits after the previous send (see the module docstring)
        self.max_gap_s = (1.0 + window_frac - gap_margin_frac) * self.period_s
        self.due: float | None = None  # the pending slot's due time (None: not started)
        self.last_fired: float | None = None  # when the previous slot was sent
        self.slots = 0  # slots fired
        self.early = 0  # of which by fresh data
        self.missed = 0  # slots skipped because the sender woke too late
        self.gap_bounded = 0  # held slots sent before their due time to bound the gap

    @property
    def started(self) -> bool:
        return self.due is not None

    def start(self, now: float) -> None:
        """Begin with a slot due now (the first pose goes out at once)."""
        self.due = now

    def on_arrival(self, now: float) -> None:
        """A fresh pose arrived: nudge the grid towards it (phase correction)."""
        if self.due is None:
            self.start(now)
            return
        P = self.period_s
        e = (now - (self.due - self.window_s / 2.0) + P / 2.0) % P - P / 2.0
        self.due += max(-0.05 * P, min(0.05 * P, self.gain * e))

    def should_fire(self, now: float, arrived: bool) -> bool:
        """Whether the pending slot sends now (``arrived``: a fresh pose came just now)."""
        wake = self.wake_at()
        if wake is None or self.due is None:
            return False
        return now >= wake or (arrived and now >= self.due - self.window_s)

    def wake_at(self) -> float | None:
        """When the sender must look again without new data (None: not started): the due
        time, or earlier where the gap since the previous send would reach ``max_gap_s``."""
        if self.due is None:
            return None
        if self.last_fired is None:
            return self.due
        return min(self.due, self.last_fired + self.max_gap_s)

    def fired(self, now: float) -> None:
        """The pending slot was sent at ``now``: the next one is due a period later."""
        assert self.due is not None
        self.slots += 1
        if now < self.due:
            if self.last_fired is not None and now >= self.last_fired + self.max_gap_s:
                self.gap_bounded += 1
            else:
                self.early += 1
        self.last_fired = now
        nxt = self.due + self.period_s
        if nxt <= now:  # the sender woke too late: skip the slots it slept through
            skip = math.floor((now - nxt) / self.period_s) + 1
            nxt += skip * self.period_s
            while nxt <= now:
                nxt += self.period_s
                skip += 1
            self.missed += skip
        self.due = nxt
