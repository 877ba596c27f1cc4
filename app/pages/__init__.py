"""Main-window pages, auto-discovered.

Each module in this package defines ``PAGE = PageSpec(title=..., order=..., factory=...)``;
``factory(ctx)`` builds the page widget from the shared :class:`app.context.AppContext`.
Pages appear in the main window's navigation sorted by ``order`` (Live is 0).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from PySide6.QtWidgets import QWidget


@dataclass(frozen=True, slots=True)
class PageSpec:
    title: str
    order: int
    factory: Callable[[Any], QWidget]
    tooltip: str = ""


def discover_pages() -> list[PageSpec]:
    specs: list[PageSpec] = []
    for mod in pkgutil.iter_modules(__path__):
        if mod.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{mod.name}")
        spec = getattr(module, "PAGE", None)
        if spec is not None:
            specs.append(spec)
    return sorted(specs, key=lambda s: (s.order, s.title))
