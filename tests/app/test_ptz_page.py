"""The PTZ page: calibration point entry by simulated clicks and typed coordinates."""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt
from PySide6.QtWidgets import QLineEdit

from engine.geometry import R_from_pan_tilt_roll_deg
from engine.ptz.dlt import compose_P, project_P


@pytest.fixture
def page(qtbot):  # type: ignore[no-untyped-def]
    import pyqtgraph as pg

    from app.context import AppContext
    from app.pages.ptz import PtzPage

    pg.setConfigOption("imageAxisOrder", "row-major")
    ctx = AppContext()
    w = PtzPage(ctx)
    qtbot.addWidget(w)
    w.resize(1300, 800)
    w.show()
    w.tabs.setCurrentWidget(w.points)
    qtbot.waitExposed(w)
    yield w
    w.ctx.run.stop()
    ctx.shutdown()


def _truth() -> tuple[np.ndarray, np.ndarray]:
    R = R_from_pan_tilt_roll_deg(0.0, -14.0, 0.0).T
    c = np.array([0.0, 0.0, 1.5])
    P = compose_P(np.array([[800.0, 0, 319.5], [0, 800, 239.5], [0, 0, 1]]), R, -R @ c)
    rng = np.random.default_rng(3)
    X = np.column_stack([rng.uniform(-1.2, 1.2, 14), rng.uniform(3, 6, 14),
                         rng.uniform(0.2, 1.4, 14)])
    return X, project_P(P, X)


def test_click_points_type_coordinates_and_solve(page, qtbot) -> None:  # type: ignore[no-untyped-def]
    panel = page.points
    X, uv = _truth()
    uv[2] += (30.0, -24.0)  # one mistyped/clicked point
    vb = panel.view.plotItem.vb
    for (u, v) in uv:
        # a real mouse click at the scene position of image point (u, v)
        scene_pt = vb.mapViewToScene(pg_point(u, v))
        view_pt = panel.view.mapFromScene(scene_pt)
        qtbot.mouseClick(panel.view.viewport(), Qt.MouseButton.LeftButton, pos=QPoint(
            round(view_pt.x()), round(view_pt.y())))
    assert panel.table.rowCount() == len(uv)
    clicked = np.array([[float(panel.table.item(r, c).text()) for c in (0, 1)]
                        for r in range(len(uv))])
    assert np.max(np.abs(clicked - uv)) < 1.5  # within a screen pixel of the image point
    # typing the world coordinates into the table
    table = panel.table
    for r, xyz in enumerate(X):
        for c, val in zip((2, 3, 4), xyz, strict=True):
            table.setCurrentCell(r, c)
            table.editItem(table.item(r, c))
            editors = [e for e in table.findChildren(QLineEdit) if e.isVisible()]
            assert len(editors) == 1
            editors[0].selectAll()
            qtbot.keyClicks(editors[0], f"{val:.4f}")
            qtbot.keyClick(editors[0], Qt.Key.Key_Return)
            qtbot.waitUntil(lambda: not any(e.isVisible() for e in
                                            table.findChildren(QLineEdit)), timeout=2000)
    Xt, _, idx = panel.rows()
    assert idx == list(range(len(X)))
    np.testing.assert_allclose(Xt, X, atol=1e-4)
    # overwrite the clicked pixels with the exact values except the bad one
    for r in range(len(uv)):
        table.item(r, 0).setText(f"{uv[r, 0]:.3f}")
        table.item(r, 1).setText(f"{uv[r, 1]:.3f}")
    qtbot.mouseClick(panel.solve_button, Qt.MouseButton.LeftButton)
    assert panel.result is not None
    res = [float(table.item(r, 5).text()) for r in range(len(uv))]
    assert int(np.argmax(res)) == 2
    assert panel.outliers[2]
    assert table.item(2, 0).background().color() == table.item(2, 5).background().color()
    assert "RMSE" in panel.status.text()


def test_coplanar_points_give_a_clear_message(page) -> None:  # type: ignore[no-untyped-def]
    panel = page.points
    for i in range(7):
        panel.add_image_point(50.0 + 40 * i, 100.0 + 13 * (i % 3), (0.3 * i, 4.0 + 0.2 * (i % 3),
                                                                   0.0))
    panel.solve()
    assert panel.result is None
    assert "coplanar" in panel.status.text()


def test_too_few_points_message(page) -> None:  # type: ignore[no-untyped-def]
    panel = page.points
    X, uv = _truth()
    for x, m in zip(X[:4], uv[:4], strict=True):
        panel.add_image_point(float(m[0]), float(m[1]), tuple(float(v) for v in x))
    panel.solve()
    assert "at least 6" in panel.status.text()


def test_lines_estimate_and_preview(page) -> None:  # type: ignore[no-untyped-def]
    from engine.ptz.distortion import RadialModel, synthetic_distorted_grid

    lines = page.lines
    lines.set_image(np.full((480, 640, 3), 120, np.uint8))
    true = RadialModel(k=(0.2, 0.0), centre_px=(320.0, 240.0), r_norm_px=400.0)
    for ln in synthetic_distorted_grid(true, (640, 480), n_lines=5, points_per_line=8):
        for u, v in ln:
            lines.add_point(float(u), float(v))
        lines.new_line()
    lines.estimate()
    assert lines.fit is not None
    assert lines.fit.model.k[0] == pytest.approx(0.2, rel=0.05)
    lines.toggle_preview()
    assert lines.preview


def test_live_runs_the_sim(page, qtbot) -> None:  # type: ignore[no-untyped-def]
    live = page.live
    assert not live.stop_button.isEnabled()
    live.start("ptz-sim:duration=20", realtime=True)
    assert not live.start_button.isEnabled()
    # the window's display clock drives the page (here: the test ticks it)
    qtbot.waitUntil(lambda: (page.display_tick(), len(live.t) > 30)[1], timeout=60000)
    live.redraw()
    assert live.p_curves
    assert "pos err" in live.readout.text()
    with qtbot.waitSignal(live.run.finished, timeout=10000):
        live.stop_button.click()
    assert live.readout.text().startswith("Stopped after")  # nothing stale after Stop
    assert live.start_button.isEnabled()


def test_another_pages_run_leaves_the_readout_of_its_own(page, qtbot) -> None:  # type: ignore[no-untyped-def]
    """A run started elsewhere (the Live page's) ends: the PTZ read-out still speaks of the
    page's own last run, not of the other run's frame count."""
    from app.run_owner import RunRequest

    live = page.live
    live.start("ptz-sim:duration=20", realtime=False)
    qtbot.waitUntil(lambda: (page.display_tick(), len(live.t) > 10)[1], timeout=60000)
    with qtbot.waitSignal(live.run.finished, timeout=10000):
        live.stop_button.click()
    own = live.readout.text()
    assert own.startswith("Stopped after")
    with qtbot.waitSignal(live.run.finished, timeout=30000):
        live.run.start(RunRequest("synthetic:frames=3,width=160,height=120", "ground-truth",
                                  realtime=False, page="Live"))
    assert live.readout.text() == own
    assert live.start_button.isEnabled()


def pg_point(u: float, v: float):  # type: ignore[no-untyped-def]
    from PySide6.QtCore import QPointF

    return QPointF(u, v)


@pytest.mark.parametrize("size", [(1280, 800), (1920, 1080)])
def test_live_video_pane_takes_the_images_aspect(qtbot, window, size) -> None:  # type: ignore[no-untyped-def]
    """The Live tab's video has no empty margins: its pane is sized to the image's 4:3,
    the plots beside and below keep their room."""
    from app.pages.ptz import KIN_MIN_PX, SIDE_MIN_PX

    window.show_page("PTZ")
    window.resize(*size)
    live = window.page("PTZ").live
    qtbot.waitUntil(lambda: live.video.width() > 100)
    live._fit_video()  # the resize event has run; once more after the layout settled
    vw, vh = live.video.width(), live.video.height()
    assert vw / vh == pytest.approx(640 / 480, rel=0.03)
    assert live.plots.width() >= SIDE_MIN_PX - 10
    assert live.kin.height() >= KIN_MIN_PX - 10
    # the image fills the view: its range is the image, no padding
    (x0, x1), (y0, y1) = live.video.getViewBox().viewRange()
    assert (x1 - x0) == pytest.approx(640, rel=0.05)
    assert (y1 - y0) == pytest.approx(480, rel=0.05)
