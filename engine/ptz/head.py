"""The pan-tilt head as the engine sees it: a reading, a move command and a port.

- :class:`PtzHeadReading` (frame payload): the head's geometry and its motor angles at
  exposure (an encoder, or the simulator's exact angles);
- :class:`PanTiltCommand` (tracker command): where the tracker wants the head to go;
- :class:`HeadPort`: what a head driver offers (the simulator's port, the VISCA-over-IP
  driver :class:`engine.ptz.visca_head.ViscaHead`); :class:`HeadCommandSink` moves it on
  each command (sink ``pan-tilt-head``) and reports the driver's health (a VISCA head that
  does not answer is ALARM "head OFFLINE").

The tracker never talks to the head: it reads the payload and returns commands.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from engine.frames import FramePayload
from engine.pipeline import SinkBase, SinkHealth, SinkLevel
from engine.ptz.kinematics import PtzHead
from engine.records import FrameRecord
from engine.results import TrackerCommand
from engine.sinks import SinkSpec


@dataclass(frozen=True, slots=True)
class PtzHeadReading(FramePayload):
    """Head geometry and the motor angles (degrees) at the frame's exposure."""

    head: PtzHead | None
    pan_deg: float
    tilt_deg: float


@dataclass(frozen=True, slots=True)
class PanTiltCommand(TrackerCommand):
    """Move the head to absolute motor angles (degrees)."""

    pan_deg: float
    tilt_deg: float


@runtime_checkable
class HeadPort(Protocol):
    """A head driver's command input (thread-safe, never blocks the caller)."""

    def command(self, pan_deg: float, tilt_deg: float) -> None: ...


class HeadCommandSink(SinkBase):
    """Moves ``port`` on every pan-tilt command (on the engine thread; ports never block)."""

    name = "pan-tilt head"

    def __init__(self, port: HeadPort, name: str | None = None) -> None:
        self.port = port
        if name:
            self.name = name
        self.commands = 0
        self.last: tuple[float, float] | None = None

    def on_record(self, record: FrameRecord) -> None:
        for cmd in record.result.commands_of(PanTiltCommand):
            self.port.command(cmd.pan_deg, cmd.tilt_deg)
            self.commands += 1
            self.last = (cmd.pan_deg, cmd.tilt_deg)

    def health(self) -> SinkHealth:
        msg = "" if self.last is None else f"last move {self.last[0]:.1f}° / {self.last[1]:.1f}°"
        port_health = getattr(self.port, "health", None)
        if callable(port_health):
            # a real driver knows whether the head answers (VISCA: OFFLINE, reconnecting)
            ph = port_health()
            text = "; ".join(m for m in (ph.message, msg) if m)
            return SinkHealth(self.name, ph.level, text,
                              counters={"commands": self.commands, **ph.counters})
        return SinkHealth(self.name, SinkLevel.OK, msg, counters={"commands": self.commands})


SINKS = (SinkSpec("pan-tilt-head", "moves a pan-tilt head on the tracker's commands",
                  HeadCommandSink),)
