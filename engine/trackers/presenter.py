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

Optional second view: a frame with an :class:`engine.floor.OverheadView` payload (the
presenter's box in it on the first frame) is tracked by a second filter with its own model;
with a floor calibration (``floor_path``: a floor.json or a studio project; else the
payload's) the output adds the presenter's floor position, height and the distance d from
the robot (``engine.floor.FloorCalibration.locate``), and a
:class:`engine.outputs.talent.TalentPosition` command (the talent tracking output the
pose-output sink sends as its own OpenTrackIO transform / FreeD camera id). Loss is decided
on both views (the paper's Sec. III-C.7: a loss in either view is a loss); each view
re-acquires on its own.
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
from engine.outputs.talent import TalentPosition
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
    #: the second view: its own state, box, and the presenter located on the floor
    overhead_state: str | None = None
    overhead_box_xywh: tuple[float, float, float, float] | None = None
    floor_xy_m: tuple[float, float] | None = None
    height_m: float | None = None  # standing height from the second view (head height)
    frontal_state: str = "TRACKING"
    overhead_loss_z: float | None = None
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
        self._floor: Any = None  # FloorCalibration loaded from floor_path
        self._floor_path_loaded: str | None = None
        #: the second view's first box and encoders, and its standing-person model
        self._over_first: Any = None
        self._over_pending: Any = None  # the last second-view frame with a box on the border
        self._over_person: Any = None

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
        self._over_first = None
        self._over_person = None
        self._over_pending = None
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
            load_model,
            model_from_box,
            model_from_parts,
        )
        from engine.presenter.view import ViewTracker
        from engine.studio.render import core_boxes_from_labels

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
        return True

    def _init_overhead(self, over: OverheadView) -> None:
        """The second view's filter, from its first box wholly inside the image: a box on
        the image's border is part of a person, its centre off the body's (a model of it
        tracks a point beside the person: the floor position off by the cut). While the
        source gives boxes on the border the filter waits; when they stop, it starts from
        the last one."""
        from engine.presenter.model import model_from_box, model_from_parts
        from engine.presenter.view import ViewTracker

        p = self._params
        use = over if over.box_xywh is not None else self._over_pending
        if use is None or use.box_xywh is None:
            return
        if over.box_xywh is not None and _on_border(over.box_xywh, over.color_bgr.shape):
            self._over_pending = over
            return
        self._over_pending = None
        oparts = dict(use.part_boxes)
        if p.use_part_boxes and len(oparts) >= 2:
            omodel = model_from_parts(use.color_bgr, use.box_xywh, oparts, p.n_bins,
                                      grey_world=p.grey_world)
        else:
            omodel = model_from_box(use.color_bgr, use.box_xywh, p.auto_patches, p.n_bins,
                                    grey_world=p.grey_world)
        self._over_first = (use.box_xywh, use.lens_encoders, omodel.rel_boxes)
        self._over_person = None
        init = None
        if p.floor_scale or p.floor_lean:
            self._over_person = self._standing_person(self._floor_calibration(use))
            if self._over_person is not None and p.floor_lean:
                init = self._over_person.first_state()  # x on the body's axis
        self._overhead = ViewTracker(omodel, p, self._view.frame_rate_hz, init_xyh=init)

    def _standing_person(self, calib: Any) -> Any:
        from engine.presenter.twoview import StandingPerson

        if calib is None or self._over_first is None:
            return None
        box, encoders, rel = self._over_first
        return StandingPerson.from_first_box(calib, box, rel, encoders)

    def _overhead_person(self, calib: Any, over: OverheadView) -> None:
        """The second view's standing-person model from the floor calibration (made from
        the first box, again if the calibration changes; following the view's encoders):
        its scale (``floor_scale``) and its patches' lean (``floor_lean``)."""
        p, view = self._params, self._overhead
        if (p.floor_scale or p.floor_lean) and calib is not None and (
                self._over_person is None or self._over_person.calib is not calib):
            self._over_person = self._standing_person(calib)
        person = self._over_person if (p.floor_scale or p.floor_lean) else None
        if person is not None:
            person.encoders = over.lens_encoders
        view.scale_model = person.heights if person is not None and p.floor_scale else None
        if person is not None and p.floor_lean:
            view.set_patch_boxes(*person.patch_boxes(view.last_good_xyh))
        elif person is not None:
            _x, _y, w, h = person.first_box_xywh
            view.set_patch_boxes(person.rel_first, w / h)

    def _floor_calibration(self, over: OverheadView) -> Any:
        """``floor_path``'s calibration (a floor.json or a studio project), else the
        payload's."""
        path = self._params.floor_path
        if not path:
            return over.floor_calibration
        if self._floor_path_loaded != path:
            from pathlib import Path

            from engine.floor import load_floor_calibration

            target = Path(path)
            if target.is_dir():
                from engine.project import open_project

                calib = open_project(target).floor_calibration
                if calib is None:
                    raise TrackerError(f"presenter tracker: {target}: the project has no "
                                       "floor calibration")
            else:
                calib = load_floor_calibration(target)
            self._floor, self._floor_path_loaded = calib, path
        return self._floor

    def track(self, frame: Frame) -> TrackResult:
        from engine.presenter.control import ControlLimits, ControlLoop

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
        out = self._view.step(bgr, frame.depth_m)
        d_m = None
        over_out = None
        floor_xy = None
        height = None
        obox = None
        over = frame.payload(OverheadView)
        if self._overhead is None and over is not None:
            self._init_overhead(over)
        if self._overhead is not None and over is not None:
            calib = self._floor_calibration(over)
            self._overhead_person(calib, over)
            over_out = self._overhead.step(_as_bgr_image(over.color_bgr))
            ox, oy, oh = over_out.raw_xyh
            ow = oh * self._overhead.model.aspect
            obox = (ox - ow / 2.0, oy - oh / 2.0, ow, oh)
            if calib is not None and over_out.state == "TRACKING":
                # a lens-model calibration: K and distortion at the view's encoders now
                lean = 0.0
                person = self._over_person
                if person is not None and p.floor_lean and person.calib is calib:
                    # the box is centred on the body's axis: locate the leaning segment
                    lean = person.lean_at(over_out.raw_xyh)
                fx_m, fy_m, height = calib.locate(obox, over.lens_encoders, lean)
                floor_xy = (fx_m, fy_m)
                rx, ry = calib.robot_floor_xy_m
                d_m = float(np.hypot(fx_m - rx, fy_m - ry))
        # the paper's rule: a loss in either view is a loss
        lost = out.state != "TRACKING" or (over_out is not None and over_out.state != "TRACKING")
        H, W = bgr.shape[:2]
        fx, fy, _fh = out.filtered_xyh
        if self._control is None:
            self._control = ControlLoop()
        cmd = self._control.update(
            t_s=frame.timestamp_s, state="LOST" if lost else "TRACKING", x_px=fx, y_px=fy,
            d_m=d_m,
            target_xy_px=(p.target_x_frac * W, p.target_y_frac * H), target_d_m=p.target_d_m,
            limits=ControlLimits(p.control_gain, p.control_ki, p.max_speed_px_s,
                                 p.max_accel_px_s2, p.max_speed_m_s, p.max_accel_m_s2))
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
        state = TrackState.LOST if lost else TrackState.TRACKING
        details = PresenterDetails(
            raw_xyh=_xyh(out.raw_xyh), filtered_xyh=_xyh(out.filtered_xyh),
            p_col=float(out.p_col), p_ref=float(out.p_ref), p_min=float(out.p_min),
            n_particles=int(out.n_particles), lost_frames=int(out.lost_frames),
            loss_z=float(out.loss_z), lag_frames=float(self._view.lag_frames),
            lag_s=float(self._view.jitter.lag_s),
            d_m=d_m, control=cmd, model_warnings=tuple(self._view.model.warnings),
            overhead_xyh=None if over_out is None else _xyh(over_out.filtered_xyh),
            overhead_state=None if over_out is None else over_out.state,
            overhead_box_xywh=obox, floor_xy_m=floor_xy, height_m=height,
            frontal_state=out.state,
            overhead_loss_z=None if over_out is None else float(over_out.loss_z),
        )
        bx, bw = out.box_cx_w if out.box_cx_w is not None else (x, w)
        return TrackResult(
            state=state,
            box_xywh=(bx - bw / 2.0, y - h / 2.0, bw, h),
            residual=float(-np.log(max(out.p_col, 1e-300))),
            timings_ms=out.timings_ms,
            overlay=overlay,
            details=details,
            commands=(robot,) if floor_xy is None else (robot, TalentPosition(floor_xy, height)),
            message="" if state is TrackState.TRACKING else _lost_message(p, out, over_out),
        )


def _lost_message(p: PresenterParams, out: Any, over_out: Any) -> str:
    if out.state != "TRACKING":
        view, o = "", out
    else:
        view, o = "second view ", over_out
    if p.loss_test == "contrast":
        return (f"{view}lost for {o.lost_frames} frames: colour contrast z {o.loss_z:.2f} > "
                f"{p.loss_contrast:.2f}")
    return (f"{view}lost for {o.lost_frames} frames: colour likelihood {o.p_col:.3g} < Pmin "
            f"{o.p_min:.3g}")


def _on_border(box_xywh: tuple[float, float, float, float], shape: tuple[int, ...],
               margin_px: float = 1.0) -> bool:
    """The box touches the image's border (within ``margin_px``)."""
    x, y, w, h = box_xywh
    H, W = shape[:2]
    return x < margin_px or y < margin_px or x + w > W - margin_px or y + h > H - margin_px


def _as_bgr_image(img: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if img.ndim == 2 else img


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
