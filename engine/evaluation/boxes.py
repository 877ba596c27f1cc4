"""OTB box metrics (Wu, Lim, Yang: Online Object Tracking: A Benchmark, CVPR 2013).

Boxes are ``x, y, w, h`` in pixels (top-left corner, width, height), one per frame.

- IoU as OTB's ``calcRectInt``: intersection over union of the continuous rectangles.
- Success plot: fraction of frames with IoU *greater than* each threshold of
  ``0:0.05:1`` (21 thresholds); its AUC is the mean of the 21 success rates.
- Precision at 20 px: fraction of frames whose centre error is at most 20 px, with OTB's
  centre ``(x + (w - 1) / 2, y + (h - 1) / 2)``.

Frames whose ground-truth box is missing (non-finite, or width/height <= 0, as OTB marks
an absent target) are left out of both numerator and denominator. A missing *estimate*
(non-finite or empty box) counts as a failure (IoU 0, centre error infinite).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from engine.errors import EvaluationError

F64 = NDArray[np.float64]

#: OTB's overlap thresholds 0:0.05:1
SUCCESS_THRESHOLDS = np.linspace(0.0, 1.0, 21)
PRECISION_THRESHOLD_PX = 20.0


def _as_boxes(boxes: object, what: str) -> F64:
    b = np.asarray(boxes, dtype=np.float64)
    if b.ndim == 1 and b.size == 4:
        b = b.reshape(1, 4)
    if b.ndim != 2 or b.shape[1] != 4:
        raise EvaluationError(f"{what}: expected (N, 4) boxes x,y,w,h, got shape {b.shape}")
    return b


def valid_boxes(boxes: F64) -> NDArray[np.bool_]:
    """True where a box is finite with positive width and height."""
    b = _as_boxes(boxes, "boxes")
    finite: NDArray[np.bool_] = np.all(np.isfinite(b), axis=1)
    return finite & (b[:, 2] > 0) & (b[:, 3] > 0)


def iou_xywh(a: object, b: object) -> F64:
    """Intersection over union of (N, 4) box pairs; 0 where either box is empty or invalid."""
    A = _as_boxes(a, "boxes a")
    B = _as_boxes(b, "boxes b")
    if A.shape != B.shape:
        raise EvaluationError(f"box counts differ: {A.shape[0]} vs {B.shape[0]}")
    iw = np.minimum(A[:, 0] + A[:, 2], B[:, 0] + B[:, 2]) - np.maximum(A[:, 0], B[:, 0])
    ih = np.minimum(A[:, 1] + A[:, 3], B[:, 1] + B[:, 3]) - np.maximum(A[:, 1], B[:, 1])
    inter = np.clip(iw, 0.0, None) * np.clip(ih, 0.0, None)
    union = A[:, 2] * A[:, 3] + B[:, 2] * B[:, 3] - inter
    ok = valid_boxes(A) & valid_boxes(B) & (union > 0)
    out = np.zeros(A.shape[0])
    out[ok] = inter[ok] / union[ok]
    return out


def centre_error_px(a: object, b: object) -> F64:
    """Distance between OTB box centres; infinite where either box is invalid."""
    A = _as_boxes(a, "boxes a")
    B = _as_boxes(b, "boxes b")
    if A.shape != B.shape:
        raise EvaluationError(f"box counts differ: {A.shape[0]} vs {B.shape[0]}")
    ca = A[:, :2] + (A[:, 2:] - 1.0) / 2.0
    cb = B[:, :2] + (B[:, 2:] - 1.0) / 2.0
    err = np.full(A.shape[0], np.inf)
    ok = valid_boxes(A) & valid_boxes(B)
    err[ok] = np.linalg.norm(ca[ok] - cb[ok], axis=1)
    return err


@dataclass(frozen=True, slots=True)
class BoxScores:
    """OTB scores of one sequence."""

    success_auc: float  # mean success rate over the 21 IoU thresholds
    precision_20px: float  # fraction of frames with centre error <= 20 px
    mean_iou: float
    n_frames: int  # frames with a valid ground-truth box
    success_rates: F64  # (21,)


def box_scores(gt: object, est: object) -> BoxScores:
    """OTB success AUC and precision at 20 px of estimated boxes against ground truth."""
    G = _as_boxes(gt, "ground-truth boxes")
    E = _as_boxes(est, "estimated boxes")
    if G.shape != E.shape:
        raise EvaluationError(
            f"{E.shape[0]} estimated boxes but {G.shape[0]} ground-truth boxes"
        )
    use = valid_boxes(G)
    n = int(use.sum())
    if n == 0:
        raise EvaluationError("no frame has a valid ground-truth box")
    iou = iou_xywh(G[use], E[use])
    cerr = centre_error_px(G[use], E[use])
    rates = np.array([np.mean(iou > thr) for thr in SUCCESS_THRESHOLDS])
    return BoxScores(
        success_auc=float(np.mean(rates)),
        precision_20px=float(np.mean(cerr <= PRECISION_THRESHOLD_PX)),
        mean_iou=float(np.mean(iou)),
        n_frames=n,
        success_rates=rates,
    )


def read_boxes(path: str | Path) -> F64:
    """Read an OTB box file: one ``x,y,w,h`` per line (comma, tab or space separated).

    ``nan`` entries are kept (a missing box); anything else malformed raises EvaluationError.
    """
    path = Path(path)
    if not path.is_file():
        raise EvaluationError(f"{path}: file not found")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise EvaluationError(f"{path}: cannot read ({exc})") from None
    rows: list[list[float]] = []
    for n, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        fields = s.replace(",", " ").replace("\t", " ").split()
        if len(fields) != 4:
            raise EvaluationError(
                f"{path}: line {n}: expected 4 values x,y,w,h, got {len(fields)}"
            )
        try:
            rows.append([float(v) for v in fields])
        except ValueError:
            raise EvaluationError(f"{path}: line {n}: {s!r} is not four numbers") from None
    if not rows:
        raise EvaluationError(f"{path}: no boxes (empty file)")
    return np.asarray(rows, dtype=np.float64)


def boxes_text(boxes: object) -> str:
    """OTB text, one ``x,y,w,h`` per line; a missing box is written as ``0,0,0,0``."""
    B = _as_boxes(boxes, "boxes")
    lines = []
    for b in B:
        if not np.all(np.isfinite(b)):
            lines.append("0,0,0,0")
        else:
            lines.append(",".join(f"{v:.2f}".rstrip("0").rstrip(".") for v in b))
    return "\n".join(lines) + "\n"


def write_boxes(path: str | Path, boxes: object) -> None:
    """Write an OTB box file atomically."""
    from engine.persist import write_text_file

    write_text_file(Path(path), boxes_text(boxes), EvaluationError)
