"""FreeD D1: golden packets, round trips, malformed input, loopback send/receive."""

from __future__ import annotations

import socket

import numpy as np
import pytest

from engine.errors import StudioTrackError
from engine.outputs import freed as fd
from engine.outputs.sender import FreeDSettings, OutputConfig, OutputSample, OutputSet, TargetSpec
from engine.outputs.studio_frame import StudioFrame, StudioPose

GOLDEN = [
    ("d1 00 df 78 aa 00 47 ef" + " 00" * 13 + " 40 00 00 15 01 d1 ff 12",
     -65.05731, 0.561981, 16384, 5377),
    ("d1 00 21 98 d8 ff eb 94" + " 00" * 13 + " 28 c6 00 13 b9 d1 ff d6",
     67.19409, -0.159546, 10438, 5049),
]


def _independent_decode(b: bytes) -> dict[str, float]:
    """Decoder written from the Vinten manual text, not from engine.outputs.freed."""
    assert len(b) == 29
    assert b[0] == 0xD1
    assert (0x40 - sum(b[:28])) % 256 == b[28]

    def s24(i: int) -> int:
        v = (b[i] << 16) | (b[i + 1] << 8) | b[i + 2]
        return v - 0x1000000 if v >= 0x800000 else v

    def u24(i: int) -> int:
        return (b[i] << 16) | (b[i + 1] << 8) | b[i + 2]

    return {
        "cam": b[1], "pan": s24(2) / 32768, "tilt": s24(5) / 32768, "roll": s24(8) / 32768,
        "x": s24(11) / 64, "y": s24(14) / 64, "z": s24(17) / 64, "zoom": u24(20),
        "focus": u24(23),
    }


@pytest.mark.parametrize(("hexstr", "pan", "tilt", "zoom", "focus"), GOLDEN)
def test_golden_packets_decode_and_reencode_byte_for_byte(hexstr, pan, tilt, zoom, focus):
    raw = bytes.fromhex(hexstr.replace(" ", ""))
    assert len(raw) == 29
    p = fd.decode_d1(raw)
    assert p.pan_deg == pytest.approx(pan, abs=1e-5)
    assert p.tilt_deg == pytest.approx(tilt, abs=1e-6)
    assert (p.zoom, p.focus, p.camera_id) == (zoom, focus, 0)
    assert fd.encode_d1(p) == raw
    assert fd.checksum(raw[:28]) == raw[28]


@pytest.mark.parametrize(
    ("data", "match"),
    [
        (b"\xd1" * 28, "29 bytes"),
        (b"\xd1" * 30, "29 bytes"),
        (b"\xd2" + bytes(28), "not D1"),
        (bytes.fromhex(GOLDEN[0][0].replace(" ", ""))[:28] + b"\x00", "checksum"),
    ],
)
def test_bad_packets_raise_module_error(data, match):
    with pytest.raises(fd.FreeDError, match=match) as info:
        fd.decode_d1(data)
    assert isinstance(info.value, StudioTrackError)


def test_out_of_range_values_raise():
    with pytest.raises(fd.FreeDError, match="24-bit"):
        fd.encode_d1(fd.FreeDPose(1, 0, 0, 0, 200_000.0, 0, 0, 0, 0))
    with pytest.raises(fd.FreeDError):
        fd.FreeDPose(256, 0, 0, 0, 0, 0, 0, 0, 0)


def test_lens_mappings():
    M = fd.ZoomFocusMapping
    assert fd.lens_field(M.RAW, 1234, 35.0) == 1234
    assert fd.lens_field(M.MM_X100, 0, 35.25) == 3525
    assert fd.lens_field(M.MM_X64, 0, 35.25) == 2256
    assert fd.lens_value_mm(M.MM_X64, 2256) == 35.25
    assert fd.lens_field(M.MM_X100, 0, 1e9) == 0xFFFFFF


def test_loopback_send_is_decoded_independently():
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(2.0)
    port = rx.getsockname()[1]
    pose = StudioPose(1.25, -2.5, 1.6, 30.0, -10.0, 2.0)
    cfg = OutputConfig(
        targets=(TargetSpec("freed", "127.0.0.1", port),),
        freed=FreeDSettings(camera_id=7, lens_mapping=fd.ZoomFocusMapping.RAW, zoom_raw=4242,
                            focus_raw=99),
    )
    try:
        with OutputSet(cfg) as out:
            for i in range(3):
                out.submit(OutputSample(i, i / 30.0, "TRACKING", pose.T_studio_cam()))
            assert out.flush()
            st = out.stats()
        got = [_independent_decode(rx.recv(64)) for _ in range(3)]
    finally:
        rx.close()
    assert st.targets[0].packets_sent == 3
    assert st.targets[0].errors == 0
    assert st.targets[0].bind == "127.0.0.1"
    g = got[-1]
    assert g["cam"] == 7
    assert g["zoom"] == 4242
    assert g["focus"] == 99
    assert g["pan"] == pytest.approx(-30.0, abs=1e-4)  # FreeD pans right-positive
    assert g["tilt"] == pytest.approx(-10.0, abs=1e-4)
    assert g["roll"] == pytest.approx(2.0, abs=1e-4)
    assert (g["x"], g["y"], g["z"]) == pytest.approx((1250.0, -2500.0, 1600.0), abs=0.02)


def test_studio_frame_from_floor_points():
    rng = np.random.default_rng(3)
    o = np.array([1.0, 2.0, 0.5])
    sf = StudioFrame.from_floor_points(o, o + np.array([2.0, 0.0, 0.0]),
                                       o + np.array([0.3, 1.0, 0.0]))
    T = sf.matrix
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], o)
    pose = StudioPose(*rng.uniform(-2, 2, 3), 40.0, 12.0, -3.0)
    T_world_cam = T @ pose.T_studio_cam()
    back = sf.studio_pose(T_world_cam)
    np.testing.assert_allclose(back.as_array(), pose.as_array(), atol=1e-9)
