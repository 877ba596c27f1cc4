"""Issue 13 in the window: the Lens page (samples, curves, import/export, into the project),
the header's timecode and HEAD chip, the PTZ page driving the loopback VISCA camera and the
calibrated chain from the project. Screenshots go to $STUDIOTRACK_SCREENSHOTS when set."""

from __future__ import annotations

import os
from pathlib import Path

import pytest


def _shot(widget, name: str) -> None:  # type: ignore[no-untyped-def]
    folder = os.environ.get("STUDIOTRACK_SCREENSHOTS")
    if folder:
        Path(folder).mkdir(parents=True, exist_ok=True)
        widget.grab().save(str(Path(folder) / name))


def test_lens_page_calibrates_samples_into_the_project(qtbot, window, tmp_path) -> None:  # type: ignore[no-untyped-def]
    page = window.page("Lens")
    window.show_page("Lens")
    assert page.table.rowCount() == 0
    for z in (0, 32768, 65535):
        page.zoom_spin.setValue(z)
        page.render_views(8)
        page.calibrate()
    lens = window.ctx.project.lens
    assert [s.zoom_raw for s in lens.samples] == [0, 32768, 65535]
    assert page.table.rowCount() == 3
    assert window.ctx.project.dirty
    assert "3 sample(s)" in page.status.text()
    # the curves: focal length rises with zoom
    _x, y = page.f_curve.getData()
    assert y[-1] > 2.5 * y[0]
    # the project's lens goes on air: runs get a lensed source
    assert window.ctx.run.source_setup is not None
    page.export_file(tmp_path / "lens.json")
    page.table.selectRow(1)
    page.delete_selected()
    assert [s.zoom_raw for s in window.ctx.project.lens.samples] == [0, 65535]
    page.import_file(tmp_path / "lens.json")
    assert len(window.ctx.project.lens.samples) == 3
    # typed encoders on air (a source without lens encoders)
    from types import SimpleNamespace

    bare = SimpleNamespace(name="bare", nominal_fps=25.0, live=False)
    assert window.ctx.run.source_setup(bare).intrinsics.fx == pytest.approx(
        lens.samples[0].fx_px)
    page.zoom_spin.setValue(32768)
    page.typed_check.setChecked(True)
    assert window.ctx.lens_typed == (32768, 0)
    assert window.ctx.run.source_setup(bare).intrinsics.fx == pytest.approx(
        lens.samples[1].fx_px)
    page.typed_check.setChecked(False)
    assert window.ctx.lens_typed is None
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    page.import_file(bad)
    assert str(bad) in page.status.text()
    window.resize(1280, 800)
    _shot(window, "lens_page_1280x800.png")
    window.resize(1920, 1080)
    _shot(window, "lens_page_1920x1080.png")


def test_lens_sample_from_the_ptz_pages_dlt_and_lens_lines(qtbot, window) -> None:  # type: ignore[no-untyped-def]
    """The Lens page makes a sample from the PTZ page's DLT and line-based distortion saved
    in the project; without them, or with a lens file of another size, one line."""
    import numpy as np

    from engine.ptz.distortion import synthetic_distorted_grid
    from engine.ptz.dlt import project_P
    from engine.ptz.sim import CircleScenario

    lens_page, ptz = window.page("Lens"), window.page("PTZ")
    window.show_page("Lens")
    lens_page.sample_from_ptz()
    assert "no pan-tilt calibration" in lens_page.status.text()
    assert window.ctx.project is None or window.ctx.project.lens is None
    # the DLT: the simulator head's projection of points spread in front of it
    sc = CircleScenario(distortion_k3=0.12)
    head = sc.head()
    rng = np.random.default_rng(4)
    X = np.column_stack([rng.uniform(-2, 2, 24), rng.uniform(3, 8, 24), rng.uniform(0, 2.5, 24)])
    uv = project_P(head.P(0.0, 0.0), X)
    for x, m in zip(X, uv, strict=True):
        ptz.points.add_image_point(float(m[0]), float(m[1]), tuple(float(c) for c in x))
    ptz.points.solve()
    assert ptz.points.result is not None
    ptz.save_head()
    assert window.ctx.project.ptz.image_size == (640, 480)
    lens_page.zoom_spin.setValue(2000)
    lens_page.sample_from_ptz()
    (s,) = window.ctx.project.lens.samples
    assert s.zoom_raw == 2000
    assert s.fx_px == pytest.approx(head.K[0, 0], rel=1e-3)
    assert s.k1 == 0.0
    assert "no distortion model" in lens_page.status.text()
    # the lens lines (lines straight in the world seen through the simulator's lens)
    ptz.lines.set_image(np.zeros((480, 640, 3), np.uint8))
    ptz.lines.lines = [[tuple(p) for p in ln] for ln in
                       synthetic_distorted_grid(sc.radial(), (640, 480), noise_px=0.2, seed=3)]
    ptz.lines.estimate()
    ptz.save_distortion()
    lens_page.sample_from_ptz()  # replaces the sample at these encoders
    (s,) = window.ctx.project.lens.samples
    assert s.k1 < -0.1  # barrel, as the simulated lens
    assert "Brown-Conrady fit" in lens_page.status.text()
    assert lens_page.table.rowCount() == 1
    assert "lens lines" in lens_page.table.item(0, 8).text()
    window.resize(1280, 800)
    _shot(window, "lens_page_from_ptz_1280x800.png")
    window.resize(1920, 1080)
    _shot(window, "lens_page_from_ptz_1920x1080.png")
    # a lens file of another image size is refused in one line, nothing lost
    import dataclasses

    window.ctx.edit_project(lambda p: setattr(p, "lens", dataclasses.replace(
        p.lens, width=320, height=240)))
    lens_page.zoom_spin.setValue(4000)
    lens_page.sample_from_ptz()
    assert "640x480 px, the lens file is 320x240" in lens_page.status.text()
    assert len(window.ctx.project.lens.samples) == 1


def test_offset_and_studio_frame_go_into_the_project_and_the_outputs(qtbot, window, tmp_path
                                                                     ) -> None:  # type: ignore[no-untyped-def]
    import numpy as np

    from engine.geometry import R_from_pan_tilt_roll_deg
    from engine.outputs.studio_frame import CameraOffset, StudioFrame
    from engine.project import open_project
    from engine.ptz.dlt import compose_P, project_P

    ctx = window.ctx
    lens = window.page("Lens")
    for key, v in (("x_m", 0.1), ("z_m", 0.05), ("pan_deg", 1.5)):
        lens.offset_spins[key].setValue(v)
    lens.save_offset()
    want = CameraOffset(x_m=0.1, z_m=0.05, pan_deg=1.5)
    assert ctx.project.nodal_offset == want
    assert ctx.run.outputs_config.offset == want  # on the outputs in force
    assert "nodal offset (0.1000" in lens.offset_status.text()
    # the studio frame from a DLT on the PTZ page
    ptz = window.page("PTZ")
    R = R_from_pan_tilt_roll_deg(0.0, -14.0, 0.0).T
    c = np.array([0.0, 0.0, 1.5])
    P = compose_P(np.array([[800.0, 0, 319.5], [0, 800, 239.5], [0, 0, 1]]), R, -R @ c)
    rng = np.random.default_rng(3)
    X = np.column_stack([rng.uniform(-1.2, 1.2, 14), rng.uniform(3, 6, 14),
                         rng.uniform(0.2, 1.4, 14)])
    ptz.points.image = None
    for (u, v), xyz in zip(project_P(P, X), X, strict=True):
        ptz.points.add_image_point(float(u), float(v), tuple(float(q) for q in xyz))
    ptz.points.solve()
    assert ptz.points.result is not None
    ptz.save_studio_frame()
    frame = ctx.project.studio_frame
    assert frame is not None
    # the studio origin seen from the camera (the pan-tilt tracker's world) is t = -R c
    np.testing.assert_allclose(frame.matrix[:3, 3], -R @ c, atol=1e-3)
    assert ctx.run.outputs_config.studio == frame
    assert ctx.run.outputs_config.offset == want  # the offset stays
    lens.show_offsets()
    assert "studio frame: origin at" in lens.offset_status.text()
    # saved and read back
    ctx.project.save(tmp_path / "proj")
    back = open_project(tmp_path / "proj")
    assert back.nodal_offset == want
    assert back.studio_frame == frame
    # reset: identity on the outputs, none in the project
    lens.reset_studio_frame()
    assert ctx.project.studio_frame is None
    assert ctx.run.outputs_config.studio == StudioFrame()


def test_header_shows_timecode_and_head_offline(qtbot, window) -> None:  # type: ignore[no-untyped-def]
    page = window.page("PTZ")
    window.show_page("PTZ")
    live = page.live
    live.head_combo.setCurrentIndex(live.head_combo.findData("visca"))
    live.start("ptz-sim:duration=30,period=20", realtime=True)
    ctx = window.ctx
    qtbot.waitUntil(lambda: ctx.run.status() is not None and ctx.run.status().frames > 20,
                    timeout=60000)
    header = window.header
    qtbot.waitUntil(lambda: header.timecode_label.text().startswith("TC 00:00:"), timeout=5000)
    qtbot.waitUntil(lambda: any(t.startswith("HEAD\nOK") for t in header.target_texts()),
                    timeout=5000)
    live.redraw()
    window.resize(1280, 800)
    _shot(window, "ptz_visca_1280x800.png")
    window.resize(1920, 1080)
    _shot(window, "ptz_visca_1920x1080.png")
    pipe = ctx.run.pipeline
    src = pipe.source
    src.visca_camera.set_fault("silent")  # the camera stops answering
    qtbot.waitUntil(lambda: any(t.startswith("HEAD\nOFFLINE") for t in header.target_texts()),
                    timeout=10000)
    n = ctx.run.status().frames
    qtbot.waitUntil(lambda: ctx.run.status().frames > n + 10, timeout=20000)  # still tracking
    window.resize(1280, 800)
    _shot(window, "ptz_visca_offline_1280x800.png")
    src.visca_camera.set_fault(None)
    qtbot.waitUntil(lambda: any(t.startswith("HEAD\nOK") for t in header.target_texts()),
                    timeout=10000)
    ctx.run.stop()


@pytest.mark.slow
def test_ptz_calibrated_chain_from_the_project(qtbot, window) -> None:  # type: ignore[no-untyped-def]
    page = window.page("PTZ")
    live = page.live
    live.head_combo.setCurrentIndex(live.head_combo.findData("calibrated"))
    live.start("ptz-sim:duration=3", realtime=False)
    assert "no pan-tilt calibration" in live.readout.text()  # nothing saved yet
    live.calibrate_from_sim()
    assert window.ctx.project.ptz.head is not None
    live.start("ptz-sim:duration=3", realtime=False)
    qtbot.waitUntil(lambda: not window.ctx.run.is_running, timeout=120000)
    st = window.ctx.run.final_status
    assert st is not None
    assert st.frames == 90
    from engine.trackers.ptz import PtzDetails

    samples, _, _ = window.ctx.run.trace_since(0)
    srcs = {s.details.pan_tilt_source for s in samples if isinstance(s.details, PtzDetails)}
    assert srcs == {"markers"}
