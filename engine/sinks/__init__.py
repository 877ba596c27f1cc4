"""Sinks: everything a tracked record drives (pose outputs, recorder, robot, head, 3D view).

A sink implements :class:`engine.pipeline.Sink` (``open``, ``on_record``, ``on_fault``,
``close``, ``health``); the pipeline feeds it on the engine thread, disables it if it
raises, and reports its health. Every module in this package (and those in
:data:`SINK_PLACES`) may declare ``SINKS: tuple[SinkSpec, ...]`` (the one registry pattern,
:mod:`engine.registry`), so adding a sink means adding one module::

    SINKS = (SinkSpec("pose-outputs", "FreeD / OpenTrackIO at the output rate",
                      PoseOutputSink),)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from engine.registry import Registry


@dataclass(frozen=True, slots=True)
class SinkSpec:
    """A kind of sink: its name, what it does, and how to build one (``factory(...)``)."""

    name: str
    description: str
    factory: Callable[..., Any]


#: sinks that live with what they drive: the head sink with the head types, the recorder sink
#: with the recorder (named as strings: no import from here into those packages)
SINK_PLACES = (__name__, "engine.ptz.head", "engine.session.recorder")

REGISTRY: Registry[SinkSpec] = Registry("sink", "SINKS", SinkSpec, places=SINK_PLACES)


def available_sinks() -> Mapping[str, SinkSpec]:
    """All registered sink kinds by name."""
    return REGISTRY.specs()
