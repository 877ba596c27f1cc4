"""The contrast loss test, the ring (scale) term, the paper preset, the PI control loop."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from engine.frames import Frame
from engine.presenter.control import ControlLimits, ControlLoop
from engine.presenter.likelihood import binned_integral, ring_similarity
from engine.presenter.params import PresenterParams
from engine.presenter.scene import presenter_frames
from engine.trackers import create_tracker
from engine.trackers.base import TrackState


def _frames(n: int, **kw: object) -> list[Frame]:
    return [Frame(index=f.index, timestamp_s=f.index / 30.0, color_bgr=f.bgr,
                  gt_box_xywh=f.box_xywh)
            for f in presenter_frames(n, 320, 240, **kw)]  # type: ignore[arg-type]


def test_ring_term_prefers_the_box_that_encloses_the_target() -> None:
    img = np.full((120, 160, 3), (40, 160, 60), np.uint8)  # green set
    cv2.rectangle(img, (60, 30), (99, 89), (40, 40, 200), -1)  # red target 40x60
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    ih = binned_integral(hsv, 10, 1)
    red = np.asarray(binned_integral(hsv[40:50, 70:80], 10, 1)[-1, -1], dtype=np.float64)
    red /= red.sum()
    aspect = 40 / 60
    states = np.array([[80.0, 60.0, 60.0], [80.0, 60.0, 30.0]])  # right size, half size
    bc = ring_similarity(ih, 1, (0, 0, 160, 120), (160, 120), states, aspect, 0.25,
                         np.sqrt(red))
    assert bc[0] < 0.2
    assert bc[1] > 0.8  # a box inside the target has the target all around it


def test_contrast_loss_catches_the_presenter_leaving_and_reacquires() -> None:
    leave, back = 30, 60
    frames = _frames(95, speed_px=1.0, leave=(leave, back))
    tracker = create_tracker("presenter")
    res = [tracker.track(f) for f in frames]
    assert all(r.state == TrackState.TRACKING for r in res[:leave])
    z_on = [r.details.loss_z for r in res[12:leave]]
    assert max(z_on) < PresenterParams().loss_contrast
    lost_at = next(i for i in range(leave, back) if res[i].state == TrackState.LOST)
    assert lost_at - leave <= 5
    assert res[lost_at].details.loss_z > PresenterParams().loss_contrast
    assert "contrast" in res[lost_at].message
    found = next(i for i in range(back, len(frames)) if res[i].state == TrackState.TRACKING)
    assert found - back <= 15


def test_paper_preset_runs_the_published_filter() -> None:
    p = PresenterParams().with_preset("paper")
    assert p.loss_test == "likelihood"
    assert p.loss_percent == 10.0
    assert p.velocity_gain == 0.0
    assert p.model_update_rate == 0.0
    assert p.ring_weight == 0.0
    assert p.sigma_h_frac > 0  # random walk in x, y and h (eq. 1)
    assert p.matching_presets() == ("paper",)
    frames = _frames(20)
    tracker = create_tracker("presenter", p)
    res = [tracker.track(f) for f in frames]
    for r in res:  # Pmin = 10 % of Pref (the Pref it was tested against)
        assert r.details.p_min == pytest.approx(0.1 * r.details.p_ref, rel=0.02)


def test_scale_is_estimated_by_default() -> None:
    assert PresenterParams().sigma_h_frac > 0
    frames = _frames(30)
    tracker = create_tracker("presenter")
    hs = [tracker.track(f).details.raw_xyh[2] for f in frames]
    assert len(set(np.round(hs, 3))) > 1  # h moves
    gt_h = frames[0].gt_box_xywh[3]  # type: ignore[index]
    assert abs(np.median(hs) - gt_h) < 0.15 * gt_h


def test_pi_control_removes_the_lag_behind_a_constant_walk() -> None:
    for ki, max_lag in ((0.0, None), (2.0, 2.0)):
        loop = ControlLoop()
        lim = ControlLimits(gain=3.0, ki=ki, max_speed_px_s=1000.0, max_accel_px_s2=5000.0)
        cam = 0.0
        errs = []
        for k in range(600):  # target moving 60 px/s; the camera integrates the command
            t = k / 30.0
            x = 60.0 * t - cam
            cmd = loop.update(t_s=t, state="TRACKING", x_px=320 + x, y_px=240, d_m=None,
                              target_xy_px=(320, 240), target_d_m=3.0, limits=lim)
            cam += cmd.v_x_px_s / 30.0
            errs.append(cmd.e_f_px[0])
        if max_lag is None:
            assert errs[-1] == pytest.approx(60.0 / 3.0, rel=0.1)  # P: lag v / gain
        else:
            assert abs(errs[-1]) < max_lag
    # LOST clears the integral: the command brakes to zero
    cmd = loop.update(t_s=30.0, state="LOST", x_px=400, y_px=240, d_m=None,
                      target_xy_px=(320, 240), target_d_m=3.0, limits=lim)
    assert abs(cmd.v_x_px_s) < abs(lim.max_speed_px_s)
    for k in range(60):
        cmd = loop.update(t_s=30.0 + k / 30.0, state="LOST", x_px=400, y_px=240, d_m=None,
                          target_xy_px=(320, 240), target_d_m=3.0, limits=lim)
    assert cmd.v_x_px_s == 0.0
