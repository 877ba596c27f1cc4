"""Run a tracker over a whole source and summarise it (used by ``studiotrack track`` and benches).

:func:`run_tracker` drives :func:`engine.loop.run_tracking` (the pipeline, with any sinks
such as pose outputs) and keeps only what evaluation needs (stamps, poses, boxes, states,
timings, ground truth) - never the images.
:func:`summarize` turns a run into the machine-readable result::

    frames, tracked, lost_frames, ms_per_frame{median, p95},
    ate_rmse_m, rpe_trans_m_per_s, rpe_rot_deg_per_s      (pose trackers; null without GT)
    success_auc, precision_20px                           (box trackers; null without GT)

``ms_per_frame`` is the tracker's own time per frame (``FrameRecord.process_ms``: reading and
decoding the source are not included). ``tracked`` counts TRACKING/DEGRADED frames,
``lost_frames`` LOST ones. The estimated trajectory has one pose per frame that has a pose -
LOST frames included, with the held pose the operator saw - and is evaluated against the
source's ground-truth file when it has one (TUM ``groundtruth.txt``, the benchmark's way),
otherwise against the per-frame ground truth the source yields. ATE/RPE are those of
:mod:`engine.evaluation.metrics`; a metric that cannot be computed (too short, too few
matches) is null with the reason in ``notes``.
"""

from __future__ import annotations

import math
import types
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.errors import EvaluationError
from engine.evaluation.trajectory import Trajectory, read_tum
from engine.frames import Heartbeat
from engine.loop import FrameRecord, run_tracking
from engine.sources.base import Source
from engine.trackers.base import Tracker, TrackState

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class TrackingRun:
    """What one pass of a tracker over a source produced (arrays have one row per frame)."""

    tracker: str
    source: str
    output: str  # "pose" | "box" | "position2d"
    timestamps_s: F64  # (N,)
    states: tuple[TrackState, ...]
    T_world_cam: F64  # (N, 4, 4), NaN where the tracker gave no pose
    boxes_xywh: F64  # (N, 4), NaN where the tracker gave no box
    process_ms: F64  # (N,)
    gt_T_world_cam: F64  # (N, 4, 4), NaN where the source has no ground truth
    gt_boxes_xywh: F64  # (N, 4), NaN where the source has no ground-truth box
    gt_path: str | None = None  # the source's ground-truth trajectory file, if any

    def __len__(self) -> int:
        return int(self.timestamps_s.shape[0])

    def estimated_trajectory(self) -> Trajectory:
        """Poses of the frames that have one (LOST frames hold the last good pose)."""
        has = np.all(np.isfinite(self.T_world_cam.reshape(len(self), -1)), axis=1)
        return Trajectory.from_poses(
            self.timestamps_s[has], self.T_world_cam[has], f"{self.tracker} on {self.source}"
        )

    def frame_ground_truth(self) -> Trajectory | None:
        """Per-frame ground truth yielded by the source, or None if it has none."""
        has = np.all(np.isfinite(self.gt_T_world_cam.reshape(len(self), -1)), axis=1)
        if not has.any():
            return None
        return Trajectory.from_poses(
            self.timestamps_s[has], self.gt_T_world_cam[has], f"ground truth of {self.source}"
        )


def run_tracker(
    source: Source,
    tracker: Tracker,
    *,
    output: str = "pose",
    max_frames: int | None = None,
    should_stop: Callable[[], bool] = lambda: False,
    on_record: Callable[[FrameRecord], None] | None = None,
    sinks: Sequence[Any] = (),
    timecode: Any = None,
) -> TrackingRun:
    """Track ``source`` with ``tracker`` to the end (or ``max_frames``) and collect the run.

    ``sinks`` (:class:`engine.pipeline.Sink`) get every record, e.g. pose outputs."""
    stamps: list[float] = []
    states: list[TrackState] = []
    poses: list[F64] = []
    boxes: list[F64] = []
    ms: list[float] = []
    gt_poses: list[F64] = []
    gt_boxes: list[F64] = []
    nan44 = np.full((4, 4), np.nan)
    nan4 = np.full(4, np.nan)
    for rec in run_tracking(source, tracker, should_stop=should_stop, max_frames=max_frames,
                            sinks=sinks, timecode=timecode):
        res, fr = rec.result, rec.frame
        if fr.payload(Heartbeat) is not None:
            continue  # a live source's "nothing new": not a frame of the run
        stamps.append(float(fr.timestamp_s))
        states.append(res.state)
        poses.append(nan44 if res.T_world_cam is None else np.asarray(res.T_world_cam, float))
        boxes.append(nan4 if res.box_xywh is None else np.asarray(res.box_xywh, float))
        ms.append(float(rec.process_ms))
        gt_poses.append(
            nan44 if fr.gt_T_world_cam is None else np.asarray(fr.gt_T_world_cam, float)
        )
        gt_boxes.append(nan4 if fr.gt_box_xywh is None else np.asarray(fr.gt_box_xywh, float))
        if on_record is not None:
            on_record(rec)
    gt_path = getattr(source, "groundtruth_path", None)
    return TrackingRun(
        tracker=tracker.name,
        source=getattr(source, "name", "source"),
        output=output,
        timestamps_s=np.asarray(stamps, dtype=np.float64),
        states=tuple(states),
        T_world_cam=np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4),
        boxes_xywh=np.asarray(boxes, dtype=np.float64).reshape(-1, 4),
        process_ms=np.asarray(ms, dtype=np.float64),
        gt_T_world_cam=np.asarray(gt_poses, dtype=np.float64).reshape(-1, 4, 4),
        gt_boxes_xywh=np.asarray(gt_boxes, dtype=np.float64).reshape(-1, 4),
        gt_path=None if gt_path is None else str(gt_path),
    )


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def summarize(run: TrackingRun, *, rpe_delta_s: float = 1.0) -> dict[str, Any]:
    """The machine-readable summary of a run (see the module docstring for the keys)."""
    from engine.evaluation.boxes import box_scores
    from engine.evaluation.metrics import ate, rpe

    n = len(run)
    notes: list[str] = []
    ms = run.process_ms
    out: dict[str, Any] = {
        "tracker": run.tracker,
        "source": run.source,
        "frames": n,
        "tracked": sum(1 for s in run.states if s.is_good),
        "lost_frames": sum(1 for s in run.states if s is TrackState.LOST),
        "ms_per_frame": {
            "median": _num(float(np.median(ms))) if n else None,
            "p95": _num(float(np.percentile(ms, 95))) if n else None,
        },
        "ate_rmse_m": None,
        "rpe_trans_m_per_s": None,
        "rpe_rot_deg_per_s": None,
    }
    if run.output == "box":
        out["success_auc"] = None
        out["precision_20px"] = None
        if n and np.isfinite(run.gt_boxes_xywh).all(axis=1).any():
            try:
                sc = box_scores(run.gt_boxes_xywh, run.boxes_xywh)
            except EvaluationError as exc:
                notes.append(f"box metrics: {exc}")
            else:
                out["success_auc"] = sc.success_auc
                out["precision_20px"] = sc.precision_20px
        else:
            notes.append("no ground-truth boxes: success_auc/precision_20px are null")
    else:
        gt: Trajectory | None = None
        try:
            gt = read_tum(Path(run.gt_path)) if run.gt_path else run.frame_ground_truth()
            est = run.estimated_trajectory()
        except EvaluationError as exc:
            notes.append(f"evaluation: {exc}")
            gt = None
        if gt is None:
            if not notes:
                notes.append("source has no ground truth: ATE/RPE are null")
        else:
            try:
                out["ate_rmse_m"] = ate(gt, est).rmse_m
            except EvaluationError as exc:
                notes.append(f"ATE: {exc}")
            try:
                r = rpe(gt, est, delta_s=rpe_delta_s)
                out["rpe_trans_m_per_s"] = r.trans_rmse_m_per_s
                out["rpe_rot_deg_per_s"] = r.rot_rmse_deg_per_s
            except EvaluationError as exc:
                notes.append(f"RPE: {exc}")
    if notes:
        out["notes"] = notes
    return out


_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"0", "false", "no", "off"}


def _convert(text: str, hint: Any, key: str) -> Any:
    """Convert ``text`` to the type ``hint`` of a params field (raises ValueError)."""
    import enum
    import types
    import typing

    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if text.strip().lower() == "none" and type(None) in args:
            return None
        for a in args:
            if a is type(None):
                continue
            try:
                return _convert(text, a, key)
            except ValueError:
                continue
        raise ValueError(f"expected one of {hint}")
    if origin is typing.Literal:
        for a in args:
            if str(a) == text:
                return a
        raise ValueError(f"expected one of {', '.join(map(str, args))}")
    if origin is tuple:
        items = [s for s in text.replace(" ", "").split(",") if s]
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(s, args[0], key) for s in items)
        if args and len(items) != len(args):
            raise ValueError(f"expected {len(args)} comma-separated values")
        kinds = args or (str,) * len(items)
        return tuple(_convert(s, a, key) for s, a in zip(items, kinds, strict=True))
    if hint is bool:
        low = text.strip().lower()
        if low in _TRUE:
            return True
        if low in _FALSE:
            return False
        raise ValueError("expected true or false")
    if hint is int or hint is float:  # the validated path: finite, no 400-digit integers
        from engine.validate import number

        try:
            return number(text, "value", integer=hint is int, text=True, error=ValueError)
        except ValueError as exc:
            msg = str(exc).removeprefix("value ")
            if msg.startswith(("must be an integer", "must be a number")):
                msg = "expected an integer" if hint is int else "expected a number"
            raise ValueError(msg) from None
    if hint is str:
        return text
    if isinstance(hint, type) and issubclass(hint, enum.Enum):
        for m in hint:
            if text in (m.name, str(m.value)) or text.lower() == m.name.lower():
                return m
        raise ValueError(f"expected one of {', '.join(m.name for m in hint)}")
    raise ValueError(f"cannot set a field of type {hint} from the command line")


def apply_param_overrides(params: Any, items: list[str] | tuple[str, ...]) -> Any:
    """``params`` with ``key=value`` overrides, each converted to its dataclass field's type.

    ``preset=NAME`` applies a preset of the params class (:meth:`engine.params.Params.
    with_preset`) first, whatever its position, so ``preset=paper n_particles=50`` is the
    paper's settings with 50 particles. An unknown key, preset or a value of the wrong type
    raises :class:`engine.errors.ParamsError` naming it; the dataclass's own validation
    (``__post_init__``) runs on the result.
    """
    import dataclasses
    import typing

    from engine.errors import ParamsError
    from engine.params import PRESET_KEY, Params

    if not items:
        return params
    cls = type(params)
    fields = {f.name: f for f in dataclasses.fields(params)}
    try:
        hints = typing.get_type_hints(cls)
    except (NameError, TypeError):  # a class defined in a function: fall back per field
        hints = {}
    pairs: list[tuple[str, str]] = []
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ParamsError(f"--param {item!r} is not key=value")
        pairs.append((key, value))
    for key, value in pairs:
        if key == PRESET_KEY and key not in fields:
            if not isinstance(params, Params) or not cls.PRESETS:
                raise ParamsError(f"--param {PRESET_KEY}={value.strip()}: {cls.__name__} has "
                                  "no presets")
            params = params.with_preset(value.strip())
    changes: dict[str, Any] = {}
    for key, value in pairs:
        if key == PRESET_KEY and key not in fields:
            continue
        if key not in fields:
            extra = [PRESET_KEY] if isinstance(params, Params) and cls.PRESETS else []
            raise ParamsError(
                f"--param {key}: {cls.__name__} has no such field; "
                f"valid: {', '.join(sorted(fields) + extra)}"
            )
        try:
            hint = hints.get(key, fields[key].type)
            if isinstance(hint, str):  # unresolvable annotation: go by the current value
                current = getattr(params, key)
                hint = (
                    types.GenericAlias(tuple, (type(current[0]), ...))  # tuple[T, ...]
                    if isinstance(current, tuple) and current
                    else type(current)
                )
            changes[key] = _convert(value.strip(), hint, key)
        except ValueError as exc:
            short = value if len(value) <= 40 else value[:37] + "..."
            raise ParamsError(f"--param {key}={short}: {exc}") from None
    try:
        return dataclasses.replace(params, **changes) if changes else params
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ParamsError):
            raise
        raise ParamsError(f"--param: {exc}") from None
