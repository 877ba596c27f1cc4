"""Helpers shared by CLI subcommands."""

from __future__ import annotations

import json
import math
import sys
from typing import Any

from engine.progress import log

__all__ = ["emit_json", "log"]


def _clean(obj: Any) -> Any:
    """JSON-safe copy: NaN/inf become null, numpy scalars become Python numbers."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item) and getattr(obj, "ndim", 1) == 0:
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def emit_json(obj: dict[str, Any]) -> None:
    """Print one JSON object as the last stdout line (the machine-readable result)."""
    sys.stdout.flush()
    print(json.dumps(_clean(obj), separators=(",", ":")), flush=True)


