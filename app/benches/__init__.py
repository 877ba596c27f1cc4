"""Benchmarks that need the operator window (Qt): discovered like :mod:`engine.bench`.

Each module declares ``BENCHES = (BenchSpec(...),)`` with :class:`engine.bench.BenchSpec`;
``studiotrack bench NAME`` lists them beside the engine's.
"""

from __future__ import annotations

from collections.abc import Mapping

from engine.bench import BenchSpec
from engine.registry import Registry

REGISTRY: Registry[BenchSpec] = Registry("bench", "BENCHES", BenchSpec, places=(__name__,))


def available_app_benches() -> Mapping[str, BenchSpec]:
    return REGISTRY.specs()
