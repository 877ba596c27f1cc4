"""Main-window pages, auto-discovered.

Each module in this package declares ``PAGES = (PageSpec(title=..., order=..., factory=...),)``;
``factory(ctx)`` builds the page widget from the shared :class:`app.context.AppContext`.
Pages appear in the main window's navigation sorted by ``order`` (Live is 0); orders are
unique. ``trackers`` names the trackers a page starts with its own controls (their set-up and
parameters live on that page); pages that start none, or any (Live), leave it empty.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from engine.registry import Registry

if TYPE_CHECKING:
    from PySide6.QtWidgets import QWidget


@dataclass(frozen=True, slots=True)
class PageSpec:
    title: str
    order: int
    factory: Callable[[Any], QWidget]
    tooltip: str = ""
    trackers: tuple[str, ...] = ()


def _title(spec: PageSpec) -> str:
    return spec.title


REGISTRY: Registry[PageSpec] = Registry("page", "PAGES", PageSpec, places=(__name__,), key=_title)


def discover_pages() -> list[PageSpec]:
    """Every page, in navigation order."""
    return sorted(REGISTRY.specs().values(), key=lambda s: (s.order, s.title))


def page_for_tracker(name: str) -> PageSpec | None:
    """The page that drives tracker ``name`` with its own controls, if any."""
    return next((p for p in discover_pages() if name in p.trackers), None)
