"""Benchmarks run by ``studiotrack bench NAME``.

Each module defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> dict``;
``run`` prints human-readable progress to stderr and returns the machine-readable results
(the CLI prints them as the last stdout line with ``--json``). Medians, and ratios against
peers run side by side in the same process.
"""

from __future__ import annotations

import importlib
import pkgutil
from functools import cache
from types import ModuleType


@cache
def available_benches() -> dict[str, ModuleType]:
    out: dict[str, ModuleType] = {}
    for mod in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if mod.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{mod.name}")
        out[module.NAME] = module
    return out
