"""Tracker ``opencv-odometry``: OpenCV 5's frame-to-frame RGB-D odometry (``cv2.Odometry``).

Each frame is aligned to the previous good frame; the pose is the accumulated motion. OpenCV's
``compute(src, dst)`` returns ``Rt`` with ``p_dst = Rt p_src`` (``Rt = T_dst_src``), so with the
previous frame as src: ``T_world_cur = T_world_prev @ inv(Rt)``.

The first pose is the source's ground truth of the first frame when it has one (so plots and
trajectory files line up with the ground truth for the operator; ATE aligns anyway), otherwise
the identity. When ``compute`` fails the state is LOST and the pose holds the last good one;
the reference stays the last good frame, so tracking resumes when the view comes back. After
``reanchor_after_lost`` consecutive failures the reference moves to the current frame (the
pose then carries the motion missed while lost - better than staying lost for ever).

OpenCV assumes an undistorted pinhole camera; images are used as they come (TUM fr1's colour
images are distorted - the reference numbers were measured that way), unless ``undistort``
is set, which remaps colour and depth to the pinhole model first.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.arrays import f32
from engine.camera import Intrinsics
from engine.errors import ParamsError
from engine.frames import Frame, readonly
from engine.geometry import invert
from engine.params import Params, param
from engine.trackers.base import TrackDetails, TrackerSpec, TrackResult, TrackState

F64 = NDArray[np.float64]

ALGORITHMS = ("rgb_depth", "icp", "rgb")


@dataclass(frozen=True, slots=True)
class OpenCVOdometryParams(Params):
    """Settings of OpenCV's RGB-D odometry (defaults are OpenCV 5's own).

    Pyramid iteration counts (7, 7, 7, 10) and gradient thresholds are OpenCV's defaults and
    not settable (see ``_build``).
    """

    algorithm: str = param("rgb_depth", choices=ALGORITHMS,
                           help="rgb_depth (photometric + ICP, OdometryType_RGB_DEPTH), icp "
                           "(depth only, OdometryType_DEPTH) or rgb (photometric, "
                           "OdometryType_RGB)")
    min_depth_m: float = param(0.0, lo=0.0, hi=10.0, help="ignore depth below this (m)")
    max_depth_m: float = param(4.0, lo=0.1, hi=20.0, help="ignore depth above this (m)")
    max_depth_diff_m: float = param(0.07, lo=0.001,
                                    help="max depth difference of a correspondence (m)")
    max_points_part: float = param(0.07, lo=0.001, hi=1.0, help="fraction of pixels used (ICP)")
    max_translation_m: float = param(0.15, lo=0.001,
                                     help="reject frame-to-frame motions longer than this (m)")
    max_rotation_deg: float = param(15.0, lo=0.1,
                                    help="reject frame-to-frame rotations larger than this (deg)")
    start_at_ground_truth: bool = param(True,
                                        help="start at the first frame's ground-truth pose when "
                                        "the source has one")
    undistort: bool = param(False,
                            help="remap colour and depth to the pinhole model before odometry")
    reanchor_after_lost: int = param(5, lo=1, hi=1000,
                                     help="consecutive failures after which the reference moves "
                                     "to the current frame")

    def validate(self) -> None:
        if self.max_depth_m <= self.min_depth_m:
            raise ParamsError(
                f"max_depth_m ({self.max_depth_m}) must exceed min_depth_m ({self.min_depth_m})"
            )


@dataclass(frozen=True, slots=True)
class OdometryDetails(TrackDetails):
    """Frame-to-frame odometry: the relative motion found (``T_cur_ref``, p_cur = T p_ref)."""

    T_cur_ref: NDArray[np.float64] | None
    initialised: bool = False


class OpenCVOdometryTracker:
    """Frame-to-frame ``cv2.Odometry``; see the module docstring for the pose chain."""

    name = "opencv-odometry"

    def __init__(self, params: OpenCVOdometryParams | None = None) -> None:
        self._params = params if params is not None else OpenCVOdometryParams()
        self._pending: OpenCVOdometryParams | None = None
        self.reset()

    @property
    def params(self) -> OpenCVOdometryParams:
        return self._pending if self._pending is not None else self._params

    def set_params(self, params: Any) -> None:
        if not isinstance(params, OpenCVOdometryParams):
            raise ParamsError(
                f"opencv-odometry needs OpenCVOdometryParams, got {type(params).__name__}"
            )
        self._pending = params

    def reset(self) -> None:
        self._odometry: Any = None
        self._intrinsics: Intrinsics | None = None
        self._undistort_maps: tuple[Any, Any] | None = None
        self._ref: Any = None  # prepared cv2.OdometryFrame of the reference (last good) frame
        self._ref_raw: tuple[np.ndarray, np.ndarray] | None = None  # its (depth, colour)
        self._T_world_ref: F64 | None = None
        self._T_world_cam: F64 | None = None
        self._lost_run = 0

    # -- set-up -------------------------------------------------------------------------
    def _build(self, cam: Intrinsics) -> None:
        import cv2

        p = self._params
        s = cv2.OdometrySettings()
        s.setCameraMatrix(cam.K.astype(np.float32))
        # Iteration counts per level (7, 7, 7, 10) and minimum gradient magnitudes (10 per
        # level) stay OpenCV's defaults: in OpenCV 5.0.0 the Python setters setIterCounts /
        # setMinGradientMagnitudes mangle their input (an (N, 1) array reads back as one
        # level; a (1, N) array crashes the process), so they are not exposed.
        s.setMinDepth(p.min_depth_m)
        s.setMaxDepth(p.max_depth_m)
        s.setMaxDepthDiff(p.max_depth_diff_m)
        s.setMaxPointsPart(p.max_points_part)
        s.setMaxTranslation(p.max_translation_m)
        s.setMaxRotation(p.max_rotation_deg)
        otype = {
            "rgb_depth": cv2.OdometryType_RGB_DEPTH,
            "icp": cv2.OdometryType_DEPTH,
            "rgb": cv2.OdometryType_RGB,
        }[p.algorithm]
        self._odometry = cv2.Odometry(otype, s, cv2.OdometryAlgoType_COMMON)
        self._intrinsics = cam
        self._undistort_maps = None
        if p.undistort and cam.has_distortion:
            self._undistort_maps = cv2.initUndistortRectifyMap(
                cam.K, cam.dist, None, cam.K, cam.size_wh, cv2.CV_32FC1
            )

    def _prepare(self, depth_m: np.ndarray, color_bgr: np.ndarray) -> Any:
        import cv2

        frame = cv2.OdometryFrame(depth_m, color_bgr)
        self._odometry.prepareFrame(frame)
        return frame

    def _inputs(self, frame: Frame) -> tuple[np.ndarray, np.ndarray]:
        import cv2

        depth = np.ascontiguousarray(frame.depth_m, dtype=np.float32)
        color = np.ascontiguousarray(frame.color_bgr)
        if self._undistort_maps is not None:
            mx, my = self._undistort_maps
            color = cv2.remap(color, mx, my, cv2.INTER_LINEAR)
            # Nearest neighbour: interpolating depth across edges invents surfaces.
            depth = f32(cv2.remap(depth, mx, my, cv2.INTER_NEAREST))
        return depth, color

    # -- per frame ----------------------------------------------------------------------
    def _held(self, msg: str, timings: dict[str, float]) -> TrackResult:
        state = TrackState.LOST if self._T_world_cam is not None else TrackState.INITIALIZING
        return TrackResult(
            state=state,
            T_world_cam=None if self._T_world_cam is None else self._T_world_cam.copy(),
            timings_ms=timings,
            message=msg,
        )

    def track(self, frame: Frame) -> TrackResult:
        t_start = time.perf_counter()
        timings: dict[str, float] = {}
        params_changed = self._pending is not None
        if self._pending is not None:
            self._params = self._pending
            self._pending = None
        if frame.depth_m is None:
            return self._held(
                f"opencv-odometry needs depth; frame {frame.index} has none", timings
            )
        if frame.color_bgr is None:
            return self._held(
                f"opencv-odometry needs an image; frame {frame.index} has none", timings
            )
        if frame.intrinsics is None:
            return self._held(
                f"opencv-odometry needs intrinsics; frame {frame.index} has none", timings
            )
        if frame.depth_m.shape[:2] != frame.color_bgr.shape[:2]:
            return self._held(
                f"frame {frame.index}: depth {frame.depth_m.shape[:2]} and colour "
                f"{frame.color_bgr.shape[:2]} sizes differ",
                timings,
            )
        rebuild = self._odometry is None or params_changed or frame.intrinsics != self._intrinsics
        if rebuild:
            self._build(frame.intrinsics)
            if self._ref_raw is not None:
                # Prepared pyramids depend on the settings: prepare the reference again.
                self._ref = self._prepare(*self._ref_raw)
        t0 = time.perf_counter()
        depth, color = self._inputs(frame)
        cur = self._prepare(depth, color)
        t1 = time.perf_counter()
        timings["prepare"] = (t1 - t0) * 1000.0

        if self._ref is None or self._T_world_ref is None:
            gt = frame.gt_T_world_cam
            start = (
                np.array(gt, dtype=np.float64)
                if self._params.start_at_ground_truth and gt is not None
                else np.eye(4)
            )
            self._set_reference(cur, depth, color, start)
            timings["total"] = (time.perf_counter() - t_start) * 1000.0
            return TrackResult(
                state=TrackState.TRACKING,
                T_world_cam=start.copy(),
                timings_ms=timings,
                details=OdometryDetails(T_cur_ref=None, initialised=True),
            )

        ok, Rt = self._odometry.compute(self._ref, cur)
        t2 = time.perf_counter()
        timings["compute"] = (t2 - t1) * 1000.0
        Rt = np.asarray(Rt, dtype=np.float64)
        if not ok or Rt.shape != (4, 4) or not np.all(np.isfinite(Rt)):
            self._lost_run += 1
            msg = f"cv2.Odometry.compute failed on frame {frame.index}"
            reanchor = self._lost_run >= self._params.reanchor_after_lost
            if reanchor and self._T_world_cam is not None:
                self._set_reference(cur, depth, color, self._T_world_cam)
                msg += f"; re-anchored after {self._lost_run} failures"
                self._lost_run = 0
            timings["total"] = (time.perf_counter() - t_start) * 1000.0
            return self._held(msg, timings)

        # Rt = T_cur_ref (p_cur = Rt p_ref), so T_world_cur = T_world_ref inv(Rt).
        T_world_cur = self._T_world_ref @ invert(Rt)
        self._set_reference(cur, depth, color, T_world_cur)
        self._lost_run = 0
        timings["total"] = (time.perf_counter() - t_start) * 1000.0
        return TrackResult(
            state=TrackState.TRACKING,
            T_world_cam=T_world_cur.copy(),
            timings_ms=timings,
            details=OdometryDetails(T_cur_ref=readonly(Rt), initialised=False),
        )

    def _set_reference(
        self, prepared: Any, depth: np.ndarray, color: np.ndarray, T_world: F64
    ) -> None:
        self._ref = prepared
        self._ref_raw = (depth, color)
        self._T_world_ref = np.array(T_world, dtype=np.float64)
        self._T_world_cam = self._T_world_ref.copy()


TRACKERS = (
    TrackerSpec(
        name="opencv-odometry",
        description="OpenCV 5 RGB-D odometry (cv2.Odometry, RGB_DEPTH), frame to frame",
        params_cls=OpenCVOdometryParams,
        factory=OpenCVOdometryTracker,
        needs_depth=True,
        output="pose",
    ),
)
