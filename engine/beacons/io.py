"""Beacon layouts and range inputs: layout JSON/CSV, CSV range logs, live UDP readings.

Layout JSON (version 1)::

    {"version": 1, "beacons": [{"id": "A", "x_m": 10.0, "y_m": 10.0}, ...]}

Layout CSV: ``id,x_m,y_m`` per line (a header line and ``#`` comments are allowed).

Range log CSV: one reading per line, ``timestamp, beacon_id, range_m`` (seconds, text id,
metres); a header line and ``#`` comments are allowed. Readings with the same timestamp (or
within ``window_s`` of the first reading of a step) form one time step. Malformed lines,
unknown beacon ids (when a layout is given), duplicate readings of a beacon within a step and
readings older than the previous step are counted in :class:`InputStats` and skipped; they
never raise.

Live UDP (bound to 127.0.0.1 by default): one JSON object per datagram, one time step::

    {"timestamp_s": 12.345, "ranges_m": {"A": 14.1, "B": 21.7}}

optionally with ``"gt_xy": [x, y]`` (ground truth, for simulators). ``timestamp_s`` (the
sender's clock) may be left out: the source then stamps readings with their receive time.
Readings of beacons not in the step are treated as missing. Malformed datagrams / readings
are counted the same way.
"""

from __future__ import annotations

import csv
import io
import json
import math
import socket
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from engine.errors import SourceError
from engine.persist import atomic_write_json, atomic_write_text
from engine.validate import number

LAYOUT_VERSION = 1
#: beacon positions, ranges and timestamps accepted from files and datagrams
POSITION_MAX_M = 1e6
RANGE_MAX_M = 1e6
TIMESTAMP_MAX_S = 1e12
_POS: dict[str, Any] = {"lo": -POSITION_MAX_M, "hi": POSITION_MAX_M, "error": SourceError}


# ---------------------------------------------------------------------------- layouts
def load_layout(path: str | Path) -> dict[str, tuple[float, float]]:
    """Read a beacon layout from ``.json`` or ``.csv``; SourceError names the problem."""
    p = Path(path).expanduser()
    if not p.is_file():
        raise SourceError(f"{p}: beacon layout file not found")
    text = p.read_text(encoding="utf-8", errors="replace")
    if p.suffix.lower() == ".json":
        try:
            obj = json.loads(text)
            items = obj["beacons"]
            layout = {
                str(b["id"]): (number(b["x_m"], f"{p}: beacon {b['id']!r} x_m", **_POS),
                               number(b["y_m"], f"{p}: beacon {b['id']!r} y_m", **_POS))
                for b in items
            }
            version = number(obj.get("version", LAYOUT_VERSION), f"{p}: 'version'",
                             integer=True, lo=0, hi=10**6, error=SourceError)
        except (ValueError, KeyError, TypeError, RecursionError) as exc:
            raise SourceError(f"{p}: not a beacon layout JSON ({exc!s})") from None
        if version > LAYOUT_VERSION:
            raise SourceError(f"{p}: layout version {version} is newer than supported")
    else:
        layout = {}
        for lineno, row in enumerate(csv.reader(io.StringIO(text)), start=1):
            cells = [c.strip() for c in row]
            if not cells or not cells[0] or cells[0].startswith("#"):
                continue
            if len(cells) < 3:
                raise SourceError(f"{p}:{lineno}: expected id,x_m,y_m")
            try:
                layout[cells[0]] = (float(cells[1]), float(cells[2]))
            except ValueError:
                if lineno == 1:  # header
                    continue
                raise SourceError(f"{p}:{lineno}: x_m/y_m are not numbers: {row}") from None
            for value, axis in zip(layout[cells[0]], ("x_m", "y_m"), strict=True):
                number(value, f"{p}:{lineno}: beacon {cells[0]!r} {axis}", **_POS)
    if not layout:
        raise SourceError(f"{p}: beacon layout has no beacons")
    for bid, (x, y) in layout.items():
        if not (math.isfinite(x) and math.isfinite(y)):
            raise SourceError(f"{p}: beacon {bid!r} has a non-finite position")
    return layout


def save_layout(path: str | Path, layout: Mapping[str, Sequence[float]]) -> None:
    """Write a layout atomically as ``.json`` (versioned) or ``.csv`` (by suffix)."""
    p = Path(path).expanduser()
    if p.suffix.lower() == ".csv":
        rows = [f"{k},{float(v[0])!r},{float(v[1])!r}" for k, v in layout.items()]
        lines = ["id,x_m,y_m", *rows]
        atomic_write_text(p, "\n".join(lines) + "\n")
    else:
        atomic_write_json(
            p,
            {
                "version": LAYOUT_VERSION,
                "beacons": [
                    {"id": k, "x_m": float(v[0]), "y_m": float(v[1])} for k, v in layout.items()
                ],
            },
        )


# ---------------------------------------------------------------------------- readings
@dataclass(frozen=True, slots=True)
class RangeStep:
    """The readings of one time step."""

    timestamp_s: float | None  # None: a live reading without the sender's time
    ranges_m: Mapping[str, float]
    gt_xy: tuple[float, float] | None = None


@dataclass(slots=True)
class InputStats:
    """Counters of what an input skipped (reported, never raised)."""

    lines: int = 0
    readings: int = 0
    steps: int = 0
    malformed: int = 0
    unknown_ids: int = 0
    duplicates: int = 0
    out_of_order: int = 0
    #: live only: empty frames while nothing arrived (never part of the estimate)
    heartbeats: int = 0
    #: live only: sender timestamps ignored because the stream started without them
    ignored_timestamps: int = 0
    #: live only: "sender" (readings' own timestamp_s) or "receive" (arrival time), fixed
    #: by the first reading; "" before it
    clock: str = ""
    unknown_id_names: set[str] = field(default_factory=set)
    first_errors: list[str] = field(default_factory=list)
    #: why the newest skipped input was skipped ("" while none was)
    last_error: str = ""

    def note(self, kind: str, msg: str) -> None:
        setattr(self, kind, getattr(self, kind) + 1)
        self.last_error = msg
        if len(self.first_errors) < 10:
            self.first_errors.append(msg)

    def as_dict(self) -> dict[str, object]:
        return {
            "lines": self.lines,
            "readings": self.readings,
            "steps": self.steps,
            "malformed": self.malformed,
            "unknown_ids": self.unknown_ids,
            "duplicates": self.duplicates,
            "out_of_order": self.out_of_order,
            "heartbeats": self.heartbeats,
            "ignored_timestamps": self.ignored_timestamps,
            "clock": self.clock,
            "unknown_id_names": sorted(self.unknown_id_names),
            "first_errors": list(self.first_errors),
            "last_error": self.last_error,
        }


def _valid_range(v: float) -> bool:
    return math.isfinite(v) and v >= 0.0


def parse_range_csv(
    lines: Iterable[str],
    known_ids: Iterable[str] | None = None,
    window_s: float = 0.0,
    where: str = "csv",
) -> tuple[list[RangeStep], InputStats]:
    """Group ``timestamp, beacon_id, range_m`` lines into time steps (see module doc)."""
    known = set(known_ids) if known_ids is not None else None
    stats = InputStats()
    steps: list[RangeStep] = []
    cur_t: float | None = None
    cur: dict[str, float] = {}

    def flush() -> None:
        nonlocal cur
        if cur_t is not None and cur:
            steps.append(RangeStep(cur_t, dict(cur)))
        cur = {}

    for lineno, raw in enumerate(lines, start=1):
        line = raw.strip()
        stats.lines += 1
        if not line or line.startswith("#"):
            continue
        cells = [c.strip() for c in line.split(",")]
        if len(cells) != 3:
            stats.note("malformed", f"{where}:{lineno}: expected 3 fields, got {len(cells)}")
            continue
        try:
            t = float(cells[0])
            r = float(cells[2])
        except ValueError:
            if lineno == 1 and not any(ch.isdigit() for ch in cells[0]):
                continue  # header
            stats.note("malformed", f"{where}:{lineno}: timestamp/range not numbers: {line!r}")
            continue
        bid = cells[1]
        if not bid or not math.isfinite(t) or not _valid_range(r):
            stats.note("malformed", f"{where}:{lineno}: bad id, timestamp or range: {line!r}")
            continue
        if known is not None and bid not in known:
            stats.unknown_id_names.add(bid)
            stats.note("unknown_ids", f"{where}:{lineno}: unknown beacon id {bid!r}")
            continue
        if cur_t is not None and t < cur_t - 1e-12:
            stats.note("out_of_order", f"{where}:{lineno}: timestamp {t} before {cur_t}")
            continue
        if cur_t is None or t > cur_t + window_s + 1e-12:
            flush()
            cur_t = t
        if bid in cur:
            stats.note("duplicates", f"{where}:{lineno}: beacon {bid!r} read twice in a step")
        cur[bid] = r
        stats.readings += 1
    flush()
    stats.steps = len(steps)
    return steps, stats


def read_range_csv(
    path: str | Path, known_ids: Iterable[str] | None = None, window_s: float = 0.0
) -> tuple[list[RangeStep], InputStats]:
    """Read a range log file; SourceError only when the file cannot be read at all."""
    p = Path(path).expanduser()
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise SourceError(f"{p}: cannot read range log ({exc.strerror})") from None
    return parse_range_csv(text.splitlines(), known_ids, window_s, where=str(p))


def parse_datagram(
    data: bytes, known_ids: Iterable[str] | None, stats: InputStats
) -> RangeStep | None:
    """One UDP datagram -> RangeStep (None, counted in ``stats``, when malformed)."""
    known = set(known_ids) if known_ids is not None else None
    try:
        obj = json.loads(data.decode("utf-8"))
        if not isinstance(obj, dict):
            raise ValueError(f"expected a JSON object, got {type(obj).__name__}")
        raw_t = obj.get("timestamp_s")
        t = None if raw_t is None else number(raw_t, "timestamp_s", lo=-TIMESTAMP_MAX_S,
                                              hi=TIMESTAMP_MAX_S, error=ValueError)
        raw = obj["ranges_m"]
        if not isinstance(raw, dict):
            raise ValueError("ranges_m must be an object")
    except KeyError as exc:
        stats.note("malformed", f"udp: malformed datagram (no {exc!s})")
        return None
    except (ValueError, TypeError, UnicodeDecodeError, RecursionError) as exc:
        stats.note("malformed", f"udp: malformed datagram ({exc!s})")
        return None
    ranges: dict[str, float] = {}
    for bid, v in raw.items():
        try:
            r = number(v, f"range of {bid!r}", lo=0.0, hi=RANGE_MAX_M, error=ValueError)
        except ValueError as exc:
            stats.note("malformed", f"udp: {exc}")
            continue
        if known is not None and bid not in known:
            stats.unknown_id_names.add(str(bid))
            stats.note("unknown_ids", f"udp: unknown beacon id {bid!r}")
            continue
        ranges[str(bid)] = r
        stats.readings += 1
    gt = obj.get("gt_xy")
    gt_xy = None
    if isinstance(gt, list | tuple) and len(gt) == 2:
        try:
            gt_xy = (number(gt[0], "gt_xy", error=ValueError),
                     number(gt[1], "gt_xy", error=ValueError))
        except ValueError:
            gt_xy = None
    stats.steps += 1
    return RangeStep(t, ranges, gt_xy)


class UdpRangeListener:
    """Receives JSON range datagrams on ``host:port`` (127.0.0.1 by default; port 0 picks one)."""

    def __init__(
        self, host: str = "127.0.0.1", port: int = 0, known_ids: Iterable[str] | None = None
    ) -> None:
        self.known_ids = set(known_ids) if known_ids is not None else None
        self.stats = InputStats()
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((host, int(port)))
        except (OSError, OverflowError) as exc:
            self._sock.close()
            why = getattr(exc, "strerror", None) or exc
            raise SourceError(f"udp {host}:{port}: cannot bind ({why})") from None
        self.host, self.port = self._sock.getsockname()[:2]

    def receive(self, timeout_s: float = 0.2) -> RangeStep | None:
        """Next valid step, or None after ``timeout_s`` without one (or on a bad datagram)."""
        self._sock.settimeout(max(timeout_s, 1e-3))
        try:
            data, _ = self._sock.recvfrom(65535)
        except TimeoutError:
            return None
        except OSError:
            return None
        self.stats.lines += 1
        return parse_datagram(data, self.known_ids, self.stats)

    def close(self) -> None:
        self._sock.close()

    def __enter__(self) -> UdpRangeListener:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def send_ranges(
    port: int,
    timestamp_s: float,
    ranges_m: Mapping[str, float],
    host: str = "127.0.0.1",
    gt_xy: Sequence[float] | None = None,
) -> None:
    """Send one step as a datagram (for simulators and tests)."""
    msg: dict[str, object] = {"timestamp_s": timestamp_s, "ranges_m": dict(ranges_m)}
    if gt_xy is not None:
        msg["gt_xy"] = [float(gt_xy[0]), float(gt_xy[1])]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.sendto(json.dumps(msg).encode("utf-8"), (host, int(port)))
