"""Built-in studio scenarios of ``studiotrack bench presenter``: loss, a normal walk, a second
person. Each returns plain numbers measured against the renderer's labels.

- ``desk``: the reference is taken with the presenter standing beside the news desk (whose
  blue front is close to a blue shirt); the presenter walks out of view past the desk, waits,
  and comes back. ``frames_to_detect``: frames from "left" (under a tenth of the
  presenter's standing pixels in view: at most a hand or a foot) to the first LOST;
  ``frames_to_reacquire``: frames from "back" (more than half of the presenter in view
  again) to TRACKING on the presenter (IoU > 0.3);
  ``false_lock_frames``: TRACKING claimed after the loss while the presenter is away.
- ``walk``: a normal walk in view of a static camera; ``false_lost_frames``: frames LOST
  while at least half of the presenter is in view.
- ``distractor``: a second person crossing in front of the presenter, walking behind or
  standing beside; a frame is *stolen* when the tracker claims TRACKING with a box on the
  second person (IoU > 0.3) and off the presenter (IoU < 0.1): following the other person,
  not being covered by one who walks in front.

The ``check`` variants (other seeds, looks and places) are what the default selection uses
to reject parameter sets that miss the loss goals; the bench reports the ``report`` variants.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from engine.frames import Frame

#: goals of issue 15 (frames)
DETECT_GOAL_FRAMES = 5
REACQUIRE_GOAL_FRAMES = 15
#: "left": under this fraction of the standing presenter's pixels in view; "back": over
LEFT_FRACTION = 0.1
BACK_FRACTION = 0.5

_BASE = "synthetic:frames={n},presenter=1,path=static,"
DESK = {
    "report": _BASE + "seed=3,presenter_mode=leave,presenter_x=0.4,presenter_out=-2.4,"
                      "presenter_leave=30,presenter_return=150",
    "check": _BASE + "seed=21,presenter_look=2,presenter_mode=leave,presenter_x=0.2,"
                     "presenter_out=-2.4,presenter_leave=25,presenter_return=140,"
                     "width=320,height=240",
    # the light coming up from dark while the set is empty: the first frame's colours are
    # the dark ones, the empty desk's drift towards the presenter's
    "check_ramp": _BASE + "seed=24,presenter_look=0,lighting=ramp,presenter_mode=leave,"
                          "presenter_x=0.3,presenter_out=-2.4,presenter_leave=25,"
                          "presenter_return=140,width=320,height=240",
    # added at stop 27 (seeds, looks and lighting fixed before any was run; the held-out
    # desks were not looked at): two check desks let a default set through that stays
    # TRACKING on held-out empty desks
    "check_warm": _BASE + "seed=81,presenter_look=6,lighting=warm,presenter_mode=leave,"
                          "presenter_x=0.5,presenter_out=-2.4,presenter_leave=25,"
                          "presenter_return=140,width=320,height=240",
    "check_dim": _BASE + "seed=82,presenter_look=4,lighting=dim,presenter_mode=leave,"
                         "presenter_x=0.0,presenter_out=-2.4,presenter_leave=25,"
                         "presenter_return=140,width=480,height=360",
    "check_cool": _BASE + "seed=83,presenter_look=5,lighting=cool,presenter_mode=leave,"
                          "presenter_x=-0.1,presenter_out=-2.4,presenter_leave=25,"
                          "presenter_return=140,width=320,height=240",
    "check_bright": _BASE + "seed=84,presenter_look=1,lighting=bright,presenter_mode=leave,"
                            "presenter_x=0.3,presenter_out=-2.4,presenter_leave=25,"
                            "presenter_return=140,width=320,height=240",
}
#: the desks the default selection checks (``meets_check_goals``)
CHECK_DESKS = ("check", "check_ramp", "check_warm", "check_dim", "check_cool", "check_bright")
WALK = {
    "report": _BASE + "seed=3",
    "check": _BASE + "seed=22,presenter_look=3,width=320,height=240",
    # a walk across a side key: the presenter's colours change along the walk (a studio's
    # light is never even), which the first frame's colours alone do not foresee
    "check_light": _BASE + "seed=23,presenter_look=1,lighting=side,width=320,height=240",
}
#: the walks the default selection checks (``meets_check_goals``)
CHECK_WALKS = ("check", "check_light")
DISTRACTOR = {
    "cross_same_look": _BASE + "seed=3,person2=cross,person2_look=0,presenter_look=0",
    "cross_other_look": _BASE + "seed=4,person2=cross,person2_look=1,presenter_look=5",
    "beside_same_look": _BASE + "seed=5,person2=beside,person2_look=0,presenter_mode=still",
    "behind_same_look": _BASE + "seed=6,person2=behind,person2_look=0",
}
#: the same cases with other seeds, looks and image sizes: what the depth agreement's std
#: (``depth_sigma_m``) was chosen on; the bench reports ``DISTRACTOR``
DISTRACTOR_CHECK = {
    "cross_same_look": _BASE + "seed=41,person2=cross,person2_look=2,presenter_look=2,"
                               "width=320,height=240",
    "beside_same_look": _BASE + "seed=42,person2=beside,person2_look=3,presenter_look=3,"
                                "presenter_mode=still",
    "behind_same_look": _BASE + "seed=43,person2=behind,person2_look=1,presenter_look=1",
    "behind_same_look_small": _BASE + "seed=44,person2=behind,person2_look=4,presenter_look=4,"
                                      "width=320,height=240",
}
N_FRAMES = {"desk": 240, "walk": 240, "distractor": 300}

#: held-out loss scenarios: seeds, presenters, lighting, places and image sizes that neither
#: the default selection (``check``) nor the development of the loss test looked at; the bench
#: reports them (``loss.heldout``) and nothing is chosen on them
_LEAVE = "presenter_mode=leave,presenter_out=-2.4,presenter_leave=30,presenter_return=150,"
DESK_HELDOUT = (
    _BASE + _LEAVE + "seed=61,presenter_look=0,lighting=cool,presenter_x=0.3",
    _BASE + _LEAVE + "seed=62,presenter_look=2,lighting=bright,presenter_x=0.5",
    _BASE + _LEAVE + "seed=63,presenter_look=4,lighting=warm,presenter_x=0.0,width=480,"
                     "height=360",
    _BASE + _LEAVE + "seed=64,presenter_look=5,lighting=dim,presenter_x=0.2",
    _BASE + _LEAVE + "seed=65,presenter_look=6,lighting=side,presenter_x=0.6,width=320,"
                     "height=240",
    _BASE + _LEAVE + "seed=66,presenter_look=1,presenter_x=-0.1",
    # added with the loss test's motion cue, run for the first time in the bench's report
    _BASE + _LEAVE + "seed=67,presenter_look=3,lighting=side,presenter_x=0.4",
    _BASE + _LEAVE + "seed=68,presenter_look=0,lighting=ramp,presenter_x=0.1,width=480,"
                     "height=360",
)
WALK_HELDOUT = (
    _BASE + "seed=71,presenter_look=0,lighting=side",
    _BASE + "seed=72,presenter_look=2,lighting=cool,width=480,height=360",
    _BASE + "seed=73,presenter_look=5,lighting=warm",
    _BASE + "seed=74,presenter_look=6,lighting=bright,width=320,height=240",
    # added with the loss test's motion cue, run for the first time in the bench's report
    _BASE + "seed=75,presenter_look=1,lighting=side,width=480,height=360",
    _BASE + "seed=76,presenter_look=3,lighting=dim",
    _BASE + "seed=77,presenter_look=4,lighting=ramp",
    _BASE + "seed=78,presenter_look=2,lighting=side,width=320,height=240",
)

_CACHE: dict[str, list[Frame]] = {}


def frames_of(spec: str) -> list[Frame]:
    """Frames of a ``synthetic:`` spec, rendered once per process."""
    if spec not in _CACHE:
        from engine.sources import open_source

        with open_source(spec) as src:
            _CACHE[spec] = list(src.frames())
    return _CACHE[spec]


def _truth(f: Frame) -> Any:
    from engine.studio.sim import StudioTruth

    return f.payload(StudioTruth)


def _pixels(f: Frame) -> float:
    """Visible presenter pixels (the studio's labels); without them 1 if a box, else 0."""
    t = _truth(f)
    if t is not None and t.presenter_pixels is not None:
        return float(t.presenter_pixels)
    return 0.0 if f.gt_box_xywh is None else 1.0


def _iou(a: Any, b: Any) -> float:
    from engine.evaluation.boxes import iou_xywh

    if a is None or b is None:
        return 0.0
    return float(iou_xywh(np.array(a, dtype=np.float64), np.array(b, dtype=np.float64))[0])


Runner = Callable[[list[Frame]], list[Any]]


def desk_loss(run: Runner, variant: str = "report") -> dict[str, Any]:
    from engine.trackers.base import TrackState

    spec = DESK[variant].format(n=N_FRAMES["desk"])
    frames = frames_of(spec)
    results = run(frames)
    pix = np.array([_pixels(f) for f in frames])
    full = float(pix[0]) if pix[0] > 0 else 1.0
    gone = pix < LEFT_FRACTION * full
    present = pix >= BACK_FRACTION * full
    leave = next((i for i, g in enumerate(gone) if g), None)
    back = next((i for i in range(leave or 0, len(present)) if present[i]), None) \
        if leave is not None else None
    out: dict[str, Any] = {"source": spec, "leave_frame": leave, "return_frame": back}
    if leave is None or back is None:
        out["error"] = "the scenario has no leave/return"
        return out
    # a LOST declared while the presenter is walking out (under half in view) counts as
    # detected at once
    out_from = next((i for i in range(leave, -1, -1) if present[i]), 0) + 1
    first_lost = next((i for i in range(out_from, back)
                       if results[i].state == TrackState.LOST), None)
    out["frames_to_detect"] = None if first_lost is None else max(first_lost - leave, 0)
    out["false_lock_frames"] = int(sum(
        1 for i in range(first_lost if first_lost is not None else leave, back)
        if results[i].state == TrackState.TRACKING and gone[i]))
    out["false_lock"] = out["false_lock_frames"] > 0
    re = next((i for i in range(back, len(frames))
               if results[i].state == TrackState.TRACKING
               and _iou(frames[i].gt_box_xywh, results[i].box_xywh) > 0.3), None)
    out["frames_to_reacquire"] = None if re is None else re - back
    return out


def walk_false_lost(run: Runner, variant: str = "report") -> dict[str, Any]:
    from engine.trackers.base import TrackState

    spec = WALK[variant].format(n=N_FRAMES["walk"])
    frames = frames_of(spec)
    results = run(frames)
    pix = np.array([_pixels(f) for f in frames])
    full = float(np.median(pix[pix > 0])) if np.any(pix > 0) else 1.0
    in_view = pix >= 0.5 * full
    lost = np.array([r.state == TrackState.LOST for r in results])
    return {"source": spec, "frames": len(frames), "frames_in_view": int(in_view.sum()),
            "false_lost_frames": int(np.sum(lost & in_view))}


def heldout_loss(run: Runner) -> dict[str, Any]:
    """The desk and walk scenarios over ``DESK_HELDOUT`` / ``WALK_HELDOUT``: per scenario
    frames to LOST / to re-acquire, frames TRACKING while the presenter is away, false LOST
    frames; and how many desks meet the goals."""
    desks, walks = [], []
    for k, spec in enumerate(DESK_HELDOUT):
        DESK[f"heldout{k}"] = spec
        d = desk_loss(run, f"heldout{k}")
        desks.append({key: d.get(key) for key in ("frames_to_detect", "frames_to_reacquire",
                                                   "false_lock_frames")})
    for k, spec in enumerate(WALK_HELDOUT):
        WALK[f"heldout{k}"] = spec
        walks.append(walk_false_lost(run, f"heldout{k}")["false_lost_frames"])
    # a scenario without leave/return (an error) counts as a false lock
    locks = [int(d["false_lock_frames"] if d["false_lock_frames"] is not None else 1)
             for d in desks]
    ok = [meets_loss_goals(d, {"false_lost_frames": 0}) and n == 0
          for d, n in zip(desks, locks, strict=True)]
    return {"desks": desks, "walk_false_lost_frames": walks,
            "desks_meeting_goals": int(sum(ok)), "n_desks": len(desks),
            "desks_tracking_on_empty_set": int(sum(n > 0 for n in locks)),
            "walks_without_false_lost": int(sum(w == 0 for w in walks)),
            "n_walks": len(walks)}


def meets_loss_goals(desk: dict[str, Any], walk: dict[str, Any]) -> bool:
    """The issue's loss goals: LOST within 5 frames, re-acquired within 15, no false LOST."""
    d, r = desk.get("frames_to_detect"), desk.get("frames_to_reacquire")
    return (d is not None and d <= DETECT_GOAL_FRAMES and r is not None
            and r <= REACQUIRE_GOAL_FRAMES and walk.get("false_lost_frames", 1) == 0)


def meets_check_goals(run: Runner, run_box: Runner) -> bool:
    """What the default selection asks of a candidate (``check`` scenarios only): on every
    check desk and every check walk, with the studio's part boxes as the model, the loss
    goals and no TRACKING on the empty desk; with the model split from the first box (what
    a bare box gives, e.g. "Split 3" on the page), no false LOST in the check walks and no
    TRACKING on the empty desks."""
    walks = [walk_false_lost(run, w) for w in CHECK_WALKS]
    for d in CHECK_DESKS:
        desk = desk_loss(run, d)
        if not all(meets_loss_goals(desk, w) for w in walks) \
                or desk.get("false_lock_frames", 1) != 0:
            return False
    if any(walk_false_lost(run_box, w)["false_lost_frames"] > 0 for w in CHECK_WALKS):
        return False
    return all(desk_loss(run_box, d).get("false_lock_frames", 1) == 0 for d in CHECK_DESKS)


def check_fingerprint() -> str:
    """sha1 of the frames of the scenarios ``meets_check_goals`` runs (rendered here)."""
    from engine.bench.presenter_loo import frames_fingerprint

    specs = [DESK[d].format(n=N_FRAMES["desk"]) for d in CHECK_DESKS] + [
        WALK[w].format(n=N_FRAMES["walk"]) for w in CHECK_WALKS]
    return frames_fingerprint([f for s in specs for f in frames_of(s)])


def distractor(run: Runner, case: str) -> dict[str, Any]:
    from engine.evaluation.boxes import box_scores
    from engine.trackers.base import TrackState

    spec = {**DISTRACTOR, **{f"check_{k}": v for k, v in DISTRACTOR_CHECK.items()}}[
        case].format(n=N_FRAMES["distractor"])
    frames = frames_of(spec)
    results = run(frames)
    stolen = 0
    near = 0
    for f, r in zip(frames, results, strict=True):
        t = _truth(f)
        other = None if t is None else t.person2_box_xywh
        if other is None:
            continue
        if _iou(f.gt_box_xywh, other) > 0.0 or _iou(r.box_xywh, other) > 0.0:
            near += 1
        if r.state != TrackState.TRACKING:
            continue
        o, t = _iou(r.box_xywh, other), _iou(r.box_xywh, f.gt_box_xywh)
        if o > 0.3 and t < 0.1:
            stolen += 1
    gt = np.array([f.gt_box_xywh if f.gt_box_xywh is not None else (np.nan,) * 4
                   for f in frames], dtype=np.float64)
    est = np.array([r.box_xywh if r.box_xywh is not None else (np.nan,) * 4 for r in results],
                   dtype=np.float64)
    s = box_scores(gt, est)
    last_on = _iou(frames[-1].gt_box_xywh, results[-1].box_xywh) > 0.3
    return {"source": spec, "stolen_frames": stolen, "frames_near": near,
            "success_auc": round(s.success_auc, 4), "ends_on_presenter": bool(last_on)}


TWO_VIEW = {
    "report": "synthetic:frames={n},presenter=1,path=static,views=2,seed=3",
    "rail": "synthetic:frames={n},presenter=1,path=rail,views=2,seed=5,presenter_look=1",
    # the second camera zooms (wide -> 1.3x -> wide); its floor calibration is the lens
    # camera model from marks taken at the wide end (issue 13)
    "zoom": "synthetic:frames={n},presenter=1,path=static,views=2,over_zoom=sweep,seed=3",
}


def two_view(run: Runner, variant: str = "report", n: int = 300) -> dict[str, Any]:
    """The presenter's floor distance d and floor position from the second view against the
    studio's truth, and the loss decided on both views.

    d alone hides errors along the circle around the robot (a presenter walking across the
    set keeps d nearly constant), so the floor position error is reported beside it.
    ``false_lost_frames``: LOST while the presenter is in view of both cameras (the paper's
    rule: a loss in either view is a loss), with the frames each view said LOST; of those,
    ``false_lost_frames_inside`` had the presenter's box wholly inside the frontal image and
    ``false_lost_frames_at_edge`` had it cut by the image border (the presenter partly out of
    the frame).
    """
    from engine.floor import OverheadView
    from engine.trackers.base import TrackState

    spec = TWO_VIEW[variant].format(n=n)
    frames = frames_of(spec)
    results = run(frames)
    errs, d_true, floor_errs, both = [], [], [], 0
    fixed_d, fixed_floor = [], []  # lens-model calibrations: the marks as a fixed homography
    false_lost = lost_front = lost_over = lost_edge = 0
    for f, r in zip(frames, results, strict=True):
        over = f.payload(OverheadView)
        det = r.details
        if r.state == TrackState.TRACKING:
            both += 1
        in_view = f.gt_box_xywh is not None and over is not None and over.box_xywh is not None
        if det is not None and in_view:
            false_lost += int(r.state == TrackState.LOST)
            if r.state == TrackState.LOST and f.gt_box_xywh is not None:
                bx, _, bw, _ = f.gt_box_xywh
                width = f.color_bgr.shape[1] if f.color_bgr is not None else None
                lost_edge += int(bx <= 1.0 or (width is not None and bx + bw >= width - 1.0))
            lost_front += int(getattr(det, "frontal_state", "TRACKING") != "TRACKING")
            # None: the second view's filter has not started (its box still on the border)
            lost_over += int(getattr(det, "overhead_state", None) not in (None, "TRACKING"))
        if over is None or over.floor_xy_m_true is None or det is None \
                or getattr(det, "d_m", None) is None or over.floor_calibration is None:
            continue
        rx, ry = over.floor_calibration.robot_floor_xy_m
        tx, ty = over.floor_xy_m_true
        dt = float(np.hypot(tx - rx, ty - ry))
        errs.append(abs(float(det.d_m) - dt))
        d_true.append(dt)
        fx, fy = det.floor_xy_m
        floor_errs.append(float(np.hypot(fx - tx, fy - ty)))
        if over.floor_calibration.has_lens_model and det.overhead_box_xywh is not None:
            hx, hy, _ = over.floor_calibration.without_lens().locate(det.overhead_box_xywh)
            fixed_floor.append(float(np.hypot(hx - tx, hy - ty)))
            fixed_d.append(abs(float(np.hypot(hx - rx, hy - ry)) - dt))
    out: dict[str, Any] = {"source": spec, "frames": len(frames), "frames_with_d": len(errs),
                           "frames_tracking_both_views": both,
                           "false_lost_frames": false_lost,
                           "false_lost_frames_inside": false_lost - lost_edge,
                           "false_lost_frames_at_edge": lost_edge,
                           "frontal_lost_frames": lost_front,
                           "overhead_lost_frames": lost_over}
    if errs:
        e = np.asarray(errs)
        out["d_err_m"] = {"median": round(float(np.median(e)), 4),
                          "p95": round(float(np.quantile(e, 0.95)), 4),
                          "max": round(float(e.max()), 4)}
        fe = np.asarray(floor_errs)
        out["floor_err_m"] = {"median": round(float(np.median(fe)), 4),
                              "p95": round(float(np.quantile(fe, 0.95)), 4),
                              "max": round(float(fe.max()), 4)}
        if fixed_d:
            # the same boxes through the homography of the marks (no lens): what zooming
            # does to a fixed floor calibration
            out["homography_only"] = {
                "d_err_m": _stats(fixed_d), "floor_err_m": _stats(fixed_floor)}
        out["d_true_m"] = {"median": round(float(np.median(d_true)), 3),
                           "min": round(float(np.min(d_true)), 3),
                           "max": round(float(np.max(d_true)), 3)}
    return out


def _stats(values: list[float]) -> dict[str, float]:
    v = np.asarray(values)
    return {"median": round(float(np.median(v)), 4), "p95": round(float(np.quantile(v, 0.95)), 4),
            "max": round(float(v.max()), 4)}


ROBOT = {
    "report": "robot-sim:frames={n},seed=3",
    "check": "robot-sim:frames={n},seed=8,presenter_look=2",
}


def robot_loop(make: Callable[[], Any], variant: str = "report", n: int = 300) -> dict[str, Any]:
    """Closed loop: the robot-mounted camera obeys the tracker; framing error in the TV
    picture (px from the framing target) and the camera's jerk."""
    from engine.loop import run_tracking
    from engine.presenter.robot_sim import RobotCameraTruth
    from engine.sources import open_source

    spec = ROBOT[variant].format(n=n)
    tracker = make()
    errs: list[float] = []
    pos: list[Any] = []
    in_picture = 0
    from engine.presenter.robot_sim import RobotSimSource

    with open_source(spec) as src:
        if not isinstance(src, RobotSimSource):
            raise TypeError(f"{spec}: not the robot-sim source")
        limits = src.rig.limits
        for rec in run_tracking(src, tracker):
            t = rec.frame.payload(RobotCameraTruth)
            if t is None:
                continue
            pos.append(np.asarray(t.T_world_tv)[:3, 3])
            W, H = t.tv_image_wh
            if t.presenter_tv_px is None:
                continue
            u, v = t.presenter_tv_px
            p = tracker.params
            errs.append(float(np.hypot(u - p.target_x_frac * W, v - p.target_y_frac * H)))
            in_picture += int(0 <= u < W and 0 <= v < H)
    dt = 1.0 / 30.0
    P = np.asarray(pos)
    acc = np.diff(P, n=2, axis=0) / dt**2
    jerk = np.linalg.norm(np.diff(P, n=3, axis=0) / dt**3, axis=1)
    e = np.asarray(errs)
    return {"source": spec, "frames": len(P),
            "framing_err_px": {"median": round(float(np.median(e)), 1),
                               "p95": round(float(np.quantile(e, 0.95)), 1)},
            "presenter_in_tv_picture": round(in_picture / max(len(e), 1), 4),
            "jerk_m_s3": {"rms": round(float(np.sqrt(np.mean(jerk ** 2))), 3),
                          "p95": round(float(np.quantile(jerk, 0.95)), 3)},
            "max_accel_m_s2": round(float(np.max(np.linalg.norm(acc, axis=1))), 3),
            # the arm's limits hold per Cartesian axis (engine.studio.robot.RobotLimits)
            "max_axis_accel_m_s2": round(float(np.max(np.abs(acc))), 3),
            "max_axis_speed_m_s": round(float(np.max(np.abs(np.diff(P, axis=0)))) / dt, 3),
            "limits": {"max_speed_m_s": limits.max_speed_m_s,
                       "max_accel_m_s2": limits.max_accel_m_s2},
            "travel_m": round(float(np.sum(np.linalg.norm(np.diff(P, axis=0), axis=1))), 3)}
