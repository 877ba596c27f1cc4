"""Atomic persistence helpers: temp file in the same folder, fsync, rename.

Readers never see a half-written file; a crash mid-write leaves the previous version intact.
A new file gets the permissions the process's umask gives (``0o666 & ~umask``, like
``open()``), a replaced file keeps its own. Versioned JSON + npz/PNG only: nothing here
pickles.

Output checks, run before any work starts (so that an unwritable ``--out`` is found in
milliseconds, not after an hour of tracking): :func:`check_output_file` and
:func:`check_output_dir` refuse folders/files that cannot be written, inputs of the same run,
read-only files, and existing stores or sessions unless the caller passes ``force``;
:func:`replace_dir` swaps a freshly written folder in for an old one.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np


def current_umask() -> int:
    """The process's umask (read from /proc where possible: setting it to read it back is
    not thread-safe)."""
    with contextlib.suppress(OSError, ValueError), open("/proc/self/status",
                                                        encoding="ascii") as fh:
        for line in fh:
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    old = os.umask(0o022)
    os.umask(old)
    return old


def _new_file_mode(path: Path) -> int:
    """The mode a rewrite of ``path`` gets: the old file's own, else what ``open()`` gives."""
    try:
        return os.stat(path).st_mode & 0o7777
    except OSError:
        return 0o666 & ~current_umask()


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temp + fsync + rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    mode = _new_file_mode(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with contextlib.suppress(OSError):  # mkstemp makes 0600; give the umask's mode
            os.fchmod(fd, mode)
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
    np.savez_compressed(buf, allow_pickle=False, **dict(arrays))
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


# ------------------------------------------------------------------------------ output checks
def _nearest_existing(path: Path) -> Path:
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _probe_writable(folder: Path, label: str, path: Path, error: type[Exception]) -> None:
    """Create and remove a temporary file in ``folder`` (the check root cannot skip)."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=".studiotrack-probe.", dir=folder)
    except OSError as exc:
        raise error(f"{label} {path}: cannot write in {folder} ({exc.strerror or exc})") from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(tmp)


def _is_input(path: Path, inputs: Sequence[str | Path]) -> Path | None:
    """The input ``path`` is (or lies inside, for a folder input), if any."""
    try:
        target = path.resolve()
    except (OSError, RuntimeError):
        return None
    for raw in inputs:
        try:
            inp = Path(raw).resolve()
        except (OSError, RuntimeError, TypeError, ValueError):
            continue
        if target == inp or (inp.is_dir() and inp in target.parents):
            return Path(raw)
    return None


def _name_error(path: Path, label: str, error: type[Exception]) -> None:
    try:
        path.exists()
        os.fspath(path)
    except (OSError, ValueError) as exc:
        why = getattr(exc, "strerror", None) or exc
        raise error(f"{label} {str(path)[:80]}...: cannot be used as a file name ({why})") \
            from None
    if any(len(part.encode()) > 255 for part in path.parts):
        raise error(f"{label} {str(path)[:80]}...: a name in the path is longer than 255 bytes")


def check_output_file(
    path: str | Path,
    *,
    error: type[Exception],
    label: str = "output",
    inputs: Sequence[str | Path] = (),
    force: bool = False,
    make_parents: bool = False,
) -> Path:
    """Check, before any work, that ``path`` can be written as a file; returns it.

    Refuses (``error``, one line starting with ``label``): a folder, a missing parent folder
    (unless ``make_parents``), a file of ``inputs`` or one inside a folder of ``inputs`` (the
    run reads it), a read-only file (unless ``force``), and a folder the process cannot
    write in (probed with a temporary file, so it holds for root and for /proc as well).
    """
    path = Path(path)
    _name_error(path, label, error)
    if path.is_dir():
        raise error(f"{label} {path}: is a folder, expected a file name")
    hit = _is_input(path, inputs)
    if hit is not None:
        what = "is" if Path(hit).resolve() == path.resolve() else f"is inside {hit}, which is"
        raise error(f"{label} {path}: {what} an input of this run; choose another file")
    if path.exists():
        if not path.is_file():
            raise error(f"{label} {path}: exists and is not a regular file")
        if not force and (path.stat().st_mode & 0o222 == 0 or not os.access(path, os.W_OK)):
            raise error(f"{label} {path}: is read-only; refusing to replace it (--force "
                        "replaces it)")
    parent = path.parent
    if not parent.exists():
        if not make_parents:
            raise error(f"{label} {path}: folder {parent} does not exist")
        parent = _nearest_existing(parent)
        if not parent.is_dir():
            raise error(f"{label} {path}: {parent} is not a folder")
    _probe_writable(parent, label, path, error)
    return path


def check_output_dir(
    path: str | Path,
    *,
    error: type[Exception],
    label: str = "output",
    kind: str = "output folder",
    marker: str | None = None,
    force: bool = False,
    inputs: Sequence[str | Path] = (),
) -> bool:
    """Check, before any work, that folder ``path`` can be created or (re)written.

    A new or empty folder is fine. An existing ``kind`` (a folder holding ``marker``, e.g. a
    keyframe store's ``keyframes.json``) is refused unless ``force``; any other non-empty
    folder, a file, an input of the run or an unwritable place is always refused. Returns
    True when ``path`` holds an existing ``kind`` that ``force`` allows to replace.
    """
    path = Path(path)
    _name_error(path, label, error)
    if path.exists() and not path.is_dir():
        raise error(f"{label} {path}: is a file, expected a folder")
    hit = _is_input(path, inputs)
    if hit is not None:
        raise error(f"{label} {path}: is (inside) {hit}, an input of this run; "
                    "choose another folder")
    for raw in inputs:  # nor may the output folder contain an input
        with contextlib.suppress(OSError, RuntimeError, TypeError, ValueError):
            if path.exists() and path.resolve() in Path(raw).resolve().parents:
                raise error(f"{label} {path}: holds {raw}, an input of this run; "
                            "choose another folder")
    replacing = False
    if path.is_dir():
        try:
            entries = list(path.iterdir())
        except OSError as exc:
            raise error(f"{label} {path}: cannot list ({exc.strerror or exc})") from None
        if entries:
            if marker is None or not (path / marker).exists():
                raise error(f"{label} {path}: folder is not empty and is not a {kind}; "
                            "choose a new or empty folder")
            if not force:
                raise error(f"{label} {path}: is a {kind} already; refusing to replace it "
                            "(--force replaces it)")
            replacing = True
    base = path if path.is_dir() else _nearest_existing(path.parent)
    if not base.is_dir():
        raise error(f"{label} {path}: {base} is not a folder")
    _probe_writable(base, label, path, error)
    if replacing:
        _probe_writable(path.parent, label, path, error)
    return replacing


def replace_dir(new: Path, target: Path) -> None:
    """Put the completely written folder ``new`` in place of ``target`` (which may exist):
    rename the old one aside, rename the new one in, then delete the old one. Nothing of
    the old folder is left inside the new one (no stale files)."""
    new, target = Path(new), Path(target)
    old = target.with_name(f".{target.name}.old-{os.getpid()}")
    if old.exists():
        shutil.rmtree(old)
    had_old = target.exists()
    if had_old:
        if target.is_dir() and not any(target.iterdir()):
            target.rmdir()
            had_old = False
        else:
            os.replace(target, old)
    try:
        os.replace(new, target)
    except BaseException:
        if had_old:
            with contextlib.suppress(OSError):
                os.replace(old, target)
        raise
    if had_old:
        shutil.rmtree(old, ignore_errors=True)
