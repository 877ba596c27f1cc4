"""Sinks: everything a tracked record drives (pose outputs, recorder, robot, head, 3D view).

A sink implements :class:`engine.pipeline.Sink` (``open``, ``on_record``, ``on_fault``,
``close``, ``health``); the pipeline feeds it on the engine thread, disables it if it
raises, and reports its health. Every module in this package may declare
``SINKS: tuple[SinkSpec, ...]`` (the one registry pattern, :mod:`engine.registry`), so adding
a sink means adding one module::

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


REGISTRY: Registry[SinkSpec] = Registry("sink", "SINKS", SinkSpec, places=(__name__,))


def available_sinks() -> Mapping[str, SinkSpec]:
    """All registered sink kinds by name."""
    return REGISTRY.specs()
