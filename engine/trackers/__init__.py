"""Tracker registry.

Every module in this package may define ``TRACKERS: tuple[TrackerSpec, ...]``; the registry
(:class:`engine.registry.Registry`) discovers them, so adding a tracker means adding one module.
Modules keep their heavy imports inside functions so discovery stays fast.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from engine.errors import TrackerError
from engine.registry import Registry, unknown_message
from engine.trackers.base import TrackerSpec

DEFAULT_TRACKER = "opencv-odometry"

REGISTRY: Registry[TrackerSpec] = Registry(
    "tracker", "TRACKERS", TrackerSpec, places=(__name__,), error=TrackerError
)


def available_trackers() -> Mapping[str, TrackerSpec]:
    """All registered trackers by name."""
    return REGISTRY.specs()


def get_spec(name: str) -> TrackerSpec:
    specs = available_trackers()  # looked up here so that tests can swap the registry
    if name not in specs:
        raise TrackerError(unknown_message("tracker", name, specs))
    return specs[name]


def default_tracker_name() -> str:
    """The tracker the app starts with: the dense keyframe tracker once it is registered."""
    specs = available_trackers()
    for name in ("dense", "dense-incremental", DEFAULT_TRACKER):
        if name in specs:
            return name
    return next(iter(specs))


def create_tracker(name: str, params: Any | None = None, **overrides: Any) -> Any:
    """Build a tracker by name with default (or given) params and field overrides."""
    spec = get_spec(name)
    p = params if params is not None else spec.params_cls()
    if overrides:
        try:
            p = dataclasses.replace(p, **overrides)
        except TypeError as exc:
            raise TrackerError(f"tracker {name!r}: {exc}") from None
    return spec.factory(p)
