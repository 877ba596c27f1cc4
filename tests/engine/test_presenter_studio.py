"""The built-in studio around the presenter: other people and light, a second camera, a robot
camera that obeys the tracker (small images, few frames)."""

from __future__ import annotations

import numpy as np
import pytest

from engine.errors import SourceError
from engine.floor import OverheadView
from engine.geometry import make_T
from engine.loop import run_tracking
from engine.presenter.control import ControlCommand, RobotCameraCommand
from engine.presenter.params import PresenterParams
from engine.presenter.robot_sim import RobotCameraTruth, RobotSimSink
from engine.results import TrackResult, TrackState
from engine.sources import open_source
from engine.studio.robot import RobotLimits, RobotRig
from engine.studio.scene import LABEL_PERSON2
from engine.studio.sim import StudioLabels, StudioTruth
from engine.trackers import create_tracker

SMALL = "width=160,height=120"


def test_a_second_person_has_its_own_label_and_box() -> None:
    src = open_source(f"synthetic:frames=40,{SMALL},presenter=1,path=static,person2=cross,"
                      "person2_look=0")
    seen = False
    for i in (0, 10, 20, 30):
        f = src.frame(i)
        t = f.payload(StudioTruth)
        labels = f.payload(StudioLabels).labels
        assert t.person2_pixels == int(np.sum(labels == LABEL_PERSON2))
        if t.person2_pixels:
            seen = True
            x, y, _, _ = t.person2_box_xywh
            ys, xs = np.nonzero(labels == LABEL_PERSON2)
            assert (xs.min(), ys.min()) == (x, y)
    assert seen


def test_looks_and_lighting_change_the_picture_not_the_geometry() -> None:
    base = open_source(f"synthetic:frames=3,{SMALL},presenter=1,path=static").frame(1)
    other = open_source(f"synthetic:frames=3,{SMALL},presenter=1,path=static,"
                        "presenter_look=1,lighting=warm").frame(1)
    assert base.payload(StudioTruth).presenter_pos_world == \
        other.payload(StudioTruth).presenter_pos_world
    lab = base.payload(StudioLabels).labels
    torso = lab == 2
    b0 = base.color_bgr[torso].mean(axis=0)
    b1 = other.color_bgr[other.payload(StudioLabels).labels == 2].mean(axis=0)
    assert b0[0] > b0[2]  # blue shirt
    assert b1[2] > b1[0]  # red top
    # warm light: red gain up, blue down on the unchanged set
    set_px = (lab == 0) & (other.payload(StudioLabels).labels == 0)
    ratio = other.color_bgr[set_px].mean(axis=0) / np.maximum(base.color_bgr[set_px].mean(0), 1)
    assert ratio[2] > 1.05 > 0.95 > ratio[0]


@pytest.mark.parametrize(("spec", "match"), [
    ("synthetic:person2=cross", "needs presenter=1"),
    ("synthetic:presenter=1,person2_look=2", "needs person2="),
    ("synthetic:presenter=1,lighting=disco", "lighting"),
    ("synthetic:views=3", "views"),
    ("robot-sim:path=rail", "leave out path"),
])
def test_bad_studio_options_are_one_line_errors(spec: str, match: str) -> None:
    with pytest.raises(SourceError, match=match):
        open_source(spec)


def test_second_view_comes_with_an_exact_floor_calibration() -> None:
    src = open_source(f"synthetic:frames=3,{SMALL},presenter=1,path=static,views=2")
    f = src.frame(0)
    over = f.payload(OverheadView)
    assert over is not None
    assert over.color_bgr.shape == (120, 160, 3)
    assert over.box_xywh is not None
    X, Y, h = over.floor_calibration.locate(over.box_xywh)
    tx, ty = over.floor_xy_m_true
    assert np.hypot(X - tx, Y - ty) < 0.25  # at 160x120: a few pixels
    assert 1.5 < h < 2.1


def test_the_tracker_measures_d_from_the_second_view() -> None:
    src = open_source("synthetic:frames=24,width=320,height=240,presenter=1,path=static,"
                      "views=2,seed=3")
    tracker = create_tracker("presenter")
    errs = []
    for f in src.frames():
        r = tracker.track(f)
        over = f.payload(OverheadView)
        d = r.details
        assert d.overhead_state is not None
        if d.d_m is not None:
            rx, ry = over.floor_calibration.robot_floor_xy_m
            tx, ty = over.floor_xy_m_true
            errs.append(abs(d.d_m - np.hypot(tx - rx, ty - ry)))
    assert len(errs) >= 20
    assert float(np.median(errs)) < 0.1


def test_second_view_model_comes_from_its_own_patches_and_follows_the_walk() -> None:
    """The second view's first frame carries the presenter's patches (the studio's labels
    standing in for the operator's); with a model split from the box instead, the second
    filter settled on the blue desk behind the blue shirt and the floor position was 2 m off
    while d (nearly constant across the set) still looked right."""
    src = open_source("synthetic:frames=70,width=320,height=240,presenter=1,path=static,"
                      "views=2,seed=3")
    frames = list(src.frames())
    first = frames[0].payload(OverheadView)
    assert first is not None
    assert {name for name, _ in first.part_boxes} == {"head", "torso", "legs"}
    # every frame's (the filter starts on the first box wholly inside the image)
    assert {name for name, _ in frames[1].payload(OverheadView).part_boxes} == {
        "head", "torso", "legs"}
    tracker = create_tracker("presenter")
    errs = []
    for f in frames:
        d = tracker.track(f).details
        over = f.payload(OverheadView)
        if d.floor_xy_m is not None:
            errs.append(np.hypot(d.floor_xy_m[0] - over.floor_xy_m_true[0],
                                 d.floor_xy_m[1] - over.floor_xy_m_true[1]))
    # measured: 67 frames, median 0.063 m; with the box split 50 frames (the rest LOST),
    # median 0.22 m
    assert len(errs) >= 60
    assert float(np.median(errs)) < 0.12


def test_robot_rig_obeys_its_speed_and_acceleration_limits() -> None:
    rig = RobotRig(make_T(np.eye(3), (0.0, 0.0, 1.5)),
                   RobotLimits(max_speed_m_s=1.0, max_accel_m_s2=2.0))
    rig.command_velocity(np.array([5.0, 0.0, 0.0]))
    v = []
    for _ in range(60):
        rig.advance(1 / 30)
        v.append(rig.v_world[0])
    acc = np.diff(v) * 30
    assert max(v) == pytest.approx(1.0)
    assert acc.max() <= 2.0 + 1e-9
    rig.command_velocity(np.array([np.nan, 0, 0]))  # ignored
    rig.advance(1 / 30)
    assert rig.v_world[0] == pytest.approx(1.0)
    for _ in range(300):  # the working box stops the axis
        rig.advance(1 / 30)
    assert rig.p_world[0] == pytest.approx(rig.limits.box_max_m[0])
    assert rig.v_world[0] == 0.0


def test_robot_sim_sink_turns_image_velocity_into_camera_motion() -> None:
    rig = RobotRig(make_T(np.eye(3), (0.0, 0.0, 1.5)))
    sink = RobotSimSink(rig, f_px=300.0, depth_m=3.0)
    msg = ControlCommand(seq=1, t_s=0.0, state="TRACKING", x_px=0, y_px=0, d_m=None,
                         target_x_px=0, target_y_px=0, target_d_m=3.0, e_f_px=(0.0, 0.0),
                         e_d_m=None, v_x_px_s=100.0, v_y_px_s=0.0, v_d_m_s=0.3)

    class Rec:
        result = TrackResult(state=TrackState.TRACKING, commands=(RobotCameraCommand(msg),))

    sink.on_record(Rec())  # type: ignore[arg-type]
    for _ in range(30):  # 1 s: long enough to reach the commanded speed
        rig.advance(1 / 30)
    assert rig.v_world[0] == pytest.approx(1.0)  # 100 px/s x 3 m / 300 px
    assert rig.zoom > 1.0  # the presenter is farther than d*: zoom in


def test_closed_loop_keeps_a_walking_presenter_framed() -> None:
    spec = "robot-sim:frames=60,width=320,height=240,seed=3"
    errs = {}
    for name, params in (("closed", PresenterParams()),
                         ("still", PresenterParams(control_gain=0.0, control_ki=0.0))):
        src = open_source(spec)
        tracker = create_tracker("presenter", params)
        e = []
        for rec in run_tracking(src, tracker):
            t = rec.frame.payload(RobotCameraTruth)
            if t.presenter_tv_px is not None:
                W, H = t.tv_image_wh
                e.append(np.hypot(t.presenter_tv_px[0] - W / 2, t.presenter_tv_px[1] - H / 2))
        errs[name] = float(np.mean(e[-20:]))
    assert errs["closed"] < 0.5 * errs["still"]


def test_second_view_starts_on_a_whole_person_and_takes_its_scale_from_the_floor() -> None:
    """The rail walk starts with the presenter cut by the second view's left edge: its filter
    waits for a box wholly inside the image (a model of half a person tracks a point beside
    them); then each box's height is the standing person's at its centre (floor_scale)
    instead of a random walk, and the patches lean with the position (floor_lean)."""
    from engine.presenter.twoview import standing_height_m

    src = open_source("synthetic:frames=14,width=320,height=240,presenter=1,path=rail,"
                      "views=2,seed=5,presenter_look=1")
    frames = list(src.frames())
    first = frames[0].payload(OverheadView)
    assert first is not None
    assert first.box_xywh is not None
    assert first.box_xywh[0] < 1.0  # on the border
    tracker = create_tracker("presenter")
    states = []
    for f in frames:
        d = tracker.track(f).details
        states.append(d.overhead_state)
        over = f.payload(OverheadView)
        if d.overhead_box_xywh is not None:
            x, y, w, h = d.overhead_box_xywh
            calib = over.floor_calibration
            person = tracker._over_person
            assert person is not None
            want = calib.standing_box_px(np.array([x + w / 2]), np.array([y + h / 2]),
                                         person.height_m)[0][0]
            assert h == pytest.approx(want, rel=0.01)  # the mean of standing heights
    started = states.index("TRACKING")
    assert started > 0
    assert all(s is None for s in states[:started])
    start_box = frames[started].payload(OverheadView).box_xywh
    assert start_box[0] >= 1.0
    assert tracker._over_person.height_m == pytest.approx(
        standing_height_m(frames[started].payload(OverheadView).floor_calibration, start_box))
    rel = tracker._overhead.model.rel_boxes
    assert not np.allclose(rel, tracker._over_person.rel_first)  # moved with the lean
