"""Benchmarks run by ``studiotrack bench NAME``.

Each module declares ``BENCHES = (BenchSpec(name, help, add_arguments, run),)``; ``run(args)``
prints human-readable progress to stderr (:func:`engine.progress.log`) and returns the
machine-readable results (the CLI prints them as the last stdout line with ``--json``).
Medians, and ratios against peers run side by side in the same process.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from engine.registry import Registry


@dataclass(frozen=True, slots=True)
class BenchSpec:
    """One ``studiotrack bench NAME``: its options and the function that measures."""

    name: str
    help: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], dict[str, Any]]


REGISTRY: Registry[BenchSpec] = Registry("bench", "BENCHES", BenchSpec, places=(__name__,))


def available_benches() -> Mapping[str, BenchSpec]:
    """All registered benchmarks by name."""
    return REGISTRY.specs()
