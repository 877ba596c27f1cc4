"""What the status header says: never greener than the truth.

:func:`header_state` turns the run owner's state (the run's :class:`RunStatus`, the pose
outputs' health) into a :class:`widgets.status_header.HeaderState`:

- ERROR while the engine is faulted (outputs hold LOST) and after a run failed to open;
  STOPPED when no run is active (every number cleared); STARTING until the first record;
- otherwise the latest record's state, except LOST when no record came for a while (what
  the render engine gets is then flagged LOST too);
- frames/s of the last second against the source's rate, "falling behind" when below 90 %
  or frames are pulled late; latency capture -> packet on the wire (p95) when outputs run,
  else capture -> tracker done;
- one chip per output target: green only while its packets leave without error and carry a
  tracked pose (amber "LOST" while they hold the last good pose flagged LOST);
- alarm (flashing border) on LOST, ERROR and any failing output or sink; while running, the
  message line starts with what fails, in words (``OUTPUT FAILING: <target>: <reason>``).
"""

from __future__ import annotations

import time
from typing import Any

from engine.pipeline import RunPhase, RunStatus, SinkHealth, SinkLevel
from widgets.status_header import IDLE, HeaderState, HeaderTarget

#: no record for this long (and at least 5 frame periods) while running: LOST (stalled)
STALL_S = 1.0

_LEVEL = {
    SinkLevel.OK: "ok",
    SinkLevel.WAITING: "waiting",
    SinkLevel.WARNING: "waiting",
    SinkLevel.ALARM: "alarm",
    SinkLevel.FAILED: "alarm",
    SinkLevel.OFF: "off",
}


def stall_message(status: RunStatus, now_mono: float) -> str | None:
    """``"no frame for N s (engine stalled)"`` once a running run has delivered no record
    for :data:`STALL_S` and at least 5 frame periods; else None. The header and every page
    use this one rule, so no page light stays green while the header says LOST."""
    if not status.last_record_mono_s:
        return None
    period = 1.0 / status.target_fps if status.target_fps else 0.0
    age = now_mono - status.last_record_mono_s
    if age > max(STALL_S, 5 * period):
        return f"no frame for {age:.1f} s (engine stalled)"
    return None


def _ms(x: float) -> str:
    return f"{x:.0f}" if x >= 10 else f"{x:.1f}"


def _targets(owner: Any, status: RunStatus | None,
             holding: bool = False) -> tuple[tuple[HeaderTarget, ...], str]:
    """Output chips and, in words, the first failing output or sink ("" when none is):
    ``OUTPUT FAILING: <target>: <reason>``, ``HEAD OFFLINE: ...``, ``<SINK> FAILING: ...``.

    ``holding``: the outputs send the last good pose flagged LOST (tracker LOST or engine
    error); a target sending fine then says "LOST" in amber, never a green rate.
    """
    bad = ""
    chips: list[HeaderTarget] = []
    health: SinkHealth | None = owner.output_health()
    if not owner.outputs_enabled:
        chips.append(HeaderTarget("outputs", "off", "off", "pose outputs are off (Outputs page)"))
    elif health is None:
        for t in owner.outputs_config.targets:
            chips.append(HeaderTarget(t.protocol, "off", "armed",
                                      f"{t.name}: sends when a run starts"))
    else:
        for t in health.targets:
            level = _LEVEL.get(t.level, "off")
            proto = t.name.split(":", 1)[0]
            text = (f"{t.rate_hz:.0f} Hz" if level == "ok" else
                    "FAILING" if level == "alarm" else "waiting")
            tip = t.name + (f": {t.message}" if t.message else f": {t.packets} packets")
            if holding and level == "ok":
                level, text = "waiting", f"LOST {t.rate_hz:.0f} Hz"
                tip += " (the last good pose, flagged LOST)"
            chips.append(HeaderTarget(proto, level, text, tip))
            if level == "alarm" and not bad:
                why = (t.message if t.message.startswith(t.name) else
                       f"{t.name}: {t.message}" if t.message else f"{t.name} failing")
                bad = f"OUTPUT FAILING: {why}"
        if health.level is SinkLevel.FAILED:
            chips.append(HeaderTarget("outputs", "alarm", "FAILED", health.message))
            bad = bad or f"OUTPUT FAILING: {health.message or 'pose outputs failed'}"
    if status is not None:
        for h in status.sinks:
            if h.name == "pose outputs":
                continue
            if "reconnects" in h.counters:  # a real head driver (VISCA): always a chip
                bad_head = h.level.is_bad
                chips.append(HeaderTarget("HEAD", "alarm" if bad_head else
                                          "ok" if h.level is SinkLevel.OK else "waiting",
                                          "OFFLINE" if bad_head else h.level.value,
                                          f"{h.name}: {h.message}"))
                if bad_head and not bad:
                    bad = f"HEAD OFFLINE: {h.message}" if h.message else "HEAD OFFLINE"
                continue
            if h.level.is_bad:
                chips.append(HeaderTarget(h.name, "alarm", h.level.value, h.message))
                bad = bad or (f"{h.name.upper()} FAILING" + (f": {h.message}" if h.message
                                                              else ""))
            elif h.name == "recorder":
                n = int(h.counters.get("frames", 0))
                level = "ok" if h.level is SinkLevel.OK else "waiting"
                chips.append(HeaderTarget("REC", level, f"{n} frames", h.message))
    return tuple(chips), bad


def header_state(owner: Any, now_mono: float | None = None) -> HeaderState:
    """The header for the run owner's present state (see the module docstring)."""
    now = time.monotonic() if now_mono is None else now_mono
    status: RunStatus | None = owner.status()
    chips, failing = _targets(owner, status if owner.is_running else None)
    req = owner.request
    if not owner.is_running:
        if owner.last_error and (status is None or not getattr(owner, "stopped_by_user",
                                                                 False)):
            return HeaderState("ERROR", "engine stopped", owner.last_error, targets=chips,
                               alarm=True)
        if req is None:
            return HeaderState(IDLE.state, IDLE.title, IDLE.message, targets=chips,
                               alarm=bool(failing))
        last = f"last run: {req.tracker} on {req.source_spec}"
        if status is not None:
            last += f", {status.frames} frames"
            if status.error:
                last += f", ended by {status.error}"
        return HeaderState("STOPPED", "no run", last, targets=chips, alarm=bool(failing))
    info = status.info if status is not None else None
    title = (f"{info.tracker_name} · {info.source_name}" if info is not None
             else f"{req.tracker} · {req.source_spec}" if req is not None else "")
    if req is not None and req.page and req.page != "Live":
        title += f"  ({req.page})"
    if status is None or status.phase is RunPhase.STARTING:
        return HeaderState("STARTING", title, "opening the source and the tracker",
                           targets=chips, alarm=bool(failing))
    # the target as the rate is named (30, 29.97, 23.98): short enough to leave the reason
    # line its width at 1280 px
    target = f"{status.target_fps:.2f}".rstrip("0").rstrip(".")
    fps = f"{status.fps:5.1f} fps" + (f" / {target}" if status.target_fps else "")
    lat = "latency –"
    out = owner.output_health()
    if out is not None and out.latency is not None:
        lat = f"capture→wire p95 {_ms(out.latency.p95_ms)} ms"
    elif status.capture_to_done is not None:
        lat = f"capture→tracked p95 {_ms(status.capture_to_done.p95_ms)} ms"
    if status.phase is RunPhase.FAULT:
        chips, _ = _targets(owner, status, holding=True)
        return HeaderState("ERROR", title, f"{status.error} — outputs hold the last pose, "
                           "flagged LOST; press Stop", fps_text="–", latency_text=lat,
                           targets=chips, timecode=status.timecode or "", alarm=True)
    if status.state is None:
        return HeaderState("STARTING", title, "waiting for the first frame", fps, False, lat,
                           chips, alarm=bool(failing))
    state = status.state.value
    message = status.message
    stalled = stall_message(status, now)
    if stalled is not None:
        state, message = "LOST", stalled
    lost = state == "LOST"
    if lost:
        chips, failing = _targets(owner, status, holding=True)
    if failing:  # what the render engine does not get is said first, in words
        message = failing + (f" · {message}" if message else "")
    return HeaderState(state, title, message, fps, status.falling_behind, lat, chips,
                       timecode=status.timecode or "", alarm=lost or bool(failing))
