"""FreeD D1 camera position/orientation packets (Vinten free-d manual V1.4.4, A.3.2 and App. B).

A D1 message is 29 bytes, big-endian::

    offset  size  field
    0       1     message type 0xD1
    1       1     camera id
    2       3     pan   signed 24-bit, 1/32768 degree (positive = pan RIGHT, clockwise from above)
    5       3     tilt  signed 24-bit, 1/32768 degree (positive = up)
    8       3     roll  signed 24-bit, 1/32768 degree (positive = clockwise seen from behind)
    11      3     X     signed 24-bit, 1/64 mm
    14      3     Y     signed 24-bit, 1/64 mm
    17      3     Z     signed 24-bit, 1/64 mm (height, up positive)
    20      3     zoom  unsigned 24-bit (lens encoder or mapped focal length)
    23      3     focus unsigned 24-bit
    26      2     spare / user defined
    28      1     checksum = (0x40 - sum(bytes 0..27)) mod 256

Axes (App. B.1): right-handed X, Y horizontal, Z up; pan = tilt = 0 looks along +Y.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from engine.outputs import OutputError

D1_TYPE = 0xD1
D1_LENGTH = 29
ANGLE_SCALE = 32768.0  # units per degree
POSITION_SCALE = 64.0  # units per millimetre
_S24_MIN = -(1 << 23)
_S24_MAX = (1 << 23) - 1
_U24_MAX = (1 << 24) - 1


class FreeDError(OutputError):
    """A FreeD packet is malformed (length, type, checksum) or a value does not fit."""


class ZoomFocusMapping(enum.Enum):
    """How zoom/focus fields are filled.

    RAW sends the operator's raw integers; MM_X100 / MM_X64 send focal length (zoom) and
    focus distance (focus) in millimetres times 100 / times 64, which is what many render
    engines' FreeD inputs expect when no lens encoder is fitted.
    """

    RAW = "raw"
    MM_X100 = "mm100"
    MM_X64 = "mm64"


@dataclass(frozen=True, slots=True)
class FreeDPose:
    """The decoded content of one D1 message (FreeD units and sign conventions)."""

    camera_id: int
    pan_deg: float
    tilt_deg: float
    roll_deg: float
    x_mm: float
    y_mm: float
    z_mm: float
    zoom: int
    focus: int
    spare: int = 0

    def __post_init__(self) -> None:
        if not 0 <= self.camera_id <= 255:
            raise FreeDError(f"FreeD camera id {self.camera_id} is outside 0..255")
        for name in ("zoom", "focus"):
            v = getattr(self, name)
            if not 0 <= v <= _U24_MAX:
                raise FreeDError(f"FreeD {name} {v} is outside 0..{_U24_MAX}")
        if not 0 <= self.spare <= 0xFFFF:
            raise FreeDError(f"FreeD spare field {self.spare} is outside 0..65535")


def checksum(first_28: bytes) -> int:
    """(0x40 - sum of bytes 0..27) mod 256."""
    return (0x40 - sum(first_28)) % 256


def _s24(value: float, scale: float, name: str) -> bytes:
    if not math.isfinite(value):
        raise FreeDError(f"FreeD {name} is not finite ({value})")
    raw = round(value * scale)
    if not _S24_MIN <= raw <= _S24_MAX:
        raise FreeDError(f"FreeD {name} {value} does not fit a signed 24-bit field")
    return (raw & 0xFFFFFF).to_bytes(3, "big")


def _read_s24(b: bytes) -> int:
    v = int.from_bytes(b, "big")
    return v - (1 << 24) if v & 0x800000 else v


def wrap_deg(a: float) -> float:
    """Angle wrapped to [-180, 180)."""
    return (a + 180.0) % 360.0 - 180.0


def encode_d1(pose: FreeDPose) -> bytes:
    """29-byte D1 message of ``pose``; ``encode_d1(decode_d1(b)) == b`` for every valid ``b``.

    Angles are written as given (callers wrap them, see :func:`wrap_deg`) so that any
    decoded packet re-encodes byte for byte.
    """
    body = bytearray([D1_TYPE, pose.camera_id])
    body += _s24(pose.pan_deg, ANGLE_SCALE, "pan")
    body += _s24(pose.tilt_deg, ANGLE_SCALE, "tilt")
    body += _s24(pose.roll_deg, ANGLE_SCALE, "roll")
    body += _s24(pose.x_mm, POSITION_SCALE, "X")
    body += _s24(pose.y_mm, POSITION_SCALE, "Y")
    body += _s24(pose.z_mm, POSITION_SCALE, "Z")
    body += pose.zoom.to_bytes(3, "big")
    body += pose.focus.to_bytes(3, "big")
    body += pose.spare.to_bytes(2, "big")
    body.append(checksum(bytes(body)))
    return bytes(body)


def decode_d1(data: bytes) -> FreeDPose:
    """Decode one D1 message; wrong length, type or checksum raises :class:`FreeDError`."""
    if not isinstance(data, bytes | bytearray | memoryview):
        raise FreeDError(f"FreeD packet must be bytes, got {type(data).__name__}")
    data = bytes(data)
    if len(data) != D1_LENGTH:
        raise FreeDError(f"FreeD D1 packet must be {D1_LENGTH} bytes, got {len(data)}")
    if data[0] != D1_TYPE:
        raise FreeDError(f"FreeD message type 0x{data[0]:02X} is not D1")
    want = checksum(data[:28])
    if data[28] != want:
        raise FreeDError(f"FreeD checksum 0x{data[28]:02X} != expected 0x{want:02X}")
    return FreeDPose(
        camera_id=data[1],
        pan_deg=_read_s24(data[2:5]) / ANGLE_SCALE,
        tilt_deg=_read_s24(data[5:8]) / ANGLE_SCALE,
        roll_deg=_read_s24(data[8:11]) / ANGLE_SCALE,
        x_mm=_read_s24(data[11:14]) / POSITION_SCALE,
        y_mm=_read_s24(data[14:17]) / POSITION_SCALE,
        z_mm=_read_s24(data[17:20]) / POSITION_SCALE,
        zoom=int.from_bytes(data[20:23], "big"),
        focus=int.from_bytes(data[23:26], "big"),
        spare=int.from_bytes(data[26:28], "big"),
    )


def lens_field(mapping: ZoomFocusMapping, raw: int, value_mm: float | None) -> int:
    """Zoom/focus field: ``raw`` for RAW, else ``value_mm`` x100 or x64, clamped to 24 bits."""
    if mapping is ZoomFocusMapping.RAW or value_mm is None or not math.isfinite(value_mm):
        v = raw
    elif mapping is ZoomFocusMapping.MM_X100:
        v = round(value_mm * 100.0)
    else:
        v = round(value_mm * 64.0)
    return min(max(int(v), 0), _U24_MAX)


def lens_value_mm(mapping: ZoomFocusMapping, field_value: int) -> float | None:
    """Inverse of :func:`lens_field` (None for RAW)."""
    if mapping is ZoomFocusMapping.MM_X100:
        return field_value / 100.0
    if mapping is ZoomFocusMapping.MM_X64:
        return field_value / 64.0
    return None
