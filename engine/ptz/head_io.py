"""A real pan-tilt head beside a video source: its position into the frames, its commands out.

:class:`HeadedSource` wraps a camera's video source (``camera:N``, a capture card, a
recording) and a head driver: every frame gets the head's newest reported motor angles as a
:class:`engine.ptz.head.PtzHeadReading` (from a FreeD input, :class:`engine.outputs.
freed_input.FreeDListener`, or the VISCA driver's position inquiry,
:class:`engine.ptz.visca_head.ViscaHead`) and, when the position source reports zoom/focus,
:class:`engine.lens.LensEncoders`; ``sinks()`` adds the head sink that moves the VISCA head
on the tracker's commands. A reading older than ``stale_s`` is not attached (the tracker
then falls back to reference points or the last command).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from engine.camera import Intrinsics
from engine.frames import Frame, FramePayload
from engine.lens import LensEncoders
from engine.ptz.head import HeadCommandSink, PtzHeadReading
from engine.sources.base import Source


class HeadedSource(Source):
    """``inner`` plus a head: readings from ``position`` (FreeDListener | ViscaHead | None),
    commands to ``driver`` (ViscaHead | None)."""

    def __init__(self, inner: Source, driver: Any = None, position: Any = None,
                 stale_s: float = 0.5) -> None:
        self.inner = inner
        self.driver = driver
        self.position = position
        self.stale_s = stale_s
        self.name = inner.name + (f" + {driver.name}" if driver is not None else "")
        self.nominal_fps = inner.nominal_fps
        self.live = inner.live
        self.head_port = driver

    @property
    def intrinsics(self) -> Intrinsics | None:
        return self.inner.intrinsics

    def __len__(self) -> int:
        return len(self.inner)

    def reading(self) -> tuple[PtzHeadReading, LensEncoders | None] | None:
        """The newest head reading if it is fresh."""
        from engine.outputs.freed_input import FreeDListener, head_reading_of

        now = time.monotonic()
        if isinstance(self.position, FreeDListener):
            r = self.position.latest()
            if r is None or now - r.arrival_mono_s > self.stale_s:
                return None
            pan, tilt = head_reading_of(r)
            return (PtzHeadReading(None, pan, tilt),
                    LensEncoders(zoom_raw=r.pose.zoom, focus_raw=r.pose.focus))
        if self.position is not None:
            pos = self.position.position()
            if pos is None or now - pos.mono_s > self.stale_s:
                return None
            enc = None if pos.zoom_raw is None else LensEncoders(zoom_raw=pos.zoom_raw)
            return PtzHeadReading(None, pos.pan_deg, pos.tilt_deg), enc
        return None

    def frames(self) -> Iterator[Frame]:
        for f in self.inner.frames():
            got = self.reading()
            if got is None:
                yield f
                continue
            reading, enc = got
            extra: list[FramePayload] = [reading]
            if enc is not None and f.payload(LensEncoders) is None:
                extra.append(enc)
            yield dataclasses.replace(f, payloads=(*f.payloads, *extra))

    def input_paths(self) -> tuple[Path, ...]:
        return self.inner.input_paths()

    def end_notes(self) -> tuple[str, ...]:
        from engine.outputs.freed_input import FreeDListener

        notes = list(self.inner.end_notes())
        d = self.driver
        if d is not None and d.acks == 0:
            notes.append(f"{d.name}: the camera never answered ({d.timeouts} timeouts, "
                         f"{d.garbage} garbage replies: {d.last_error or 'no reply'}); "
                         "tracking went on without moving it")
        elif d is not None and (d.timeouts or d.garbage or d.reconnects):
            notes.append(f"{d.name}: {d.timeouts} timeouts, {d.garbage} garbage replies, "
                         f"{d.reconnects} reconnects during the run")
        pos = self.position
        if isinstance(pos, FreeDListener) and pos.count == 0:
            notes.append(f"head position: no FreeD packet arrived on {pos.host}:{pos.port} "
                         f"({pos.errors} malformed)")
        return tuple(notes)

    def sinks(self) -> Sequence[Any]:
        own = tuple(self.inner.sinks())
        if self.driver is None:
            return own
        return (*own, HeadCommandSink(self.driver, self.driver.name))

    def close(self) -> None:
        try:
            self.inner.close()
        finally:
            for part in (self.driver, self.position):
                if part is not None:
                    part.close()
