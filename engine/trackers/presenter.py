"""``presenter``: the VR-TV multi-patch colour + motion particle filter as a box tracker.

Initialisation: from a saved model (``model_path``: a folder with model.json + reference.png)
or, by default, from the first frame's ground-truth box (``Frame.gt_box_xywh``) split into
``auto_patches`` horizontal patches. ``box_xywh`` is the particle mean of eq. (6) (what the
OTB metrics score) - for a full-body model with the width and centre x measured by
``engine.presenter.extent`` (``fit_width``); the jitter-filtered position drives the
cross-hair and the robot-camera correction (``details.filtered_xyh``). While LOST the box
holds the last good estimate. Each frame's correction is returned as a
:class:`engine.presenter.control.RobotCameraCommand` (its ``target`` is the UDP destination
when ``control_udp`` is on); the pipeline's robot-control sink sends it - the tracker does no
I/O. ``details`` is a :class:`PresenterDetails`.

Optional second view: a frame with an :class:`engine.presenter.twoview.OverheadView`
payload (its box on the first frame) is tracked by a second filter; with the payload's floor
calibration the output adds the floor distance d.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.arrays import XYWH, xywh
from engine.errors import TrackerError
from engine.frames import Frame
from engine.presenter.control import ControlCommand, RobotCameraCommand
from engine.presenter.params import PresenterParams
from engine.presenter.twoview import OverheadView
from engine.trackers.base import Overlay, TrackDetails, TrackerSpec, TrackResult, TrackState

XYH = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class PresenterDetails(TrackDetails):
    """One frame of the presenter filter: likelihoods (eq. 3-5), positions, control."""

    raw_xyh: XYH  # particle mean, eq. (6)
    filtered_xyh: XYH  # jitter-filtered (drives the cross-hair and the control)
    p_col: float  # colour likelihood of the best particle
    p_ref: float  # reference likelihood (model time)
    p_min: float  # loss threshold
    n_particles: int
    lost_frames: int
    lag_frames: float
    lag_s: float
    d_m: float | None  # floor distance from the overhead view
    control: ControlCommand
    model_warnings: tuple[str, ...] = ()
    overhead_xyh: XYH | None = None
    #: contrast loss statistic at the tested state: 0 = the target's own colour match,
    #: 1 = the most target-like background's (NaN until known)
    loss_z: float = float("nan")


def _as_bgr(frame: Frame) -> np.ndarray:
    import cv2

    img = frame.color_bgr
    if img is None:
        raise TrackerError(f"presenter tracker: frame {frame.index} has no image")
    if img.ndim == 2:
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    return img


class PresenterTracker:
    name = "presenter"

    def __init__(self, params: PresenterParams | None = None) -> None:
        self._params = params or PresenterParams()
        self._view: Any = None
        self._overhead: Any = None
        self._control: Any = None
        self.model: Any = None
        self._t_prev: float | None = None

    @property
    def params(self) -> PresenterParams:
        return self._params

    def set_params(self, params: PresenterParams) -> None:
        if not isinstance(params, PresenterParams):
            raise TrackerError(f"presenter tracker: expected PresenterParams, got "
                               f"{type(params).__name__}")
        old = self._params
        self._params = params
        if params.model_path != old.model_path or params.auto_patches != old.auto_patches \
                or params.n_bins != old.n_bins or params.grey_world != old.grey_world:
            self.reset()
            return
        for v in (self._view, self._overhead):
            if v is not None:
                v.set_params(params)

    def reset(self) -> None:
        self._view = None
        self._overhead = None
        self._t_prev = None
        if self._control is not None:
            self._control.reset()

    def sinks(self) -> tuple[Any, ...]:
        """The sink that sends this tracker's robot-camera corrections (UDP when asked)."""
        from engine.sinks.robot import RobotControlSink

        return (RobotControlSink(),)

    def use_model(self, model: Any) -> None:
        """Track this (already built) PatchModel from the next frame on (GUI set-up)."""
        self.reset()
        self.model = model

    def _init(self, frame: Frame, bgr: np.ndarray) -> bool:
        from engine.presenter.model import (
            core_boxes_from_labels,
            load_model,
            model_from_box,
            model_from_parts,
        )
        from engine.presenter.view import ViewTracker

        p = self._params
        model = self.model
        if model is None and p.model_path:
            model, _ = load_model(Path(p.model_path))
        if model is None:
            if frame.gt_box_xywh is None:
                return False
            from engine.studio.sim import StudioLabels, StudioTruth

            truth = frame.payload(StudioTruth)
            label_map = frame.payload(StudioLabels)
            parts: Mapping[str, XYWH | None] = (
                dict(truth.presenter_part_boxes or {}) if truth is not None else {})
            labels = label_map.labels if label_map is not None else None
            if p.use_part_boxes and labels is not None and parts:
                from engine.studio.scene import LABEL_HEAD, LABEL_LEGS, LABEL_TORSO

                parts = core_boxes_from_labels(
                    labels, {"head": LABEL_HEAD, "torso": LABEL_TORSO, "legs": LABEL_LEGS})
            if p.use_part_boxes and len(parts) >= 2 and all(parts.values()):
                # the built-in studio's per-part truth stands in for the operator's patches
                boxes = {k: b for k, b in parts.items() if b is not None}  # all, as checked
                model = model_from_parts(bgr, frame.gt_box_xywh, boxes, p.n_bins,
                                         grey_world=p.grey_world)
            else:
                model = model_from_box(bgr, frame.gt_box_xywh, p.auto_patches, p.n_bins,
                                       grey_world=p.grey_world)
        self.model = model
        fps = 30.0  # until the timestamps give the rate (track())
        self._view = ViewTracker(model, p, fps)
        over = frame.payload(OverheadView)
        if over is not None and over.box_xywh is not None:
            omodel = model_from_box(over.color_bgr, over.box_xywh, 2, p.n_bins)
            self._overhead = ViewTracker(omodel, p, fps)
        return True

    def track(self, frame: Frame) -> TrackResult:
        from engine.presenter.control import ControlLimits, ControlLoop
        from engine.presenter.twoview import fuse

        bgr = _as_bgr(frame)
        if self._view is None and not self._init(frame, bgr):
            return TrackResult(
                state=TrackState.INITIALIZING,
                message="no presenter model: set up a model or use a source with a "
                        "ground-truth box on its first frame")
        p = self._params
        if self._t_prev is not None and frame.timestamp_s > self._t_prev:
            # the jitter filter's frame rate from the timestamps (unless the operator set one)
            self._view.frame_rate_hz = 1.0 / (frame.timestamp_s - self._t_prev)
        self._t_prev = frame.timestamp_s
        out = self._view.step(bgr)
        d_m = None
        over_out = None
        over = frame.payload(OverheadView)
        if self._overhead is not None and over is not None:
            over_out = self._overhead.step(over.color_bgr)
            _, _, d_m = fuse(0.0, 0.0, over_out.filtered_xyh[:2], over.floor_calibration)
        H, W = bgr.shape[:2]
        fx, fy, _fh = out.filtered_xyh
        if self._control is None:
            self._control = ControlLoop()
        cmd = self._control.update(
            t_s=frame.timestamp_s, state=out.state, x_px=fx, y_px=fy, d_m=d_m,
            target_xy_px=(p.target_x_frac * W, p.target_y_frac * H), target_d_m=p.target_d_m,
            limits=ControlLimits(p.control_gain, p.max_speed_px_s, p.max_accel_px_s2,
                                 p.max_speed_m_s, p.max_accel_m_s2))
        robot = RobotCameraCommand(
            cmd, (p.control_host, int(p.control_port)) if p.control_udp else None)
        x, y, h = out.raw_xyh
        boxes = self._view.model.boxes_at(x, y, h)
        w = boxes[0][2]
        wmax = float(out.weights.max()) if len(out.weights) else 1.0
        overlay = Overlay(
            points_uv=out.particles_xyh[:, :2].astype(np.float32),
            point_weights=(out.weights / (wmax or 1.0)).astype(np.float32),
            boxes_xywh=tuple(xywh(b) for b in boxes),
            box_labels=("presenter", *self._view.model.names),
            crosshair_uv=(fx, fy),
        )
        state = TrackState.TRACKING if out.state == "TRACKING" else TrackState.LOST
        details = PresenterDetails(
            raw_xyh=_xyh(out.raw_xyh), filtered_xyh=_xyh(out.filtered_xyh),
            p_col=float(out.p_col), p_ref=float(out.p_ref), p_min=float(out.p_min),
            n_particles=int(out.n_particles), lost_frames=int(out.lost_frames),
            loss_z=float(out.loss_z), lag_frames=float(self._view.lag_frames),
            lag_s=float(self._view.jitter.lag_s),
            d_m=d_m, control=cmd, model_warnings=tuple(self._view.model.warnings),
            overhead_xyh=None if over_out is None else _xyh(over_out.filtered_xyh),
        )
        bx, bw = out.box_cx_w if out.box_cx_w is not None else (x, w)
        return TrackResult(
            state=state,
            box_xywh=(bx - bw / 2.0, y - h / 2.0, bw, h),
            residual=float(-np.log(max(out.p_col, 1e-300))),
            timings_ms=out.timings_ms,
            overlay=overlay,
            details=details,
            commands=(robot,),
            message="" if state is TrackState.TRACKING else
            f"lost for {out.lost_frames} frames: colour likelihood {out.p_col:.3g}, "
            f"Pmin {out.p_min:.3g}",
        )


def _xyh(v: Any) -> XYH:
    return (float(v[0]), float(v[1]), float(v[2]))


def _add_cli(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("presenter tracker")
    g.add_argument("--particles", type=int, help="particles while tracking (default 100)")
    g.add_argument("--presenter-model", help="saved presenter model folder (model.json)")
    g.add_argument("--jitter-hz", type=float, help="jitter low-pass cut-off in Hz (0 = off)")
    g.add_argument("--lambda-col", type=float, help="colour likelihood covariance (eq. 3)")


def _from_cli(args: argparse.Namespace, params: PresenterParams) -> PresenterParams:
    changes: dict[str, Any] = {}
    for arg, fieldname in (("particles", "n_particles"), ("presenter_model", "model_path"),
                           ("jitter_hz", "jitter_cutoff_hz"), ("lambda_col", "lambda_col")):
        v = getattr(args, arg, None)
        if v is not None:
            changes[fieldname] = v
    return dataclasses.replace(params, **changes) if changes else params


TRACKERS = (
    TrackerSpec(
        name="presenter",
        description="VR-TV presenter tracker: multi-patch colour + motion particle filter "
        "with loss detection, jitter filter and robot-camera control errors",
        params_cls=PresenterParams,
        factory=PresenterTracker,
        output="box",
        add_cli_arguments=_add_cli,
        params_from_cli=_from_cli,
    ),
)
