"""Acceptance: the Keyframes workflow on the built-in studio, driven through the GUI.

new project -> record a sweep (>= 10 keyframes) -> fuse -> inject a known pose error into the
last keyframes -> annotate >= 8 points by clicks on the image panes (predict + snap) -> SBA
removes >= 90 % of the injected error -> save -> reopen -> dense tracking with that store
stays within 1 cm of the ground truth.
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
from PySide6.QtCore import Qt, QTimer

from engine.geometry import se3_exp
from engine.keyframes.depth_sample import depth_at
from engine.keyframes.fusion import FusionParams
from engine.keyframes.sweep import SweepParams
from engine.project import new_project, open_project
from engine.sources import open_source

SPEC = "synthetic:frames=120,width=320,height=240,path=rail,cycle_s=8,dropouts=1"
SHOTS = Path(os.environ.get("STUDIOTRACK_SHOTS", "/tmp/studiotrack_shots"))


def _grab(widget, name: str) -> None:  # type: ignore[no-untyped-def]
    SHOTS.mkdir(parents=True, exist_ok=True)
    widget.grab().save(str(SHOTS / name))


def _grid_corners(kf, nx: int = 4, ny: int = 3, margin: int = 25) -> list[tuple[float, float]]:  # type: ignore[no-untyped-def]
    """The strongest corner per grid cell that lies on one surface: no depth edge under the
    15 x 15 patch the editor matches (depths within 5 %)."""
    h, w = kf.gray.shape
    corners = cv2.goodFeaturesToTrack(kf.gray, 400, 0.02, 10, blockSize=7)[:, 0, :]
    cells: dict[tuple[int, int], tuple[float, float]] = {}
    for u, v in corners:  # strongest first
        if not (margin < u < w - margin and margin < v < h - margin):
            continue
        if not np.isfinite(depth_at(kf.depth_m, float(u), float(v), 7, 0.05)):
            continue
        c = (
            int((u - margin) * nx // (w - 2 * margin)),
            int((v - margin) * ny // (h - 2 * margin)),
        )
        cells.setdefault(c, (float(u), float(v)))
    return [cells[c] for c in sorted(cells)]


def test_keyframe_workflow(qtbot, ctx, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    from app.pages.keyframes import KeyframesPage

    ctx.set_project(new_project("acceptance"))
    page = KeyframesPage(ctx)
    qtbot.addWidget(page)
    page.resize(1500, 900)
    page.show()
    page.source.set_spec(SPEC)
    page.sweep_form.set_params(SweepParams(kf_add_dist_m=0.15, kf_add_angle_deg=8.0, keep_every=1))

    # ---- record (a run of the window's run owner; the display clock draws its progress:
    # here a timer ticks the page as the main window would)
    shot = {"done": False}

    def tick() -> None:
        page.display_tick()
        prog = page.sweep.progress if page.sweep is not None else None
        if not shot["done"] and prog is not None and prog.keyframes >= 6:
            shot["done"] = True
            _grab(page, "keyframes_recording.png")

    ticker = QTimer()
    ticker.timeout.connect(tick)
    ticker.start(30)
    with qtbot.waitSignal(page.job_finished, timeout=180_000):
        qtbot.mouseClick(page.record_button, Qt.MouseButton.LeftButton)
        assert ctx.run.is_running
        assert ctx.run.request.page == "Keyframes"
    ticker.stop()
    store = ctx.project.keyframes
    assert len(store) >= 10, page.state_label.text()
    assert page.strip.count() == len(store)
    assert "Sweep done" in page.state_label.text()
    assert page.recording.lost_frames == 0

    # ---- fuse
    page.fusion_form.set_params(FusionParams(delta_inv_m=0.01))
    with qtbot.waitSignal(page.job_finished, timeout=180_000):
        qtbot.mouseClick(page.fuse_button, Qt.MouseButton.LeftButton)
    res = page.fusion
    assert not res.cancelled
    assert res.hole_fraction_after < 0.5 * res.hole_fraction_before
    assert page.fusion_table.rowCount() == len(store)
    _grab(page, "keyframes_fused.png")

    # ---- inject a known pose error into the last 3 keyframes (drift at the sweep's end)
    store = ctx.project.keyframes
    tracked = {k.id: k.T_world_cam.copy() for k in store.keyframes}
    # ground truth of each keyframe (only to evaluate SBA): the frame it was recorded from
    traj = page.recording.trajectory
    src = open_source(SPEC)
    frame_of = {
        k: min(traj, key=lambda i, T=T: float(np.abs(traj[i] - T).sum()))  # type: ignore[misc]
        for k, T in tracked.items()
    }
    truth = {k: src.frame(i).gt_T_world_cam for k, i in frame_of.items()}
    last = [k.id for k in store.keyframes][-3:]
    rng = np.random.default_rng(7)
    bad = {}
    for n, kid in enumerate(last, start=1):
        d = rng.normal(size=6)
        d[:3] *= 0.01 * n / np.linalg.norm(d[:3])  # 1, 2, 3 cm
        d[3:] *= np.radians(0.3 * n) / np.linalg.norm(d[3:])
        bad[kid] = tracked[kid] @ se3_exp(d)
    page._set_store(store.with_poses(bad), "test: injected pose error")
    store = ctx.project.keyframes

    # ---- annotate by clicks, as an operator would: in every third keyframe and in each
    # drifted one, one well-textured corner per cell of a 4 x 3 grid over the view (points
    # spread across the view, near and far), each on one surface (no depth edge under the
    # matched patch), clicked with up to 2 px error; the editor predicts and snaps the point
    # in the other keyframes and the operator accepts the confident suggestions
    page.tabs.setCurrentWidget(page.editor)
    ed = page.editor
    kfs = store.keyframes
    ed.set_keyframes(kfs[0].id, last[-1])
    qtbot.waitUntil(lambda: ed.left.height() > 300)  # the tab's layout has settled
    anchors = sorted({*range(0, len(kfs), 3), len(kfs) - 2, len(kfs) - 1})
    # STUDIOTRACK_CLICK_SEED: other click errors (seeds 1-11 were checked, see below)
    click_rng = np.random.default_rng(int(os.environ.get("STUDIOTRACK_CLICK_SEED", "11")))
    for a in anchors:
        anchor = kfs[a]
        ed.set_keyframes(anchor.id, kfs[a - 1 if a else 1].id)
        ed.left.fit()
        for u, v in _grid_corners(anchor):
            r, phi = 2.0 * np.sqrt(click_rng.uniform()), click_rng.uniform(0, 2 * np.pi)
            qtbot.keyClick(ed, Qt.Key.Key_N)
            pos = ed.left.to_widget(u + r * np.cos(phi), v + r * np.sin(phi)).toPoint()
            qtbot.mouseClick(ed.left, Qt.MouseButton.LeftButton, pos=pos)
            if len(ed.suggested) >= 2:
                qtbot.mouseClick(ed.accept_button, Qt.MouseButton.LeftButton)
            else:
                qtbot.keyClick(ed, Qt.Key.Key_Delete)  # no confident match: drop the point
    _grab(ed, "annotation_editor.png")
    pts = ctx.project.annotations
    assert len(pts) >= 8
    assert sum(len(p.observations_px) for p in pts) >= 8 * 4
    assert all(sum(k in p.observations_px for p in pts) >= 8 for k in last)
    # undo / redo of the last acceptance
    n_obs = len(pts[-1].observations_px)
    ed.undo_stack.undo()
    assert len(ed.points[-1].observations_px) == 1
    ed.undo_stack.redo()
    assert len(ed.points[-1].observations_px) == n_obs

    # ---- SBA, apply
    with qtbot.waitSignal(page.job_finished, timeout=60_000):
        qtbot.mouseClick(page.sba_button, Qt.MouseButton.LeftButton)
    sba = page.sba
    assert sba is not None, page.sba_label.text()
    assert sba.rmse_after_px < sba.rmse_before_px
    qtbot.mouseClick(page.apply_button, Qt.MouseButton.LeftButton)
    store = ctx.project.keyframes
    # The error is measured against the ground truth expressed in the gauge keyframe's frame
    # (SBA fixes the gauge's tracked pose), not against the pre-injection tracked poses: the
    # clicks see the true studio, so a perfect SBA lands on the truth and also removes the
    # sweep's own drift (~7 mm at its end), which a comparison with the tracked poses would
    # count as error (it caps that "reduction" at ~65 %).
    g = sba.gauge_id
    align = tracked[g] @ np.linalg.inv(truth[g])
    gt = {k: align @ truth[k] for k in last}

    def centre_err(T: dict) -> float:  # type: ignore[type-arg]
        return float(np.mean([np.linalg.norm(T[k][:3, 3] - gt[k][:3, 3]) for k in last]))

    drift = centre_err(tracked)
    err_before = centre_err(bad)
    err_after = centre_err({k: store.by_id(k).T_world_cam for k in last})
    reduction = 1.0 - err_after / err_before
    print(
        f"SBA: {len(pts)} points; pose error of the drifted keyframes vs truth "
        f"{1e3 * err_before:.1f} mm (sweep drift alone {1e3 * drift:.1f} mm) -> "
        f"{1e3 * err_after:.1f} mm ({100 * reduction:.1f} % removed); RMSE "
        f"{sba.rmse_before_px:.2f} -> {sba.rmse_after_px:.2f} px"
    )
    # click seeds 1-11: 93.0-96.8 % (median 95 %); 86-94 % before the tight robust scales
    # of engine.keyframes.sba (0.1 px, 0.1 depth sigma) down-weighted the few snaps 0.2-0.8 px off
    assert reduction >= 0.9, f"SBA removed only {100 * reduction:.1f} % of the pose error"
    page.tabs.setCurrentIndex(0)
    _grab(page, "keyframes_sba.png")
    # the 3D view of the project: keyframe frustums, cloud, annotated points; a frustum click
    # selects the keyframe in the strip
    page.open_3d_view(open_browser=False)
    assert page.viewer.url in page.view_label.text()
    names = page.viewer.node_names()
    assert "/cloud" in names
    assert f"/keyframes/kf_{last[-1]:04d}" in names
    page._on_frustum_clicked(last[0])
    qtbot.waitUntil(lambda: page.selected_keyframe() == last[0])
    store = ctx.project.keyframes

    # ---- save, reopen, track with the store
    ctx.project.save(tmp_path / "studio")
    prj = open_project(tmp_path / "studio")
    assert len(prj.keyframes) == len(store)
    assert len(prj.annotations) == len(pts)
    from engine.dense.params import DenseParams
    from engine.dense.tracking import DenseKeyframeTracker

    tracker = DenseKeyframeTracker(DenseParams(), prj.keyframes)
    errs = []
    src = open_source(SPEC)
    for i in range(120):
        f = src.frame(i)
        r = tracker.track(f)
        if r.T_world_cam is not None:
            errs.append(np.linalg.norm(r.T_world_cam[:3, 3] - f.gt_T_world_cam[:3, 3]))
    print(f"dense tracking with the store: max error {1e3 * max(errs):.1f} mm over {len(errs)}")
    assert len(errs) == 120
    assert max(errs) <= 0.01, np.round(errs, 3)
    page.shutdown()
