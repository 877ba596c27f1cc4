"""Human-readable progress for CLI runs and benchmarks, on stderr (stdout ends with JSON).

Progress lines are not errors: the CLI's error boundary prints the one error line itself.
:func:`redirected` sends progress elsewhere for a while (the CLI fuzz tests use it to tell
progress from error lines).
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator

_sinks: list[Callable[[str], None]] = []


def log(msg: str) -> None:
    if _sinks:
        _sinks[-1](msg)
        return
    print(msg, file=sys.stderr, flush=True)


def warn(msg: str) -> None:
    """A warning the operator must see (skipped input, partial result): ``warning: ...``."""
    log(f"warning: {msg}")


@contextlib.contextmanager
def redirected(sink: Callable[[str], None]) -> Iterator[None]:
    """Send progress lines to ``sink`` inside the block."""
    _sinks.append(sink)
    try:
        yield
    finally:
        _sinks.remove(sink)
