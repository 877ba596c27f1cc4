"""SMPTE timecode on every record: parsed, validated, generated, and carried to the outputs.

The arithmetic (frame counts, drop-frame numbering) is the maintained ``timecode`` library's;
this module adds what the air path needs around it:

- :class:`Timecode`: a frozen value (hours, minutes, seconds, frames, rate) that crosses
  threads, with ``str()`` in SMPTE notation (``01:00:00:00``, drop frame ``00:01:00;02``) and
  the OpenTrackIO ``timing.timecode`` object (:meth:`Timecode.to_opentrackio`);
- :func:`parse_timecode`: strict parsing with one-line errors naming the field (hours
  0-23, minutes/seconds 0-59, frames below the rate, drop-frame labels that do not exist);
- :class:`SourceTimecode`: the frame payload of a source that has its own timecode (a
  recording, a tracker input); :class:`TimecodeClock`: the record's timecode, the source's
  where it has one, otherwise generated from a start value and the output rate: frame ``n``
  frames of the rate after the first frame's media time gets ``start + n``.

Rates (``TIMECODE_RATES``): 23.976, 24, 25, 29.97 (drop frame), 30, 50, 59.94 (drop frame),
60. 23.976 counts 24 labels per second without dropping (as SMPTE ST 12-1 does).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

from engine.errors import StudioTrackError
from engine.frames import Frame, FramePayload

#: the broadcast rates timecode runs at (names as the operator types them)
TIMECODE_RATES = ("23.976", "24", "25", "29.97", "30", "50", "59.94", "60")
#: exact frame rates as rationals (num, den)
RATE_RATIONALS: dict[str, tuple[int, int]] = {
    "23.976": (24000, 1001), "24": (24, 1), "25": (25, 1), "29.97": (30000, 1001),
    "30": (30, 1), "50": (50, 1), "59.94": (60000, 1001), "60": (60, 1),
}
#: labels per second (the frames field runs 0 .. labels - 1)
_LABELS = {"23.976": 24, "24": 24, "25": 25, "29.97": 30, "30": 30, "50": 50, "59.94": 60,
           "60": 60}
_DROP = {"29.97": 2, "59.94": 4}  # labels dropped at each minute except every tenth
_TC = re.compile(r"^(\d{1,2})[:;.](\d{1,2})[:;.](\d{1,2})([:;.])(\d{1,3})$")


class TimecodeError(StudioTrackError):
    """A timecode string or rate is malformed (one line naming the field)."""


def parse_rate(text: str | float, where: str = "timecode rate") -> str:
    """The rate name of ``text`` (``"29.97"``, ``29.97``, ``"30000/1001"``, ``"25"``...)."""
    s = str(text).strip().lower().removesuffix("df").removesuffix("fps").strip()
    if "/" in s:
        num_s, _, den_s = s.partition("/")
        try:
            value = int(num_s) / int(den_s)
        except (ValueError, ZeroDivisionError):
            raise TimecodeError(f"{where} {text!r} is not a rate") from None
    else:
        try:
            value = float(s)
        except ValueError:
            raise TimecodeError(f"{where} {text!r} is not one of "
                                f"{', '.join(TIMECODE_RATES)}") from None
    for name, (n, d) in RATE_RATIONALS.items():
        if math.isfinite(value) and abs(value - n / d) < 5e-3:
            return name
    raise TimecodeError(f"{where} {text!r} is not one of {', '.join(TIMECODE_RATES)}")


def nearest_rate(fps: float) -> str:
    """The timecode rate nearest to a source's frame rate (30 when it has none)."""
    if not math.isfinite(fps) or fps <= 0:
        return "30"
    return min(TIMECODE_RATES, key=lambda r: abs(RATE_RATIONALS[r][0] / RATE_RATIONALS[r][1]
                                                 - fps))


def _lib(rate: str, text: str | None = None, frames: int | None = None) -> Any:
    from timecode.timecode import Timecode as LibTimecode

    if frames is not None:
        return LibTimecode(rate, frames=frames)
    return LibTimecode(rate, text)


@dataclass(frozen=True, slots=True)
class Timecode:
    """One SMPTE timecode label at a rate (validated; see :func:`parse_timecode`)."""

    hours: int
    minutes: int
    seconds: int
    frames: int
    rate: str = "25"

    def __post_init__(self) -> None:
        _check_fields(self.hours, self.minutes, self.seconds, self.frames, self.rate,
                      "timecode")

    @property
    def drop_frame(self) -> bool:
        return self.rate in _DROP

    @property
    def rate_rational(self) -> tuple[int, int]:
        return RATE_RATIONALS[self.rate]

    @property
    def rate_hz(self) -> float:
        n, d = self.rate_rational
        return n / d

    def __str__(self) -> str:
        sep = ";" if self.drop_frame else ":"
        return f"{self.hours:02d}:{self.minutes:02d}:{self.seconds:02d}{sep}{self.frames:02d}"

    @property
    def frame_number(self) -> int:
        """Frames since 00:00:00:00 (drop-frame labels skipped), by the timecode library."""
        return int(_lib(self.rate, str(self)).frames) - 1

    @staticmethod
    def from_frame_number(n: int, rate: str) -> Timecode:
        """The label ``n`` frames after midnight (wrapping at 24 h)."""
        rate = parse_rate(rate)
        per_day = _frames_per_day(rate)
        lib = _lib(rate, frames=int(n) % per_day + 1)
        return Timecode(int(lib.hrs), int(lib.mins), int(lib.secs), int(lib.frs), rate)

    def plus(self, frames: int) -> Timecode:
        """The label ``frames`` frames later (or earlier when negative), wrapping at 24 h."""
        return Timecode.from_frame_number(self.frame_number + int(frames), self.rate)

    def to_opentrackio(self) -> dict[str, Any]:
        """OpenTrackIO ``timing.timecode`` (hours, minutes, seconds, frames, frameRate,
        dropFrame)."""
        n, d = self.rate_rational
        return {"hours": self.hours, "minutes": self.minutes, "seconds": self.seconds,
                "frames": self.frames, "frameRate": {"num": n, "denom": d},
                "dropFrame": self.drop_frame}

    def to_json(self) -> dict[str, Any]:
        return {"timecode": str(self), "rate": self.rate}


def _frames_per_day(rate: str) -> int:
    labels = _LABELS[rate]
    drop = _DROP.get(rate, 0)
    return 24 * 3600 * labels - 24 * (60 - 6) * drop


def _check_fields(h: int, m: int, s: int, f: int, rate: str, where: str) -> None:
    if rate not in RATE_RATIONALS:
        raise TimecodeError(f"{where}: rate {rate!r} is not one of {', '.join(TIMECODE_RATES)}")
    for name, v, hi in (("hours", h, 23), ("minutes", m, 59), ("seconds", s, 59),
                        ("frames", f, _LABELS[rate] - 1)):
        if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= hi:
            raise TimecodeError(f"{where}: {name} {v!r} is outside 0..{hi} at {rate} fps")
    drop = _DROP.get(rate, 0)
    if drop and s == 0 and m % 10 != 0 and f < drop:
        raise TimecodeError(
            f"{where}: {h:02d}:{m:02d}:{s:02d};{f:02d} does not exist at {rate} drop frame "
            f"(labels 00-{drop - 1:02d} are dropped at minutes not divisible by 10)"
        )


def parse_timecode(text: str, rate: str | float = "25", where: str = "timecode") -> Timecode:
    """``"HH:MM:SS:FF"`` (``;`` or ``.`` before the frames allowed) at ``rate``.

    One-line :class:`TimecodeError` naming ``where`` for anything malformed."""
    rate_name = parse_rate(rate, f"{where} rate")
    m = _TC.match(str(text).strip())
    if not m:
        raise TimecodeError(f"{where} {text!r} is not HH:MM:SS:FF")
    h, mi, s, _sep, f = m.groups()
    _check_fields(int(h), int(mi), int(s), int(f), rate_name, f"{where} {text!r}")
    return Timecode(int(h), int(mi), int(s), int(f), rate_name)


@dataclass(frozen=True, slots=True)
class SourceTimecode(FramePayload):
    """A source's own timecode for the frame (a recording, a tracking input with timecode)."""

    timecode: Timecode


class TimecodeClock:
    """The timecode of each record: the source's, else ``start`` + frames at the rate.

    Generated labels count the frames of the rate elapsed since the first frame's media time
    (``frame.timestamp_s``), so a tracker slower than the video rate gets the label of the
    video frame its picture belongs to, and a clocked output that holds a pose counts on.
    """

    def __init__(self, start: Timecode | None = None, rate: str | None = None) -> None:
        rate_name = parse_rate(rate) if rate is not None else (start.rate if start else "25")
        if start is None:
            start = Timecode(0, 0, 0, 0, rate_name)
        elif start.rate != rate_name:
            start = Timecode.from_frame_number(
                round(start.frame_number * RATE_RATIONALS[rate_name][0]
                      * RATE_RATIONALS[start.rate][1]
                      / (RATE_RATIONALS[rate_name][1] * RATE_RATIONALS[start.rate][0])),
                rate_name)
        self.start = start
        self.rate = rate_name
        self._start_frame = start.frame_number
        self._t0: float | None = None

    def reset(self) -> None:
        self._t0 = None

    def stamp(self, frame: Frame) -> Timecode:
        src = frame.payload(SourceTimecode)
        if src is not None:
            return src.timecode
        t = float(frame.timestamp_s)
        if self._t0 is None or not math.isfinite(t) or t < self._t0:
            self._t0 = t if math.isfinite(t) else 0.0
        n, d = RATE_RATIONALS[self.rate]
        elapsed = round((t - self._t0) * n / d) if math.isfinite(t) else 0
        return Timecode.from_frame_number(self._start_frame + elapsed, self.rate)
