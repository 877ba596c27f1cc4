"""Test configuration shared by all suites.

- Qt runs offscreen (set before any Qt import).
- ``shared_data`` gives ``../shared/data`` or skips with a clear reason when it is absent.
- No test may leave a QThread running (napari's dangling-thread check).
"""

from __future__ import annotations

import os
from pathlib import Path

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


@pytest.fixture(autouse=True)
def _no_dangling_qthreads(request: pytest.FixtureRequest):  # type: ignore[no-untyped-def]
    yield
    if "qtbot" not in request.fixturenames:
        return
    from PySide6.QtCore import QThread

    from app.engine_bridge import running_threads

    alive = [t for t in running_threads() if isinstance(t, QThread) and t.isRunning()]
    if alive:
        for t in alive:
            t.requestInterruption()
            t.wait(5000)
        pytest.fail(f"test left {len(alive)} QThread(s) running: {alive}")
