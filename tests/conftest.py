"""Test configuration shared by all suites.

- Qt runs offscreen (set before any Qt import).
- ``shared_data`` gives ``../shared/data`` or skips with a clear reason when it is absent.
- No test may leave a QThread running (napari's dangling-thread check: ``QThread.start`` is
  patched, so every thread is seen).
"""

from __future__ import annotations

import os
import traceback
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from weakref import WeakKeyDictionary

import pytest

from engine.shared_data import shared_data_dir

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("MPLBACKEND", "Agg")

SHARED_DATA = shared_data_dir()


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path of the shared real data folder; skips the test when it is not there."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data folder {SHARED_DATA} is absent (see ../shared/README.md)")
    return SHARED_DATA


def shared_path(*parts: str) -> Path:
    """A path inside the shared data folder; skips when it does not exist."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"real data {p} is absent (see ../shared/README.md)")
    return p


def _install_qthread_start_spy() -> WeakKeyDictionary[Any, str]:
    """Patch ``QThread.start`` once so that every thread any code starts is seen (not only
    those that register themselves): thread -> where it was started."""
    from PySide6.QtCore import QThread

    started: WeakKeyDictionary[Any, str] = WeakKeyDictionary()
    base_start = QThread.start

    def start(self: QThread, *args: Any, **kwargs: Any) -> None:
        caller = traceback.extract_stack(limit=2)[0]  # the frame that called start()
        started[self] = f"{type(self).__name__} started at {caller.filename}:{caller.lineno}"
        base_start(self, *args, **kwargs)

    QThread.start = start  # type: ignore[method-assign]
    return started


_STARTED_QTHREADS = _install_qthread_start_spy()


@pytest.fixture(autouse=True)
def _no_dangling_qthreads() -> Iterator[None]:
    """No test may leave a QThread running (napari's check: ``QThread.start`` is patched)."""
    yield
    alive = []
    for thread, where in list(_STARTED_QTHREADS.items()):
        try:
            running = thread.isRunning()
        except RuntimeError:  # the C++ object is already deleted: not running
            continue
        if running:
            alive.append(where)
            thread.requestInterruption()
            thread.quit()
            thread.wait(5000)
    _STARTED_QTHREADS.clear()
    if alive:
        pytest.fail(f"test left {len(alive)} QThread(s) running: {'; '.join(alive)}")
