"""Tracker registry.

Every module in this package may define ``TRACKERS: tuple[TrackerSpec, ...]``; the registry
discovers them, so adding a tracker means adding one module. Modules keep their heavy imports
inside functions so discovery stays fast.
"""

from __future__ import annotations

import dataclasses
import importlib
import pkgutil
from functools import cache
from typing import Any

from engine.errors import TrackerError
from engine.trackers.base import TrackerSpec

DEFAULT_TRACKER = "opencv-odometry"


@cache
def available_trackers() -> dict[str, TrackerSpec]:
    """All registered trackers by name."""
    specs: dict[str, TrackerSpec] = {}
    for mod in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if mod.name.startswith("_") or mod.name == "base":
            continue
        module = importlib.import_module(f"{__name__}.{mod.name}")
        for spec in getattr(module, "TRACKERS", ()):
            if spec.name in specs:
                raise TrackerError(f"tracker name {spec.name!r} registered twice ({mod.name})")
            specs[spec.name] = spec
    return specs


def get_spec(name: str) -> TrackerSpec:
    specs = available_trackers()
    if name not in specs:
        raise TrackerError(f"unknown tracker {name!r}; available: {', '.join(sorted(specs))}")
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
