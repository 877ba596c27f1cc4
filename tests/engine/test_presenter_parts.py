"""Particle filter, jitter filter, model validation, two-view distance and control (no Qt)."""

from __future__ import annotations

import json
import socket

import numpy as np
import pytest

from engine.errors import CalibrationError
from engine.presenter import PresenterError
from engine.presenter import filter as pf
from engine.presenter.control import (
    MESSAGE_TYPE,
    ControlLimits,
    ControlLoop,
    UdpControlSender,
    depth_error,
    image_error,
)
from engine.presenter.jitter import JitterFilter, noise_gain, ramp_lag_frames
from engine.presenter.model import (
    PatchSpec,
    auto_patches,
    build_model,
    load_model,
    model_from_box,
    save_model,
    validate_selection,
)
from engine.presenter.scene import presenter_frames
from engine.presenter.twoview import calibrate_floor, fuse


def test_weighted_mean_and_prediction() -> None:
    parts = np.array([[0.0, 0.0, 10.0], [10.0, 20.0, 30.0]])
    assert pf.weighted_mean(parts, np.array([0.25, 0.75])) == pytest.approx([7.5, 15.0, 25.0])
    out = pf.predict(np.zeros((5000, 3)) + 100, (2.0, 3.0, 0.0), np.random.default_rng(1),
                     (50.0, 200.0))
    assert out[:, :2].std(axis=0) == pytest.approx([2.0, 3.0], rel=0.05)
    assert np.all(out[:, 2] == 100.0)
    assert pf.normalise(np.zeros(4)) == pytest.approx([0.25] * 4)


def test_jitter_filter_lag_matches_its_formula_and_smooths_noise() -> None:
    fps, fc = 30.0, 1.0
    f = JitterFilter(fc, fps)
    v = 4.0  # px per frame
    out = [f(np.array([v * k])) for k in range(400)]
    lag_px = v * 399 - out[-1][0]
    assert lag_px / v == pytest.approx(ramp_lag_frames(fc, fps), rel=1e-3)
    rng = np.random.default_rng(0)
    g = JitterFilter(fc, fps)
    noisy = rng.normal(size=20000)
    smooth = np.array([g(np.array([x]))[0] for x in noisy])[200:]
    assert smooth.var() == pytest.approx(noise_gain(fc, fps), rel=0.1)
    off = JitterFilter(0.0, fps)
    assert off(np.array([3.0]))[0] == 3.0
    assert off(np.array([5.0]))[0] == 5.0


def _ref_image() -> np.ndarray:
    return next(iter(presenter_frames(1, 160, 120))).bgr


def test_degenerate_selections_get_clear_messages() -> None:
    img = _ref_image()
    main = (40.0, 20.0, 40.0, 80.0)
    two = [PatchSpec("a", (40, 20, 40, 30)), PatchSpec("b", (40, 50, 40, 40))]
    with pytest.raises(PresenterError, match="zero-area"):
        validate_selection(img.shape, (10, 10, 0, 30), two)
    with pytest.raises(PresenterError, match="at least two patches"):
        validate_selection(img.shape, main, two[:1])
    with pytest.raises(PresenterError, match="not inside the main region"):
        validate_selection(img.shape, main, [two[0], PatchSpec("c", (0, 0, 20, 20))])
    with pytest.raises(PresenterError, match="unique"):
        validate_selection(img.shape, main, [two[0], PatchSpec("a", (40, 60, 10, 10))])
    grey = np.full_like(img, 128)
    with pytest.raises(PresenterError, match="grey"):
        build_model(grey, main, two, allow_grey=False)
    model = build_model(grey, main, two, allow_grey=True)
    assert any("grey" in w for w in model.warnings)


def test_model_save_load_round_trip(tmp_path) -> None:  # type: ignore[no-untyped-def]
    frame = next(iter(presenter_frames(1, 160, 120)))
    model = model_from_box(frame.bgr, frame.box_xywh)
    assert model.names == ("head", "torso", "legs")
    save_model(tmp_path / "m", model, frame.bgr)
    doc = json.loads((tmp_path / "m" / "model.json").read_text())
    assert doc["version"] == 1
    assert len(doc["patches"]) == 3
    again, img = load_model(tmp_path / "m")
    np.testing.assert_allclose(again.hists, model.hists)
    assert img.shape == frame.bgr.shape
    with pytest.raises(PresenterError, match="no such presenter model"):
        load_model(tmp_path / "missing")
    assert len(auto_patches((0, 0, 10, 40), 2)) == 2


def test_floor_homography_gives_distance() -> None:
    img = [(100, 400), (540, 400), (500, 100), (140, 100)]
    floor = [(-1.0, 1.0), (1.0, 1.0), (1.0, 5.0), (-1.0, 5.0)]
    calib = calibrate_floor(img, floor, robot_floor_xy_m=(0.0, 0.0))
    for (u, v), (x, y) in zip(img, floor, strict=True):
        assert calib.floor_point(u, v) == pytest.approx((x, y), abs=1e-6)
    assert calib.distance_m(100, 400) == pytest.approx(np.hypot(1.0, 1.0))
    assert fuse(10.0, 20.0, (540, 400), calib) == pytest.approx((10.0, 20.0, np.hypot(1, 1)))
    assert fuse(10.0, 20.0, None, calib)[2] is None
    with pytest.raises(CalibrationError, match="collinear"):
        calibrate_floor([(0, 0), (1, 1), (2, 2), (0, 5)], floor)


def test_control_errors_and_limits() -> None:
    assert image_error(330, 200, 320, 240) == (10, -40)
    assert depth_error(3.5, 3.0) == pytest.approx(0.5)
    loop = ControlLoop()
    lim = ControlLimits(gain=2.0, max_speed_px_s=100.0, max_accel_px_s2=300.0)
    cmd = loop.update(t_s=0.0, state="TRACKING", x_px=420, y_px=240, d_m=4.0,
                      target_xy_px=(320, 240), target_d_m=3.0, limits=lim)
    assert cmd.e_f_px == (100, 0)
    assert cmd.e_d_m == pytest.approx(1.0)
    assert cmd.v_x_px_s == pytest.approx(300.0 / 30.0)  # acceleration limited
    for k in range(1, 60):
        cmd = loop.update(t_s=k / 30.0, state="TRACKING", x_px=420, y_px=240, d_m=4.0,
                          target_xy_px=(320, 240), target_d_m=3.0, limits=lim)
    assert cmd.v_x_px_s == pytest.approx(100.0)  # speed limited
    cmd = loop.update(t_s=2.0, state="LOST", x_px=420, y_px=240, d_m=4.0,
                      target_xy_px=(320, 240), target_d_m=3.0, limits=lim)
    assert 0 < cmd.v_x_px_s < 100.0  # braking within the acceleration limit


def test_udp_control_message_is_received_by_a_test_socket() -> None:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(5.0)
    port = rx.getsockname()[1]
    try:
        sender = UdpControlSender("127.0.0.1", port)
        cmd = ControlLoop().update(t_s=1.5, state="TRACKING", x_px=300.0, y_px=250.0,
                                   d_m=None, target_xy_px=(320.0, 240.0), target_d_m=3.0,
                                   limits=ControlLimits())
        assert sender.send(cmd)
        data, _ = rx.recvfrom(65536)
        sender.close()
    finally:
        rx.close()
    msg = json.loads(data.decode("utf-8"))
    assert msg["type"] == MESSAGE_TYPE
    assert msg["version"] == 1
    assert msg["e_f_px"] == [-20.0, 10.0]
    assert msg["d_m"] is None
    assert msg["e_d_m"] is None
    assert msg["target"] == {"x_px": 320.0, "y_px": 240.0, "d_m": 3.0}
    assert set(msg["v_cmd"]) == {"x_px_s", "y_px_s", "d_m_s"}
