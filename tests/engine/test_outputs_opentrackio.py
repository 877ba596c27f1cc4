"""OpenTrackIO: schema validation, header/checksum from the protocol text, segmentation,
JSON and CBOR loopback round trips decoded by an independent decoder."""

from __future__ import annotations

import json
import socket
import struct

import cbor2
import jsonschema
import numpy as np
import pytest

from engine.camera import Intrinsics
from engine.errors import StudioTrackError
from engine.outputs import opentrackio as ot
from engine.outputs.sender import OutputConfig, OutputSample, OutputSet, TargetSpec
from engine.outputs.studio_frame import StudioPose
from tests.conftest import shared_path

INTR = Intrinsics(600.0, 600.0, 330.0, 238.0, 640, 480, (0.1, -0.2, 0.001, 0.002, 0.05))


@pytest.fixture(scope="module")
def schema() -> dict:
    return json.loads(shared_path("opentrackio", "schema.json").read_text())


def _fletcher_256(data: bytes) -> tuple[int, int]:
    a = b = 0
    for x in data:
        a = (a + x) % 256
        b = (b + a) % 256
    return a, b


def independent_decode(packets: list[bytes]) -> tuple[int, dict]:
    """From the protocol text: 16-byte header, Fletcher-16 mod 256, reassemble by offset."""
    parts = {}
    encoding = None
    total = None
    for p in packets:
        assert p[0:4] == b"OTrk"
        assert p[4] == 0
        encoding = p[5]
        seq = int.from_bytes(p[6:8], "big")
        off = int.from_bytes(p[8:12], "big")
        fl = int.from_bytes(p[12:14], "big")
        n = fl & 0x7FFF
        body = p[16:]
        assert len(body) == n
        s1, s2 = _fletcher_256(p[:14] + body)
        assert p[14] == s2
        assert p[15] == s1
        parts[off] = body
        if fl & 0x8000:
            total = off + n
        assert n <= 1484
    payload = b"".join(parts[k] for k in sorted(parts))
    assert len(payload) == total
    obj = json.loads(payload) if encoding == 1 else cbor2.loads(payload)
    return seq, obj


def _sample(status="TRACKING", **kw) -> dict:
    b = ot.SampleBuilder(source_number=3)
    return b.build(ot.SampleInputs(StudioPose(1.0, -2.0, 1.5, 20.0, -5.0, 0.5), status,
                                   1_763_700_000.5, 42, 30000 / 1001, INTR, **kw))


@pytest.mark.parametrize("status", ["TRACKING", "DEGRADED", "LOST"])
def test_samples_validate_against_schema(schema, status):
    s = _sample(status)
    jsonschema.validate(s, schema)
    assert s["tracker"]["status"] == status
    assert s["timing"]["sampleRate"] == {"num": 30000, "denom": 1001}
    assert s["timing"]["sequenceNumber"] == 42
    assert s["timing"]["sampleTimestamp"] == {"seconds": 1_763_700_000, "nanoseconds": 500_000_000}
    lens = s["lens"]
    assert lens["distortion"][0]["radial"] == [0.1, -0.2, 0.05]
    assert lens["distortion"][0]["tangential"] == [0.001, 0.002]
    assert lens["pinholeFocalLength"] == pytest.approx(600.0 * 9.59 / 640)


def test_shared_examples_are_valid_and_decode(schema):
    for name in ("complete_dynamic_example.json", "recommended_dynamic_example.json"):
        ex = json.loads(shared_path("opentrackio", name).read_text())
        jsonschema.validate(ex, schema)
        for enc in ("json", "cbor"):
            pk = ot.build_packets(ot.encode_payload(ex, enc), 9, enc)
            assert independent_decode(pk)[1] == ex


def test_header_layout_and_checksum_mod_256():
    payload = b'{"a":1}'
    (pkt,) = ot.build_packets(payload, 0x1234, "json")
    assert pkt[:4] == b"OTrk"
    assert pkt[4] == 0
    assert pkt[5] == 1
    assert struct.unpack(">HIH", pkt[6:14]) == (0x1234, 0, 0x8000 | len(payload))
    s1, s2 = _fletcher_256(pkt[:14] + payload)
    assert pkt[14:16] == bytes([s2, s1])
    # mod 256 differs from classic mod 255 on a byte sum above 255:
    assert ot.fletcher16_mod256(b"\xff\x02") == (((0xFF + 0xFF + 2) % 256) << 8) | 1


@pytest.mark.parametrize("enc", ["json", "cbor"])
def test_segmentation_above_1484_bytes(enc):
    big = dict(_sample(), lens={**_sample()["lens"], "custom": [float(i) for i in range(400)]})
    payload = ot.encode_payload(big, enc)
    assert len(payload) > 1484
    pk = ot.build_packets(payload, 5, enc)
    assert len(pk) == -(-len(payload) // 1484)
    assert all(len(p) <= 1500 for p in pk)
    seq, obj = independent_decode(list(reversed(pk)))
    assert seq == 5
    assert obj == big
    assert ot.decode_datagrams(list(reversed(pk))) == [big]


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda p: p[:10], "shorter"),
        (lambda p: b"XTrk" + p[4:], "identifier"),
        (lambda p: p[:5] + b"\x07" + p[6:], "encoding"),
        (lambda p: p[:-1], "payload bytes"),
        (lambda p: p[:-1] + bytes([p[-1] ^ 1]), "checksum"),
    ],
)
def test_malformed_packets_raise_module_error(mutate, match):
    (pkt,) = ot.build_packets(b'{"x":1}', 1, "json")
    with pytest.raises(ot.OpenTrackIOError, match=match) as info:
        ot.Reassembler().feed(mutate(pkt))
    assert isinstance(info.value, StudioTrackError)


@pytest.mark.parametrize("enc", ["json", "cbor"])
def test_loopback_round_trip(schema, enc):
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(2.0)
    port = rx.getsockname()[1]
    pose = StudioPose(0.5, 3.0, 1.7, -15.0, 4.0, 1.0)
    cfg = OutputConfig(targets=(TargetSpec("opentrackio", "127.0.0.1", port, enc),),
                       opentrackio_source_number=4)
    states = ["TRACKING", "DEGRADED", "LOST"]
    with OutputSet(cfg) as out:
        for i, st in enumerate(states):
            out.submit(OutputSample(i, i / 25.0, st, pose.T_studio_cam(), INTR, 1.7e9 + i))
        assert out.flush()
    got = [independent_decode([rx.recv(2048)]) for _ in states]
    rx.close()
    for i, (seq, s) in enumerate(got):
        jsonschema.validate(s, schema)
        assert seq == i
        assert s["tracker"]["status"] == states[i]
        assert s["sourceNumber"] == 4
        tr = s["transforms"][0]
        assert tr["translation"] == pytest.approx({"x": 0.5, "y": 3.0, "z": 1.7})
        assert tr["rotation"]["pan"] == pytest.approx(-15.0)
        assert tr["rotation"]["tilt"] == pytest.approx(4.0)
    assert got[1][1]["timing"]["sampleRate"] == {"num": 25, "denom": 1}


def test_default_multicast_group():
    assert ot.default_multicast_group(7) == "239.135.1.7"
    with pytest.raises(ot.OpenTrackIOError):
        ot.default_multicast_group(0)


def test_multicast_on_loopback_interface(schema):
    group = ot.default_multicast_group(9)
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    rx.bind((group, 0))
    rx.settimeout(2.0)
    try:
        rx.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP,
                      socket.inet_aton(group) + socket.inet_aton("127.0.0.1"))
        joined = True
    except OSError:
        joined = False  # no multicast on lo here: the sender must still not raise
    cfg = OutputConfig(targets=(TargetSpec("opentrackio", group, rx.getsockname()[1],
                                           bind_host="127.0.0.1"),),
                       opentrackio_source_number=9)
    pose = StudioPose(0.0, 0.0, 1.5, 0.0, 0.0, 0.0)
    with OutputSet(cfg) as out:
        out.submit(OutputSample(0, 0.0, "TRACKING", pose.T_studio_cam(), INTR))
        assert out.flush()
        t = out.stats().targets[0]
    assert t.packets_sent + t.errors == 1
    if joined and t.packets_sent:
        _, s = independent_decode([rx.recv(4096)])
        jsonschema.validate(s, schema)
        assert s["sourceNumber"] == 9
    rx.close()


def test_fletcher16_matches_the_running_sums() -> None:
    """The vectorised checksum equals the definition (running sums mod 256), any length."""

    def reference(data: bytes) -> int:
        s1 = s2 = 0
        for b in data:
            s1 = (s1 + b) & 0xFF
            s2 = (s2 + s1) & 0xFF
        return (s2 << 8) | s1

    rng = np.random.default_rng(7)
    for n in (0, 1, 2, 255, 256, 257, 1500, 70000):
        data = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        assert ot.fletcher16_mod256(data) == reference(data), n
    assert ot.fletcher16_mod256(b"\xff" * 4000) == reference(b"\xff" * 4000)
