"""VISCA over IP: the byte codec (from the Sony manuals' packets), the driver against the
loopback camera simulator (finite speed, FreeD out), faults (silent, garbage, late) ->
OFFLINE and reconnect, tracking never waiting for the head; the FreeD input."""

from __future__ import annotations

import socket
import time

import pytest

from engine.outputs.freed import FreeDPose, encode_d1
from engine.outputs.freed_input import FreeDListener, head_reading_of, open_freed
from engine.pipeline import SinkLevel
from engine.ptz import visca as vc
from engine.ptz.visca_head import ViscaHead, parse_head_spec
from engine.ptz.visca_sim import ViscaCameraSim


def _wait(cond, timeout=3.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.01)
    return False


def test_codec_matches_the_manual_packets():
    # Pan-tiltDrive AbsolutePosition: 8x 01 06 02 VV WW 0Y 0Y 0Y 0Y 0Z 0Z 0Z 0Z FF
    p = vc.pan_tilt_absolute(-1440, 0x0168, 0x18, 0x14)  # EVI-D100: -100 deg, +25 deg
    assert p.hex(" ") == "81 01 06 02 18 14 0f 0a 06 00 00 01 06 08 ff"
    assert vc.parse_command(p) == vc.PanTiltAbsolute(-1440, 0x168, 0x18, 0x14)
    assert vc.PAN_TILT_POS_INQ.hex(" ") == "81 09 06 12 ff"
    assert vc.zoom_direct(0x4000).hex(" ") == "81 01 04 47 04 00 00 00 ff"
    msg = vc.encode_message(vc.ViscaMessage(vc.COMMAND, 7, p))
    assert msg[:8].hex(" ") == "01 00 00 0f 00 00 00 07"
    assert vc.decode_message(msg) == vc.ViscaMessage(vc.COMMAND, 7, p)
    assert vc.parse_reply(vc.ACK).kind == "ack"
    r = vc.parse_reply(vc.pan_tilt_position_reply(-5, 12))
    assert vc.parse_pan_tilt(r.data) == (-5, 12)
    assert vc.parse_reply(vc.error_reply(0x41, 1)).error_name == "command not executable"
    u = vc.ViscaUnits()
    assert u.pan_counts(10.0) == -144  # our pan grows to the left, Sony's to the right
    assert u.pan_deg(u.pan_counts(-33.3)) == pytest.approx(-33.3, abs=0.05)


@pytest.mark.parametrize(("data", "match"), [
    (b"\x01\x00\x00", "shorter than header"),
    (b"\x09\x99\x00\x01\x00\x00\x00\x01\xff", "payload type 0x0999"),
    (b"\x01\x00\x00\x05\x00\x00\x00\x01\x81\xff", "header says 5 payload bytes"),
    (b"\x01\x00\x00\x02\x00\x00\x00\x01\x81\x01", "does not end with FF"),
])
def test_malformed_datagrams_raise_one_line(data, match):
    with pytest.raises(vc.ViscaError, match=match):
        vc.decode_message(data)


def test_head_spec_errors_are_one_line():
    with pytest.raises(vc.ViscaError, match="expected visca:HOST"):
        parse_head_spec("pelco:1.2.3.4")
    with pytest.raises(vc.ViscaError, match="unknown option 'speed'"):
        parse_head_spec("visca:127.0.0.1,speed=3")
    with pytest.raises(vc.ViscaError, match=r"pan_speed 1\.\.24"):
        parse_head_spec("visca:127.0.0.1:52381,pan_speed=99")
    for cpd in ("inf", "1e400", "nan", "0"):  # counts_per_deg: positive and finite
        with pytest.raises(vc.ViscaError, match="counts_per_deg > 0 and finite"):
            parse_head_spec(f"visca:127.0.0.1,counts_per_deg={cpd}")
    with pytest.raises(vc.ViscaError, match=r"VISCA port 99999 is outside 1\.\.65535"):
        parse_head_spec("visca:127.0.0.1:99999")


@pytest.fixture
def loop():
    listener = FreeDListener(0)
    cam = ViscaCameraSim(freed_to=("127.0.0.1", listener.port))
    head = ViscaHead("127.0.0.1", cam.port, poll_hz=50, timeout_s=0.1, offline_after_s=0.4,
                     reconnect_s=0.2)
    yield cam, head, listener
    head.close()
    cam.close()
    listener.close()


def test_the_head_moves_at_finite_speed_and_reports_by_freed_and_inquiry(loop):
    cam, head, listener = loop
    assert _wait(lambda: head.online)
    head.command(20.0, -8.0)
    assert _wait(lambda: cam._target == pytest.approx((20.0, -8.0), abs=0.1))
    pan, tilt = cam.advance(0.0)
    pan, tilt = cam.advance(0.1)  # 80 deg/s pan, 50 deg/s tilt at full speed
    assert pan == pytest.approx(8.0, abs=0.1)
    assert tilt == pytest.approx(-5.0, abs=0.1)
    assert _wait(lambda: listener.count >= 2)
    # FreeD carries what the camera reports, to 1/32768 degree
    assert head_reading_of(listener.latest()) == pytest.approx((pan, tilt), abs=1e-4)
    cam.advance(1.0)
    assert cam.angles() == pytest.approx((20.0, -8.0), abs=0.07)
    assert _wait(lambda: head.position() is not None
                 and abs(head.position().pan_deg - 20.0) < 0.1)
    assert head.health().level is SinkLevel.OK


@pytest.mark.parametrize("fault", ["silent", "garbage", "slow"])
def test_a_camera_that_fails_is_offline_then_reconnects(loop, fault):
    cam, head, _ = loop
    assert _wait(lambda: head.online)
    cam.set_fault(fault)
    assert _wait(lambda: head.health().level is SinkLevel.ALARM)
    h = head.health()
    assert "head OFFLINE" in h.message
    assert "\n" not in h.message
    t0 = time.monotonic()
    head.command(5.0, 1.0)  # never blocks, even while offline
    assert time.monotonic() - t0 < 0.01
    if fault != "slow":  # the driver tries a fresh socket while the camera is gone
        assert _wait(lambda: head.reconnects >= 1, 4.0)
    cam.set_fault(None)
    assert _wait(lambda: head.online, 4.0)
    assert _wait(lambda: cam._target == pytest.approx((5.0, 1.0), abs=0.1), 3.0)


def test_tracking_keeps_running_while_the_head_is_offline():
    from engine.ptz.sim import CircleScenario, PtzSimSource
    from engine.trackers.ptz import PtzParams, PtzTracker

    sc = CircleScenario(duration_s=1.5, width=320, height=240, f_px=400.0)
    src = PtzSimSource(sc, head="visca")
    try:
        src.visca_camera.set_fault("silent")
        from engine.loop import run_tracking

        tr = PtzTracker(PtzParams().with_preset("ptz-sim"))
        recs = list(run_tracking(src, tr))
        assert len(recs) == len(src)
        assert sum(r.result.state.is_good for r in recs) > len(recs) // 2
        sink = next(s for s in src.sinks())
        # the head may have acknowledged its first RESET before the fault was set: it is
        # then online for offline_after_s (1 s) after that reply, which a fast run can end
        # within; OFFLINE must follow once that time has passed without a reply
        assert _wait(lambda: sink.health().level is SinkLevel.ALARM, 3.0), sink.health()
        assert "OFFLINE" in sink.health().message
    finally:
        src.close()


def test_freed_input_source_and_garbage_is_counted():
    src = open_freed("0,timeout_s=0.2")
    out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        addr = ("127.0.0.1", src.listener.port)
        out.sendto(b"garbage", addr)
        pkt = encode_d1(FreeDPose(1, pan_deg=-12.5, tilt_deg=3.0, roll_deg=0.0, x_mm=100.0,
                                  y_mm=-200.0, z_mm=1500.0, zoom=4321, focus=99))
        out.sendto(pkt, addr)
        frames = src.frames()
        f = next(frames)
        from engine.lens import LensEncoders
        from engine.outputs.freed_input import FreeDReading

        r = f.payload(FreeDReading)
        assert r is not None
        assert r.pose.zoom == 4321
        assert f.payload(LensEncoders) == LensEncoders(4321, 99)
        assert head_reading_of(r) == pytest.approx((12.5, 3.0))
        assert src.listener.errors == 1
        lost = next(frames)  # no packet within timeout_s
        assert lost.link_lost_reason == "no FreeD packets"
        # the relay turns the packet into a pose that re-encodes to the same FreeD angles
        from engine.outputs.studio_frame import StudioFrame
        from engine.trackers.freed_relay import T_world_cam_of

        pose = StudioFrame().studio_pose(T_world_cam_of(r))
        assert (pose.freed_pan_deg, pose.tilt_deg) == pytest.approx((-12.5, 3.0), abs=1e-6)
        assert (pose.x_m, pose.y_m, pose.z_m) == pytest.approx((0.1, -0.2, 1.5))
    finally:
        out.close()
        src.close()
