"""One registry pattern for every kind of plug-in: trackers, sources, benches, sinks, CLI
commands and pages.

A plug-in module declares what it adds in one module-level tuple of frozen spec records
(``TRACKERS``, ``SOURCES``, ``BENCHES``, ``SINKS``, ``COMMANDS``, ``PAGES``); a
:class:`Registry` finds them by importing the public modules (names not starting with ``_``)
of the packages it is given, so adding a plug-in means adding a module, never editing a
shared list. Plug-in modules keep their heavy imports inside functions so that discovery stays
fast. Example (the whole tracker registry)::

    TRACKERS: Registry[TrackerSpec] = Registry(
        "tracker", "TRACKERS", TrackerSpec, packages=("engine.trackers",), error=TrackerError
    )
    TRACKERS.specs()        # {"dense": TrackerSpec(...), ...} in module-name order
    TRACKERS.get("dense")   # unknown name: "unknown tracker 'x'; available: a, b, c"

The places are given as dotted names (strings), so a registry in a lower layer can find
plug-ins declared higher up (e.g. the ``ptz-sim`` source in :mod:`engine.ptz.sim`) without a
static import: the layers and no-cycle checks see only real imports.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Iterator, Mapping, Sequence
from types import MappingProxyType, ModuleType
from typing import Any, Generic, TypeVar

from engine.errors import StudioTrackError

S = TypeVar("S")


class RegistryError(StudioTrackError):
    """A plug-in is declared wrongly (duplicate name, wrong record type) or is unknown."""


def _name_of(spec: Any) -> str:
    return str(spec.name)


def iter_plugin_modules(places: Sequence[str]) -> Iterator[ModuleType]:
    """Import and yield the modules named in ``places``: a package stands for its public
    modules (sorted by name, not recursive), a module for itself."""
    for place in places:
        module = importlib.import_module(place)
        path = getattr(module, "__path__", None)
        if path is None:
            yield module
            continue
        for info in sorted(pkgutil.iter_modules(path), key=lambda m: m.name):
            if not info.name.startswith("_"):
                yield importlib.import_module(f"{place}.{info.name}")


class Registry(Generic[S]):
    """The specs of one kind of plug-in, discovered once (on first use) and then cached.

    ``kind`` names the plug-in in messages ("tracker"), ``attr`` is the module attribute that
    holds the tuple of specs, ``spec_type`` the record class every entry must be, ``places``
    the packages/modules to search, ``key`` a spec's unique name (``spec.name`` by default),
    ``error`` the :class:`StudioTrackError` subclass raised for unknown or duplicate names.
    """

    def __init__(
        self,
        kind: str,
        attr: str,
        spec_type: type[S],
        *,
        places: Sequence[str],
        key: Callable[[S], str] = _name_of,
        error: type[StudioTrackError] = RegistryError,
    ) -> None:
        self.kind = kind
        self.attr = attr
        self.spec_type = spec_type
        self.places = tuple(places)
        self.key = key
        self.error = error
        self._specs: Mapping[str, S] | None = None

    def specs(self) -> Mapping[str, S]:
        """Every registered spec by name (read-only), in module-name then declaration order."""
        if self._specs is None:
            self._specs = MappingProxyType(self._discover())
        return self._specs

    def names(self) -> list[str]:
        return list(self.specs())

    def get(self, name: str) -> S:
        """The spec called ``name``; an unknown name raises a one-line error listing all."""
        specs = self.specs()
        if name not in specs:
            raise self.error(unknown_message(self.kind, name, specs))
        return specs[name]

    def clear(self) -> None:
        """Forget the discovered specs (the next call discovers again)."""
        self._specs = None

    def _discover(self) -> dict[str, S]:
        found: dict[str, S] = {}
        where: dict[str, str] = {}
        for module in iter_plugin_modules(self.places):
            declared = getattr(module, self.attr, None)
            if declared is None:
                continue
            if not isinstance(declared, tuple):
                raise self.error(
                    f"{module.__name__}.{self.attr} must be a tuple of {self.spec_type.__name__}"
                )
            for spec in declared:
                if not isinstance(spec, self.spec_type):
                    raise self.error(
                        f"{module.__name__}.{self.attr} holds a {type(spec).__name__}, "
                        f"not a {self.spec_type.__name__}"
                    )
                name = self.key(spec)
                if name in found:
                    raise self.error(
                        f"{self.kind} name {name!r} registered twice "
                        f"({where[name]}, {module.__name__})"
                    )
                found[name] = spec
                where[name] = module.__name__
        return found


def unknown_message(kind: str, name: str, available: Mapping[str, Any] | Sequence[str]) -> str:
    """``unknown tracker 'x'; available: a, b, c`` (sorted)."""
    names = ", ".join(sorted(available)) or "none"
    return f"unknown {kind} {name!r}; available: {names}"
