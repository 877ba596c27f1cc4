"""TUM trajectory files and timestamp association.

A TUM trajectory file has one pose per line, ``timestamp tx ty tz qx qy qz qw`` (seconds,
metres, unit quaternion scalar last), ``#`` comment lines, and fields separated by spaces,
tabs or commas (as TUM's own ``evaluate_ate.py`` accepts). The pose is ``T_world_cam``.

Reading is strict where TUM's scripts silently drop data: a malformed line, a non-finite value,
a zero quaternion or a timestamp smaller than the previous one raises
:class:`engine.errors.EvaluationError` naming the file, the line and the problem. A repeated
timestamp keeps the later pose, as TUM's scripts do.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from engine.errors import EvaluationError
from engine.geometry import R_from_quat_xyzw, make_T, quat_xyzw_from_R

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

#: TUM's evaluate_ate.py default for ``--max_difference`` (seconds).
TUM_MAX_DIFF_S = 0.02

TUM_HEADER = "# timestamp tx ty tz qx qy qz qw"


@dataclass(frozen=True, slots=True)
class Trajectory:
    """Stamped camera poses: ``timestamps_s`` (N,) strictly increasing, ``T_world_cam`` (N, 4, 4).

    ``name`` says where it came from (a file path) for error messages.
    """

    timestamps_s: F64
    T_world_cam: F64
    name: str = "trajectory"

    def __post_init__(self) -> None:
        t = np.asarray(self.timestamps_s, dtype=np.float64)
        T = np.asarray(self.T_world_cam, dtype=np.float64)
        if t.ndim != 1 or T.shape != (t.shape[0], 4, 4):
            raise EvaluationError(
                f"{self.name}: need N timestamps and (N, 4, 4) poses, "
                f"got {t.shape} and {T.shape}"
            )
        t.flags.writeable = False
        T.flags.writeable = False
        object.__setattr__(self, "timestamps_s", t)
        object.__setattr__(self, "T_world_cam", T)

    def __len__(self) -> int:
        return int(self.timestamps_s.shape[0])

    @property
    def positions_xyz(self) -> F64:
        """(N, 3) camera centres in the world."""
        return self.T_world_cam[:, :3, 3]

    @property
    def duration_s(self) -> float:
        return float(self.timestamps_s[-1] - self.timestamps_s[0]) if len(self) else 0.0

    @classmethod
    def from_poses(
        cls, timestamps_s: Sequence[float] | F64, poses: Sequence[F64] | F64, name: str = "poses"
    ) -> Trajectory:
        """Build from timestamps and 4x4 poses, checking that the timestamps increase."""
        t = np.asarray(timestamps_s, dtype=np.float64).reshape(-1)
        T = (
            np.stack([np.asarray(p, dtype=np.float64) for p in poses])
            if len(poses)
            else np.zeros((0, 4, 4))
        )
        if t.size > 1:
            bad = np.flatnonzero(np.diff(t) <= 0)
            if bad.size:
                k = int(bad[0]) + 1
                raise EvaluationError(
                    f"{name}: timestamp {t[k]!r} (pose {k}) is not after the previous one "
                    f"({t[k - 1]!r}); timestamps must increase"
                )
        return cls(t, T, name)


def _tum_rows(path: Path) -> tuple[list[int], list[list[str]]]:
    """Data lines of a TUM-style text file: (1-based line numbers, split fields)."""
    if not path.exists():
        raise EvaluationError(f"{path}: file not found")
    if not path.is_file():
        raise EvaluationError(f"{path}: not a file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise EvaluationError(f"{path}: not a text file (cannot decode as UTF-8)") from None
    except OSError as exc:
        raise EvaluationError(f"{path}: cannot read ({exc.strerror or exc})") from None
    numbers: list[int] = []
    rows: list[list[str]] = []
    for n, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        numbers.append(n)
        rows.append(s.replace(",", " ").replace("\t", " ").split())
    return numbers, rows


def read_tum(path: str | Path) -> Trajectory:
    """Read a TUM trajectory file; raises EvaluationError naming the file, line and problem."""
    path = Path(path)
    numbers, rows = _tum_rows(path)
    if not rows:
        raise EvaluationError(f"{path}: no poses (empty or only comments)")
    data = np.empty((len(rows), 8), dtype=np.float64)
    for k, (n, fields) in enumerate(zip(numbers, rows, strict=True)):
        if len(fields) != 8:
            raise EvaluationError(
                f"{path}: line {n}: expected 8 values (timestamp tx ty tz qx qy qz qw), "
                f"got {len(fields)}"
            )
        try:
            data[k] = [float(v) for v in fields]
        except ValueError:
            bad = next(v for v in fields if not _is_float(v))
            raise EvaluationError(f"{path}: line {n}: {bad!r} is not a number") from None
        if not np.all(np.isfinite(data[k])):
            raise EvaluationError(f"{path}: line {n}: non-finite value (nan or inf)")
        if float(np.dot(data[k, 4:8], data[k, 4:8])) < 1e-12:
            raise EvaluationError(f"{path}: line {n}: zero quaternion")
        if k > 0 and data[k, 0] < data[k - 1, 0]:
            raise EvaluationError(
                f"{path}: line {n}: timestamp {fields[0]} is not after the previous one "
                f"({data[k - 1, 0]!r}); timestamps must increase"
            )
    # A repeated timestamp keeps the later line, as TUM's scripts do (they read into a dict);
    # TUM's own fr2/desk ground truth has one such line.
    keep = np.append(data[1:, 0] != data[:-1, 0], True)
    data = data[keep]
    T = np.empty((data.shape[0], 4, 4), dtype=np.float64)
    for k in range(data.shape[0]):
        T[k] = make_T(R_from_quat_xyzw(data[k, 4:8]), data[k, 1:4])
    return Trajectory(data[:, 0], T, str(path))


def _is_float(v: str) -> bool:
    try:
        float(v)
    except ValueError:
        return False
    return True


def format_tum_line(timestamp_s: float, T_world_cam: F64) -> str:
    """One TUM line ``timestamp tx ty tz qx qy qz qw`` (quaternion with w >= 0)."""
    t = T_world_cam[:3, 3]
    q = quat_xyzw_from_R(T_world_cam[:3, :3])
    vals = " ".join(f"{v:.9f}" for v in (*t, *q))
    return f"{timestamp_s:.6f} {vals}"


def tum_text(traj: Trajectory) -> str:
    """The TUM file text of a trajectory (header comment + one line per pose)."""
    lines = [TUM_HEADER]
    pairs = zip(traj.timestamps_s, traj.T_world_cam, strict=True)
    lines += [format_tum_line(float(t), T) for t, T in pairs]
    return "\n".join(lines) + "\n"


def write_tum(path: str | Path, traj: Trajectory) -> None:
    """Write a TUM trajectory file atomically (readable by TUM's scripts and evo)."""
    from engine.persist import write_text_file

    write_text_file(Path(path), tum_text(traj), EvaluationError)


def associate(
    stamps_a: F64,
    stamps_b: F64,
    max_diff_s: float = TUM_MAX_DIFF_S,
    offset_s: float = 0.0,
) -> tuple[I64, I64]:
    """Pair timestamps one-to-one exactly as TUM's ``associate.py`` / ``evaluate_ate.py``.

    All candidate pairs with ``|a - (b + offset)| < max_diff`` are taken greedily in order of
    increasing difference (ties by a, then b), each stamp at most once; the result is sorted
    by ``a``. Candidates are found with a sorted-window search instead of TUM's all-pairs list,
    which gives the same matches in O(N log N + K log K).

    Returns index arrays ``(ia, ib)`` into ``stamps_a`` and ``stamps_b``.
    """
    a = np.asarray(stamps_a, dtype=np.float64)
    b = np.asarray(stamps_b, dtype=np.float64) + offset_s
    order_b = np.argsort(b, kind="stable")
    b_sorted = b[order_b]
    lo = np.searchsorted(b_sorted, a - max_diff_s, side="left")
    hi = np.searchsorted(b_sorted, a + max_diff_s, side="right")
    counts = hi - lo
    ia = np.repeat(np.arange(a.size), counts)
    if ia.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    starts = np.repeat(lo - np.cumsum(counts) + counts, counts)
    ib_sorted = np.arange(ia.size) + starts
    ib = order_b[ib_sorted]
    diff = np.abs(a[ia] - b[ib])
    keep = diff < max_diff_s
    ia, ib, diff = ia[keep], ib[keep], diff[keep]
    # TUM sorts (diff, a, b) tuples: a and b are stamps, so ties break by stamp value.
    order = np.lexsort((b[ib], a[ia], diff))
    used_a = np.zeros(a.size, dtype=bool)
    used_b = np.zeros(b.size, dtype=bool)
    out_a: list[int] = []
    out_b: list[int] = []
    for k in order:
        i, j = int(ia[k]), int(ib[k])
        if used_a[i] or used_b[j]:
            continue
        used_a[i] = used_b[j] = True
        out_a.append(i)
        out_b.append(j)
    res_a = np.asarray(out_a, dtype=np.int64)
    res_b = np.asarray(out_b, dtype=np.int64)
    srt = np.argsort(a[res_a], kind="stable")
    return res_a[srt], res_b[srt]
