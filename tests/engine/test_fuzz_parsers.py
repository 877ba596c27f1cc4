"""Property/fuzz tests: every parser raises its module's clear error, never crashes or hangs.

Owned parsers (FreeD, OpenTrackIO packets/payloads/reassembly, session index and records) are
fuzzed with random and mutated inputs; other modules' parsers (TUM lists and trajectories,
camera.json, OTB ground truth) get the same treatment through files.
"""

from __future__ import annotations

import contextlib
import json
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.errors import StudioTrackError
from engine.outputs import freed as fd
from engine.outputs import opentrackio as ot
from engine.session import SessionError
from engine.session.reader import parse_index, read_index, read_records

FUZZ = settings(max_examples=150, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])
GOLDEN = bytes.fromhex("d100df78aa0047ef" + "00" * 13 + "4000001501d1ff12")


def _mutations(seed: bytes) -> st.SearchStrategy[bytes]:
    """Seed bytes with random byte flips, truncations and extensions."""
    return st.builds(
        lambda flips, cut, tail: (
            bytes(b ^ flips.get(i, 0) for i, b in enumerate(seed))[:cut] + tail
        ),
        st.dictionaries(st.integers(0, max(len(seed) - 1, 0)), st.integers(1, 255),
                        max_size=4),
        st.integers(0, len(seed)),
        st.binary(max_size=8),
    )


# ------------------------------------------------------------------------------ FreeD
@FUZZ
@given(st.one_of(st.binary(max_size=64), _mutations(GOLDEN)))
def test_freed_decoder_never_crashes(data):
    try:
        p = fd.decode_d1(data)
    except fd.FreeDError:
        return
    assert fd.encode_d1(p) == data  # anything accepted re-encodes byte for byte


@FUZZ
@given(st.binary(min_size=28, max_size=28))
def test_freed_any_valid_packet_round_trips(body):
    pkt = bytes([0xD1]) + body[1:] + bytes([fd.checksum(bytes([0xD1]) + body[1:])])
    assert fd.encode_d1(fd.decode_d1(pkt)) == pkt


# ------------------------------------------------------------------------------ OpenTrackIO
_SAMPLE = ot.encode_payload({"protocol": {"name": "OpenTrackIO", "version": [1, 0, 0]},
                             "transforms": [{"translation": {"x": 1.0, "y": 2.0, "z": 3.0},
                                             "rotation": {"pan": 1.0, "tilt": 2.0,
                                                          "roll": 3.0}}]}, "json")
_PACKETS = ot.build_packets(_SAMPLE, 7, "json", max_segment=64)


def _with_valid_checksum(packet: bytes) -> bytes:
    if len(packet) < 16:
        return packet
    c = ot.fletcher16_mod256(packet[:14] + packet[16:])
    return packet[:14] + c.to_bytes(2, "big") + packet[16:]


@FUZZ
@given(st.lists(st.one_of(st.binary(max_size=96), _mutations(_PACKETS[0]),
                          _mutations(_PACKETS[1]).map(_with_valid_checksum)),
                max_size=6))
def test_opentrackio_reassembler_never_crashes(packets):
    r = ot.Reassembler(max_pending=4, max_bytes=1 << 16)
    for p in packets:
        try:
            s = r.feed(p)
        except ot.OpenTrackIOError:
            continue
        assert s is None or isinstance(s, dict)


@FUZZ
@given(st.binary(max_size=300), st.sampled_from([ot.ENCODING_JSON, ot.ENCODING_CBOR]))
def test_opentrackio_payload_decoder_never_crashes(payload, enc):
    try:
        obj = ot.decode_payload(payload, enc)
    except ot.OpenTrackIOError:
        return
    assert isinstance(obj, dict)


@FUZZ
@given(st.permutations(list(range(len(_PACKETS)))))
def test_opentrackio_segments_in_any_order(order):
    assert ot.decode_datagrams([_PACKETS[i] for i in order]) == [json.loads(_SAMPLE)]


# ------------------------------------------------------------------------------ sessions
_INDEX = {
    "format": "studiotrack-session", "version": 1, "status": "complete", "stop_reason": "",
    "source": {"spec": "synthetic", "name": "s", "kind": "frames", "nominal_fps": 30.0,
               "length": 3, "video_file": ""},
    "intrinsics": {"fx": 500.0, "fy": 500.0, "cx": 319.5, "cy": 239.5, "width": 640,
                   "height": 480, "distortion": [0.0] * 5, "depth_scale": 5000.0},
    "tracker": {"name": "ground-truth", "params": {}},
    "frames_recorded": 3, "has_depth": False,
}
_json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6) | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner,
                                                                 max_size=4),
    max_leaves=12,
)


def _replace_path(obj, path, value):
    obj = json.loads(json.dumps(obj))
    d = obj
    for k in path[:-1]:
        d = d[k]
    d[path[-1]] = value
    return obj


_PATHS = [("format",), ("version",), ("status",), ("source",), ("source", "kind"),
          ("source", "nominal_fps"), ("source", "video_file"), ("intrinsics",),
          ("intrinsics", "fx"), ("intrinsics", "width"), ("intrinsics", "distortion"),
          ("tracker",), ("tracker", "name"), ("tracker", "params"), ("frames_recorded",),
          ("stop_reason",)]


@FUZZ
@given(st.sampled_from(_PATHS), _json_values)
def test_session_index_field_fuzz(path, value):
    try:
        idx = parse_index(_replace_path(_INDEX, path, value))
    except SessionError:
        return
    assert idx.version == 1


@FUZZ
@given(_json_values)
def test_session_index_whole_value_fuzz(value):
    with pytest.raises(SessionError):
        parse_index(value)


@FUZZ
@given(st.one_of(st.binary(max_size=200), _mutations(json.dumps(_INDEX).encode())),
       st.binary(max_size=200))
def test_session_files_fuzz(index_bytes, records_bytes):
    with tempfile.TemporaryDirectory() as d:
        (Path(d) / "index.json").write_bytes(index_bytes)
        (Path(d) / "records.jsonl").write_bytes(records_bytes)
        with contextlib.suppress(SessionError):
            read_index(d)
        try:
            recs = read_records(d)
        except SessionError:
            return
        assert all(isinstance(r, dict) for r in recs)


# ------------------------------------------------------------------------------ others' parsers
_TEXTY = st.text(alphabet=st.sampled_from(list("0123456789.-+eEnaif ,\t#\n")), max_size=200)


def _file_fuzz(content: bytes, reader, name: str) -> None:
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / name
        p.write_bytes(content)
        with contextlib.suppress(StudioTrackError):
            reader(p)


@FUZZ
@given(st.one_of(_TEXTY.map(str.encode), st.binary(max_size=100)))
def test_tum_trajectory_reader_fuzz(content):
    from engine.evaluation.trajectory import read_tum

    _file_fuzz(content, read_tum, "traj.txt")


@FUZZ
@given(st.one_of(
    st.text(alphabet=st.sampled_from(list("0123456789.- #\nrgb/abc.png")), max_size=200)
    .map(str.encode), st.binary(max_size=100)))
def test_tum_list_reader_fuzz(content):
    from engine.sources.tum import read_tum_groundtruth, read_tum_list

    _file_fuzz(content, read_tum_list, "rgb.txt")
    _file_fuzz(content, read_tum_groundtruth, "groundtruth.txt")


@FUZZ
@given(st.one_of(_TEXTY.map(str.encode), st.binary(max_size=100)))
def test_otb_groundtruth_readers_fuzz(content):
    from engine.evaluation.boxes import read_boxes
    from engine.sources.otb import read_box_file

    _file_fuzz(content, read_boxes, "groundtruth_rect.txt")
    _file_fuzz(content, read_box_file, "groundtruth_rect.txt")


@FUZZ
@given(st.one_of(
    st.binary(max_size=100),
    _json_values.map(lambda v: json.dumps(v).encode()),
    st.sampled_from(["fx", "fy", "cx", "width", "distortion", "depth_scale"]).flatmap(
        lambda k: _json_values.map(lambda v, k=k: json.dumps(
            {"fx": 500, "fy": 500, "cx": 320, "cy": 240, "width": 640, "height": 480,
             "distortion": [0] * 5, "depth_scale": 5000, k: v}).encode())),
))
def test_camera_json_fuzz(content):
    from engine.camera import load_camera_json

    _file_fuzz(content, load_camera_json, "camera.json")


@FUZZ
@given(st.lists(st.one_of(
    st.text(alphabet=st.sampled_from(list("0123456789.,-+eEnaif b#AB")), max_size=30),
    st.text(max_size=20)), max_size=15))
def test_range_csv_parser_fuzz(lines):
    from engine.beacons.io import parse_range_csv

    steps, stats = parse_range_csv(lines, None, 0.0)  # malformed lines are counted, not raised
    assert stats.steps == len(steps)


@FUZZ
@given(st.one_of(st.binary(max_size=120),
                 _json_values.map(lambda v: json.dumps({"timestamp_s": 1.0, "ranges_m": v})
                                  .encode())))
def test_beacon_datagram_parser_fuzz(data):
    from engine.beacons.io import InputStats, parse_datagram

    step = parse_datagram(data, None, InputStats())
    assert step is None or step.ranges_m is not None


DEEP_JSON = b"[" * 100_000 + b"]" * 100_000


def test_deeply_nested_json_in_owned_parsers_is_a_clear_error(tmp_path):
    with pytest.raises(ot.OpenTrackIOError, match="RecursionError"):
        ot.decode_payload(DEEP_JSON, ot.ENCODING_JSON)
    with pytest.raises(ot.OpenTrackIOError):
        ot.decode_payload(b"\x81" * 100_000 + b"\x00", ot.ENCODING_CBOR)
    (tmp_path / "index.json").write_bytes(DEEP_JSON)
    with pytest.raises(SessionError, match="nested too deeply"):
        read_index(tmp_path)


def test_camera_json_deeply_nested(tmp_path):
    from engine.camera import load_camera_json

    (tmp_path / "camera.json").write_bytes(DEEP_JSON)
    with pytest.raises(StudioTrackError):
        load_camera_json(tmp_path / "camera.json")


def test_beacon_datagram_deeply_nested():
    from engine.beacons.io import InputStats, parse_datagram

    assert parse_datagram(DEEP_JSON, None, InputStats()) is None


@pytest.mark.parametrize(
    "loader",
    ["project", "presenter_model", "keyframe_store", "floor_calibration", "beacon_layout"],
)
def test_other_json_files_nested_too_deeply_give_clear_errors(tmp_path, loader):
    from engine.errors import StudioTrackError

    if loader == "project":
        from engine.project import open_project as load

        target = tmp_path
        (tmp_path / "project.json").write_bytes(DEEP_JSON)
    elif loader == "presenter_model":
        from engine.presenter.model import load_model as load

        target = tmp_path
        (tmp_path / "model.json").write_bytes(DEEP_JSON)
    elif loader == "keyframe_store":
        from engine.keyframes.store import KeyframeStore

        load = KeyframeStore.load
        target = tmp_path
        (tmp_path / "keyframes.json").write_bytes(DEEP_JSON)
    elif loader == "floor_calibration":
        from engine.presenter.twoview import load_floor_calibration as load

        target = tmp_path / "floor.json"
        target.write_bytes(DEEP_JSON)
    else:
        from engine.beacons.io import load_layout as load

        target = tmp_path / "layout.json"
        target.write_bytes(DEEP_JSON)
    with pytest.raises(StudioTrackError):
        load(target)
