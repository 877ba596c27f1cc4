"""The dangling-thread check sees every QThread, also one that registers nowhere."""

from __future__ import annotations

from PySide6.QtCore import QThread

from tests.conftest import _STARTED_QTHREADS


class _Idle(QThread):
    def run(self) -> None:
        while not self.isInterruptionRequested():
            self.msleep(5)


def test_every_started_qthread_is_seen(qtbot) -> None:  # type: ignore[no-untyped-def]
    thread = _Idle()
    thread.start()
    try:
        assert thread in _STARTED_QTHREADS
        assert "test_thread_check.py" in _STARTED_QTHREADS[thread]  # where it was started
    finally:
        thread.requestInterruption()
        assert thread.wait(5000)
