"""What goes on air from the set-up: OpenTrackIO lens + timecode (schema-valid), FreeD
zoom/focus from the same encoders, the nodal offset before every output, studio origin."""

from __future__ import annotations

import json
import socket
import time

import jsonschema
import numpy as np
import pytest

from engine.outputs import OutputError
from engine.outputs.freed import ZoomFocusMapping, decode_d1
from engine.outputs.opentrackio import SampleBuilder, SampleInputs, decode_datagrams
from engine.outputs.sender import FreeDSettings, OutputConfig, OutputSample, OutputSet, TargetSpec
from engine.outputs.studio_frame import CameraOffset, StudioFrame, StudioPose
from engine.timecode import Timecode
from tests.conftest import shared_path


@pytest.fixture(scope="module")
def schema() -> dict:
    return json.loads(shared_path("opentrackio", "schema.json").read_text())


def _state(zoom: int = 32768):
    from engine.studio.zoom import FOCUS_RAW, studio_zoom_lens

    return studio_zoom_lens(640, 480).evaluate(zoom, FOCUS_RAW, iris_raw=77)


@pytest.mark.parametrize("rate", ["23.976", "25", "29.97", "59.94"])
def test_sample_with_lens_and_timecode_validates(schema, rate):
    st = _state()
    tc = Timecode(1, 2, 3, 4, rate)
    s = SampleBuilder().build(SampleInputs(
        pose=StudioPose(1, 2, 3, 10, -5, 0.5), status="TRACKING", timestamp_s=12.5,
        sequence_number=3, sample_rate_hz=25.0, lens=st, timecode=tc))
    jsonschema.validate(s, schema)
    ln = s["lens"]
    assert ln["pinholeFocalLength"] == pytest.approx(st.focal_length_mm)
    assert ln["distortion"][0]["radial"][0] == pytest.approx(st.k1)
    assert ln["entrancePupilOffset"] == pytest.approx(st.entrance_pupil_m)
    assert ln["rawEncoders"] == {"zoom": 32768, "focus": st.focus_raw, "iris": 77}
    assert 0 <= ln["encoders"]["zoom"] <= 1
    assert s["timing"]["timecode"]["frames"] == 4
    assert s["timing"]["timecode"]["dropFrame"] is (rate in ("29.97", "59.94"))


def _listener():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(2.0)
    return s


def _recv_all(sock, n):
    out = []
    for _ in range(n):
        out.append(sock.recv(65535))
    return out


def test_freed_zoom_focus_are_the_encoders_and_otio_matches(schema):
    lo, lf = _listener(), _listener()
    cfg = OutputConfig(targets=(TargetSpec("opentrackio", "127.0.0.1", lo.getsockname()[1]),
                                TargetSpec("freed", "127.0.0.1", lf.getsockname()[1])),
                       freed=FreeDSettings(lens_mapping=ZoomFocusMapping.RAW))
    try:
        with OutputSet(cfg) as out:
            for i, z in enumerate((0, 20000, 65535)):
                st = _state(z)
                out.submit(OutputSample(i, i / 25, "TRACKING", np.eye(4), lens=st,
                                        timecode=Timecode(0, 0, 0, i, "25")))
            assert out.flush()
        freed = [decode_d1(p) for p in _recv_all(lf, 3)]
        otio = decode_datagrams(_recv_all(lo, 3))
    finally:
        lo.close()
        lf.close()
    assert [(p.zoom, p.focus) for p in freed] == [(z, _state(z).focus_raw)
                                                  for z in (0, 20000, 65535)]
    for s, z in zip(otio, (0, 20000, 65535), strict=True):
        jsonschema.validate(s, schema)
        assert s["lens"]["rawEncoders"]["zoom"] == z
        assert s["lens"]["pinholeFocalLength"] == pytest.approx(_state(z).focal_length_mm)
    assert [s["timing"]["timecode"]["frames"] for s in otio] == [0, 1, 2]


def test_clocked_held_slots_count_timecode_on():
    lo = _listener()
    cfg = OutputConfig(targets=(TargetSpec("opentrackio", "127.0.0.1", lo.getsockname()[1]),))
    try:
        with OutputSet(cfg, rate_hz=50.0, stale_after_s=5.0) as out:
            out.submit(OutputSample(0, 0.0, "TRACKING", np.eye(4),
                                    timecode=Timecode(0, 0, 10, 0, "50"),
                                    submit_mono_s=time.monotonic()))
            pk = _recv_all(lo, 6)  # one fresh slot, then held ones at 50 Hz
    finally:
        lo.close()
    frames = [s["timing"]["timecode"]["frames"] for s in decode_datagrams(pk)]
    assert frames == [0, 1, 2, 3, 4, 5]


def test_nodal_offset_is_applied_before_the_studio_frame():
    off = CameraOffset(x_m=0.1, y_m=-0.05, z_m=0.2)
    cfg = OutputConfig(offset=off, studio=StudioFrame().with_origin_at([1.0, 0.0, 0.0]))
    out = OutputSet(cfg, start=False)
    T = np.eye(4)
    from engine.geometry import R_from_pan_tilt_roll_deg

    T[:3, :3] = R_from_pan_tilt_roll_deg(0, 0, 0)  # looking along +Y, camera x = world x
    T[:3, 3] = [2.0, 3.0, 1.5]
    out._ingest(OutputSample(0, 0.0, "TRACKING", T), cfg)
    pose = out._comp.held().pose
    # camera x right = world +x, camera y down = world -z, camera z forward = world +y
    assert (pose.x_m, pose.y_m, pose.z_m) == pytest.approx((2.0 + 0.1 - 1.0, 3.0 + 0.2,
                                                           1.5 + 0.05))
    out.close()


def test_offsets_and_studio_frame_reject_bad_values_in_one_line():
    with pytest.raises(OutputError, match=r"nodal offset.x_m: nan"):
        CameraOffset.from_json_dict({"x_m": float("nan")})
    with pytest.raises(OutputError, match=r"unknown field 'dx'"):
        CameraOffset.from_json_dict({"dx": 1.0})
    with pytest.raises(OutputError, match="over 10 m"):
        CameraOffset(x_m=12.0)
    with pytest.raises(OutputError, match="not a finite 3D point"):
        StudioFrame().with_origin_at([1.0, float("inf"), 0.0])


def test_studio_frame_from_dlt_makes_the_calibration_points_the_origin():
    from engine.geometry import R_from_pan_tilt_roll_deg, invert, make_T

    # a camera 2 m behind the DLT origin looking at it; the tracker's world is shifted
    T_dlt_cam = make_T(R_from_pan_tilt_roll_deg(0, 0, 0), np.array([0.0, -2.0, 1.5]))
    T_world_dlt = make_T(R_from_pan_tilt_roll_deg(30, 0, 0), np.array([5.0, 1.0, 0.0]))
    T_world_cam = T_world_dlt @ T_dlt_cam
    T_cam_dlt = invert(T_dlt_cam)
    sf = StudioFrame.from_dlt(T_world_cam, T_cam_dlt[:3, :3], T_cam_dlt[:3, 3])
    assert sf.matrix == pytest.approx(T_world_dlt)
    pose = sf.studio_pose(T_world_cam)
    assert (pose.x_m, pose.y_m, pose.z_m) == pytest.approx((0.0, -2.0, 1.5))
