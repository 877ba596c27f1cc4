"""``studiotrack eval --gt GT --est EST [--json]``: ATE/RPE of two TUM trajectories.

ATE and RPE are the TUM RGB-D benchmark's (see ``engine.evaluation.metrics``): ATE after rigid
alignment (no scale), stamps associated within ``--max-diff`` seconds; RPE over pose pairs
``--delta`` seconds apart, reported as RMSE in m/s and deg/s. OTB box files (four values per
line, ``x,y,w,h``) are scored with OTB's success AUC and precision at 20 px instead.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from app.commands import CommandSpec
from app.commands._common import emit_json, log, number_arg


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--gt", required=True, metavar="GT", help="ground truth (TUM or OTB boxes)")
    p.add_argument("--est", required=True, metavar="EST", help="estimate (same format as GT)")
    p.add_argument("--json", action="store_true", help="end with one JSON line of results")
    p.add_argument("--max-diff", type=number_arg(gt=0, hi=1e6), default=0.02, metavar="S",
                   help="max timestamp difference for association (s, default 0.02 as TUM)")
    p.add_argument("--delta", type=number_arg(gt=0, hi=1e6), default=1.0, metavar="S",
                   help="RPE pose-pair spacing in seconds (default 1.0)")


def _columns(path: Path) -> int:
    """Number of values on the first data line (8 for TUM, 4 for OTB boxes); 0 if unknown."""
    try:
        with path.open(encoding="utf-8") as fh:
            for line in fh:
                s = line.strip()
                if s and not s.startswith("#"):
                    return len(s.replace(",", " ").replace("\t", " ").split())
    except (OSError, UnicodeDecodeError):
        return 0
    return 0


def evaluate_files(gt_path: Path, est_path: Path, *, max_diff_s: float = 0.02,
                   delta_s: float = 1.0) -> dict[str, Any]:
    """The metrics of ``est_path`` against ``gt_path`` as a JSON-ready dict."""
    from engine.errors import EvaluationError

    if _columns(gt_path) == 4 or _columns(est_path) == 4:
        return _evaluate_boxes(gt_path, est_path)
    from engine.evaluation.metrics import ate, rpe
    from engine.evaluation.trajectory import read_tum

    gt = read_tum(gt_path)
    est = read_tum(est_path)
    a = ate(gt, est, max_diff_s=max_diff_s)
    out: dict[str, Any] = {
        "gt": str(gt_path),
        "est": str(est_path),
        "poses_gt": len(gt),
        "poses_est": len(est),
        "associated": a.n_associated,
        "ate_rmse_m": a.rmse_m,
        "ate_mean_m": a.mean_m,
        "ate_median_m": a.median_m,
        "ate_max_m": a.max_m,
        "rpe_trans_m_per_s": None,
        "rpe_rot_deg_per_s": None,
        "rpe_pairs": 0,
        "rpe_delta_s": delta_s,
    }
    try:
        r = rpe(gt, est, delta_s=delta_s)
    except EvaluationError as exc:
        out["notes"] = [f"RPE: {exc}"]
        log(f"note: RPE: {exc}")
    else:
        out["rpe_trans_m_per_s"] = r.trans_rmse_m_per_s
        out["rpe_rot_deg_per_s"] = r.rot_rmse_deg_per_s
        out["rpe_pairs"] = r.n_pairs
    return out


def _evaluate_boxes(gt_path: Path, est_path: Path) -> dict[str, Any]:
    from engine.evaluation.boxes import box_scores, read_boxes

    g = read_boxes(gt_path)
    e = read_boxes(est_path)
    if g.shape[0] != e.shape[0]:
        from engine.errors import EvaluationError

        raise EvaluationError(
            f"{est_path}: {e.shape[0]} boxes but {gt_path} has {g.shape[0]} (one per frame)"
        )
    sc = box_scores(g, e)
    return {
        "gt": str(gt_path),
        "est": str(est_path),
        "frames": int(g.shape[0]),
        "frames_with_gt": sc.n_frames,
        "success_auc": sc.success_auc,
        "precision_20px": sc.precision_20px,
        "mean_iou": sc.mean_iou,
    }


def run(args: argparse.Namespace) -> int:
    res = evaluate_files(Path(args.gt), Path(args.est), max_diff_s=args.max_diff,
                         delta_s=args.delta)
    if args.json:
        emit_json(res)
    else:
        for k, v in res.items():
            print(f"{k:18s} {v:.6f}" if isinstance(v, float) else f"{k:18s} {v}")
    return 0


COMMANDS = (
    CommandSpec(
        name="eval",
        help="ATE/RPE of an estimated TUM trajectory against ground truth (or OTB box scores)",
        description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
        add_arguments=add_arguments,
        run=run,
    ),
)
