"""The bench's studio scenarios measure what they claim (tiny versions of them)."""

from __future__ import annotations

from typing import Any

import pytest

from engine.bench import presenter_scenarios as sc
from engine.frames import Frame
from engine.trackers import create_tracker

TINY = "synthetic:frames={n},presenter=1,path=static,width=160,height=120,"


def _run(frames: list[Frame]) -> list[Any]:
    t = create_tracker("presenter")
    return [t.track(f) for f in frames]


def test_desk_walk_two_view_and_robot_report_their_keys(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sc.DESK, "tiny", TINY + "presenter_mode=leave,presenter_x=0.4,"
                        "presenter_out=-2.4,presenter_leave=5,presenter_return=110")
    monkeypatch.setitem(sc.WALK, "tiny", TINY + "seed=2")
    monkeypatch.setitem(sc.TWO_VIEW, "tiny", TINY + "views=2")
    monkeypatch.setitem(sc.ROBOT, "tiny", "robot-sim:frames={n},width=160,height=120")
    monkeypatch.setitem(sc.N_FRAMES, "desk", 170)
    monkeypatch.setitem(sc.N_FRAMES, "walk", 30)
    desk = sc.desk_loss(_run, "tiny")
    assert desk["leave_frame"] is not None
    assert desk["return_frame"] > desk["leave_frame"]
    assert desk["frames_to_detect"] is not None
    assert desk["frames_to_detect"] <= sc.DETECT_GOAL_FRAMES
    walk = sc.walk_false_lost(_run, "tiny")
    assert walk["frames_in_view"] == 30
    assert walk["false_lost_frames"] == 0
    tv = sc.two_view(_run, "tiny", n=12)
    assert tv["frames_with_d"] > 0
    assert set(tv["d_err_m"]) == {"median", "p95", "max"}
    rb = sc.robot_loop(lambda: create_tracker("presenter"), "tiny", n=20)
    assert set(rb["framing_err_px"]) == {"median", "p95"}
    assert rb["frames"] == 20
    assert sc.meets_loss_goals(desk, walk) == (desk["frames_to_reacquire"] is not None
                                               and desk["frames_to_reacquire"] <= 15)


#: a presenter in white beside the desk in bright light, 320x240: with the loss test against
#: the adapted model and the set's colours counted, a box-split model sits on the empty set
#: claiming TRACKING for ~75 frames
EMPTY_SET_TRAP = ("synthetic:frames={n},presenter=1,path=static,seed=45,presenter_look=5,"
                  "lighting=bright,presenter_mode=leave,presenter_x=0.5,presenter_out=-2.4,"
                  "presenter_leave=30,presenter_return=150,width=320,height=240")


def test_box_split_model_never_claims_tracking_on_the_empty_set(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from engine.presenter.params import PresenterParams

    monkeypatch.setitem(sc.DESK, "trap", EMPTY_SET_TRAP)
    monkeypatch.setitem(sc.N_FRAMES, "desk", 200)

    def runner(**changes: Any) -> Any:
        def run(frames: list[Frame]) -> list[Any]:
            p = PresenterParams(use_part_boxes=False, **changes)
            t = create_tracker("presenter", p)
            return [t.track(f) for f in frames]
        return run

    desk = sc.desk_loss(runner(), "trap")
    assert desk["frames_to_detect"] is not None
    assert desk["frames_to_detect"] <= sc.DETECT_GOAL_FRAMES
    assert desk["false_lock_frames"] == 0
    # the trap is real: the former loss reference (the adapted model, the set's colours
    # counted) is fooled by it
    old = sc.desk_loss(runner(loss_reference="anchored", loss_bg_weighting=0.0), "trap")
    assert old["false_lock_frames"] > 10


def test_motion_cue_keeps_a_box_split_model_through_a_side_lit_walk(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Walking across a side key, a box-split model's colours leave the first frame's: the
    colour test alone calls the walking presenter LOST; the motion cue does not."""
    from engine.presenter.params import PresenterParams

    monkeypatch.setitem(sc.N_FRAMES, "walk", 160)

    def runner(**changes: Any) -> Any:
        def run(frames: list[Frame]) -> list[Any]:
            t = create_tracker("presenter", PresenterParams(use_part_boxes=False, **changes))
            return [t.track(f) for f in frames]
        return run

    # at loss_contrast 0.5 the colour test alone breaks in this walk
    off = runner(loss_motion=0.0, loss_contrast=0.5)
    on = runner(loss_motion=0.1, loss_contrast=0.5)
    assert sc.walk_false_lost(off, "check_light")["false_lost_frames"] > 10
    assert sc.walk_false_lost(on, "check_light")["false_lost_frames"] == 0


def test_check_scenarios_are_apart_from_the_held_out_ones_and_include_a_light_ramp() -> None:
    import re

    def seed(spec: str) -> int:
        m = re.search(r"seed=(\d+)", spec)
        assert m is not None, spec
        return int(m.group(1))

    checks = [sc.DESK[d] for d in sc.CHECK_DESKS] + [sc.WALK[w] for w in sc.CHECK_WALKS]
    held = list(sc.DESK_HELDOUT) + list(sc.WALK_HELDOUT) + [sc.DESK["report"], sc.WALK["report"]]
    assert not {seed(s) for s in checks} & {seed(s) for s in held}
    # the defaults are chosen on a desk whose light comes up while the set is empty
    assert any("lighting=ramp" in sc.DESK[d] and "presenter_mode=leave" in sc.DESK[d]
               for d in sc.CHECK_DESKS)


def test_distractor_reports_the_defaults_stolen_frames_over_seeds(
        monkeypatch: pytest.MonkeyPatch) -> None:
    import argparse

    from engine.bench import presenter as bp

    monkeypatch.setattr(sc, "DISTRACTOR", {"tiny": TINY + "seed=6,person2=behind,person2_look=0"})
    monkeypatch.setitem(sc.N_FRAMES, "distractor", 8)
    out = bp._distractor(argparse.Namespace(particles=30))
    over = out["tiny"]["presenter"]["stolen_frames_over_seeds"]
    assert over["seeds"] == list(bp.DISTRACTOR_SEEDS)
    assert len(over["stolen_frames"]) == len(bp.DISTRACTOR_SEEDS)
    assert over["stolen_frames"][0] == out["tiny"]["presenter"]["stolen_frames"]
    assert over["max"] == max(over["stolen_frames"])
    assert "stolen_frames_over_seeds" not in out["tiny"]["paper"]


def test_exposure_normalisation_holds_a_walk_while_the_lights_come_up(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Lights coming up during a walk (``lighting=ramp``: exposure 0.4 -> 1.1): without
    exposure normalisation the darker reference's colours no longer match and the presenter
    is declared LOST while in view; with it, not (a development case, seed 29, not one the
    bench reports)."""
    monkeypatch.setitem(sc.WALK, "ramp_dev", sc._BASE + "seed=29,presenter_look=2,"
                        "lighting=ramp,width=320,height=240")

    def runner(on: bool) -> Any:
        def run(frames: list[Frame]) -> list[Any]:
            from engine.bench.presenter import presenter_params

            t = create_tracker("presenter", presenter_params(exposure_normalise=on))
            return [t.track(f) for f in frames]
        return run

    assert sc.walk_false_lost(runner(False), "ramp_dev")["false_lost_frames"] > 30
    assert sc.walk_false_lost(runner(True), "ramp_dev")["false_lost_frames"] == 0


def test_two_view_tells_losses_at_the_image_edge_from_losses_inside(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Every frame said LOST: those with the presenter's box on the frontal image's border
    are counted apart from those with the box wholly inside."""
    import dataclasses

    from engine.trackers.base import TrackState

    # the presenter walks from the middle of a 160-px-wide frame out past its left border
    monkeypatch.setitem(sc.TWO_VIEW, "edge", TINY + "views=2,presenter_mode=leave,"
                        "presenter_x=0.0,presenter_out=-2.4,presenter_leave=0,"
                        "presenter_return=1000")

    def always_lost(frames: list[Frame]) -> list[Any]:
        return [dataclasses.replace(r, state=TrackState.LOST) for r in _run(frames)]

    tv = sc.two_view(always_lost, "edge", n=40)
    frames = sc.frames_of(sc.TWO_VIEW["edge"].format(n=40))
    boxes = [f.gt_box_xywh for f in frames if f.gt_box_xywh is not None]
    edge = [b for b in boxes if b[0] <= 1.0 or b[0] + b[2] >= 159.0]
    assert 0 < len(edge) < len(boxes)  # the walk both starts inside and reaches the edge
    assert tv["false_lost_frames_at_edge"] > 0
    assert tv["false_lost_frames_inside"] > 0
    assert tv["false_lost_frames_inside"] + tv["false_lost_frames_at_edge"] == \
        tv["false_lost_frames"]
