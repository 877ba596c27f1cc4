"""Ablation of the pan-tilt tracker's extensions beyond Gaspar 2009 (``bench ptz`` ``ablation``).

Each extension of :data:`engine.trackers.ptz.EXTENSIONS` that is on by default is switched
off (its overrides, the paper's computation for that part) one at a time from our default
set; and, on the paper's own scenarios, switched on one at a time in the paper's set
(``preset=paper``). Every variant runs the same scenarios on the same seeds (the simulator's
image-noise seed), so each difference is paired per seed (:func:`engine.bench.stats.
paired_difference`, bootstrap interval over the seeds):

- ``paper_experiment``: the circle of sec. 6.2 (2 pi 0.0217 rad/s, 140 s, 0.5 s sampling,
  distorting lens corrected by the line-based model), as ``paper_experiment.*``;
- ``paper_range``: 7 m to 40 cm and back along the line of sight, as ``paper_range.*``;
- ``harder_30hz`` / ``harder_beyond_bank``: our harder cases (the circle at 30 Hz; a target
  turning at 2 pi 0.08 rad/s on a 1.2 m circle, faster than the bank's largest model),
  shortened to :data:`HARDER_DURATION_S` (the steady window starts at 20 s as everywhere).

Per scenario, ``rows`` (default all on, then ``without X``: ``minus_default`` > 0 means the
extension helps) and ``added`` (paper all off, then ``paper + X``: ``minus_paper`` < 0 means
the extension helps); ``attribution`` puts the paper-minus-default difference beside each
extension's single effect, both ways (the effects need not add up: they interact); a row's
``active`` is false where switching the extension changed nothing on any seed (it never acted).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np

from engine.bench.plots import save_figure
from engine.bench.stats import bootstrap_ci, paired_difference
from engine.progress import log

#: the harder cases run this long in the ablation (the full groups run 140 s)
HARDER_DURATION_S = 40.0
#: image-noise seeds of the simulator (3 is the seed of the other ``bench ptz`` groups)
DEFAULT_SEEDS = (3, 4, 5)
#: the per-run figures compared (medians over the run's steady window)
METRICS = ("pos_err_m_steady", "pos_err_m_steady_p95", "vel_err_m_s_steady")
#: the scenarios on which the paper's set is also run with one extension on
PAPER_SCENARIOS = ("paper_experiment", "paper_range")


def scenarios(harder_duration_s: float = HARDER_DURATION_S) -> dict[str, tuple[Any, float]]:
    """name -> (scenario, true turn rate rad/s)."""
    from engine.ptz.paper_sim import PAPER_OMEGA_RAD_S, paper_circle, paper_range

    circle = paper_circle()
    fast = dataclasses.replace(circle, fps=30.0, duration_s=harder_duration_s)
    beyond = dataclasses.replace(fast, period_s=1.0 / 0.08, radius_m=1.2)
    return {"paper_experiment": (circle, PAPER_OMEGA_RAD_S),
            "paper_range": (paper_range(), PAPER_OMEGA_RAD_S),
            "harder_30hz": (fast, PAPER_OMEGA_RAD_S),
            "harder_beyond_bank": (beyond, 2.0 * math.pi * 0.08)}


def variants(base: Any) -> tuple[dict[str, Any], dict[str, Any]]:
    """(default-side, paper-side) variants of ``base`` (our params for a scenario): name ->
    params. Extensions off by default get no default-side variant (nothing to switch off);
    a ``paper + X`` that equals the paper set is left out."""
    from engine.trackers.ptz import EXTENSIONS

    paper = base.with_preset("paper")
    dflt: dict[str, Any] = {"default": base}
    pap: dict[str, Any] = {"paper": paper}
    for name, ext in EXTENSIONS.items():
        off = dataclasses.replace(base, **ext.values)
        if off == base:
            continue
        dflt[f"without {name}"] = off
        on = dataclasses.replace(paper, **{k: getattr(base, k) for k in ext.values})
        if on != paper:
            pap[f"paper + {name}"] = on
    return dflt, pap


def _run(sc: Any, params: Any, omega: float, calibration: Any) -> dict[str, float]:
    from engine.bench.ptz_paper import summary, track

    s = summary(track(sc, params, calibration=calibration), params.omegas, omega)
    out = {k: (math.nan if s[k] is None else float(s[k])) for k in METRICS}
    out["true_model_prob_final"] = (math.nan if s["true_model_prob_final"] is None
                                    else float(s["true_model_prob_final"]))
    out["resets"] = float(s["resets"])
    return out


def _row(name: str, runs: Sequence[dict[str, float]]) -> dict[str, Any]:
    row: dict[str, Any] = {"name": name}
    for k in (*METRICS, "true_model_prob_final", "resets"):
        v = np.array([r[k] for r in runs], dtype=np.float64)
        row[k] = float(np.mean(v))
        row[f"{k}_per_seed"] = v.tolist()
        if k in METRICS:
            row[f"{k}_ci95"] = list(bootstrap_ci(v))
    return row


def _paired(runs: Sequence[dict[str, float]], ref: Sequence[dict[str, float]]
            ) -> dict[str, Any]:
    return {k: paired_difference([r[k] for r in runs], [r[k] for r in ref]) for k in METRICS}


def _rows(runs: Mapping[str, list[dict[str, float]]], names: Sequence[str], ref: str,
          ref_label: str, prefix: str, diff_key: str) -> list[dict[str, Any]]:
    """The reference's row, then one per variant with its paired difference to it."""
    out = [_row(ref_label, runs[ref])]
    for vname in names:
        if vname != ref:
            out.append({**_row(vname, runs[vname]), "extension": vname.removeprefix(prefix),
                        diff_key: _paired(runs[vname], runs[ref]),
                        "active": runs[vname] != runs[ref]})
    return out


def ablation(names: Sequence[str] | None = None, seeds: Sequence[int] = DEFAULT_SEEDS,
             harder_duration_s: float = HARDER_DURATION_S,
             table: Mapping[str, tuple[Any, float]] | None = None,
             added_on: Sequence[str] = PAPER_SCENARIOS) -> dict[str, Any]:
    """The ablation table (module docstring) over ``names`` of :func:`scenarios` (all by
    default; ``table`` replaces the scenarios, for tests); the ``paper + X`` rows on the
    scenarios ``added_on``."""
    from engine.ptz.paper_sim import lens_calibration
    from engine.ptz.sim import PtzSimSource
    from engine.trackers.ptz import EXTENSIONS, PtzParams

    table = dict(table if table is not None else scenarios(harder_duration_s))
    out: dict[str, Any] = {
        "seeds": list(seeds), "metrics": list(METRICS),
        "what": "default set with one extension off at a time ('minus_default' > 0: the "
        "extension helps), and on the paper's scenarios the paper set with one extension on "
        "('minus_paper' < 0: it helps); paired per-seed differences of the steady-window "
        "medians, bootstrap 95 % intervals over the seeds",
        "extensions": {n: {"help": e.help, "off_values": dict(e.values),
                           "on_by_default": dataclasses.replace(cast(Any, PtzParams()),
                                                                **e.values) != PtzParams()}
                       for n, e in EXTENSIONS.items()},
        "scenarios": {}}
    for name in names or list(table):
        sc0, omega = table[name]
        base = PtzParams(target_b=sc0.ball_bgr[0], target_g=sc0.ball_bgr[1],
                         target_r=sc0.ball_bgr[2], target_radius_m=sc0.ball_radius_m)
        cal = lens_calibration(PtzSimSource(sc0))[0] if sc0.distortion_k3 != 0.0 else None
        dflt, pap = variants(base)
        if name not in added_on:
            pap = {"paper": pap["paper"]}
        runs: dict[str, list[dict[str, float]]] = {}
        for vname, params in {**dflt, **pap}.items():
            runs[vname] = [_run(dataclasses.replace(sc0, seed=int(s)), params, omega, cal)
                           for s in seeds]
            e = np.mean([r["pos_err_m_steady"] for r in runs[vname]])
            log(f"  ablation {name}: {vname:28s} steady pos err {100 * e:.1f} cm "
                f"(mean over {len(seeds)} seeds)")
        rows = _rows(runs, list(dflt), "default", "default (all on)", "without ",
                     "minus_default")
        added = _rows(runs, list(pap), "paper", "paper (all off)", "paper + ", "minus_paper")
        total = paired_difference([r["pos_err_m_steady"] for r in runs["paper"]],
                                  [r["pos_err_m_steady"] for r in runs["default"]])
        attribution: dict[str, Any] = {"paper_minus_default_pos_err_m": total}
        for r in rows[1:]:
            attribution[r["extension"]] = {
                "removed_from_default_m": r["minus_default"]["pos_err_m_steady"]["mean_diff"]}
        for r in added[1:]:
            attribution.setdefault(r["extension"], {})["added_to_paper_m"] = (
                -r["minus_paper"]["pos_err_m_steady"]["mean_diff"])
        out["scenarios"][name] = {
            "duration_s": float(sc0.duration_s), "fps": float(sc0.fps),
            "true_omega_rad_s": float(omega), "lens_k3": float(sc0.distortion_k3),
            "rows": rows, "added": added, "attribution": attribution}
    return out


def plot(abl: Mapping[str, Any], folder: Path) -> str:
    """``ptz_ablation.png``: per scenario, each extension's effect on the steady position
    error, removed from the default and added to the paper set (bars, with intervals)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    scen = abl["scenarios"]
    fig, axes = plt.subplots(1, len(scen), figsize=(4.2 * len(scen), 3.8), squeeze=False)
    for ax, (name, s) in zip(axes[0], scen.items(), strict=True):
        labels, vals, lo, hi, colours = [], [], [], [], []
        for r in s["rows"][1:]:
            d = r["minus_default"]["pos_err_m_steady"]
            labels.append(f"- {r['extension']}")
            vals.append(100 * d["mean_diff"])
            lo.append(100 * (d["mean_diff"] - d["ci95"][0]))
            hi.append(100 * (d["ci95"][1] - d["mean_diff"]))
            colours.append("tab:blue")
        for r in s["added"][1:]:
            d = r["minus_paper"]["pos_err_m_steady"]
            labels.append(f"paper + {r['extension']}")
            vals.append(-100 * d["mean_diff"])
            lo.append(100 * (d["ci95"][1] - d["mean_diff"]))
            hi.append(100 * (d["mean_diff"] - d["ci95"][0]))
            colours.append("tab:orange")
        y = np.arange(len(labels))
        ax.barh(y, vals, xerr=[lo, hi], color=colours)
        ax.set_yticks(y, labels, fontsize=7)
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_xlabel("error the extension saves (cm)", fontsize=8)
        ax.set_title(name, fontsize=9)
        ax.grid(alpha=0.3, axis="x")
    fig.suptitle("PTZ ablation: blue = default minus the extension, orange = paper plus it "
                 "(> 0: the extension helps)", fontsize=9)
    return save_figure(fig, folder, "ptz_ablation.png")
