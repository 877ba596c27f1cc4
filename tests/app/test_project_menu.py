"""File > New / Open / Save / Save As / recent projects and the unsaved-changes prompt."""

from __future__ import annotations

import json
from pathlib import Path

from engine.project import open_project


def test_new_save_open_recent_and_close_prompt(window, ctx, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    pa = window.project_actions
    titles = [a.text() for a in window.menuBar().actions()[0].menu().actions()]
    assert titles[:5] == [
        "&New project...",
        "&Open project...",
        "Open &recent",
        "&Save project",
        "Save project &as...",
    ]
    assert pa.new_project("studio B")
    assert ctx.project.name == "studio B"
    assert not ctx.project.dirty  # an empty new project asks nothing on close
    ctx.project.params["y"] = {"b": 2}
    ctx.project.mark_dirty()
    # closing with unsaved changes asks; Cancel keeps the window open
    pa.ask_unsaved = lambda name: "cancel"
    assert not pa.confirm_close()
    window.close()
    assert window.isVisible()  # Cancel kept the window open
    pa.pick_save = lambda title: str(tmp_path / "b")
    pa.save_action.trigger()  # no folder yet -> Save As
    assert (tmp_path / "b" / "project.json").exists()
    assert not ctx.project.dirty
    assert ctx.recent_files()[0] == str(tmp_path / "b")
    assert [a.text() for a in pa.recent_menu.actions()] == [str(tmp_path / "b")]
    assert pa.confirm_close()  # clean
    ctx.project.params["x"] = {"a": 1}
    ctx.project.mark_dirty()
    pa.ask_unsaved = lambda name: "save"
    assert pa.new_project("studio C")  # saves B first
    assert open_project(tmp_path / "b").params == {"y": {"b": 2}, "x": {"a": 1}}
    # open via recent; a newer-version project fails in one line and changes nothing
    pa.ask_unsaved = lambda name: "discard"
    pa.recent_menu.actions()[0].trigger()
    assert ctx.project.name == "studio B"
    idx = tmp_path / "b" / "project.json"
    d = json.loads(idx.read_text())
    d["version"] = 99
    idx.write_text(json.dumps(d))
    before = idx.read_bytes()
    assert not pa.open_project(tmp_path / "b")
    assert "newer than this StudioTrack supports" in window.status_text()
    assert idx.read_bytes() == before
    assert ctx.project.name == "studio B"
    window.close()
