"""VISCA over IP: the byte protocol of Sony (and Panasonic, BirdDog...) PTZ cameras.

A small codec from the protocol description (Sony SRG-300H / EVI-D100 technical manuals);
the ``visca-over-ip`` package on the registry was looked at and not used: it binds its
sockets to every interface on the fixed port 52381 (our rule is 127.0.0.1 unless the
operator chooses; a loopback camera simulator needs that port), it blocks the caller for up
to five 0.1 s retries per command and prints to stdout.

Message (UDP, port 52381), big-endian::

    offset  size  field
    0       2     payload type: 0x0100 VISCA command, 0x0110 VISCA inquiry,
                  0x0111 VISCA reply, 0x0120 device setting, 0x0200 control command,
                  0x0201 control reply
    2       2     payload length (1..16)
    4       4     sequence number (the controller counts up, wraps to 0; replies echo it)
    8       n     payload

VISCA payloads (camera address 1 over IP: ``8x`` = 0x81 from the controller, replies from
0x90; ``FF`` terminates)::

    Pan-tiltDrive AbsolutePosition  81 01 06 02 VV WW 0Y 0Y 0Y 0Y 0Z 0Z 0Z 0Z FF
                                    (VV pan speed 01-18, WW tilt speed 01-14, YYYY pan and
                                    ZZZZ tilt position: signed 16-bit, one nibble a byte)
    PanTiltPosInq                   81 09 06 12 FF -> 90 50 0Y 0Y 0Y 0Y 0Z 0Z 0Z 0Z FF
    CAM_Zoom Direct                 81 01 04 47 0p 0q 0r 0s FF
    CAM_ZoomPosInq / FocusPosInq    81 09 04 47 FF / 81 09 04 48 FF -> 90 50 0p 0q 0r 0s FF
    replies                         ACK 90 41 FF, completion 90 51 FF,
                                    error 90 6y EE FF (02 syntax, 03 buffer full,
                                    04 cancelled, 05 no socket, 41 not executable)
    control RESET                   payload 01 (type 0x0200) -> control reply 01

Positions: Sony's pan/tilt unit is 1/14.4 degree on the EVI-D100 (FA60h = -100 deg) and the
SRG series; pan counts grow to the RIGHT, tilt counts UP. Our motor pan grows to the LEFT
(:mod:`engine.ptz.kinematics`), so :class:`ViscaUnits` converts with the sign.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from engine.errors import StudioTrackError

VISCA_PORT = 52381
COMMAND = 0x0100
INQUIRY = 0x0110
REPLY = 0x0111
DEVICE_SETTING = 0x0120
CONTROL = 0x0200
CONTROL_REPLY = 0x0201
PAYLOAD_TYPES = (COMMAND, INQUIRY, REPLY, DEVICE_SETTING, CONTROL, CONTROL_REPLY)
HEADER = 8
MAX_PAYLOAD = 16
SEQ_MAX = 0xFFFFFFFF

ERROR_NAMES = {0x01: "message length error", 0x02: "syntax error", 0x03: "command buffer full",
               0x04: "command cancelled", 0x05: "no socket", 0x41: "command not executable"}
PAN_SPEED_MAX = 0x18
TILT_SPEED_MAX = 0x14


class ViscaError(StudioTrackError):
    """A VISCA message is malformed, or a camera refused or did not answer a command."""


@dataclass(frozen=True, slots=True)
class ViscaMessage:
    payload_type: int
    sequence: int
    payload: bytes


def encode_message(msg: ViscaMessage) -> bytes:
    if msg.payload_type not in PAYLOAD_TYPES:
        raise ViscaError(f"VISCA payload type 0x{msg.payload_type:04X} is unknown")
    if not 1 <= len(msg.payload) <= MAX_PAYLOAD:
        raise ViscaError(f"VISCA payload of {len(msg.payload)} bytes is outside 1..16")
    if not 0 <= msg.sequence <= SEQ_MAX:
        raise ViscaError(f"VISCA sequence number {msg.sequence} is outside 0..2^32-1")
    return struct.pack(">HHI", msg.payload_type, len(msg.payload), msg.sequence) + msg.payload


def decode_message(data: bytes) -> ViscaMessage:
    """Check and split one datagram; anything malformed raises :class:`ViscaError`."""
    data = bytes(data)
    if len(data) < HEADER + 1:
        raise ViscaError(f"VISCA datagram of {len(data)} bytes is shorter than header+1")
    ptype, length, seq = struct.unpack(">HHI", data[:HEADER])
    if ptype not in PAYLOAD_TYPES:
        raise ViscaError(f"VISCA payload type 0x{ptype:04X} is unknown")
    payload = data[HEADER:]
    if length != len(payload) or not 1 <= length <= MAX_PAYLOAD:
        raise ViscaError(f"VISCA header says {length} payload bytes, datagram has "
                         f"{len(payload)}")
    if ptype in (COMMAND, INQUIRY, REPLY, DEVICE_SETTING) and payload[-1] != 0xFF:
        raise ViscaError(f"VISCA payload does not end with FF: {payload.hex(' ')}")
    return ViscaMessage(ptype, seq, payload)


# --------------------------------------------------------------------------- nibbles
def to_nibbles(value: int, n: int = 4, signed: bool = True) -> bytes:
    """``value`` as ``n`` bytes 0x0h (most significant first); signed = two's complement."""
    bits = 4 * n
    lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
    if not lo <= value <= hi:
        raise ViscaError(f"VISCA value {value} does not fit {n} nibbles")
    v = value & ((1 << bits) - 1)
    return bytes((v >> (4 * (n - 1 - i))) & 0x0F for i in range(n))


def from_nibbles(b: bytes, signed: bool = True) -> int:
    if any(x & 0xF0 for x in b):
        raise ViscaError(f"VISCA nibble bytes {b.hex(' ')} have high bits set")
    v = 0
    for x in b:
        v = (v << 4) | x
    bits = 4 * len(b)
    if signed and v & (1 << (bits - 1)):
        v -= 1 << bits
    return v


# ------------------------------------------------------------------ controller payloads
def pan_tilt_absolute(pan_counts: int, tilt_counts: int, pan_speed: int = PAN_SPEED_MAX,
                      tilt_speed: int = TILT_SPEED_MAX) -> bytes:
    if not 1 <= pan_speed <= PAN_SPEED_MAX or not 1 <= tilt_speed <= TILT_SPEED_MAX:
        raise ViscaError(f"VISCA speeds {pan_speed}/{tilt_speed} are outside 1..24 / 1..20")
    return (bytes([0x81, 0x01, 0x06, 0x02, pan_speed, tilt_speed]) + to_nibbles(pan_counts)
            + to_nibbles(tilt_counts) + b"\xff")


PAN_TILT_POS_INQ = bytes([0x81, 0x09, 0x06, 0x12, 0xFF])
ZOOM_POS_INQ = bytes([0x81, 0x09, 0x04, 0x47, 0xFF])
FOCUS_POS_INQ = bytes([0x81, 0x09, 0x04, 0x48, 0xFF])
IF_CLEAR = bytes([0x81, 0x01, 0x00, 0x01, 0xFF])
CONTROL_RESET = b"\x01"


def zoom_direct(zoom_raw: int) -> bytes:
    return bytes([0x81, 0x01, 0x04, 0x47]) + to_nibbles(zoom_raw, signed=False) + b"\xff"


# -------------------------------------------------------------------- camera payloads
ACK = bytes([0x90, 0x41, 0xFF])
COMPLETION = bytes([0x90, 0x51, 0xFF])


def error_reply(code: int, socket_no: int = 0) -> bytes:
    return bytes([0x90, 0x60 | (socket_no & 0x0F), code & 0xFF, 0xFF])


def pan_tilt_position_reply(pan_counts: int, tilt_counts: int) -> bytes:
    return bytes([0x90, 0x50]) + to_nibbles(pan_counts) + to_nibbles(tilt_counts) + b"\xff"


def value_reply(value: int) -> bytes:
    return bytes([0x90, 0x50]) + to_nibbles(value, signed=False) + b"\xff"


@dataclass(frozen=True, slots=True)
class Reply:
    """A parsed camera reply: ``kind`` "ack" | "completion" | "error" | "data"."""

    kind: str
    data: bytes = b""
    error_code: int = 0

    @property
    def error_name(self) -> str:
        return ERROR_NAMES.get(self.error_code, f"error 0x{self.error_code:02X}")


def parse_reply(payload: bytes) -> Reply:
    p = bytes(payload)
    if len(p) < 3 or p[-1] != 0xFF or p[0] & 0xF0 != 0x90:
        raise ViscaError(f"VISCA reply {p.hex(' ')} is not 9x .. FF")
    kind = p[1] & 0xF0
    if kind == 0x40 and len(p) == 3:
        return Reply("ack")
    if kind == 0x50:
        return Reply("completion") if len(p) == 3 else Reply("data", p[2:-1])
    if kind == 0x60 and len(p) == 4:
        return Reply("error", error_code=p[2])
    raise ViscaError(f"VISCA reply {p.hex(' ')} is not an ACK, completion, error or data")


def parse_pan_tilt(data: bytes) -> tuple[int, int]:
    if len(data) != 8:
        raise ViscaError(f"VISCA pan-tilt position has {len(data)} nibbles, expected 8")
    return from_nibbles(data[:4]), from_nibbles(data[4:])


# ----------------------------------------------------------------- camera-side parsing
@dataclass(frozen=True, slots=True)
class PanTiltAbsolute:
    pan_counts: int
    tilt_counts: int
    pan_speed: int
    tilt_speed: int


@dataclass(frozen=True, slots=True)
class ZoomDirect:
    zoom_raw: int


def parse_command(payload: bytes) -> PanTiltAbsolute | ZoomDirect | str:
    """What a controller's command/inquiry payload asks (camera side): a command record or
    the inquiry's name ("pan_tilt_pos", "zoom_pos", "focus_pos", "if_clear")."""
    p = bytes(payload)
    if len(p) < 3 or p[0] != 0x81 or p[-1] != 0xFF:
        raise ViscaError(f"VISCA command {p.hex(' ')} is not 81 .. FF")
    if p == PAN_TILT_POS_INQ:
        return "pan_tilt_pos"
    if p == ZOOM_POS_INQ:
        return "zoom_pos"
    if p == FOCUS_POS_INQ:
        return "focus_pos"
    if p == IF_CLEAR:
        return "if_clear"
    if p[1:4] == b"\x01\x06\x02" and len(p) == 15:
        return PanTiltAbsolute(from_nibbles(p[6:10]), from_nibbles(p[10:14]), p[4], p[5])
    if p[1:4] == b"\x01\x04\x47" and len(p) == 9:
        return ZoomDirect(from_nibbles(p[4:8], signed=False))
    raise ViscaError(f"VISCA command {p.hex(' ')} is not supported")


@dataclass(frozen=True, slots=True)
class ViscaUnits:
    """Position counts per degree and direction (Sony: pan counts grow to the right)."""

    pan_counts_per_deg: float = 14.4
    tilt_counts_per_deg: float = 14.4
    pan_right_positive: bool = True

    def pan_counts(self, motor_pan_deg: float) -> int:
        s = -1.0 if self.pan_right_positive else 1.0  # motor pan grows to the left
        return round(s * motor_pan_deg * self.pan_counts_per_deg)

    def tilt_counts(self, motor_tilt_deg: float) -> int:
        return round(motor_tilt_deg * self.tilt_counts_per_deg)

    def pan_deg(self, counts: int) -> float:
        s = -1.0 if self.pan_right_positive else 1.0
        return s * counts / self.pan_counts_per_deg

    def tilt_deg(self, counts: int) -> float:
        return counts / self.tilt_counts_per_deg
