"""Tracker ``open3d-odometry``: Open3D's frame-to-frame RGB-D odometry (hybrid Jacobian,
Park et al. 2017 photometric + geometric terms), a peer of the dense trackers.

``compute_rgbd_odometry(src, dst, ...)`` returns ``T`` with ``p_dst = T p_src``; with the
current frame as source and the previous good frame as target, ``T = T_prev_cur`` and
``T_world_cur = T_world_prev @ T``. Open3D assumes an undistorted pinhole camera, so images
are used as they come. Failure (no convergence, or a jump beyond the limits) reports LOST and
holds the last good pose; the reference stays the last good frame.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.errors import TrackerError
from engine.frames import Frame
from engine.geometry import rotation_angle_rad
from engine.params import Params, param
from engine.trackers.base import TrackerSpec, TrackResult, TrackState

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Open3DOdometryParams(Params):
    """Settings of Open3D's RGB-D odometry (iteration schedule is Open3D's default 20/10/5)."""

    jacobian: str = param("hybrid", choices=("hybrid", "color"),
                          help="hybrid (colour + depth) or color (photometric only)")
    max_depth_m: float = param(4.0, lo=0.1, hi=20.0, help="ignore depth beyond this (m)")
    max_depth_diff_m: float = param(0.07, lo=0.001, hi=1.0,
                                    help="max depth difference of a correspondence (m)")
    max_translation_m: float = param(0.15, lo=0.001,
                                     help="reject per-frame moves longer than this (m)")
    max_rotation_deg: float = param(15.0, lo=0.1,
                                    help="reject per-frame turns larger than this (deg)")
    start_at_ground_truth: bool = param(True,
                                        help="start at the first frame's ground-truth pose if "
                                        "known")


class Open3DOdometryTracker:
    name = "open3d-odometry"

    def __init__(self, params: Open3DOdometryParams | None = None) -> None:
        self._params = params or Open3DOdometryParams()
        self._pending: Open3DOdometryParams | None = None
        self.reset()

    @property
    def params(self) -> Open3DOdometryParams:
        return self._pending or self._params

    def set_params(self, params: Any) -> None:
        if not isinstance(params, Open3DOdometryParams):
            raise TrackerError(f"{self.name}: expected Open3DOdometryParams")
        self._pending = params

    def reset(self) -> None:
        self._prev: Any = None
        self._T_world_prev: F64 | None = None
        self._intrinsic: Any = None

    def _rgbd(self, frame: Frame) -> Any:
        import open3d as o3d

        assert frame.color_bgr is not None
        assert frame.depth_m is not None
        rgb = np.ascontiguousarray(frame.color_bgr[:, :, ::-1])
        depth = np.ascontiguousarray(frame.depth_m, dtype=np.float32)
        return o3d.geometry.RGBDImage.create_from_color_and_depth(
            o3d.geometry.Image(rgb), o3d.geometry.Image(depth), depth_scale=1.0,
            depth_trunc=self._params.max_depth_m, convert_rgb_to_intensity=True,
        )

    def track(self, frame: Frame) -> TrackResult:
        import open3d as o3d

        t0 = time.perf_counter()
        if self._pending is not None:
            self._params, self._pending = self._pending, None
        p = self._params
        if frame.color_bgr is None or frame.depth_m is None:
            raise TrackerError(f"{self.name}: frame {frame.index} needs colour and depth")
        if self._intrinsic is None:
            c = frame.intrinsics
            if c is None:
                raise TrackerError(f"{self.name}: frame {frame.index} has no intrinsics")
            self._intrinsic = o3d.camera.PinholeCameraIntrinsic(
                c.width, c.height, c.fx, c.fy, c.cx, c.cy
            )
        cur = self._rgbd(frame)
        t1 = time.perf_counter()
        if self._prev is None:
            self._prev = cur
            self._T_world_prev = (
                np.array(frame.gt_T_world_cam)
                if p.start_at_ground_truth and frame.gt_T_world_cam is not None
                else np.eye(4)
            )
            return TrackResult(
                TrackState.TRACKING, self._T_world_prev.copy(),
                timings_ms={"preprocess": (t1 - t0) * 1e3, "total": (t1 - t0) * 1e3},
            )
        option = o3d.pipelines.odometry.OdometryOption()
        option.depth_diff_max = p.max_depth_diff_m
        option.depth_max = p.max_depth_m
        jac = (
            o3d.pipelines.odometry.RGBDOdometryJacobianFromHybridTerm()
            if p.jacobian == "hybrid"
            else o3d.pipelines.odometry.RGBDOdometryJacobianFromColorTerm()
        )
        ok, T, _info = o3d.pipelines.odometry.compute_rgbd_odometry(
            cur, self._prev, self._intrinsic, np.eye(4), jac, option
        )
        t2 = time.perf_counter()
        T = np.asarray(T)
        ang = math.degrees(rotation_angle_rad(T[:3, :3]))
        timings = {"preprocess": (t1 - t0) * 1e3, "minimize": (t2 - t1) * 1e3}
        assert self._T_world_prev is not None
        if not ok or np.linalg.norm(T[:3, 3]) > p.max_translation_m or ang > p.max_rotation_deg:
            timings["total"] = (time.perf_counter() - t0) * 1e3
            return TrackResult(
                TrackState.LOST, self._T_world_prev.copy(), timings_ms=timings,
                message="odometry failed" if not ok else "jump",
            )
        self._T_world_prev = self._T_world_prev @ T
        self._prev = cur
        timings["total"] = (time.perf_counter() - t0) * 1e3
        return TrackResult(TrackState.TRACKING, self._T_world_prev.copy(), timings_ms=timings)


TRACKERS = (
    TrackerSpec(
        name="open3d-odometry",
        description="Open3D frame-to-frame RGB-D odometry (hybrid colour + depth Jacobian)",
        params_cls=Open3DOdometryParams,
        factory=lambda p: Open3DOdometryTracker(p),
        needs_depth=True,
        output="pose",
    ),
)
