"""Delay compensation, hold-while-LOST, and the sender's never-block / never-raise rules."""

from __future__ import annotations

import time

import numpy as np
import pytest

from engine.errors import ParamsError
from engine.outputs.sender import OutputConfig, OutputSample, OutputSet, TargetSpec
from engine.outputs.studio_frame import StudioPose
from engine.outputs.timing import DelayCompensator, DelayParams


def _pose(t: float) -> StudioPose:
    # x moves 1 m/s, pan 90 deg/s: easy to check interpolation.
    return StudioPose(t, 0.0, 1.5, 90.0 * t, 0.0, 0.0)


def test_zero_delay_passes_pose_through():
    c = DelayCompensator()
    out = c.update(0.0, _pose(0.0), True)
    assert out is not None
    assert out.pose == _pose(0.0)
    assert not out.held


def test_positive_delay_interpolates_between_frames():
    c = DelayCompensator(DelayParams(x_ms=10.0, pan_ms=20.0))
    for i in range(5):
        out = c.update(i / 25.0, _pose(i / 25.0), True)
    t = 4 / 25.0
    assert out.pose.x_m == pytest.approx(t - 0.010)
    assert out.pose.pan_deg == pytest.approx(90.0 * (t - 0.020))
    assert out.pose.y_m == 0.0
    assert out.pose.z_m == 1.5


def test_negative_delay_extrapolates_but_is_clamped():
    c = DelayCompensator(DelayParams(x_ms=-20.0, max_extrapolation_ms=50.0))
    for i in range(3):
        out = c.update(i / 25.0, _pose(i / 25.0), True)
    assert out.pose.x_m == pytest.approx(2 / 25.0 + 0.020)
    c.set_params(DelayParams(x_ms=-200.0, max_extrapolation_ms=50.0))
    out = c.update(3 / 25.0, _pose(3 / 25.0), True)
    assert out.pose.x_m == pytest.approx(3 / 25.0 + 0.050)


def test_lost_holds_last_good_pose_without_drift():
    c = DelayCompensator(DelayParams(x_ms=-30.0))
    for i in range(4):
        c.update(i / 25.0, _pose(i / 25.0), True)
    held = [c.update(i / 25.0, _pose(99.0), False) for i in range(4, 30)]
    assert all(h.held for h in held)
    assert all(h.pose == _pose(3 / 25.0) for h in held)


def test_pan_crossing_180_interpolates_the_short_way():
    c = DelayCompensator(DelayParams(pan_ms=20.0))
    c.update(0.00, StudioPose(0, 0, 0, 179.0, 0, 0), True)
    out = c.update(0.04, StudioPose(0, 0, 0, -179.0, 0, 0), True)
    assert abs(out.pose.pan_deg) == pytest.approx(180.0)


def test_delay_params_validate():
    with pytest.raises(ParamsError):
        DelayParams(x_ms=float("nan"))
    with pytest.raises(ParamsError):
        DelayParams(pan_ms=5000.0)


def test_full_queue_drops_oldest_and_counts():
    cfg = OutputConfig(targets=(TargetSpec("freed", "127.0.0.1", 9),), queue_size=4)
    out = OutputSet(cfg, start=False)
    T = _pose(0.0).T_studio_cam()
    t0 = time.perf_counter()
    for i in range(100):
        out.submit(OutputSample(i, i / 30.0, "TRACKING", T))
    assert time.perf_counter() - t0 < 1.0  # never waits for the network
    st = out.stats()
    assert (st.submitted, st.dropped) == (100, 96)
    out.start()
    assert out.flush()
    st = out.stats()
    assert st.processed == 4
    out.close()


def test_unreachable_target_is_counted_not_raised():
    # A socket bound to loopback cannot reach a TEST-NET address: sendto fails locally
    # (no packet leaves the machine).
    bad = TargetSpec("opentrackio", "192.0.2.1", 55555, bind_host="127.0.0.1")
    cfg = OutputConfig(targets=(bad,))
    with OutputSet(cfg) as out:
        for i in range(5):
            out.submit(OutputSample(i, i / 30.0, "TRACKING", np.eye(4)))
        assert out.flush()
        st = out.stats()
    t = st.targets[0]
    assert t.errors == 5
    assert t.packets_sent == 0
    assert "192.0.2.1" in t.last_error
    assert st.encode_errors == 0


def test_no_pose_before_first_good_frame_is_skipped():
    with OutputSet(OutputConfig(targets=(TargetSpec("freed", "127.0.0.1", 9),))) as out:
        out.submit(OutputSample(0, 0.0, "INITIALIZING", None))
        out.submit(OutputSample(1, 0.04, "TRACKING", np.eye(4)))
        assert out.flush()
        st = out.stats()
    assert st.skipped_no_pose == 1
    assert st.targets[0].packets_sent == 1


def test_mark_lost_resends_last_pose_flagged_lost():
    import socket

    from engine.outputs import opentrackio as ot

    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(2.0)
    cfg = OutputConfig(targets=(TargetSpec("opentrackio", "127.0.0.1", rx.getsockname()[1]),))
    T = _pose(0.2).T_studio_cam()
    with OutputSet(cfg) as out:
        out.submit(OutputSample(0, 0.0, "TRACKING", T))
        out.mark_lost()
        assert out.flush()
    a = ot.decode_datagrams([rx.recv(4096)])[0]
    b = ot.decode_datagrams([rx.recv(4096)])[0]
    rx.close()
    assert a["tracker"]["status"] == "TRACKING"
    assert b["tracker"]["status"] == "LOST"
    assert a["transforms"] == b["transforms"]


def test_a_slot_that_fails_to_encode_is_spent_not_retried_in_a_hot_loop(monkeypatch):
    # A clocked slot whose encoding raises is counted as an encode error and its slot is
    # spent: the sender waits for the next slot instead of retrying the same one at once
    # (a hot loop that, at the sender's real-time priority, takes a core and half the GIL).
    from engine.outputs import sender as sender_mod

    def broken(self, *a, **k):  # type: ignore[no-untyped-def]
        raise ValueError("cannot encode")

    monkeypatch.setattr(sender_mod.OutputSet, "_tick", broken)
    cfg = OutputConfig(targets=(TargetSpec("freed", "127.0.0.1", 9),))
    with OutputSet(cfg, rate_hz=50.0) as out:
        out.submit(OutputSample(0, 0.0, "TRACKING", _pose(0.0).T_studio_cam()))
        time.sleep(0.5)
        errors = out.stats().encode_errors
    assert 1 <= errors <= 40  # about one per slot at 50 Hz over 0.5 s, not thousands
    assert "cannot encode" in out.stats().last_encode_error
