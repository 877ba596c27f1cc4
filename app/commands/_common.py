"""Helpers shared by CLI subcommands."""

from __future__ import annotations

import contextlib
import json
import math
import sys
from pathlib import Path
from typing import Any

from engine.progress import log, warn
from engine.validate import cli_number as number_arg
from engine.validate import cli_port as port_arg

__all__ = ["emit_json", "log", "number_arg", "port_arg", "run_inputs", "warn"]


def run_inputs(args: Any, *sources: Any, skip: tuple[str, ...] = ("out",)) -> list[Path]:
    """Every path the run reads: each source's own inputs and every command-line value that
    names an existing file or folder (except the ``skip`` options, the outputs)."""
    paths: list[Path] = []
    for src in sources:
        if src is not None and hasattr(src, "input_paths"):
            paths += list(src.input_paths())
    for key, value in vars(args).items():
        if key in skip or key == "func":
            continue
        for v in value if isinstance(value, list | tuple) else (value,):
            if isinstance(v, str | Path) and str(v):
                p = Path(v)
                with contextlib.suppress(OSError, ValueError):
                    if p.exists():
                        paths.append(p)
                for prefix in ("beacons-csv:",):  # spec strings that embed a file name
                    if isinstance(v, str) and v.startswith(prefix):
                        paths.append(Path(v[len(prefix):].split(",", 1)[0]))
    return paths


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


