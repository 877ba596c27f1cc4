"""OpenTrackIO 1.0 samples over UDP (SMPTE RIS OSVP camdkit, opentrackio.org).

Every datagram is a 16-byte big-endian header followed by (a segment of) the payload::

    offset  size  field
    0       4     identifier "OTrk"
    4       1     reserved (0)
    5       1     encoding: 0x01 JSON, 0x02 CBOR
    6       2     sequence number (uint16, one per complete sample; all segments share it)
    8       4     segment offset (uint32, byte offset of this segment in the payload)
    12      2     bit 15: last segment; bits 0-14: this segment's payload length
    14      2     Fletcher-16 over header bytes 0..13 + segment payload, (sum2 << 8) | sum1

Both Fletcher running sums are taken modulo 256 (uint8 wrap-around), as the SMPTE-compatible
senders and Unreal's LiveLink OpenTrackIO parser do; classic Fletcher-16 uses 255. Payloads
longer than 1484 bytes (1500-byte MTU minus the header) are split into segments.

Default destination: multicast 239.135.1.<sourceNumber>, port 55555. The sample's JSON shape
follows ``schema.json`` (camdkit); tests validate every emitted sample against it.
"""

from __future__ import annotations

import json
import math
import struct
import uuid
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from engine.camera import Intrinsics
from engine.lens import LensState
from engine.outputs import OutputError
from engine.outputs.studio_frame import StudioPose
from engine.timecode import Timecode

IDENTIFIER = b"OTrk"
HEADER_LENGTH = 16
MTU = 1500
MAX_SEGMENT_PAYLOAD = MTU - HEADER_LENGTH  # 1484
ENCODING_JSON = 0x01
ENCODING_CBOR = 0x02
DEFAULT_PORT = 55555
MULTICAST_PREFIX = "239.135.1."
PROTOCOL_NAME = "OpenTrackIO"
PROTOCOL_VERSION = (1, 0, 0)
_LAST_FLAG = 0x8000
_LEN_MASK = 0x7FFF


class OpenTrackIOError(OutputError):
    """An OpenTrackIO packet or payload is malformed, or a sample cannot be built."""


def default_multicast_group(source_number: int) -> str:
    """239.135.1.<sourceNumber> (source numbers 1..200 as in the reference tools)."""
    if not 1 <= source_number <= 200:
        raise OpenTrackIOError(f"OpenTrackIO source number {source_number} is outside 1..200")
    return f"{MULTICAST_PREFIX}{source_number}"


def fletcher16_mod256(data: bytes) -> int:
    """Fletcher-16 with both running sums modulo 256: ``(sum2 << 8) | sum1``.

    Closed form of the running sums (``sum1 += b; sum2 += sum1``, both mod 256): sum1 is
    the byte sum and sum2 weighs byte ``k`` of ``n`` by ``n - k`` - vectorised, since the
    sender computes it for every packet (a Python loop was ~60 us per 1 kB packet, holding
    the interpreter lock the other threads wait for)."""
    b = np.frombuffer(data, dtype=np.uint8).astype(np.int64)
    s1 = int(b.sum()) & 0xFF
    s2 = int(b @ np.arange(b.size, 0, -1, dtype=np.int64)) & 0xFF
    return (s2 << 8) | s1


def encoding_byte(encoding: str) -> int:
    enc = encoding.lower()
    if enc == "json":
        return ENCODING_JSON
    if enc == "cbor":
        return ENCODING_CBOR
    raise OpenTrackIOError(f"OpenTrackIO encoding {encoding!r} is not 'json' or 'cbor'")


# --------------------------------------------------------------------------------------------
# Samples


@dataclass(frozen=True, slots=True)
class LensInfo:
    """What the sample says about the lens, derived from the calibration.

    ``sensor_width_mm`` converts the pixel focal length to millimetres
    (``f_mm = fx * sensor_width_mm / width``); 9.59 mm is a 2/3-inch broadcast sensor.
    """

    sensor_width_mm: float = 9.59
    focus_distance_m: float | None = None
    f_stop: float | None = None


_COMMON_RATES = ((24000, 1001), (24, 1), (25, 1), (30000, 1001), (30, 1), (48, 1), (50, 1),
                 (60000, 1001), (60, 1), (100, 1), (120, 1))


def _rational(rate_hz: float) -> dict[str, int]:
    """Sample rate as num/denom, snapped to a broadcast rate within 1% (29.97 = 30000/1001)."""
    if not math.isfinite(rate_hz) or rate_hz <= 0:
        return {"num": 30, "denom": 1}
    num, den = min(_COMMON_RATES, key=lambda r: abs(r[0] / r[1] - rate_hz))
    if abs(num / den - rate_hz) <= 0.01 * rate_hz:
        return {"num": num, "denom": den}
    return {"num": max(1, min(round(rate_hz * 1000), 2147483647)), "denom": 1000}


def lens_block(intr: Intrinsics | None, lens: LensInfo,
               state: LensState | None = None) -> dict[str, Any]:
    """``lens`` object: pinhole focal length, projection offset, Brown-Conrady distortion;
    with a lens file's ``state`` (zoom/focus encoders) also the entrance-pupil offset and
    the encoders (normalised and raw), and the intrinsics and sensor width are the state's."""
    out: dict[str, Any] = {}
    sensor_width_mm = lens.sensor_width_mm
    if state is not None:
        intr = state.intrinsics
        sensor_width_mm = state.sensor_width_mm
        out["entrancePupilOffset"] = float(state.entrance_pupil_m)
        out["encoders"] = {"zoom": float(state.zoom_norm), "focus": float(state.focus_norm)}
        raw = {"zoom": int(state.zoom_raw), "focus": int(state.focus_raw)}
        if state.iris_raw is not None:
            raw["iris"] = int(state.iris_raw)
        out["rawEncoders"] = raw
    if intr is not None:
        pitch_mm = sensor_width_mm / intr.width
        out["pinholeFocalLength"] = intr.fx * pitch_mm
        # Principal point offset from the image centre on the sensor, mm (y up).
        out["projectionOffset"] = {
            "x": (intr.cx - (intr.width - 1) / 2.0) * pitch_mm,
            "y": -(intr.cy - (intr.height - 1) / 2.0) * pitch_mm,
        }
        k1, k2, p1, p2, k3 = (float(v) for v in intr.dist_k1k2p1p2k3)
        # engine.camera applies the Caltech model to undistorted points: "U-D".
        out["distortion"] = [
            {"model": "Brown-Conrady U-D", "radial": [k1, k2, k3], "tangential": [p1, p2]}
        ]
    if lens.focus_distance_m is not None and lens.focus_distance_m > 0:
        out["focusDistance"] = float(lens.focus_distance_m)
    if lens.f_stop is not None and lens.f_stop > 0:
        out["fStop"] = float(lens.f_stop)
    return out


@dataclass(frozen=True, slots=True)
class SampleInputs:
    """Per-sample values the sender passes in."""

    pose: StudioPose
    status: str  # "TRACKING", "DEGRADED", "LOST", ...
    timestamp_s: float
    sequence_number: int
    sample_rate_hz: float
    intrinsics: Intrinsics | None = None
    recording: bool = False
    transform_id: str = "Camera"  # "Talent" for the presenter's position
    lens: LensState | None = None  # the lens file at the frame's encoders
    timecode: Timecode | None = None  # SMPTE timecode of the sample


@dataclass(frozen=True, slots=True)
class SampleBuilder:
    """Builds OpenTrackIO sample dicts for one source (stable ``sourceId``)."""

    source_number: int = 1
    source_id: str = field(default_factory=lambda: f"urn:uuid:{uuid.uuid4()}")
    lens: LensInfo = field(default_factory=LensInfo)
    tracker_make: str = "StudioTrack"
    tracker_model: str = "StudioTrack optical tracker"

    def build(self, s: SampleInputs) -> dict[str, Any]:
        p = s.pose
        vals = (p.x_m, p.y_m, p.z_m, p.pan_deg, p.tilt_deg, p.roll_deg)
        if not all(math.isfinite(v) for v in vals):
            raise OpenTrackIOError(f"OpenTrackIO pose has a non-finite value: {vals}")
        ts = max(0.0, s.timestamp_s)
        seconds = math.floor(ts)
        nanos = min(round((ts - seconds) * 1e9), 999_999_999)
        static: dict[str, Any] = {
            "tracker": {"make": self.tracker_make, "model": self.tracker_model}
        }
        intr = s.lens.intrinsics if s.lens is not None else s.intrinsics
        sensor_w = s.lens.sensor_width_mm if s.lens is not None else self.lens.sensor_width_mm
        if intr is not None:
            static["camera"] = {
                "activeSensorResolution": {"width": intr.width, "height": intr.height},
                "activeSensorPhysicalDimensions": {
                    "width": sensor_w, "height": sensor_w * intr.height / intr.width,
                },
            }
        sample: dict[str, Any] = {
            "protocol": {"name": PROTOCOL_NAME, "version": list(PROTOCOL_VERSION)},
            "sampleId": f"urn:uuid:{uuid.uuid4()}",
            "sourceId": self.source_id,
            "sourceNumber": self.source_number,
            "static": static,
            "tracker": {"status": s.status or "UNKNOWN", "recording": bool(s.recording)},
            "timing": {
                "mode": "internal",
                "sampleRate": _rational(s.sample_rate_hz),
                "sampleTimestamp": {"seconds": seconds, "nanoseconds": nanos},
                "sequenceNumber": int(s.sequence_number) & 0xFFFFFFFF,
            },
            "transforms": [
                {
                    "id": s.transform_id,
                    "translation": {"x": p.x_m, "y": p.y_m, "z": p.z_m},
                    "rotation": {"pan": p.pan_deg, "tilt": p.tilt_deg, "roll": p.roll_deg},
                }
            ],
        }
        if s.timecode is not None:
            sample["timing"]["timecode"] = s.timecode.to_opentrackio()
        lens = lens_block(s.intrinsics, self.lens, s.lens)
        if lens:
            sample["lens"] = lens
        return sample


def encode_payload(sample: Mapping[str, Any], encoding: str) -> bytes:
    """Serialise a sample dict as compact JSON (UTF-8) or CBOR."""
    if encoding_byte(encoding) == ENCODING_JSON:
        return json.dumps(sample, separators=(",", ":"), allow_nan=False).encode("utf-8")
    import cbor2

    return bytes(cbor2.dumps(sample))


# --------------------------------------------------------------------------------------------
# Datagrams


def build_packets(
    payload: bytes, sequence: int, encoding: str, max_segment: int = MAX_SEGMENT_PAYLOAD
) -> list[bytes]:
    """Header + payload datagrams; payloads above ``max_segment`` bytes are segmented."""
    if not 1 <= max_segment <= _LEN_MASK:
        raise OpenTrackIOError(f"segment size {max_segment} is outside 1..{_LEN_MASK}")
    if len(payload) > 0xFFFFFFFF:
        raise OpenTrackIOError(f"payload of {len(payload)} bytes is too large")
    enc = encoding_byte(encoding)
    seq = sequence & 0xFFFF
    packets = []
    offsets = range(0, max(len(payload), 1), max_segment)
    for off in offsets:
        seg = payload[off : off + max_segment]
        last = off + max_segment >= len(payload)
        flag_len = (_LAST_FLAG if last else 0) | len(seg)
        head = IDENTIFIER + struct.pack(">BBHIH", 0, enc, seq, off, flag_len)
        packets.append(head + struct.pack(">H", fletcher16_mod256(head + seg)) + seg)
    return packets


@dataclass(frozen=True, slots=True)
class Header:
    encoding: int
    sequence: int
    segment_offset: int
    last_segment: bool
    payload_length: int
    checksum: int


def parse_packet(packet: bytes) -> tuple[Header, bytes]:
    """Check and split one datagram; raises :class:`OpenTrackIOError` on any defect."""
    if not isinstance(packet, bytes | bytearray | memoryview):
        raise OpenTrackIOError(f"packet must be bytes, got {type(packet).__name__}")
    packet = bytes(packet)
    if len(packet) < HEADER_LENGTH:
        raise OpenTrackIOError(f"packet of {len(packet)} bytes is shorter than the header")
    if packet[:4] != IDENTIFIER:
        raise OpenTrackIOError(f"packet identifier {packet[:4]!r} is not b'OTrk'")
    _res, enc, seq, off, flag_len, csum = struct.unpack(">BBHIHH", packet[4:16])
    if enc not in (ENCODING_JSON, ENCODING_CBOR):
        raise OpenTrackIOError(f"packet encoding 0x{enc:02X} is not JSON (1) or CBOR (2)")
    length = flag_len & _LEN_MASK
    payload = packet[HEADER_LENGTH:]
    if len(payload) != length:
        raise OpenTrackIOError(f"header says {length} payload bytes, packet has {len(payload)}")
    want = fletcher16_mod256(packet[:14] + payload)
    if csum != want:
        raise OpenTrackIOError(f"packet checksum 0x{csum:04X} != expected 0x{want:04X}")
    return Header(enc, seq, off, bool(flag_len & _LAST_FLAG), length, csum), payload


def decode_payload(payload: bytes, encoding: int) -> dict[str, Any]:
    """JSON/CBOR payload to a sample dict; malformed data raises :class:`OpenTrackIOError`."""
    try:
        if encoding == ENCODING_JSON:
            obj = json.loads(payload.decode("utf-8"))
        elif encoding == ENCODING_CBOR:
            import cbor2

            obj = cbor2.loads(payload)
        else:
            raise OpenTrackIOError(f"unknown encoding 0x{encoding:02X}")
    except OpenTrackIOError:
        raise
    except (ValueError, UnicodeDecodeError, RecursionError, MemoryError) as exc:
        raise OpenTrackIOError(f"payload is not valid: {type(exc).__name__}: {exc}") from None
    except Exception as exc:  # cbor2 raises its own decode errors (CBORDecodeError etc.)
        raise OpenTrackIOError(f"payload is not valid: {type(exc).__name__}: {exc}") from None
    if not isinstance(obj, dict):
        raise OpenTrackIOError(f"payload decodes to {type(obj).__name__}, not an object")
    return obj


class Reassembler:
    """Collects segments per sequence number and returns complete samples.

    At most ``max_pending`` incomplete samples are kept (oldest dropped) and each one holds
    at most ``max_bytes`` of segment data (counted as received: overlapping or repeated
    segments count every time, so a hostile stream cannot make one sample hold more); a
    segment that would exceed it drops that sample and raises. Memory stays below
    ``max_pending * max_bytes`` whatever arrives. :attr:`dropped` counts abandoned samples.
    """

    def __init__(self, max_pending: int = 8, max_bytes: int = 1 << 20) -> None:
        self._pending: dict[tuple[int, int], dict[int, bytes]] = {}
        self._held: dict[tuple[int, int], int] = {}
        self._total: dict[tuple[int, int], int] = {}
        self.max_pending = max_pending
        self.max_bytes = max_bytes
        self.dropped = 0

    @property
    def held_bytes(self) -> int:
        """Segment bytes held for incomplete samples now (all of them together)."""
        return sum(len(seg) for parts in self._pending.values() for seg in parts.values())

    def _drop(self, key: tuple[int, int]) -> None:
        if self._pending.pop(key, None) is not None:
            self.dropped += 1
        self._held.pop(key, None)
        self._total.pop(key, None)

    def feed(self, packet: bytes) -> dict[str, Any] | None:
        """Add one datagram; returns the decoded sample when it completes one."""
        head, seg = parse_packet(packet)
        key = (head.sequence, head.encoding)
        if head.segment_offset == 0 and head.last_segment:
            self._drop(key)
            return decode_payload(seg, head.encoding)
        end = head.segment_offset + len(seg)
        held = self._held.get(key, 0) + len(seg)
        if end > self.max_bytes or held > self.max_bytes:
            self._drop(key)
            raise OpenTrackIOError(
                f"sample #{head.sequence}: segments exceed the {self.max_bytes}-byte limit "
                f"(segment end {end}, {held} bytes received); sample dropped"
            )
        parts = self._pending.setdefault(key, {})
        parts[head.segment_offset] = seg
        self._held[key] = held
        if head.last_segment:
            self._total[key] = end
        while len(self._pending) > self.max_pending:
            self._drop(next(iter(self._pending)))
        total = self._total.get(key)
        if total is None or key not in self._pending:
            return None
        buf = bytearray()
        for off in sorted(parts):
            if off != len(buf):
                return None  # gap (or overlap): wait for the missing segment
            buf += parts[off]
        if len(buf) != total:
            return None
        self._pending.pop(key, None)
        self._held.pop(key, None)
        self._total.pop(key, None)
        return decode_payload(bytes(buf), head.encoding)


@dataclass(frozen=True, slots=True)
class DecodedPose:
    """The camera transform and status of a received sample (what ``listen`` prints)."""

    sequence_number: int | None
    status: str
    x_m: float
    y_m: float
    z_m: float
    pan_deg: float
    tilt_deg: float
    roll_deg: float


def sample_pose(sample: Mapping[str, Any]) -> DecodedPose:
    """The last transform of a decoded sample, every number validated (finite, in range);
    a malformed sample (``transforms`` not a list of objects, a value that is no number,
    ``1e400``, a 400-digit integer) raises :class:`OpenTrackIOError`."""
    from engine.validate import number

    transforms = sample.get("transforms", [])
    if not isinstance(transforms, list) or not all(isinstance(t, dict) for t in transforms):
        raise OpenTrackIOError("'transforms' must be a list of objects")
    tr = transforms[-1] if transforms else {}
    t, r = tr.get("translation", {}), tr.get("rotation", {})
    if not isinstance(t, dict) or not isinstance(r, dict):
        raise OpenTrackIOError("transform 'translation'/'rotation' must be objects")
    timing = sample.get("timing", {})
    tracker = sample.get("tracker", {})
    if not isinstance(timing, dict) or not isinstance(tracker, dict):
        raise OpenTrackIOError("'timing'/'tracker' must be objects")
    seq = timing.get("sequenceNumber")

    def num(d: Mapping[str, Any], key: str, where: str) -> float:
        return number(d.get(key, 0.0), f"{where}.{key}", lo=-1e9, hi=1e9,
                      error=OpenTrackIOError)

    return DecodedPose(
        sequence_number=None if seq is None else number(
            seq, "timing.sequenceNumber", integer=True, lo=0, hi=2**32,
            error=OpenTrackIOError),
        status=str(tracker.get("status", ""))[:40],
        x_m=num(t, "x", "translation"), y_m=num(t, "y", "translation"),
        z_m=num(t, "z", "translation"),
        pan_deg=num(r, "pan", "rotation"), tilt_deg=num(r, "tilt", "rotation"),
        roll_deg=num(r, "roll", "rotation"),
    )


def decode_datagrams(packets: Sequence[bytes]) -> list[dict[str, Any]]:
    """Decode a list of datagrams (in any order within a sample) into samples."""
    r = Reassembler()
    out = []
    for p in packets:
        s = r.feed(p)
        if s is not None:
            out.append(s)
    return out
