"""Writing a session folder while tracking.

Determinism: the tracker must see exactly what replay will read back. Colour PNGs are
lossless, but depth is stored as 16-bit PNG in units of ``1/depth_scale`` metres, so the
recorder first *normalises* each frame (quantises depth the way the reader decodes it) and
the tracker consumes the normalised frame. Replaying then feeds bit-identical inputs.

Failure: any write error (disk full, permissions, device gone) stops recording. The index is
rewritten (best effort) with ``status: "stopped"`` and the reason, records written so far stay
readable (one flushed JSON line per frame, images written before their line), and
:class:`RecordingStopped` carries a one-line message naming the file and the error.

Interruption: a recording whose ``should_stop`` turned true before the source ended (Ctrl-C,
SIGTERM, the operator's Stop) is finished with ``status: "interrupted"`` and the reason
(``should_stop.reason`` when the flag has one); a source that fails mid-way is finished as
``"interrupted"`` with the source's error. ``"complete"`` means the source ran to its end
(or to ``max_frames``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as _dt
import enum
import json
import math
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from engine.frames import Frame
from engine.pipeline import SinkBase, SinkHealth, SinkLevel
from engine.records import FrameRecord
from engine.session import FORMAT_NAME, FORMAT_VERSION, RecordingStopped, SessionError
from engine.session.reader import decode_depth_png
from engine.sinks import SinkSpec
from engine.sources.base import Source
from engine.sources.video import VIDEO_SUFFIXES


def _write_file(path: Path, data: bytes) -> None:
    """Plain write (no fsync per frame: a record line is only appended after its images)."""
    with open(path, "wb") as fh:
        fh.write(data)


def to_jsonable(obj: Any) -> Any:
    """Params/records to JSON types: enums by value, tuples as lists, non-finite as None."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, enum.Enum):
        return to_jsonable(obj.value)
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return to_jsonable(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    if obj is None or isinstance(obj, bool | int | float | str):
        return obj
    return repr(obj)


def quantize_depth(depth_m: np.ndarray, depth_scale: float) -> np.ndarray:
    """float metres -> uint16 units of 1/depth_scale m (0 = invalid, saturating)."""
    d = np.nan_to_num(np.asarray(depth_m, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    return np.clip(np.rint(d * depth_scale), 0, 65535).astype(np.uint16)


def is_video_spec(spec: str) -> bool:
    return Path(spec).suffix.lower() in VIDEO_SUFFIXES and Path(spec).is_file()


class SessionRecorder:
    """Writes one session folder; :meth:`normalize` frames before tracking them."""

    def __init__(
        self,
        out_dir: str | Path,
        *,
        source: Source,
        source_spec: str,
        tracker_name: str,
        tracker_params: Any = None,
        outputs_config: Any = None,
        overwrite: bool = False,
    ) -> None:
        self.dir = Path(out_dir)
        if self.dir.exists() and any(self.dir.iterdir()):
            if not overwrite:
                raise SessionError(f"{self.dir}: folder exists and is not empty")
            if not (self.dir / "index.json").exists():
                raise SessionError(f"{self.dir}: not a session folder, refusing to overwrite")
            shutil.rmtree(self.dir)
        self.frames_written = 0
        self.stopped = False
        self.stop_reason = ""
        self.has_depth = False
        self.depth_scale = source.intrinsics.depth_scale if source.intrinsics else 5000.0
        self.video_file = ""
        kind = "frames"
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
            if is_video_spec(source_spec):
                kind = "video"
                self.video_file = "input" + Path(source_spec).suffix.lower()
                shutil.copyfile(source_spec, self.dir / self.video_file)
            else:
                (self.dir / "frames").mkdir(exist_ok=True)
                (self.dir / "depth").mkdir(exist_ok=True)
            self._records = open(self.dir / "records.jsonl", "ab")  # noqa: SIM115
        except OSError as exc:
            raise SessionError(f"{self.dir}: cannot create session ({exc.strerror or exc})") \
                from None
        self.kind = kind
        self._index: dict[str, Any] = {
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "status": "recording",
            "stop_reason": "",
            "partial": False,
            "source": {
                "spec": source_spec,
                "name": getattr(source, "name", ""),
                "kind": kind,
                "nominal_fps": float(getattr(source, "nominal_fps", 30.0) or 0.0),
                "length": len(source),
                "video_file": self.video_file,
            },
            "intrinsics": source.intrinsics.to_json_dict() if source.intrinsics else None,
            "tracker": {"name": tracker_name, "params": to_jsonable(tracker_params) or {}},
            "outputs": _outputs_summary(outputs_config),
            "frames_recorded": 0,
            "has_depth": False,
            "notes": "depth PNG units: 1/intrinsics.depth_scale metres; source payloads "
            "(ground truth beyond the pose and box) are not recorded",
        }
        self._write_index()

    # ------------------------------------------------------------------ frames
    def normalize(self, frame: Frame) -> Frame:
        """The frame as replay will read it back (depth quantised to 16 bits)."""
        if self.kind == "video" or frame.depth_m is None:
            return frame
        scale = frame.intrinsics.depth_scale if frame.intrinsics else self.depth_scale
        q = quantize_depth(frame.depth_m, scale)
        return dataclasses.replace(frame, depth_m=decode_depth_png(q, scale))

    def normalizing(self, source: Source) -> Source:
        return _NormalizingSource(source, self)

    def write(self, record: Any, outputs_info: dict[str, Any] | None = None) -> None:
        """Append one FrameRecord (images first, then its JSON line)."""
        if self.stopped:
            raise RecordingStopped(self._message())
        frame: Frame = record.frame
        res = record.result
        seq = int(record.seq)
        line: dict[str, Any] = {
            "seq": seq,
            "index": int(frame.index),
            "timestamp_s": float(frame.timestamp_s),
            "state": res.state.value,
            "T_world_cam": None if res.T_world_cam is None
            else [float(v) for v in np.asarray(res.T_world_cam).reshape(-1)],
            "box_xywh": to_jsonable(res.box_xywh),
            "residual": to_jsonable(res.residual),
            "inlier_fraction": to_jsonable(res.inlier_fraction),
            "keyframe_id": res.keyframe_id,
            "timings_ms": to_jsonable(dict(res.timings_ms)),
            "process_ms": float(record.process_ms),
            "fps": to_jsonable(float(record.fps)),
            "gt_T_world_cam": None if frame.gt_T_world_cam is None
            else [float(v) for v in frame.gt_T_world_cam.reshape(-1)],
            "gt_box_xywh": to_jsonable(frame.gt_box_xywh),
            "depth_timestamp_s": to_jsonable(frame.depth_timestamp_s),
            "timecode": None if getattr(record, "timecode", None) is None
            else str(record.timecode),
            "timecode_rate": None if getattr(record, "timecode", None) is None
            else record.timecode.rate,
            "color_file": False,
            "depth_file": False,
        }
        if outputs_info is not None:
            line["outputs"] = to_jsonable(outputs_info)
        try:
            if self.kind == "frames":
                import cv2

                if frame.color_bgr is not None:
                    ok, enc = cv2.imencode(".png", np.ascontiguousarray(frame.color_bgr))
                    if not ok:
                        raise OSError(f"PNG encoding failed for frame {seq}")
                    _write_file(self.dir / "frames" / f"{seq:06d}.png", enc.tobytes())
                    line["color_file"] = True
                if frame.depth_m is not None:
                    scale = frame.intrinsics.depth_scale if frame.intrinsics else self.depth_scale
                    ok, enc = cv2.imencode(".png", quantize_depth(frame.depth_m, scale))
                    if not ok:
                        raise OSError(f"PNG encoding failed for depth {seq}")
                    _write_file(self.dir / "depth" / f"{seq:06d}.png", enc.tobytes())
                    line["depth_file"] = True
                    self.has_depth = True
            data = json.dumps(line, separators=(",", ":"), allow_nan=False).encode() + b"\n"
            self._records.write(data)
            self._records.flush()
        except OSError as exc:
            where = getattr(exc, "filename", None) or self.dir
            self._stop(f"{where}: {exc.strerror or exc}")
            raise RecordingStopped(self._message()) from None
        self.frames_written += 1
        if self.frames_written % 100 == 0:
            try:
                self._write_index()
            except OSError as exc:
                self._stop(f"{self.dir / 'index.json'}: {exc.strerror or exc}")
                raise RecordingStopped(self._message()) from None

    def finish(self, outputs_stats: dict[str, Any] | None = None,
               interrupted: str = "") -> None:
        """Close the records and write the final index: status ``complete``, or
        ``interrupted`` with the reason ``interrupted`` gives, or ``stopped`` (write error)."""
        if not self._records.closed:
            with contextlib.suppress(OSError):
                self._records.close()
        if not self.stopped:
            self._index["status"] = "interrupted" if interrupted else "complete"
            self._index["stop_reason"] = interrupted
            self._index["partial"] = bool(interrupted)
        try:
            if outputs_stats is not None:
                from engine.persist import atomic_write_json

                atomic_write_json(self.dir / "outputs.json", to_jsonable(outputs_stats))
            self._write_index()
        except OSError as exc:
            if not self.stopped:
                self._stop(f"{self.dir / 'index.json'}: {exc.strerror or exc}")
                raise RecordingStopped(self._message()) from None

    # ------------------------------------------------------------------ internals
    def _message(self) -> str:
        return (f"recording stopped after {self.frames_written} frame(s): {self.stop_reason}; "
                f"the frames written so far in {self.dir} stay readable")

    def _stop(self, reason: str) -> None:
        self.stopped = True
        self.stop_reason = reason
        self._index["status"] = "stopped"
        self._index["stop_reason"] = reason
        self._index["partial"] = True
        with contextlib.suppress(OSError):
            self._records.flush()
        with contextlib.suppress(OSError):  # the reader still works from records.jsonl
            self._write_index()

    def _write_index(self) -> None:
        from engine.persist import atomic_write_json

        self._index["frames_recorded"] = self.frames_written
        self._index["has_depth"] = self.has_depth
        atomic_write_json(self.dir / "index.json", self._index)


class _NormalizingSource(Source):
    def __init__(self, inner: Source, rec: SessionRecorder) -> None:
        self.inner = inner
        self.rec = rec
        self.name = inner.name
        self.nominal_fps = inner.nominal_fps
        self.live = inner.live

    @property
    def intrinsics(self) -> Any:
        return self.inner.intrinsics

    def __len__(self) -> int:
        return len(self.inner)

    def frames(self) -> Iterator[Frame]:
        for f in self.inner.frames():
            yield self.rec.normalize(f)

    def sinks(self) -> Any:
        return self.inner.sinks()

    def close(self) -> None:
        self.inner.close()


def _outputs_summary(cfg: Any) -> Any:
    if cfg is None:
        return None
    return to_jsonable(cfg)


class RecorderSink(SinkBase):
    """Writes every record into ``recorder``'s session folder.

    ``outputs_config`` (an :class:`engine.outputs.sender.OutputConfig`) adds the studio pose
    and the target names to each record; ``outputs_stats`` gives the sender statistics
    stored in ``outputs.json`` when the recording is finished; ``interrupted`` says why the
    run ended before its source did (the index then says ``"interrupted"`` and the reason).
    """

    name = "recorder"

    def __init__(self, recorder: SessionRecorder, *, outputs_config: Any = None,
                 outputs_stats: Callable[[], dict[str, Any] | None] | None = None,
                 interrupted: Callable[[], str] | None = None) -> None:
        self.recorder = recorder
        self.outputs_config = outputs_config
        self.outputs_stats = outputs_stats
        self.interrupted = interrupted
        self.finished = False

    def on_record(self, record: FrameRecord) -> None:
        info = None
        cfg = self.outputs_config
        if cfg is not None:
            T = record.result.T_world_cam
            pose = None if T is None else cfg.studio.studio_pose(T).as_array().tolist()
            info = {"targets": [t.name for t in cfg.targets],
                    "studio_pose_xyz_m_pan_tilt_roll_deg": pose}
        self.recorder.write(record, info)

    def close(self) -> None:
        if self.finished:
            return
        self.finished = True
        stats = self.outputs_stats() if self.outputs_stats is not None else None
        reason = self.interrupted() if self.interrupted is not None else ""
        self.recorder.finish(stats, interrupted=reason)

    def health(self) -> SinkHealth:
        rec = self.recorder
        if rec.stopped:
            return SinkHealth(self.name, SinkLevel.FAILED, rec.stop_reason,
                              counters={"frames": rec.frames_written})
        return SinkHealth(self.name, SinkLevel.OK, str(rec.dir),
                          counters={"frames": rec.frames_written})


def _stats_of(outputs: Any) -> Callable[[], dict[str, Any] | None]:
    def stats() -> dict[str, Any] | None:
        st = outputs.stats()
        return None if st is None else st.to_json_dict()

    return stats


def record_session(
    source: Source,
    tracker: Any,
    recorder: SessionRecorder,
    *,
    max_frames: int | None = None,
    outputs: Any = None,
    should_stop: Callable[[], bool] = lambda: False,
    timecode: Any = None,
) -> Iterator[Any]:
    """Track ``source`` with ``tracker``, recording each frame; yields the FrameRecords.

    Runs the pipeline with a :class:`engine.sinks.recorder.RecorderSink` (and ``outputs``,
    a :class:`engine.sinks.pose_output.PoseOutputSink`, before it: each record stores the
    studio pose submitted, ``outputs.json`` the sender statistics). The recorder is finished
    on exit; a write error stops the run and raises :class:`RecordingStopped`.
    """
    from engine.loop import run_tracking
    from engine.sources.base import StopOnError

    sinks: list[Any] = []
    stats_fn: Callable[[], dict[str, Any] | None] | None = None
    if outputs is not None:
        sinks.append(outputs)
        stats_fn = _stats_of(outputs)

    guarded = StopOnError(recorder.normalizing(source))

    def interrupted() -> str:
        """Why the recording ended before its source did ('' when it did not)."""
        if guarded.error is not None:
            return f"source error: {guarded.error}"
        if should_stop():
            return str(getattr(should_stop, "reason", "") or "stop requested")
        return ""

    sink = RecorderSink(recorder, outputs_config=getattr(outputs, "config", None),
                        outputs_stats=stats_fn, interrupted=interrupted)
    sinks.append(sink)
    records = run_tracking(guarded, tracker, sinks=sinks,
                           should_stop=lambda: should_stop() or recorder.stopped,
                           max_frames=max_frames, timecode=timecode)
    try:
        for rec in records:
            if recorder.stopped:
                break
            yield rec
    finally:
        records.close()  # closes the sinks: outputs first, then the recorder (index)
        sink.close()
    if recorder.stopped:
        raise RecordingStopped(recorder._message())
    if guarded.error is not None:
        raise guarded.error


SINKS = (SinkSpec("recorder", "records a replayable session folder", RecorderSink),)
