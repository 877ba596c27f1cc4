"""Pose outputs to the render engine (FreeD D1, OpenTrackIO) as a pipeline sink.

In a real-time run (the operator window, a live source) packets leave at the output rate -
the operator's (23.976 ... 60 Hz) or, by default, the source's - from the sender thread's
:class:`engine.outputs.clock.OutputClock`: the newest delayed/interpolated pose each slot,
the held pose when the tracker is late, the last good pose flagged LOST when the engine
stalls or fails (until the run is stopped). Headless runs send one packet per record.

Health is green only while packets leave without error: a target whose latest send failed
(no route, unresolvable host, encode error) is an ALARM with the error; no packet for a
while on a clocked run is an ALARM too ("stalled").
"""

from __future__ import annotations

import math
from typing import Any

from engine.outputs.sender import OutputConfig, OutputSet, SenderStats
from engine.pipeline import LatencyStats, RunInfo, SinkBase, SinkHealth, SinkLevel, TargetHealth
from engine.realtime import PriorityGrant, use_air_switch_interval
from engine.records import FrameRecord
from engine.sinks import SinkSpec


class PoseOutputSink(SinkBase):
    """FreeD / OpenTrackIO targets of an :class:`OutputConfig`.

    ``clocked``: None = clocked in real-time runs, per record otherwise. ``rate_hz``:
    the output rate; None = ``config.rate_hz`` or else the source's nominal rate.
    """

    name = "pose outputs"

    def __init__(self, config: OutputConfig, *, clocked: bool | None = None,
                 rate_hz: float | None = None, stale_after_s: float | None = None) -> None:
        self.config = config
        self.clocked = clocked
        self.rate_hz = rate_hz
        self.stale_after_s = stale_after_s
        self.outputs: OutputSet | None = None
        self._final: SenderStats | None = None

    def open(self, run: RunInfo) -> None:
        clocked = self.clocked if self.clocked is not None else (run.realtime or run.live)
        rate = self.rate_hz or self.config.rate_hz or run.nominal_fps or 30.0
        if clocked:
            use_air_switch_interval()
            self.outputs = OutputSet(self.config, rate_hz=rate, stale_after_s=self.stale_after_s)
        else:
            self.outputs = OutputSet(self.config)

    @property
    def priority(self) -> PriorityGrant | None:
        """The OS priority of the clocked sender thread (logged by the pipeline)."""
        return self.outputs.priority if self.outputs is not None else None

    def on_record(self, record: FrameRecord) -> None:
        if self.outputs is not None:
            self.outputs.submit_record(record)

    def on_fault(self, message: str) -> None:
        if self.outputs is not None:
            self.outputs.mark_lost()

    def close(self) -> None:
        out, self.outputs = self.outputs, None
        if out is None:
            return
        if not out.clocked:
            out.flush(2.0)
        self._final = out.stats()
        out.close()

    def set_config(self, config: OutputConfig) -> None:
        """Swap the settings in while running (targets re-open if they changed)."""
        self.config = config
        if self.outputs is not None:
            self.outputs.set_config(config)

    def stats(self) -> SenderStats | None:
        """The sender's statistics (the final ones after close)."""
        out = self.outputs
        return out.stats() if out is not None else self._final

    def health(self) -> SinkHealth:
        st = self.stats()
        if st is None:
            return SinkHealth(self.name, SinkLevel.WAITING, "not open")
        return health_of(self.name, st, running=self.outputs is not None)


def health_of(name: str, st: SenderStats, *, running: bool = True) -> SinkHealth:
    """Sink health from sender statistics (also used by the app while no run is on)."""
    stall_s = max(0.5, 4.0 / st.rate_hz) if st.clocked and math.isfinite(st.rate_hz) else math.inf
    targets = []
    for t in st.targets:
        if t.failing:
            level, msg = SinkLevel.ALARM, t.last_error or "send failed"
        elif t.samples_sent == 0:
            level, msg = SinkLevel.WAITING, "waiting for a pose"
        elif running and t.last_ok_age_s > stall_s:
            level, msg = SinkLevel.ALARM, f"stalled: no packet for {t.last_ok_age_s:.1f} s"
        else:
            level, msg = SinkLevel.OK, ""
        targets.append(TargetHealth(t.name, level, t.rate_hz, t.packets_sent, t.errors, msg))
    order = [SinkLevel.FAILED, SinkLevel.ALARM, SinkLevel.WARNING, SinkLevel.WAITING,
             SinkLevel.OK]
    level = min((th.level for th in targets), key=order.index, default=SinkLevel.WAITING)
    msg = next((th.message for th in targets if th.level is level and th.message), "")
    if not targets:
        level, msg = SinkLevel.OFF, "no target"
    p50, p95, mx = st.capture_to_send_ms
    lat = (LatencyStats(p50, p95, mx, st.ticks) if math.isfinite(p50) else None)
    counters: dict[str, Any] = {
        "ticks": st.ticks, "held_ticks": st.held_ticks, "lost_ticks": st.lost_ticks,
        "missed_ticks": st.missed_ticks, "dropped": st.dropped, "rate_hz": st.rate_hz,
    }
    return SinkHealth(name, level, msg, tuple(targets), lat, counters)


SINKS = (SinkSpec("pose-outputs", "FreeD D1 / OpenTrackIO 1.0 to render engines, at the "
                  "output rate", PoseOutputSink),)
