"""One way to declare operator parameters: typed fields, validation from their metadata, presets.

A parameter group is a frozen, slotted dataclass deriving from :class:`Params`; each field is
declared with :func:`param`, which returns the default's type (so type checkers see
``n: int = param(...)`` as an ``int`` field with a default, no ignore comment) and stores
the metadata that the GUI form (``widgets.param_form``), ``track --list-params`` and the
validation read::

    @dataclass(frozen=True, slots=True)
    class FilterParams(Params):
        n_particles: int = param(100, help="particles M", lo=10, hi=5000, step=10)
        sigma_m: float = param(0.3, help="range noise std (eq. 8)", lo=0.001, hi=10.0)
        mode: str = param("fast", help="update rule", choices=("fast", "exact"))
        PRESETS: ClassVar[Mapping[str, Preset]] = {"paper": Preset("as published", mode="exact")}

Every instance is checked in :meth:`Params.__post_init__` from that metadata (the value has
the field's type: a real ``bool``, an integer for ``int``, a finite number for ``float``; it
lies in ``[lo, hi]``; it is one of ``choices``), then by the class's own cross-field rules in
:meth:`Params.validate`. A failure raises the class's ``ERROR`` (:class:`ParamsError` unless
the class says otherwise) with one line naming ``Class.field``, the rule and the value.

Presets are named field overrides declared on the class (``PRESETS``, e.g. ``paper`` = the
paper's method as published): :meth:`Params.with_preset` applies one on top of the current
values (``--param preset=NAME`` on the command line, the form's preset box in the GUI).
"""

from __future__ import annotations

import dataclasses
import enum
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar, Self, TypeVar, cast

from engine.errors import ParamsError
from engine.validate import shown, violation

T = TypeVar("T")

#: metadata keys written by :func:`param` (the form also reads ``decimals`` if present)
META_KEYS = ("help", "unit", "min", "max", "step", "choices", "label")
#: field name reserved for selecting a preset on the command line (``--param preset=NAME``)
PRESET_KEY = "preset"


def param(
    default: T,
    *,
    help: str,
    unit: str | None = None,
    lo: float | None = None,
    hi: float | None = None,
    step: float | None = None,
    choices: Sequence[T] | None = None,
    label: str | None = None,
) -> T:
    """A parameter field: ``default`` plus the metadata its form, listing and checks use.

    ``help`` becomes the tooltip and the ``--list-params`` comment; ``unit`` the label's unit
    when the name has no unit suffix; ``lo``/``hi`` the inclusive valid range (and the spin
    box limits); ``step`` the spin box step; ``choices`` the allowed values (a combo box);
    ``label`` replaces the label derived from the name.
    """
    if not help.strip():
        raise ParamsError("param(): help must not be empty")
    if lo is not None and hi is not None and lo > hi:
        raise ParamsError(f"param(): lo {lo} > hi {hi}")
    meta: dict[str, object] = {"help": help}
    for key, value in (("unit", unit), ("min", lo), ("max", hi), ("step", step),
                       ("label", label)):
        if value is not None:
            meta[key] = value
    if choices is not None:
        meta["choices"] = tuple(choices)
    return field(default=default, metadata=MappingProxyType(meta))


@dataclass(frozen=True, slots=True)
class Preset:
    """A named set of field overrides, e.g. ``Preset("the paper as published", p=0.0)``."""

    help: str
    values: Mapping[str, object]

    def __init__(self, help: str, **values: object) -> None:
        object.__setattr__(self, "help", help)
        object.__setattr__(self, "values", MappingProxyType(dict(values)))


_BUILTIN_KINDS: dict[str, type] = {"bool": bool, "int": int, "float": float, "str": str}


@dataclass(frozen=True, slots=True)
class _Check:
    name: str
    kind: type | None
    lo: float | None
    hi: float | None
    choices: tuple[object, ...] | None


def _kind(f: dataclasses.Field[Any]) -> type | None:
    """The field's value type: its annotation if a builtin scalar, else the default's type."""
    ann = f.type
    if isinstance(ann, str):
        if ann in _BUILTIN_KINDS:
            return _BUILTIN_KINDS[ann]
    elif ann in (bool, int, float, str):
        return cast(type, ann)
    default = f.default
    if default is dataclasses.MISSING or default is None:
        return None
    kind = type(default)
    return kind if issubclass(kind, enum.Enum | tuple) else None


_CHECKS: dict[type, tuple[_Check, ...]] = {}


def _checks(cls: type) -> tuple[_Check, ...]:
    """The per-field checks of a params class (built once per class)."""
    cached = _CHECKS.get(cls)
    if cached is not None:
        return cached
    out = []
    for f in dataclasses.fields(cls):
        md = f.metadata
        choices = md.get("choices")
        out.append(_Check(f.name, _kind(f), md.get("min"), md.get("max"),
                          None if choices is None else tuple(choices)))
    _CHECKS[cls] = tuple(out)
    return _CHECKS[cls]


def _is_number(v: object) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def _range_text(lo: float | None, hi: float | None) -> str:
    if lo is not None and hi is not None:
        return f"in [{lo}, {hi}]"
    return f">= {lo}" if lo is not None else f"<= {hi}"


def _check_value(c: _Check, v: object) -> str | None:
    """Why ``v`` is not a valid value of the field (None: valid)."""
    kind = c.kind
    if kind is bool:
        if not (isinstance(v, bool) or getattr(getattr(v, "dtype", None), "kind", "") == "b"):
            return f"must be true or false, got {v!r}"
    elif kind is int:
        if not isinstance(v, numbers.Integral) or isinstance(v, bool):
            return f"must be an integer, got {v!r}"
    elif kind is float:
        if not _is_number(v):
            return f"must be a number, got {v!r}"
    elif kind is str:
        if not isinstance(v, str):
            return f"must be text, got {v!r}"
    elif kind is not None and issubclass(kind, enum.Enum):
        if not isinstance(v, kind):
            return f"must be one of {', '.join(m.name for m in kind)}, got {v!r}"
    elif kind is not None and issubclass(kind, tuple) and not isinstance(v, tuple):
        return f"must be a tuple, got {v!r}"
    values = v if isinstance(v, tuple) else (v,)
    for x in values:
        if _is_number(x):
            rule = violation(x, lo=c.lo, hi=c.hi)  # exact: a 400-digit int is no OverflowError
            if rule == "finite":
                return f"must be finite, got {shown(v)}"
            if rule == "range":
                if c.lo is None and c.hi is None:
                    return f"must be a number, got {shown(v)}"
                return f"must be {_range_text(c.lo, c.hi)}, got {shown(v)}"
    if c.choices is not None and v not in c.choices:
        return f"{v!r} is not one of {', '.join(map(str, c.choices))}"
    return None


class Params:
    """Base of every parameter group: a ``@dataclass(frozen=True, slots=True)`` subclass.

    Subclasses declare fields with :func:`param`, put cross-field rules in :meth:`validate`
    (never their own ``__post_init__``), and may declare ``PRESETS`` and ``ERROR``.
    """

    __slots__ = ()

    #: named field overrides (``--param preset=NAME``, the form's preset box)
    PRESETS: ClassVar[Mapping[str, Preset]] = MappingProxyType({})
    #: the exception type a rejected value raises (the module's own error type)
    ERROR: ClassVar[type[Exception]] = ParamsError

    def __post_init__(self) -> None:
        cls = type(self)
        for c in _checks(cls):
            why = _check_value(c, getattr(self, c.name))
            if why is not None:
                raise cls.ERROR(f"{cls.__name__}.{c.name} {why}")
        self.validate()

    def validate(self) -> None:
        """Cross-field rules of the subclass (raise ``self.ERROR``); the metadata checks
        (type, finite, range, choices) have run already."""

    # ------------------------------------------------------------------ presets
    @classmethod
    def preset_names(cls) -> tuple[str, ...]:
        return tuple(cls.PRESETS)

    def with_preset(self, name: str) -> Self:
        """These params with preset ``name``'s overrides (the other fields are kept)."""
        cls = type(self)
        preset = cls.PRESETS.get(name)
        if preset is None:
            valid = ", ".join(cls.PRESETS) or "none"
            raise ParamsError(f"{cls.__name__} has no preset {name!r} (presets: {valid})")
        try:
            return cast(Self, dataclasses.replace(cast(Any, self), **preset.values))
        except TypeError as exc:  # a preset naming a field the class does not have
            raise ParamsError(f"{cls.__name__} preset {name!r}: {exc}") from None

    def matching_presets(self) -> tuple[str, ...]:
        """Names of the presets whose every override equals the current value."""
        return tuple(
            name for name, p in type(self).PRESETS.items()
            if all(getattr(self, k, _MISSING) == v for k, v in p.values.items())
        )


_MISSING = object()


def is_params_class(cls: object) -> bool:
    """True for a dataclass deriving from :class:`Params`."""
    return isinstance(cls, type) and issubclass(cls, Params) and dataclasses.is_dataclass(cls)
