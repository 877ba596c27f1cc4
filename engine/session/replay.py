"""Replay a recorded session through the same engine and compare poses bit for bit."""

from __future__ import annotations

import dataclasses
import enum
import typing
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.session import SessionError
from engine.session.reader import SessionSource, pose_of, records_problems


@dataclass(frozen=True, slots=True)
class ReplayResult:
    records: list[dict[str, Any]]
    frames: int
    identical: bool  # every pose equal bit for bit to the recorded one
    mismatches: int
    max_abs_diff: float
    params_restored: bool
    #: why the recording cannot be compared whole (count, numbering); identical is then False
    integrity: tuple[str, ...] = ()


def params_from_json(params_cls: type, data: dict[str, Any]) -> Any:
    """Rebuild a frozen params dataclass from its recorded JSON (lists back to tuples)."""
    try:
        hints = typing.get_type_hints(params_cls)
    except Exception:
        hints = {}
    kwargs = {}
    for f in dataclasses.fields(params_cls):
        if f.name not in data:
            continue
        v = data[f.name]
        hint = hints.get(f.name)
        if isinstance(hint, type) and issubclass(hint, enum.Enum):
            v = hint(v)
        elif isinstance(v, list):
            v = tuple(tuple(x) if isinstance(x, list) else x for x in v)
        kwargs[f.name] = v
    return params_cls(**kwargs)


def make_tracker_for(index: Any) -> tuple[Any, bool]:
    """The recorded tracker with its recorded params (defaults if they cannot be rebuilt)."""
    from engine.trackers import create_tracker, get_spec

    spec = get_spec(index.tracker_name)
    try:
        params = params_from_json(spec.params_cls, index.tracker_params)
        restored = True
    except Exception:
        params = spec.params_cls()
        restored = False
    return create_tracker(index.tracker_name, params), restored


def replay_session(
    session_dir: str | Path,
    tracker: Any = None,
    *,
    max_frames: int | None = None,
    should_stop: Callable[[], bool] = lambda: False,
) -> ReplayResult:
    """Run the session's frames through ``tracker`` (default: the recorded one)."""
    from engine.loop import run_tracking

    src = SessionSource(session_dir)
    if not src.records:
        src.close()
        missing = not (Path(session_dir) / "records.jsonl").exists()
        raise SessionError(
            f"{Path(session_dir) / 'records.jsonl'}: "
            + ("missing" if missing else "holds no frame records")
            + "; there is nothing to replay or compare"
        )
    problems = records_problems(src.index, src.records)
    restored = True
    if tracker is None:
        tracker, restored = make_tracker_for(src.index)
    recorded = {r["seq"]: r for r in src.records}
    out: list[dict[str, Any]] = []
    mismatches = 0
    max_diff = 0.0
    try:
        for rec in run_tracking(src, tracker, should_stop=should_stop, max_frames=max_frames):
            T = rec.result.T_world_cam
            row = {
                "seq": rec.seq,
                "index": rec.frame.index,
                "timestamp_s": rec.frame.timestamp_s,
                "state": rec.result.state.value,
                "T_world_cam": None if T is None else [float(v) for v in np.ravel(T)],
                "residual": rec.result.residual,
                "inlier_fraction": rec.result.inlier_fraction,
                "process_ms": rec.process_ms,
            }
            out.append(row)
            ref = recorded.get(rec.seq)
            A = None if ref is None else pose_of(ref)
            B = None if T is None else np.asarray(T, dtype=np.float64)
            same = (A is None and B is None) or (
                A is not None and B is not None and np.array_equal(A, B)
            )
            if ref is not None and ref.get("state") != row["state"]:
                same = False
            if not same:
                mismatches += 1
                if A is not None and B is not None:
                    max_diff = max(max_diff, float(np.nanmax(np.abs(A - B))))
                else:
                    max_diff = float("inf")
    finally:
        src.close()
    if not out:
        raise SessionError(f"{session_dir}: replay produced no frames")
    expected = len(src.records) if max_frames is None else min(len(src.records), max_frames)
    if len(out) != expected and not should_stop():
        problems.append(f"replayed {len(out)} frame(s) of the {expected} recorded")
    identical = mismatches == 0 and not problems
    return ReplayResult(out, len(out), identical, mismatches, max_diff, restored,
                        tuple(problems))
