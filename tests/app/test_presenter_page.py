"""Presenter page: drag a model with the mouse, see its histograms, start tracking."""

from __future__ import annotations

from PySide6.QtCore import QPoint, Qt
from PySide6.QtTest import QTest

from engine.sources import open_source

SOURCE = "synthetic:frames=60,width=160,height=120,seed=3,presenter=1,path=static"


def _drag(canvas, a: tuple[float, float], b: tuple[float, float]) -> None:  # type: ignore[no-untyped-def]
    pa, pb = canvas.to_widget(*a).toPoint(), canvas.to_widget(*b).toPoint()
    QTest.mousePress(canvas, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, pa)
    mid = QPoint((pa.x() + pb.x()) // 2, (pa.y() + pb.y()) // 2)
    QTest.mouseMove(canvas, mid)
    QTest.mouseMove(canvas, pb)
    QTest.mouseRelease(canvas, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, pb)


def test_drag_main_region_and_three_patches_then_track(qtbot, ctx) -> None:  # type: ignore[no-untyped-def]
    from app.main import configure_pyqtgraph
    from app.pages.presenter import HistogramTile, PresenterPage

    configure_pyqtgraph()
    with open_source(SOURCE) as src:
        first = next(iter(src.frames()))
    x, y, w, h = first.gt_box_xywh
    page = PresenterPage(ctx)
    qtbot.addWidget(page)
    page.resize(1200, 800)
    page.show()
    page.source_edit.setText(SOURCE)
    page.realtime_check.setChecked(False)
    qtbot.mouseClick(page.take_button, Qt.MouseButton.LeftButton)
    assert page.reference is not None
    assert page.reference.shape[:2] == (120, 160)

    qtbot.mouseClick(page.mode_buttons["main"], Qt.MouseButton.LeftButton)
    _drag(page.canvas, (x, y), (x + w, y + h))
    assert page.canvas.main is not None
    assert abs(page.canvas.main[0] - x) < 2
    assert abs(page.canvas.main[3] - h) < 2
    assert "at least two patches" not in page.message.text() or page.model is None

    qtbot.mouseClick(page.mode_buttons["patch"], Qt.MouseButton.LeftButton)
    bands = ((0.02, 0.22), (0.26, 0.58), (0.62, 0.98))
    for a, b in bands:
        _drag(page.canvas, (x + 0.1 * w, y + a * h), (x + 0.9 * w, y + b * h))
    assert [p.name for p in page.canvas.patches] == ["patch 1", "patch 2", "patch 3"]
    assert page.model is not None, page.message.text()
    tiles = page.hist_box.findChildren(HistogramTile)
    assert len(tiles) == 3

    # rename through the list, select and move a patch in Edit mode
    page.patch_list.item(0).setText("head")
    assert page.canvas.patches[0].name == "head"
    qtbot.mouseClick(page.mode_buttons["edit"], Qt.MouseButton.LeftButton)
    px, py, pw, ph = page.canvas.patches[1].xywh
    _drag(page.canvas, (px + pw / 2, py + ph / 2), (px + pw / 2, py + ph / 2 + 2))
    assert page.canvas.selected == 1

    assert not page.stop_button.isEnabled()  # Stop only while a run is active
    with qtbot.waitSignal(page.run.started, timeout=20000):
        qtbot.mouseClick(page.start_button, Qt.MouseButton.LeftButton)
    assert not page.start_button.isEnabled()
    assert page.stop_button.isEnabled()
    # the window's display clock drives the page (here: the test ticks it)
    qtbot.waitUntil(lambda: (page.display_tick(), page._frames >= 5)[1], timeout=30000)
    page.redraw()
    assert page.light.state is not None
    assert "contrast z" in page.readout.text()  # the default loss test, with its threshold
    assert "LOST above" in page.readout.text()
    assert "e_f" in page.control_label.text()
    # a live edit goes to the engine as SetParams
    editor = page.form.editor("n_particles")
    editor.setValue(150)
    qtbot.waitUntil(lambda: (page.display_tick(), page.latest is not None
                             and page.latest.result.details.n_particles == 150)[1],
                    timeout=20000)
    with qtbot.waitSignal(page.run.finished, timeout=20000):
        page.stop_tracking()
    # nothing stale after Stop
    assert page.light.text == "STOPPED"
    assert page.readout.text() == "Not tracking."
    assert page.message.text() != "tracking started"  # the Start message does not stay
    assert page.start_button.isEnabled()
    assert not page.stop_button.isEnabled()


def test_degenerate_selection_message(qtbot, ctx) -> None:  # type: ignore[no-untyped-def]
    from app.pages.presenter import PresenterPage

    page = PresenterPage(ctx)
    qtbot.addWidget(page)
    page.resize(900, 700)
    page.show()
    import numpy as np

    page.set_reference(np.full((120, 160, 3), 90, np.uint8))
    page.canvas.set_model((20.0, 10.0, 60.0, 100.0), [("a", (20.0, 10.0, 60.0, 40.0))])
    assert "at least two patches" in page.message.text()
    page.canvas.set_model((20.0, 10.0, 60.0, 100.0),
                          [("a", (20.0, 10.0, 60.0, 40.0)), ("b", (100.0, 10.0, 30.0, 30.0))])
    assert "not inside the main region" in page.message.text()
    page.canvas.set_model((20.0, 10.0, 60.0, 100.0),
                          [("a", (20.0, 10.0, 60.0, 40.0)), ("b", (20.0, 60.0, 60.0, 40.0))])
    assert "grey" in page.message.text()
    assert page.model is not None  # grey is a warning, not an error
    page.source_edit.setText(SOURCE)
    page.realtime_check.setChecked(False)
    with qtbot.waitSignal(page.run.started, timeout=20000):
        assert page.start_tracking() is True
    with qtbot.waitSignal(page.run.finished, timeout=20000):
        page.stop_tracking()


TWO_VIEW = ("synthetic:frames=60,width=320,height=240,seed=3,presenter=1,path=static,"
            "views=2")


def test_two_views_floor_calibration_and_distance(qtbot, ctx) -> None:  # type: ignore[no-untyped-def]
    from app.pages.presenter import PresenterPage
    from engine.project import new_project

    ctx.set_project(new_project("show"))
    page = PresenterPage(ctx)
    qtbot.addWidget(page)
    page.resize(1280, 800)
    page.show()
    page.source_edit.setText(TWO_VIEW)
    page.realtime_check.setChecked(False)
    page.take_reference()
    # the second view came with the reference, and the studio's floor marks with it
    assert page.over_reference is not None
    assert len(page.over_canvas.floor_points) == 4
    assert page.floor_table.item(3, 3).text() != ""
    # a missing coordinate is a one-line message, not a calibration
    page.floor_table.item(2, 2).setText("")
    assert page.save_floor_calibration() is None
    assert "F3" in page.message.text()
    page.floor_table.item(2, 2).setText("1.000")
    calib = page.save_floor_calibration()
    assert calib is not None
    assert ctx.project.floor_calibration is calib
    assert ctx.project.dirty
    assert "above the floor" in page.floor_status.text()
    from engine.sources import open_source

    with open_source(TWO_VIEW) as src:
        box = next(iter(src.frames())).gt_box_xywh
    page.canvas.set_model(box, [])
    page.auto_split()
    with qtbot.waitSignal(page.run.started, timeout=20000):
        assert page.start_tracking() is True
    assert page.form.params.floor_path.endswith("floor.json")
    qtbot.waitUntil(lambda: (page.display_tick(), page._frames >= 8)[1], timeout=30000)
    page.redraw()
    text = page.readout.text()
    assert "overhead" in text
    assert "floor (" in text
    assert page.over_canvas.overlay_boxes
    with qtbot.waitSignal(page.run.finished, timeout=20000):
        page.stop_tracking()
    assert page.over_canvas.overlay_boxes == []


def test_floor_calibration_of_a_zooming_second_view_uses_a_lens_file(qtbot, ctx) -> None:  # type: ignore[no-untyped-def]
    from app.pages.presenter import PresenterPage

    page = PresenterPage(ctx)
    qtbot.addWidget(page)
    page.source_edit.setText(TWO_VIEW.replace("frames=60", "frames=4") + ",over_zoom=sweep")
    page.take_reference()
    # the studio's second camera zooms: its marks come with its lens file and encoders
    assert page.floor_lens.currentData() == "source"
    assert page.floor_focus.value() == 30000
    calib = page.save_floor_calibration()
    assert calib is not None
    assert calib.has_lens_model
    assert not calib.lens_from_project
    assert "lens model" in page.floor_status.text()
    # no project open before: the page made one (one way to change the project)
    assert ctx.project is not None
    assert ctx.project.floor_calibration is calib
    # the project's lens file is asked for but there is none: one line, nothing changed
    page.floor_lens.setCurrentIndex(page.floor_lens.findData("project"))
    assert page.save_floor_calibration() is None
    assert "no complete lens file" in page.message.text()
    assert ctx.project.floor_calibration is calib
    ctx.edit_project(lambda p: setattr(p, "lens", calib.lens))
    got = page.save_floor_calibration()
    assert got is not None
    assert got.lens_from_project
    assert got.has_lens_model
    # a source without a second view: the other source's overhead picture does not stay
    page.source_edit.setText(SOURCE)
    page.take_reference()
    assert page.over_reference is None
    assert page.over_canvas._qimage is None
    assert page.over_canvas.floor_points == []


# played in real time (30 fps): ~5 s in view, then ~8 s with the lens covered, so that the
# display ticks see both states however loaded the machine is
COVERED = ("synthetic:frames=400,width=160,height=120,seed=3,presenter=1,path=static,"
           "cover_start=150,cover_frames=1000")


def test_lost_shows_only_the_last_position_dashed(qtbot, ctx) -> None:  # type: ignore[no-untyped-def]
    from app.pages.presenter import PresenterPage
    from engine.trackers.base import TrackState

    page = PresenterPage(ctx)
    qtbot.addWidget(page)
    page.resize(1280, 800)
    page.show()
    page.source_edit.setText(COVERED)
    page.realtime_check.setChecked(True)
    page.take_reference()
    with open_source(COVERED) as src:
        box = next(iter(src.frames())).gt_box_xywh
    page.canvas.set_model(box, [])
    page.auto_split()
    with qtbot.waitSignal(page.run.started, timeout=20000):
        assert page.start_tracking() is True

    def state() -> object:
        page.display_tick()
        rec = page.latest
        return None if rec is None else rec.result.state

    # each check draws the newest record: the assertions are about that drawn frame
    qtbot.waitUntil(lambda: state() is TrackState.TRACKING, timeout=30000)
    assert not page.canvas.overlay_lost
    assert [lab for _, lab in page.canvas.overlay_boxes][:1] == ["presenter"]
    qtbot.waitUntil(lambda: state() is TrackState.LOST, timeout=30000)
    assert page.light.state is TrackState.LOST
    assert page.readout.text().startswith("LOST")
    assert page.canvas.overlay_lost  # the held box drawn dashed, its patches not at all
    with qtbot.waitSignal(page.run.finished, timeout=20000):
        page.stop_tracking()
    assert not page.canvas.overlay_lost


def test_page_fits_1280x800_in_height_so_the_plot_axes_show(window, qtbot) -> None:  # type: ignore[no-untyped-def]
    """At 1280 x 800 with the log dock the page must not need vertical scrolling: its bottom
    row is the plots, whose frame axes a scrolled page cut off (the floor form's height set
    the page's minimum before it scrolled in its own tab)."""
    from PySide6.QtWidgets import QScrollArea

    window.resize(1280, 800)
    window.show_page("Presenter")
    page = window.page("Presenter")
    scroll = page.parentWidget()
    while scroll is not None and not isinstance(scroll, QScrollArea):
        scroll = scroll.parentWidget()
    assert scroll is not None
    qtbot.waitUntil(lambda: scroll.viewport().height() < 800)
    assert page.minimumSizeHint().height() <= scroll.viewport().height()
    assert page.minimumSizeHint().width() <= scroll.viewport().width()
    assert page.z_plot.height() >= 120 or not page.z_plot.isVisible()
