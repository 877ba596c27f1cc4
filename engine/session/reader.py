"""Reading a session folder: the index, the per-frame records, and a replay source."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.arrays import xywh
from engine.camera import Intrinsics
from engine.frames import Frame
from engine.persist import read_json_file
from engine.session import FORMAT_NAME, FORMAT_VERSION, SessionError
from engine.sources.base import Source

STATUSES = ("recording", "complete", "stopped", "interrupted")


@dataclass(frozen=True, slots=True)
class SessionIndex:
    """The validated content of ``index.json``."""

    version: int
    status: str
    stop_reason: str
    source_spec: str
    source_name: str
    source_kind: str  # "frames" | "video"
    nominal_fps: float
    intrinsics: Intrinsics | None
    tracker_name: str
    tracker_params: dict[str, Any]
    frames_recorded: int
    has_depth: bool
    video_file: str
    raw: dict[str, Any]


def _req(d: dict[str, Any], key: str, typ: type | tuple[type, ...], where: str) -> Any:
    if key not in d:
        raise SessionError(f"{where}: missing key {key!r}")
    v = d[key]
    if isinstance(v, bool) and typ in (int, float, (int, float)):
        raise SessionError(f"{where}: {key!r} must be a number, got {v!r}")
    if not isinstance(v, typ):
        raise SessionError(f"{where}: {key!r} has the wrong type ({type(v).__name__})")
    return v


def parse_index(obj: Any, where: str = "index.json") -> SessionIndex:
    """Validate a decoded ``index.json``; any defect raises :class:`SessionError`."""
    if not isinstance(obj, dict):
        raise SessionError(f"{where}: expected a JSON object, got {type(obj).__name__}")
    if obj.get("format") != FORMAT_NAME:
        raise SessionError(f"{where}: not a StudioTrack session (format {obj.get('format')!r})")
    version = _req(obj, "version", int, where)
    if isinstance(version, bool) or version > FORMAT_VERSION or version < 1:
        raise SessionError(f"{where}: unsupported session version {version!r}")
    status = _req(obj, "status", str, where)
    if status not in STATUSES:
        raise SessionError(f"{where}: unknown status {status!r}")
    src = _req(obj, "source", dict, where)
    trk = _req(obj, "tracker", dict, where)
    kind = _req(src, "kind", str, where + " source")
    if kind not in ("frames", "video"):
        raise SessionError(f"{where}: unknown source kind {kind!r}")
    fps = _req(src, "nominal_fps", (int, float), where + " source")
    if not math.isfinite(fps) or fps < 0:
        raise SessionError(f"{where}: nominal_fps {fps!r} is not a non-negative number")
    intr = None
    intr_d = obj.get("intrinsics")
    if intr_d is not None:
        if not isinstance(intr_d, dict):
            raise SessionError(f"{where}: 'intrinsics' must be an object")
        from engine.camera import intrinsics_from_json

        intr = intrinsics_from_json(intr_d, f"{where} intrinsics", SessionError)
    params = trk.get("params", {})
    if not isinstance(params, dict):
        raise SessionError(f"{where}: tracker params must be an object")
    frames = _req(obj, "frames_recorded", int, where)
    if frames < 0:
        raise SessionError(f"{where}: frames_recorded {frames} is negative")
    stop_reason = obj.get("stop_reason", "")
    video = src.get("video_file", "")
    spec = src.get("spec", "")
    name = src.get("name", "")
    for label, v in (("stop_reason", stop_reason), ("video_file", video), ("spec", spec),
                     ("name", name)):
        if not isinstance(v, str):
            raise SessionError(f"{where}: {label!r} must be a string")
    if kind == "video" and (not video or "/" in video or "\\" in video or video.startswith(".")):
        raise SessionError(f"{where}: video_file {video!r} must be a plain file name")
    return SessionIndex(
        version=version,
        status=status,
        stop_reason=stop_reason,
        source_spec=spec,
        source_name=name,
        source_kind=kind,
        nominal_fps=float(fps),
        intrinsics=intr,
        tracker_name=_req(trk, "name", str, where + " tracker"),
        tracker_params=params,
        frames_recorded=frames,
        has_depth=bool(obj.get("has_depth", False)),
        video_file=video,
        raw=obj,
    )


def read_index(session_dir: str | Path) -> SessionIndex:
    path = Path(session_dir) / "index.json"
    obj = read_json_file(
        path, SessionError, missing=f"not found (is {session_dir} a session folder?)"
    )
    return parse_index(obj, str(path))


def read_records(session_dir: str | Path) -> list[dict[str, Any]]:
    """Per-frame records; a truncated last line (crash, disk full) is ignored."""
    path = Path(session_dir) / "records.jsonl"
    if not path.exists():
        return []
    out: list[dict[str, Any]] = []
    try:
        lines = path.read_bytes().split(b"\n")
    except OSError as exc:
        raise SessionError(f"{path}: cannot read ({exc})") from None
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            rec = json.loads(line.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):
            if i >= len(lines) - 2:  # only the last (partial) line may be damaged
                break
            raise SessionError(f"{path}: line {i + 1} is not valid JSON") from None
        if not isinstance(rec, dict) or not isinstance(rec.get("seq"), int):
            raise SessionError(f"{path}: line {i + 1} is not a frame record")
        out.append(rec)
    return out


def records_problems(index: SessionIndex, records: list[dict[str, Any]]) -> list[str]:
    """Why ``records`` cannot be the whole recording the index describes (empty: they can).

    Checked: the count the finished index states, frame numbers 0..N-1 each exactly once.
    A replay may only claim identity when this is empty.
    """
    problems = []
    if index.status != "recording" and index.frames_recorded != len(records):
        problems.append(f"index.json says {index.frames_recorded} frame(s) were recorded, "
                        f"records.jsonl holds {len(records)}")
    seqs = [int(r["seq"]) for r in records]
    if seqs != list(range(len(seqs))):
        from collections import Counter

        counts = Counter(seqs)
        dup = next((q for q, c in counts.items() if c > 1), None)
        gap = next((i for i in range(len(seqs)) if i not in counts), None)
        what = f"frame {dup} appears twice" if dup is not None else f"frame {gap} is missing"
        problems.append(f"records.jsonl: frames are not numbered 0..{len(seqs) - 1} ({what})")
    return problems


def pose_of(rec: dict[str, Any]) -> np.ndarray | None:
    T = rec.get("T_world_cam")
    if T is None:
        return None
    a = np.asarray(T, dtype=np.float64)
    if a.shape != (16,):
        raise SessionError(f"record {rec.get('seq')}: T_world_cam must have 16 numbers")
    return a.reshape(4, 4)


def decode_depth_png(q: np.ndarray, depth_scale: float) -> np.ndarray:
    """16-bit depth units to float32 metres; the recorder uses the same function."""
    return q.astype(np.float32) / np.float32(depth_scale)


class SessionSource(Source):
    """Frames of a recorded session, bit-identical to what the tracker saw while recording."""

    def __init__(self, session_dir: str | Path) -> None:
        self.dir = Path(session_dir)
        self.index = read_index(self.dir)
        self.records = read_records(self.dir)
        self.name = f"session {self.dir.name}"
        self.nominal_fps = self.index.nominal_fps or 30.0
        self._video: Source | None = None
        if self.index.source_kind == "video":
            from engine.sources import open_source

            vpath = self.dir / self.index.video_file
            if not vpath.exists():
                raise SessionError(f"{vpath}: the session's video file is missing")
            self._video = open_source(str(vpath))

    @property
    def intrinsics(self) -> Intrinsics | None:
        return self.index.intrinsics

    def __len__(self) -> int:
        return len(self.records)

    def frames(self) -> Iterator[Frame]:
        import cv2

        if self._video is not None:
            by_index = {int(r.get("index", r["seq"])): r for r in self.records}
            for frame in self._video.frames():
                rec = by_index.get(frame.index)
                if rec is None:
                    if frame.index > max(by_index, default=-1):
                        return
                    continue
                yield Frame(
                    index=frame.index,
                    timestamp_s=float(rec.get("timestamp_s", frame.timestamp_s)),
                    color_bgr=frame.color_bgr,
                    intrinsics=self.index.intrinsics or frame.intrinsics,
                    depth_m=frame.depth_m,
                    gt_T_world_cam=_gt(rec),
                    gt_box_xywh=_box(rec.get("gt_box_xywh")),
                    payloads=self._timecode(rec),
                )
            return
        scale = self.index.intrinsics.depth_scale if self.index.intrinsics else 5000.0
        for rec in self.records:
            seq = rec["seq"]
            color = None
            if rec.get("color_file"):
                cpath = self.dir / "frames" / f"{seq:06d}.png"
                img = cv2.imread(str(cpath), cv2.IMREAD_UNCHANGED)
                if img is None or img.dtype != np.uint8:
                    raise SessionError(f"{cpath}: missing or not an 8-bit frame image")
                color = np.asarray(img, dtype=np.uint8)
            depth = None
            if rec.get("depth_file"):
                dpath = self.dir / "depth" / f"{seq:06d}.png"
                q = cv2.imread(str(dpath), cv2.IMREAD_UNCHANGED)
                if q is None or q.dtype != np.uint16:
                    raise SessionError(f"{dpath}: missing or not a 16-bit depth PNG")
                depth = decode_depth_png(q, scale)
            yield Frame(
                index=int(rec.get("index", seq)),
                timestamp_s=float(rec["timestamp_s"]),
                color_bgr=color,
                intrinsics=self.index.intrinsics,
                depth_m=depth,
                gt_T_world_cam=_gt(rec),
                gt_box_xywh=_box(rec.get("gt_box_xywh")),
                depth_timestamp_s=_opt_float(rec.get("depth_timestamp_s")),
                payloads=self._timecode(rec),
            )

    def _timecode(self, rec: dict[str, Any]) -> tuple[Any, ...]:
        """The recorded timecode as the replayed frame's own (a session keeps its timecode)."""
        tc = rec.get("timecode")
        if tc is None:
            return ()
        from engine.timecode import SourceTimecode, TimecodeError, parse_timecode

        try:
            return (SourceTimecode(parse_timecode(str(tc), rec.get("timecode_rate") or "25",
                                                  where="timecode")),)
        except TimecodeError as exc:
            raise SessionError(f"{self.dir / 'records.jsonl'}: record {rec.get('seq')}: "
                               f"{exc}") from None

    def close(self) -> None:
        if self._video is not None:
            self._video.close()


def _gt(rec: dict[str, Any]) -> np.ndarray | None:
    g = rec.get("gt_T_world_cam")
    return None if g is None else np.asarray(g, dtype=np.float64).reshape(4, 4)


def _opt_float(v: Any) -> float | None:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


def _box(b: Any) -> tuple[float, float, float, float] | None:
    if b is None:
        return None
    try:
        return xywh(b)
    except (TypeError, ValueError) as exc:
        raise SessionError(f"recorded gt_box_xywh {b!r}: {exc}") from None
