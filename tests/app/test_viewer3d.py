"""The 3D studio view serves HTTP on 127.0.0.1 and holds the expected scene nodes."""

from __future__ import annotations

import urllib.request
from pathlib import Path

import numpy as np
import pytest

from app.viewer3d import StudioViewer, export_cloud_ply, export_mesh_ply, keyframe_cloud
from engine.camera import Intrinsics
from engine.keyframes.store import KeyframeStore


@pytest.fixture(scope="module")
def store() -> KeyframeStore:
    intr = Intrinsics(fx=60.0, fy=60.0, cx=39.5, cy=29.5, width=80, height=60)
    st = KeyframeStore(intr)
    rng = np.random.default_rng(0)
    for i in range(3):
        T = np.eye(4)
        T[0, 3] = 0.2 * i
        st.add(
            T, rng.integers(0, 255, (60, 80), dtype=np.uint8), np.full((60, 80), 2.0, np.float32)
        )
    return st


def test_viewer_serves_http_and_lists_nodes(store: KeyframeStore) -> None:
    clicked: list[int] = []
    v = StudioViewer(port=8093, on_keyframe_clicked=clicked.append)
    try:
        assert v.url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(v.url, timeout=10) as r:
            assert r.status == 200
            assert b"<html" in r.read(2000).lower()
        v.set_store(store)
        v.set_points(np.array([[0.0, 0.0, 2.0], [0.1, 0.0, 2.0]]))
        v.set_live_camera(np.eye(4))
        T = np.eye(4)
        T[2, 3] = 0.5
        v.set_live_camera(T)  # updates the same node
        assert v.node_names() == [
            "/annotations",
            "/cloud",
            "/keyframes/kf_0000",
            "/keyframes/kf_0001",
            "/keyframes/kf_0002",
            "/live_camera",
            "/picks/point_0000",
            "/picks/point_0001",
        ]
        np.testing.assert_allclose(v.nodes["/live_camera"].position, [0, 0, 0.5])
        picked: list[np.ndarray] = []
        v.on_point_clicked = picked.append
        v.point_clicked(1)  # what the sphere's click handler calls
        v.point_clicked(7)  # no such point: nothing
        assert len(picked) == 1
        np.testing.assert_allclose(picked[0], [0.1, 0.0, 2.0])
        v.set_store(store.subset([0, 1]))  # a deleted keyframe disappears
        assert "/keyframes/kf_0002" not in v.node_names()
    finally:
        v.stop()


def test_cloud_and_exports(store: KeyframeStore, tmp_path: Path) -> None:
    pts, cols = keyframe_cloud(store, stride=4)
    assert pts.shape == (3 * 15 * 20, 3)
    assert cols.shape == pts.shape
    np.testing.assert_allclose(pts[:, 2], 2.0, atol=1e-9)
    n = export_cloud_ply(store, tmp_path / "cloud.ply")
    assert n == 3 * 30 * 40
    assert (tmp_path / "cloud.ply").stat().st_size > 1000
    tris = export_mesh_ply(store, tmp_path / "mesh.ply", voxel_m=0.05)
    assert tris > 0
    assert (tmp_path / "mesh.ply").exists()


def test_live_frustum_follows_the_runs_view_feed(qtbot) -> None:  # type: ignore[no-untyped-def]
    """Every pose run moves the live frustum through the run's 3D-view sink (its own thread,
    latest pose only), no store needed; a box tracker's run gets no feed."""
    from app.run_owner import _outputs_pose
    from engine.frames import Frame
    from engine.loop import FrameRecord
    from engine.pipeline import SinkLevel
    from engine.sinks.view_feed import ViewFeedSink
    from engine.trackers.base import TrackResult, TrackState

    intr = Intrinsics(fx=60.0, fy=60.0, cx=39.5, cy=29.5, width=80, height=60)

    def record(seq: int, x_m: float) -> FrameRecord:
        T = np.eye(4)
        T[0, 3] = x_m
        frame = Frame(seq, seq / 30.0, np.zeros((60, 80, 3), np.uint8), intr)
        result = TrackResult(TrackState.TRACKING, T_world_cam=T)
        return FrameRecord(seq, frame, result, "dense", 1.0, 30.0, 0)

    class Owner:
        publish = None

        def set_view_publish(self, fn):  # type: ignore[no-untyped-def]
            self.publish = fn

    owner = Owner()
    v = StudioViewer(port=8094)
    try:
        v.follow(owner)
        assert owner.publish is not None
        sink = ViewFeedSink(owner.publish, rate_hz=100.0)
        sink.open(None)  # type: ignore[arg-type]
        sink.on_record(record(0, 0.1))
        qtbot.waitUntil(lambda: "/live_camera" in v.node_names(), timeout=3000)
        np.testing.assert_allclose(v.nodes["/live_camera"].position, [0.1, 0, 0])
        for i in range(1, 5):  # several records between two draws: the latest one is drawn
            sink.on_record(record(i, 0.1 * (i + 1)))
        qtbot.waitUntil(lambda: abs(v.nodes["/live_camera"].position[0] - 0.5) < 1e-9)
        assert sink.health().level is SinkLevel.OK
        sink.close()
    finally:
        v.stop()
    assert owner.publish is None  # the viewer stopped following
    assert _outputs_pose("dense")
    assert not _outputs_pose("kcf")


def test_a_clicked_point_moves_the_studio_origin(qtbot, ctx) -> None:  # type: ignore[no-untyped-def]
    from app.pages.keyframes import KeyframesPage
    from engine.outputs.studio_frame import StudioFrame
    from engine.project import new_project

    ctx.set_project(new_project("p"))
    page = KeyframesPage(ctx)
    qtbot.addWidget(page)
    page.set_studio_origin(np.array([1.0, 2.0, 0.0]))  # the option is off: nothing
    assert ctx.project.studio_frame is None
    page.origin_pick.setChecked(True)
    page.set_studio_origin(np.array([1.0, 2.0, 0.0]))
    frame = ctx.project.studio_frame
    np.testing.assert_allclose(frame.matrix[:3, 3], [1.0, 2.0, 0.0])
    np.testing.assert_allclose(frame.matrix[:3, :3], np.eye(3))
    assert ctx.project.dirty
    assert ctx.run.outputs_config.studio == frame
    assert ctx.run.outputs_config.studio != StudioFrame()
