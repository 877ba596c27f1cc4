"""The 3D studio view: a viser server on 127.0.0.1 (Tykkälä 2014 Fig. 1 and 11).

Shows the keyframe point cloud (fused depth, coloured by the keyframe grey values),
keyframe frustums (click -> ``on_keyframe_clicked(kf_id)``), annotated points (click ->
``on_point_clicked(X_world)``: the Keyframes page can move the studio origin there) and the
live camera frustum. The live frustum follows a keyframe sweep being recorded and, once
``follow(ctx.run)`` is called, every pose run of the window: the run owner feeds it from a
3D-view sink (:class:`engine.sinks.view_feed.ViewFeedSink`, its own thread, at most 20 Hz),
so the browser never slows the engine or the window.
viser is imported when the server starts (start-up stays fast); viser serves
from its own thread and moves to the next port when the asked one is busy: read ``port``.
Exports: the fused cloud (and an open3d TSDF mesh) as PLY.
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics, backproject_depth_image
from engine.geometry import quat_xyzw_from_R

F64 = NDArray[np.float64]


def _wxyz(T: F64) -> tuple[float, float, float, float]:
    x, y, z, w = quat_xyzw_from_R(T[:3, :3])
    return (float(w), float(x), float(y), float(z))


def keyframe_cloud(
    store: Any, stride: int = 4, max_depth_m: float = 8.0
) -> tuple[F64, NDArray[np.uint8]]:
    """World points (N, 3) and grey colours (N, 3) of every keyframe's depth, subsampled."""
    pts, cols = [], []
    intr: Intrinsics = store.intrinsics
    for kf in store.keyframes:
        P = backproject_depth_image(intr, np.asarray(kf.depth_m))[::stride, ::stride].reshape(
            -1, 3
        )
        g = np.asarray(kf.gray)[::stride, ::stride].reshape(-1)
        ok = np.isfinite(P[:, 2]) & (P[:, 2] > 0) & (P[:, 2] < max_depth_m)
        T = kf.T_world_cam
        pts.append(P[ok] @ T[:3, :3].T + T[:3, 3])
        cols.append(np.repeat(g[ok][:, None], 3, axis=1))
    if not pts:
        return np.zeros((0, 3)), np.zeros((0, 3), np.uint8)
    return np.concatenate(pts), np.concatenate(cols).astype(np.uint8)


class StudioViewer:
    """A viser scene of the studio project. Thread-safe setters; ``stop()`` ends the server."""

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 8080,
        on_keyframe_clicked: Callable[[int], None] | None = None,
        on_point_clicked: Callable[[F64], None] | None = None,
    ) -> None:
        import viser

        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.host = host
        self.on_keyframe_clicked = on_keyframe_clicked
        self.on_point_clicked = on_point_clicked
        self._points = np.zeros((0, 3))
        self._lock = threading.Lock()
        self.nodes: dict[str, Any] = {}
        self._intr: Intrinsics | None = None
        self._cloud: tuple[F64, NDArray[np.uint8]] | None = None
        self._store: Any | None = None
        self._live_intr: Intrinsics | None = None
        self._owner: Any | None = None
        self.drawn = 0  # live frusta moved (tests)

    def follow(self, owner: Any) -> None:
        """Move the live frustum with every pose run of ``owner`` (an
        :class:`app.run_owner.RunOwner`); ``stop()`` ends it."""
        self._owner = owner
        owner.set_view_publish(self.set_live_camera)

    @property
    def port(self) -> int:
        return int(self.server.get_port())

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def node_names(self) -> list[str]:
        with self._lock:
            return sorted(self.nodes)

    def _put(self, name: str, handle: Any) -> None:
        old = self.nodes.get(name)
        if old is not None and old is not handle:
            with contextlib.suppress(Exception):
                old.remove()
        self.nodes[name] = handle

    def _drop(self, prefix: str, keep: set[str]) -> None:
        for name in [n for n in self.nodes if n.startswith(prefix) and n not in keep]:
            with contextlib.suppress(Exception):
                self.nodes.pop(name).remove()

    def _frustum(
        self,
        name: str,
        T: F64,
        color: tuple[int, int, int],
        scale: float,
        image: NDArray[np.uint8] | None = None,
        intr: Intrinsics | None = None,
    ) -> Any:
        intr = intr if intr is not None else self._intr
        assert intr is not None
        fov = 2.0 * math.atan2(intr.height / 2.0, intr.fy)
        return self.server.scene.add_camera_frustum(
            name,
            fov=fov,
            aspect=intr.width / intr.height,
            scale=scale,
            color=color,
            image=image,
            wxyz=_wxyz(T),
            position=tuple(float(v) for v in T[:3, 3]),
        )

    def set_store(self, store: Any, stride: int = 4) -> None:
        """Point cloud and keyframe frustums of a keyframe store (call after fusion/SBA)."""
        with self._lock:
            self._intr = store.intrinsics
            self._store = store
            pts, cols = keyframe_cloud(store, stride)
            self._cloud = (pts, cols)
            self._put(
                "/cloud",
                self.server.scene.add_point_cloud(
                    "/cloud", points=pts.astype(np.float32), colors=cols, point_size=0.01
                ),
            )
            keep = set()
            for kf in store.keyframes:
                name = f"/keyframes/kf_{kf.id:04d}"
                thumb = np.asarray(kf.gray)[::8, ::8]
                h = self._frustum(
                    name,
                    kf.T_world_cam,
                    (40, 110, 230),
                    0.15,
                    np.repeat(thumb[:, :, None], 3, axis=2),
                )
                kf_id = kf.id

                def clicked(_event: Any, kf_id: int = kf_id) -> None:
                    if self.on_keyframe_clicked is not None:
                        self.on_keyframe_clicked(kf_id)

                h.on_click(clicked)
                self._put(name, h)
                keep.add(name)
            self._drop("/keyframes/", keep)

    def set_points(self, X_world: Sequence[F64] | F64) -> None:
        """Annotated 3D points (red), each a clickable sphere (``on_point_clicked``)."""
        X = np.asarray(X_world, dtype=np.float32).reshape(-1, 3)
        with self._lock:
            self._points = X.astype(np.float64)
            self._put(
                "/annotations",
                self.server.scene.add_point_cloud(
                    "/annotations",
                    points=X,
                    colors=(230, 30, 30),
                    point_size=0.05,
                    point_shape="circle",
                ),
            )
            keep = set()
            for i, x in enumerate(X):
                name = f"/picks/point_{i:04d}"
                h = self.server.scene.add_icosphere(name, radius=0.04, color=(230, 30, 30),
                                                    opacity=0.35, position=tuple(map(float, x)))

                def clicked(_event: Any, i: int = i) -> None:
                    self.point_clicked(i)

                h.on_click(clicked)
                self._put(name, h)
                keep.add(name)
            self._drop("/picks/", keep)

    def point_clicked(self, index: int) -> None:
        """Annotated point ``index`` was clicked (viser's thread): tell the owner."""
        with self._lock:
            X = self._points[index].copy() if 0 <= index < len(self._points) else None
        if X is not None and self.on_point_clicked is not None:
            self.on_point_clicked(X)

    def set_live_camera(
        self, T_world_cam: F64 | None, intrinsics: Intrinsics | None = None
    ) -> None:
        """The live camera frustum (orange), e.g. from each tracking record.

        The frustum takes the store's intrinsics, else ``intrinsics`` (the live frame's), so
        it shows before any keyframe store exists.
        """
        with self._lock:
            if intrinsics is not None:
                self._live_intr = intrinsics
            intr = self._intr if self._intr is not None else self._live_intr
            if T_world_cam is None or intr is None:
                return
            self.drawn += 1
            h = self.nodes.get("/live_camera")
            if h is None:
                self._put(
                    "/live_camera",
                    self._frustum(
                        "/live_camera", np.asarray(T_world_cam), (255, 140, 0), 0.25, intr=intr
                    ),
                )
            else:
                h.wxyz = _wxyz(np.asarray(T_world_cam))
                h.position = tuple(float(v) for v in np.asarray(T_world_cam)[:3, 3])

    def stop(self) -> None:
        if self._owner is not None:
            self._owner.set_view_publish(None)
            self._owner = None
        self.server.stop()


def export_cloud_ply(store: Any, path: str | Path, stride: int = 2) -> int:
    """Write the keyframe point cloud (coloured) to a PLY file; returns the point count."""
    import open3d as o3d

    pts, cols = keyframe_cloud(store, stride)
    pc = o3d.geometry.PointCloud()
    pc.points = o3d.utility.Vector3dVector(pts)
    pc.colors = o3d.utility.Vector3dVector(cols.astype(np.float64) / 255.0)
    if not o3d.io.write_point_cloud(str(path), pc):
        raise OSError(f"{path}: open3d could not write the point cloud")
    return len(pts)


def export_mesh_ply(
    store: Any, path: str | Path, voxel_m: float = 0.03, max_depth_m: float = 6.0
) -> int:
    """Integrate the keyframes into an open3d TSDF volume and write its mesh (PLY).
    Returns the number of triangles."""
    import open3d as o3d

    intr: Intrinsics = store.intrinsics
    vol = o3d.pipelines.integration.ScalableTSDFVolume(
        voxel_length=voxel_m,
        sdf_trunc=4 * voxel_m,
        color_type=o3d.pipelines.integration.TSDFVolumeColorType.RGB8,
    )
    cam = o3d.camera.PinholeCameraIntrinsic(
        intr.width, intr.height, intr.fx, intr.fy, intr.cx, intr.cy
    )
    for kf in store.keyframes:
        gray = np.ascontiguousarray(np.repeat(np.asarray(kf.gray)[:, :, None], 3, axis=2))
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
            o3d.geometry.Image(gray),
            o3d.geometry.Image(np.asarray(kf.depth_m, np.float32)),
            depth_scale=1.0,
            depth_trunc=max_depth_m,
            convert_rgb_to_intensity=False,
        )
        vol.integrate(rgbd, cam, np.linalg.inv(kf.T_world_cam))
    mesh = vol.extract_triangle_mesh()
    if not o3d.io.write_triangle_mesh(str(path), mesh):
        raise OSError(f"{path}: open3d could not write the mesh")
    return len(mesh.triangles)
