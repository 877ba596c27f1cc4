"""One validated path for numbers that come from outside: CLI flags, source options, JSON files
(camera.json, layouts, projects), datagrams and decoded packets.

:func:`number` accepts a Python/numpy number or its text and returns a finite ``float`` (or an
``int`` with ``integer=True``) inside the given range; anything else raises the caller's error
type with one line naming *what* and the rule, in the words :mod:`engine.params` uses for
parameter fields ("must be an integer", "must be finite", "must be in [lo, hi]")::

    width = number(raw["width"], "camera.json: 'width'", integer=True, lo=1, hi=100_000,
                   error=CalibrationError)

It never raises ``OverflowError`` (a 400-digit integer, ``1e400``), never accepts ``nan``,
``inf``, booleans or ``160.5`` where an integer is needed.
"""

from __future__ import annotations

import argparse
import math
import numbers
from collections.abc import Callable
from typing import Any, Literal, overload

from engine.errors import ParamsError

#: largest magnitude accepted by default: far beyond any physical quantity we handle, far
#: inside float range (so products of two such numbers stay finite)
DEFAULT_LIMIT = 1e15
PORT_RANGE = (0, 65535)


def shown(value: object, limit: int = 40) -> str:
    """``repr`` of an input value, shortened for a one-line message (400-digit integers...)."""
    if isinstance(value, int) and not isinstance(value, bool):
        text = str(value)
        if len(text) > limit:
            return f"{text[:12]}... ({len(text.lstrip('-'))} digits)"
        return text
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _range_text(lo: float | None, hi: float | None, gt: float | None) -> str:
    if gt is not None:
        low = f"> {gt:g}"
        return low if hi is None else f"{low} and <= {hi:g}"
    if lo is not None and hi is not None:
        return f"in [{lo:g}, {hi:g}]"
    if lo is not None:
        return f">= {lo:g}"
    return f"<= {hi:g}"


@overload
def number(value: object, what: str, *, integer: Literal[True], lo: float | None = ...,
           hi: float | None = ..., gt: float | None = ...,
           error: type[Exception] = ..., text: bool = ...) -> int: ...
@overload
def number(value: object, what: str, *, integer: Literal[False] = ..., lo: float | None = ...,
           hi: float | None = ..., gt: float | None = ...,
           error: type[Exception] = ..., text: bool = ...) -> float: ...
@overload
def number(value: object, what: str, *, integer: bool, lo: float | None = ...,
           hi: float | None = ..., gt: float | None = ...,
           error: type[Exception] = ..., text: bool = ...) -> float | int: ...
def number(
    value: object,
    what: str,
    *,
    integer: bool = False,
    lo: float | None = None,
    hi: float | None = None,
    gt: float | None = None,
    error: type[Exception] = ParamsError,
    text: bool = False,
) -> float | int:
    """``value`` as a finite float (or an int with ``integer``) in range, else ``error``.

    ``lo``/``hi`` are inclusive bounds, ``gt`` an exclusive lower bound; without ``hi`` the
    magnitude is still limited to :data:`DEFAULT_LIMIT`. With ``text`` a string is parsed
    (``"12"``, ``"1e-3"``: command-line values, source options); otherwise (JSON values) a
    string is refused. Integral floats (``160.0``) are accepted where an integer is needed,
    ``160.5`` is not.
    """
    kind = "an integer" if integer else "a number"
    if isinstance(value, str) and text:
        s = value.strip()
        try:
            v: float | int = int(s) if integer and _is_int_text(s) else float(s)
        except ValueError:
            raise error(f"{what} must be {kind}, got {shown(value)}") from None
    elif isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise error(f"{what} must be {kind}, got {shown(value)}")
    elif isinstance(value, numbers.Integral):
        v = int(value)
    else:
        v = float(value)
    if isinstance(v, float):
        if not math.isfinite(v):
            rule = kind if integer else "finite"
            raise error(f"{what} must be {rule}, got {shown(value)}")
        if integer:
            if v != math.floor(v):
                raise error(f"{what} must be {kind}, got {shown(value)}")
            v = int(v)
    limit_hi = DEFAULT_LIMIT if hi is None else hi
    limit_lo = -DEFAULT_LIMIT if lo is None and gt is None else lo
    too_low = (gt is not None and not v > gt) or (limit_lo is not None and v < limit_lo)
    if too_low or v > limit_hi:
        rule = _range_text(lo, hi, gt) if (lo, hi, gt) != (None, None, None) else \
            f"in [{-DEFAULT_LIMIT:g}, {DEFAULT_LIMIT:g}]"
        raise error(f"{what} must be {rule}, got {shown(value)}")
    return int(v) if integer else float(v)


def violation(value: object, *, lo: float | None = None, hi: float | None = None,
              limit: float = math.inf) -> str | None:
    """Which rule a (non-bool, real) number breaks: ``"finite"``, ``"range"`` or None.

    The comparison is exact (no float conversion of integers), so a 400-digit integer is
    simply out of range, never an ``OverflowError``; :mod:`engine.params` checks its fields
    with it.
    """
    if isinstance(value, numbers.Integral):
        v: float | int = int(value)
    elif isinstance(value, numbers.Real):
        v = float(value)
    else:
        return "finite"  # not a real number at all (the callers check the type first)
    if isinstance(v, float) and not math.isfinite(v):
        return "finite"
    if (lo is not None and v < lo) or (hi is not None and v > hi) or abs(v) > limit:
        return "range"
    return None


def _is_int_text(text: str) -> bool:
    t = text[1:] if text[:1] in "+-" else text
    return t.isdigit() and t.isascii()


def port(value: object, what: str, *, error: type[Exception] = ParamsError,
         allow_zero: bool = True) -> int:
    """A UDP/TCP port number (0 = any free port when ``allow_zero``)."""
    return number(value, what, integer=True, lo=PORT_RANGE[0] if allow_zero else 1,
                  hi=PORT_RANGE[1], error=error, text=True)


def cli_number(
    *,
    integer: bool = False,
    lo: float | None = None,
    hi: float | None = None,
    gt: float | None = None,
) -> Callable[[str], Any]:
    """An argparse ``type=``: the text through :func:`number`; a bad value becomes argparse's
    one-line error (``argument --square: must be > 0, got '-1'``)."""

    def parse(text: str) -> float | int:
        try:
            return number(text, "value", integer=integer, lo=lo, hi=hi, gt=gt, text=True)
        except ParamsError as exc:
            raise argparse.ArgumentTypeError(str(exc).removeprefix("value ")) from None

    parse.__name__ = "integer" if integer else "number"
    return parse


def cli_port(*, allow_zero: bool = False) -> Callable[[str], int]:
    """An argparse ``type=`` for a UDP port (1..65535; 0 = any free port with ``allow_zero``)."""

    def parse(text: str) -> int:
        try:
            return port(text, "port", allow_zero=allow_zero)
        except ParamsError as exc:
            raise argparse.ArgumentTypeError(str(exc).removeprefix("port ")) from None

    parse.__name__ = "port"
    return parse
