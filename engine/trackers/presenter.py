"""``presenter``: the VR-TV multi-patch colour + motion particle filter as a box tracker.

Initialisation: from a saved model (``model_path``: a folder with model.json + reference.png)
or, by default, from the first frame's ground-truth box (``Frame.gt_box_xywh``) split into
``auto_patches`` horizontal patches. ``box_xywh`` is the particle mean of eq. (6) (what the
OTB metrics score) - for a full-body model with the width and centre x measured by
``engine.presenter.extent`` (``fit_width``); the jitter-filtered position drives the
cross-hair and the control message (``extras['filtered_xyh']``). While LOST the box holds
the last good estimate.

Optional second view: a frame whose ``extras`` carries ``overhead_bgr`` and ``overhead_box_xywh``
(first frame) is tracked by a second filter; with a floor calibration
(``extras['floor_calibration']``, an ``engine.presenter.twoview.FloorCalibration``) the
output adds the floor distance d.
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

import numpy as np

from engine.errors import TrackerError
from engine.frames import Frame
from engine.presenter.params import PresenterParams
from engine.trackers.base import Overlay, TrackerSpec, TrackResult, TrackState


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
        self._sender: Any = None
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
            model, _ = load_model(p.model_path)
        if model is None:
            if frame.gt_box_xywh is None:
                return False
            parts = frame.extras.get("presenter_part_boxes") or {}
            labels = frame.extras.get("labels")
            if p.use_part_boxes and labels is not None and parts:
                from engine.studio.scene import LABEL_HEAD, LABEL_LEGS, LABEL_TORSO

                parts = core_boxes_from_labels(
                    labels, {"head": LABEL_HEAD, "torso": LABEL_TORSO, "legs": LABEL_LEGS})
            if p.use_part_boxes and len(parts) >= 2 and all(parts.values()):
                # the built-in studio's per-part truth stands in for the operator's patches
                model = model_from_parts(bgr, frame.gt_box_xywh, parts, p.n_bins,
                                         grey_world=p.grey_world)
            else:
                model = model_from_box(bgr, frame.gt_box_xywh, p.auto_patches, p.n_bins,
                                       grey_world=p.grey_world)
        self.model = model
        fps = float(frame.extras.get("fps", 0.0) or 30.0)
        self._view = ViewTracker(model, p, fps)
        over = frame.extras.get("overhead_bgr")
        obox = frame.extras.get("overhead_box_xywh")
        if over is not None and obox is not None:
            omodel = model_from_box(over, obox, 2, p.n_bins)
            self._overhead = ViewTracker(omodel, p, fps)
        return True

    def track(self, frame: Frame) -> TrackResult:
        from engine.presenter.control import ControlLimits, ControlLoop, UdpControlSender
        from engine.presenter.twoview import fuse

        bgr = _as_bgr(frame)
        if self._view is None and not self._init(frame, bgr):
            return TrackResult(state=TrackState.INITIALIZING, extras={
                "message": "no presenter model: set up a model or use a source with a "
                           "ground-truth box on its first frame"})
        p = self._params
        if self._t_prev is not None and frame.timestamp_s > self._t_prev:
            # the jitter filter's frame rate from the timestamps (unless the operator set one)
            self._view.frame_rate_hz = 1.0 / (frame.timestamp_s - self._t_prev)
        self._t_prev = frame.timestamp_s
        out = self._view.step(bgr)
        d_m = None
        over_out = None
        if self._overhead is not None and frame.extras.get("overhead_bgr") is not None:
            over_out = self._overhead.step(frame.extras["overhead_bgr"])
            calib = frame.extras.get("floor_calibration")
            _, _, d_m = fuse(0.0, 0.0, over_out.filtered_xyh[:2], calib)
        H, W = bgr.shape[:2]
        fx, fy, _fh = out.filtered_xyh
        if self._control is None:
            self._control = ControlLoop()
        cmd = self._control.update(
            t_s=frame.timestamp_s, state=out.state, x_px=fx, y_px=fy, d_m=d_m,
            target_xy_px=(p.target_x_frac * W, p.target_y_frac * H), target_d_m=p.target_d_m,
            limits=ControlLimits(p.control_gain, p.max_speed_px_s, p.max_accel_px_s2,
                                 p.max_speed_m_s, p.max_accel_m_s2))
        if p.control_udp:
            if self._sender is None:
                self._sender = UdpControlSender(p.control_host, p.control_port)
            self._sender.retarget(p.control_host, p.control_port)
            self._sender.send(cmd)
        x, y, h = out.raw_xyh
        boxes = self._view.model.boxes_at(x, y, h)
        w = boxes[0][2]
        wmax = float(out.weights.max()) if len(out.weights) else 1.0
        overlay = Overlay(
            points_uv=out.particles_xyh[:, :2].astype(np.float32),
            point_weights=(out.weights / (wmax or 1.0)).astype(np.float32),
            boxes_xywh=tuple(tuple(float(v) for v in b) for b in boxes),  # type: ignore[misc]
            box_labels=("presenter", *self._view.model.names),
            crosshair_uv=(fx, fy),
        )
        state = TrackState.TRACKING if out.state == "TRACKING" else TrackState.LOST
        extras: dict[str, Any] = {
            "raw_xyh": out.raw_xyh, "filtered_xyh": out.filtered_xyh,
            "p_col": out.p_col, "p_ref": out.p_ref, "p_min": out.p_min,
            "n_particles": out.n_particles, "lost_frames": out.lost_frames,
            "lag_frames": self._view.lag_frames,
            "lag_s": self._view.jitter.lag_s,
            "d_m": d_m, "control": cmd,
            "model_warnings": self._view.model.warnings,
        }
        if over_out is not None:
            extras["overhead_xyh"] = over_out.filtered_xyh
        bx, bw = out.box_cx_w if out.box_cx_w is not None else (x, w)
        return TrackResult(
            state=state,
            box_xywh=(bx - bw / 2.0, y - h / 2.0, bw, h),
            residual=float(-np.log(max(out.p_col, 1e-300))),
            timings_ms=out.timings_ms,
            overlay=overlay,
            extras=extras,
        )


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
