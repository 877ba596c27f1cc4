"""Trajectory export of session (or replay) records: TUM, CSV and JSON."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from engine.geometry import pan_tilt_roll_deg, tum_from_T
from engine.persist import write_text_file
from engine.session import SessionError
from engine.session.reader import pose_of

CSV_COLUMNS = ("seq", "index", "timestamp_s", "state", "tx", "ty", "tz", "qx", "qy", "qz",
               "qw", "pan_deg", "tilt_deg", "roll_deg", "residual", "inlier_fraction",
               "process_ms", "timecode")


def finite_pose(rec: dict[str, Any]) -> np.ndarray | None:
    """The record's pose, or None when it has none or it is not finite (a damaged record):
    exports never write ``nan``."""
    T = pose_of(rec)
    return T if T is not None and bool(np.all(np.isfinite(T))) else None


def nonfinite_poses(records: Sequence[dict[str, Any]]) -> list[int]:
    """``seq`` of the records whose pose is present but not finite (left out of exports)."""
    return [int(r["seq"]) for r in records
            if pose_of(r) is not None and finite_pose(r) is None]


def _rows(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    rows = []
    for r in records:
        T = finite_pose(r)
        if T is None:
            continue
        tum = tum_from_T(T)
        pan, tilt, roll = pan_tilt_roll_deg(T[:3, :3])
        rows.append({
            "seq": r["seq"], "index": r.get("index", r["seq"]),
            "timestamp_s": float(r["timestamp_s"]), "state": r.get("state", ""),
            **dict(zip(("tx", "ty", "tz", "qx", "qy", "qz", "qw"), map(float, tum),
                       strict=True)),
            "pan_deg": pan, "tilt_deg": tilt, "roll_deg": roll,
            "residual": r.get("residual"), "inlier_fraction": r.get("inlier_fraction"),
            "process_ms": r.get("process_ms"), "timecode": r.get("timecode"),
        })
    return rows


def tum_text(records: Sequence[dict[str, Any]]) -> str:
    """``timestamp tx ty tz qx qy qz qw`` per posed frame (TUM RGB-D format)."""
    lines = ["# timestamp tx ty tz qx qy qz qw"]
    for row in _rows(records):
        vals = [row[k] for k in ("tx", "ty", "tz", "qx", "qy", "qz", "qw")]
        lines.append(f"{row['timestamp_s']:.6f} " + " ".join(f"{v:.9f}" for v in vals))
    return "\n".join(lines) + "\n"


def csv_text(records: Sequence[dict[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, lineterminator="\n")
    w.writeheader()
    for row in _rows(records):
        w.writerow({k: ("" if row[k] is None else row[k]) for k in CSV_COLUMNS})
    return buf.getvalue()


def json_text(records: Sequence[dict[str, Any]]) -> str:
    out = []
    for r in records:
        T = finite_pose(r)
        out.append({"seq": r["seq"], "timestamp_s": r["timestamp_s"], "state": r.get("state"),
                    "timecode": r.get("timecode"), "timecode_rate": r.get("timecode_rate"),
                    "T_world_cam": None if T is None else np.asarray(T).tolist()})
    return json.dumps({"format": "studiotrack-trajectory", "version": 1, "poses": out},
                      indent=1) + "\n"


def export_trajectory(records: Sequence[dict[str, Any]], path: str | Path,
                      fmt: str | None = None) -> str:
    """Write records as TUM (.txt/.tum), CSV (.csv) or JSON (.json); returns the format."""
    path = Path(path)
    fmt = (fmt or {".csv": "csv", ".json": "json"}.get(path.suffix.lower(), "tum")).lower()
    text = {"tum": tum_text, "csv": csv_text, "json": json_text}.get(fmt)
    if text is None:
        raise SessionError(f"unknown trajectory format {fmt!r} (tum, csv, json)")
    write_text_file(path, text(records), SessionError)
    return fmt
