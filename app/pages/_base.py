"""The small page base: pages draw when the window's display clock says so, only if visible.

The main window owns one display clock (:data:`DISPLAY_HZ`); on each tick it calls
:meth:`Page.display_tick` of the page that is shown (hidden pages cost nothing). The base
hands a run page what is new since it last drew:

- :meth:`Page.add_samples` - the run's light history since the page's cursor (every frame's
  numbers, also those the display skipped; a page shown again catches up);
- :meth:`Page.draw` - the newest record, once per new record;
- :meth:`Page.refresh` - every tick (or every ``refresh_interval_s``), for read-outs that are
  not per record (run state, health);
- :meth:`Page.run_changed` - a new run started (clear plots), and :meth:`Page.run_ended`;
- :meth:`Page.run_faulted` - once, when the engine raised mid-run (the run stays open, the
  outputs hold the last pose flagged LOST, no record follows): the page says ERROR and never
  leaves the last record looking live;
- :meth:`Page.run_stalled` - once, when a running run delivered no record for a while (the
  header's rule, :func:`app.status.stall_message`): the page says LOST until the next draw.

``follows(info)`` says whether the page shows a run (default: any; a tracker's page: runs
of its trackers). A page never keeps engine objects of its own: it asks ``ctx.run``.
"""

from __future__ import annotations

import time
from typing import Any

from PySide6.QtWidgets import QWidget

from app.status import stall_message
from engine.loop import FrameRecord
from engine.pipeline import RunInfo, RunPhase, RunStatus, TraceSample

DISPLAY_HZ = 30


class Page(QWidget):
    """Base of every main-window page (see the module docstring)."""

    #: seconds between ``refresh`` calls (0: every display tick)
    refresh_interval_s = 0.0
    #: trackers whose runs the page shows (empty: any run)
    follows_trackers: tuple[str, ...] = ()

    def __init__(self, ctx: Any, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.ctx = ctx
        self._epoch = -1
        self._cursor = 0
        self._drawn_seq: int | None = None
        self._next_refresh = 0.0
        self._was_running = False
        self._faulted = False
        self._stalled = False
        self.draws = 0  # records drawn (tests, benches)

    # ------------------------------------------------------------- overridables
    def follows(self, info: RunInfo | None) -> bool:
        if info is None:
            return False
        return not self.follows_trackers or info.tracker_name in self.follows_trackers

    def run_changed(self, info: RunInfo | None) -> None:
        """A new run started (``info`` may still be None while it opens)."""

    def run_ended(self, status: RunStatus | None) -> None:
        """The run this page showed ended: clear live read-outs, keep what is history."""

    def run_faulted(self, status: RunStatus | None) -> None:
        """The engine raised mid-run (``status.error`` says what); the run is still open."""

    def run_stalled(self, message: str) -> None:
        """No record for a while (``message`` says how long); the next :meth:`draw` follows
        when records come again. Pages with a state light say LOST here."""

    def add_samples(self, samples: list[TraceSample], missed: int) -> None:
        """Every processed frame's numbers since the last tick (``missed``: beyond the
        history)."""

    def draw(self, record: FrameRecord) -> None:
        """Draw the newest record (image, overlay, read-outs of that very frame)."""

    def refresh(self) -> None:
        """Periodic read-outs (state, health)."""

    # ------------------------------------------------------------------- host
    def display_tick(self, now: float | None = None) -> None:
        """Called by the main window's display clock while this page is shown."""
        run = getattr(self.ctx, "run", None)
        if run is not None:
            if run.epoch != self._epoch:
                self._epoch = run.epoch
                self._cursor = 0
                self._drawn_seq = None
                self._faulted = False
                self._stalled = False
                self._next_refresh = 0.0  # read-outs follow a run change at once
                self.run_changed(run.run_info)
            running = run.is_running
            if self.follows(run.run_info):
                # also the last frames of a run that just ended: short runs plot completely
                samples, self._cursor, missed = run.trace_since(self._cursor)
                if samples or missed:
                    self.add_samples(samples, missed)
                rec = run.latest() if running else None
                if rec is not None and rec.seq != self._drawn_seq:
                    self._drawn_seq = rec.seq
                    self._stalled = False
                    self.draws += 1
                    self.draw(rec)
                elif running and not self._stalled and not self._faulted:
                    status = run.status()
                    stalled = (stall_message(status, time.monotonic() if now is None else now)
                               if status is not None else None)
                    if stalled is not None:
                        self._stalled = True
                        self.run_stalled(stalled)
                p = run.pipeline if running else None
                if not self._faulted and p is not None and p.phase is RunPhase.FAULT:
                    self._faulted = True  # after the last draw: the page ends on ERROR
                    self._next_refresh = 0.0
                    self.run_faulted(run.status())
            if self._was_running != running:
                self._next_refresh = 0.0  # read-outs follow start/stop at once
            if self._was_running and not running:
                self.run_ended(run.status())
            self._was_running = running
        t = time.monotonic() if now is None else now
        if t >= self._next_refresh:
            self._next_refresh = t + self.refresh_interval_s
            self.refresh()
