"""File > New / Open / Save / Save As / Open Recent for studio projects.

:func:`install` adds the actions to a main window's File menu (before Quit) and returns the
:class:`ProjectActions`; the window asks :meth:`ProjectActions.confirm_close` before closing
(unsaved changes prompt Save / Discard / Cancel). Projects are folders
(:mod:`engine.project`); recent projects live in QSettings (``ctx.add_recent_file``).
Errors (corrupt or newer-version projects) are shown in one line and change nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from PySide6.QtCore import QObject
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QFileDialog, QInputDialog, QMenu, QMessageBox, QWidget

from engine.errors import StudioTrackError


class ProjectActions(QObject):
    """The project actions of one window; dialogs are replaceable for tests."""

    def __init__(self, window: QWidget, ctx: Any) -> None:
        super().__init__(window)
        self.window, self.ctx = window, ctx
        #: folder pickers: (title) -> path or "" (tests replace them)
        self.pick_open: Callable[[str], str] = lambda title: QFileDialog.getExistingDirectory(
            window, title
        )
        self.pick_save: Callable[[str], str] = lambda title: QFileDialog.getExistingDirectory(
            window, title
        )
        #: unsaved-changes question: returns "save", "discard" or "cancel"
        self.ask_unsaved: Callable[[str], str] = self._ask_unsaved
        self.new_action = QAction("&New project...", self)
        self.new_action.setShortcut(QKeySequence.StandardKey.New)
        self.open_action = QAction("&Open project...", self)
        self.open_action.setShortcut(QKeySequence.StandardKey.Open)
        self.save_action = QAction("&Save project", self)
        self.save_action.setShortcut(QKeySequence.StandardKey.Save)
        self.save_as_action = QAction("Save project &as...", self)
        self.save_as_action.setShortcut(QKeySequence("Ctrl+Shift+S"))
        self.recent_menu = QMenu("Open &recent", window)
        self.new_action.triggered.connect(lambda: self.new_project())
        self.open_action.triggered.connect(lambda: self.open_project())
        self.save_action.triggered.connect(lambda: self.save())
        self.save_as_action.triggered.connect(lambda: self.save_as())
        ctx.recent_files_changed.connect(self._fill_recent)
        ctx.project_changed.connect(lambda _p: self._update_title())
        self._fill_recent()

    # ----------------------------------------------------------------- helpers
    def _log_error(self, msg: str) -> None:
        self.ctx.log.error(msg)

    def _update_title(self) -> None:
        prj = self.ctx.project
        name = (
            ""
            if prj is None
            else f" - {prj.name}" + (f" ({prj.folder})" if prj.folder is not None else "")
        )
        self.window.setWindowTitle(f"StudioTrack{name}")

    def _fill_recent(self) -> None:
        self.recent_menu.clear()
        for path in self.ctx.recent_files():
            if not Path(path, "project.json").exists():
                continue
            act = self.recent_menu.addAction(path)
            act.triggered.connect(lambda _c=False, p=path: self.open_project(p))
        self.recent_menu.setEnabled(not self.recent_menu.isEmpty())

    def _ask_unsaved(self, name: str) -> str:
        from PySide6.QtWidgets import QApplication

        if QApplication.platformName() in ("offscreen", "minimal"):
            # headless (tests, CI): nobody can answer a modal dialog; keep the files as saved
            self.ctx.log.warning(f"Project '{name}': unsaved changes discarded (headless)")
            return "discard"
        box = QMessageBox(
            QMessageBox.Icon.Warning,
            "Unsaved changes",
            f"Project '{name}' has unsaved changes.",
            QMessageBox.StandardButton.Save
            | QMessageBox.StandardButton.Discard
            | QMessageBox.StandardButton.Cancel,
            self.window,
        )
        ans = box.exec()
        return {
            QMessageBox.StandardButton.Save: "save",
            QMessageBox.StandardButton.Discard: "discard",
        }.get(QMessageBox.StandardButton(ans), "cancel")

    def confirm_close(self) -> bool:
        """True when the current project may be dropped (saved, discarded or clean)."""
        prj = self.ctx.project
        if prj is None or not prj.dirty:
            return True
        ans = self.ask_unsaved(prj.name)
        if ans == "save":
            return self.save()
        return ans == "discard"

    # ----------------------------------------------------------------- actions
    def new_project(self, name: str | None = None) -> bool:
        from engine.project import new_project

        if not self.confirm_close():
            return False
        if name is None:
            name, ok = QInputDialog.getText(
                self.window, "New project", "Studio name:", text="studio"
            )
            if not ok:
                return False
        self.ctx.set_project(new_project(name or "studio"))
        self.ctx.log.info(f"New project '{name}' (not saved yet)")
        return True

    def open_project(self, path: str | Path | None = None) -> bool:
        from engine.project import open_project

        if not self.confirm_close():
            return False
        if path is None:
            path = self.pick_open("Open studio project folder")
            if not path:
                return False
        try:
            prj = open_project(path)
        except StudioTrackError as exc:
            self._log_error(f"Open project: {exc}")
            return False
        self.ctx.set_project(prj)
        self.ctx.add_recent_file(str(prj.folder))
        self.ctx.log.info(f"Opened project '{prj.name}' (revision {prj.revision}) from {path}")
        return True

    def save(self) -> bool:
        prj = self.ctx.project
        if prj is None:
            return False
        if prj.folder is None:
            return self.save_as()
        return self._save_to(prj.folder)

    def save_as(self, path: str | Path | None = None) -> bool:
        if self.ctx.project is None:
            return False
        if path is None:
            path = self.pick_save("Save studio project to folder")
            if not path:
                return False
        return self._save_to(Path(path))

    def _save_to(self, folder: Path) -> bool:
        prj = self.ctx.project
        try:
            prj.save(folder)
        except (StudioTrackError, OSError) as exc:
            self._log_error(f"Save project: {exc}")
            return False
        self.ctx.add_recent_file(str(folder))
        self._update_title()
        self.ctx.log.info(f"Saved project '{prj.name}' revision {prj.revision} to {folder}")
        return True


def install(window: Any) -> ProjectActions:
    """Add the project actions to ``window``'s File menu, before its existing entries."""
    actions = ProjectActions(window, window.ctx)
    file_menu = None
    for act in window.menuBar().actions():
        if act.menu() is not None and act.text().replace("&", "") == "File":
            file_menu = act.menu()
    if file_menu is None:
        file_menu = window.menuBar().addMenu("&File")
    first = file_menu.actions()[0] if file_menu.actions() else None
    for a in (actions.new_action, actions.open_action):
        file_menu.insertAction(first, a)
    file_menu.insertMenu(first, actions.recent_menu)
    for a in (actions.save_action, actions.save_as_action):
        file_menu.insertAction(first, a)
    if first is not None:
        file_menu.insertSeparator(first)
    return actions
