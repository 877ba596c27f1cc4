"""Atomic persistence helpers: temp file in the same folder, fsync, rename.

Readers never see a half-written file; a crash mid-write leaves the previous version intact.
Versioned JSON + npz/PNG only: nothing here pickles.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temp + fsync + rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: Path, obj: Any) -> None:
    atomic_write_text(path, json.dumps(obj, indent=2, sort_keys=False) + "\n")


def atomic_write_npz(path: Path, arrays: Mapping[str, np.ndarray]) -> None:
    """Compressed npz written atomically; loading uses ``allow_pickle=False``."""
    buf = io.BytesIO()
    np.savez_compressed(buf, **dict(arrays))
    atomic_write_bytes(path, buf.getvalue())


def atomic_write_png(path: Path, image: np.ndarray) -> None:
    """PNG (8- or 16-bit, grey or BGR) written atomically through OpenCV's encoder."""
    import cv2

    ok, enc = cv2.imencode(".png", image)
    if not ok:
        raise OSError(f"{path}: PNG encoding failed for array {image.shape} {image.dtype}")
    atomic_write_bytes(path, enc.tobytes())


def write_text_file(path: Path, text: str, error: type[Exception]) -> None:
    """Write a text result atomically; a failure raises ``error`` with one line naming the file."""
    try:
        atomic_write_text(Path(path), text)
    except OSError as exc:
        raise error(f"{path}: cannot write ({exc.strerror or exc})") from None


def read_json_file(
    path: Path,
    error: type[Exception],
    *,
    missing: str = "not found",
    corrupt: str = "malformed JSON",
) -> Any:
    """Parse a JSON file; every failure raises ``error`` with one line naming the file.

    ``missing`` and ``corrupt`` word the not-found and parse-error messages for the caller
    (e.g. "not found (not a keyframe store?)", "corrupt JSON").
    """
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise error(f"{path}: {missing}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{path}: cannot read ({exc})") from None
    except json.JSONDecodeError as exc:
        raise error(f"{path}: {corrupt} at line {exc.lineno} ({exc.msg})") from None
    except RecursionError:
        raise error(f"{path}: JSON nested too deeply") from None


def backup_existing(path: Path, suffix: str = ".bak") -> Path | None:
    """Copy an existing file or folder to ``path + suffix`` (replacing an older backup)."""
    path = Path(path)
    if not path.exists():
        return None
    bak = path.with_name(path.name + suffix)
    if bak.is_dir():
        shutil.rmtree(bak)
    elif bak.exists():
        bak.unlink()
    if path.is_dir():
        shutil.copytree(path, bak)
    else:
        shutil.copy2(path, bak)
    return bak
