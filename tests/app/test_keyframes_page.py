"""Keyframes page pieces: delete, SBA errors shown, fusion cancel, append sweep."""

from __future__ import annotations

from PySide6.QtCore import Qt

from engine.keyframes.sweep import SweepParams, record_sweep
from engine.project import new_project
from engine.sources import open_source

SPEC = "synthetic:frames=30,width=320,height=240,path=rail,cycle_s=2"


def test_delete_sba_message_cancel_and_append(qtbot, ctx) -> None:  # type: ignore[no-untyped-def]
    from app.pages.keyframes import KeyframesPage

    src = open_source(SPEC)
    rec = record_sweep(src, SweepParams(kf_add_dist_m=0.1, kf_add_angle_deg=5.0))
    prj = new_project("p")
    prj.keyframes = rec.store
    ctx.set_project(prj)
    page = KeyframesPage(ctx)
    qtbot.addWidget(page)
    page.show()
    n = len(rec.store)
    assert page.strip.count() == n
    assert not page.fuse_button.isEnabled()  # fusion needs the sweep's frames
    # SBA without annotations: a clear one-line message, nothing applied
    with qtbot.waitSignal(page.job_finished, timeout=30_000):
        qtbot.mouseClick(page.sba_button, Qt.MouseButton.LeftButton)
    assert "annotate 6 more" in page.sba_label.text()
    assert page.sba is None
    assert not page.apply_button.isEnabled()
    # delete the selected keyframe
    page.strip.setCurrentRow(1)
    qtbot.mouseClick(page.delete_button, Qt.MouseButton.LeftButton)
    assert page.strip.count() == n - 1
    assert len(ctx.project.keyframes) == n - 1
    assert ctx.project.dirty
    # fusion can be cancelled: the depth maps stay as they were
    page.recording = rec
    page._update_buttons()
    depth0 = ctx.project.keyframes.keyframes[0].depth_m
    page.fusion_form.set_params(page.fusion_form.params)
    with qtbot.waitSignal(page.job_finished, timeout=60_000):
        qtbot.mouseClick(page.fuse_button, Qt.MouseButton.LeftButton)
        page.stop_job()
    assert page.fusion.cancelled
    assert ctx.project.keyframes.keyframes[0].depth_m is depth0
    # append a second sweep (pan) to the store: ids continue, the strip grows
    page.source.set_spec("synthetic:frames=40,width=320,height=240,path=pan,cycle_s=4")
    page.append_box.setChecked(True)
    with qtbot.waitSignal(page.job_finished, timeout=60_000):
        qtbot.mouseClick(page.record_button, Qt.MouseButton.LeftButton)
    assert len(ctx.project.keyframes) > n - 1
    assert page.strip.count() == len(ctx.project.keyframes)
    assert "new)" in page.state_label.text()
    page.shutdown()
