"""The tracker registry's spec; the tracker interface and its result live in :mod:`engine.results`.

``Tracker``, ``TrackResult``, ``TrackState``, ``Overlay``, ``TrackDetails`` and
``TrackerCommand`` are re-exported here so that adapters keep one import.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from engine.results import (
    Overlay,
    TrackDetails,
    Tracker,
    TrackerCommand,
    TrackResult,
    TrackState,
)

__all__ = [
    "Overlay",
    "TrackDetails",
    "TrackResult",
    "TrackState",
    "Tracker",
    "TrackerCommand",
    "TrackerSpec",
]


@dataclass(frozen=True, slots=True)
class TrackerSpec:
    """How to build a tracker by name, its parameter class and optional CLI hooks."""

    name: str
    description: str
    params_cls: type
    factory: Callable[[Any], Tracker]
    needs_depth: bool = False
    needs_image: bool = True
    output: str = "pose"  # "pose" | "box" | "position2d"
    add_cli_arguments: Callable[[argparse.ArgumentParser], None] | None = None
    params_from_cli: Callable[[argparse.Namespace, Any], Any] | None = None
