"""What every page gets: the run owner, the log, settings and the current project.

Pages are built by ``factory(ctx: AppContext)`` (see :mod:`app.pages`). ``ctx.run`` (an
:class:`app.run_owner.RunOwner`) is the window's one camera pipeline: pages start, stop and
tune runs through it (``ctx.run.start(RunRequest(...))``, ``stop()``, ``set_params``),
read the newest record and the run's history at the display rate, and switch the pose
outputs; its signals (``started``, ``failed``, ``finished``) say when a run changes. Pages
report through ``ctx.log`` (``ctx.log.info(...)``, ``.warning``, ``.error``), which feeds
the log dock and, for warnings and errors, the main window's status bar.

QSettings holds only window geometry and recent files (STYLE.md); everything else is
persisted as versioned JSON by the engine.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from PySide6.QtCore import QObject, QSettings, Signal

from app.run_owner import RunOwner
from widgets.log_panel import LogModel

ORGANIZATION = "StudioTrack"
APPLICATION = "StudioTrack"
MAX_RECENT = 10

#: set to an .ini path to keep settings out of the user's profile (tests, CI, kiosks)
SETTINGS_ENV = "STUDIOTRACK_SETTINGS"


def default_settings() -> QSettings:
    """The app's QSettings: ``$STUDIOTRACK_SETTINGS`` (ini file) if set, else per user."""
    path = os.environ.get(SETTINGS_ENV)
    if path:
        return QSettings(path, QSettings.Format.IniFormat)
    return QSettings(ORGANIZATION, APPLICATION)


class AppContext(QObject):
    """Shared state handed to every page factory."""

    project_changed = Signal(object)  # the new project (or None)
    recent_files_changed = Signal()

    def __init__(
        self,
        run: RunOwner | None = None,
        log: LogModel | None = None,
        settings: QSettings | None = None,
        parent: QObject | None = None,
    ) -> None:
        super().__init__(parent)
        self.log = log if log is not None else LogModel(parent=self)
        self.run = run if run is not None else RunOwner(self, log=self.log)
        if self.run.log is None:
            self.run.log = self.log
        self.settings = settings if settings is not None else default_settings()
        self._project: Any | None = None
        #: typed lens encoders (zoom, focus) for frames that carry none (the Lens page);
        #: None: the lens file's first sample
        self.lens_typed: tuple[int, int] | None = None

    # ------------------------------------------------------------- project slot
    @property
    def project(self) -> Any | None:
        """The open project (``None`` until project files exist)."""
        return self._project

    def set_project(self, project: Any | None) -> None:
        self._project = project
        self.apply_project_setup()
        self.project_changed.emit(project)

    def edit_project(self, change: Callable[[Any], None]) -> Any:
        """Apply ``change`` to the open project (a new studio project when none is open), mark
        it changed and put its set-up on air: the next run and the running one use it."""
        from engine.project import new_project

        proj = self._project
        created = proj is None
        if proj is None:
            proj = new_project("studio")
        change(proj)
        proj.mark_dirty()
        if created:
            self.set_project(proj)
        else:
            self.apply_project_setup()
        return proj

    def apply_project_setup(self) -> None:
        """Put the project's set-up on air: its lens file on every run's source (when the
        table is complete), its studio frame and nodal offset on the pose outputs."""
        proj = self._project
        lens = getattr(proj, "lens", None)
        if lens is not None and lens.complete:
            from engine.sources.lensed import LensedSource

            typed = self.lens_typed
            self.run.source_setup = lambda src, lf=lens, t=typed: LensedSource(src, lf, t)
            pipe = self.run.pipeline if self.run.is_running else None
            running = getattr(pipe, "source", None)
            if isinstance(running, LensedSource):  # an edit reaches the run on its next frame
                running.set_lens(lens)
                running.set_encoders(*(typed if typed is not None else (None,)))
        else:
            self.run.source_setup = None
        if proj is None:
            return
        from dataclasses import replace

        from engine.outputs.studio_frame import CameraOffset

        cfg = self.run.outputs_config
        # the nodal offset lives only in the project; a studio frame set on the Outputs page
        # before any project existed is kept when the project has none
        new = replace(cfg, offset=proj.nodal_offset or CameraOffset(),
                      studio=cfg.studio if proj.studio_frame is None else proj.studio_frame)
        if new != cfg:
            try:
                self.run.apply_outputs(new)
            except Exception as exc:  # an unreachable target: keep the old config
                self.log.warning(f"project set-up not applied to the outputs: {exc}")

    # ------------------------------------------------------------- recent files
    def recent_files(self) -> list[str]:
        value = self.settings.value("recent_files", [])
        if isinstance(value, str):  # QSettings returns a bare str for one-item lists
            value = [value]
        return [str(v) for v in (value or []) if str(v)]

    def add_recent_file(self, path: str | Path) -> None:
        text = str(path)
        items = [text, *[p for p in self.recent_files() if p != text]][:MAX_RECENT]
        self.settings.setValue("recent_files", items)
        self.recent_files_changed.emit()

    def shutdown(self) -> None:
        """Stop the engine and flush settings (called when the main window closes)."""
        self.run.stop()
        self.settings.sync()
