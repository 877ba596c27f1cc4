from __future__ import annotations

import logging
import threading

from PySide6.QtGui import QGuiApplication

from widgets.log_panel import LogDock, LogLevel, LogModel, QtLogHandler


def test_levels_filter_and_copy(qtbot) -> None:  # type: ignore[no-untyped-def]
    model = LogModel()
    dock = LogDock(model)
    qtbot.addWidget(dock)
    model.debug("d-msg")
    model.info("i-msg")
    model.warning("w-msg")
    model.error("e-msg", origin="engine")
    view = dock.view
    assert view.min_level is LogLevel.INFO
    text = view.text.toPlainText()
    assert "d-msg" not in text
    assert "i-msg" in text
    assert "[engine] e-msg" in text
    view.set_min_level(LogLevel.WARNING)
    assert "i-msg" not in view.text.toPlainText()
    view.copy_button.click()
    copied = QGuiApplication.clipboard().text()
    assert "w-msg" in copied
    assert "e-msg" in copied
    assert "i-msg" not in copied
    view.clear_button.click()
    assert view.text.toPlainText() == ""
    assert model.entries() == []


def test_entries_from_other_threads_arrive_in_the_gui_thread(qtbot) -> None:  # type: ignore[no-untyped-def]
    model = LogModel()
    seen_threads: list[bool] = []
    model.entry_added.connect(
        lambda _e: seen_threads.append(threading.current_thread() is threading.main_thread())
    )
    handler = QtLogHandler(model)
    logger = logging.getLogger("studiotrack.test_log_panel")
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        worker = threading.Thread(target=lambda: logger.warning("from a worker"))
        with qtbot.waitSignal(model.entry_added, timeout=5000):
            worker.start()
            worker.join()
    finally:
        logger.removeHandler(handler)
    assert seen_threads == [True]
    [entry] = model.entries()
    assert entry.level is LogLevel.WARNING
    assert entry.message == "from a worker"
