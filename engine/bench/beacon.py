"""``studiotrack bench beacon``: the experiments of Yang et al. 2007 (sec. IV) and beyond.

Range-only data with a random-walk motion model fix the map and path only up to a rotation /
reflection about the start; the paper's quadrant initialisation (sec. III.B) does not pin
that down for its own layout (beacons and path are nearly symmetric about y = x, and the
mirrored map fits every quadrant). So two settings are run side by side:

A. **The paper's experiment** (top-level ``with_ma`` / ``without_ma``): 4 beacons A(10, 10),
   B(22, 0), C(-12, -16), D(5, 15), 120 steps, 200 particles, quadrant-only initialisation
   with the multi-hypothesis start-up (each beacon a mixture of bearings on its first-range
   circle until the path turns) and the gauge-aligned estimate (``engine.beacons.filter``).
   ``path_rmse`` / ``beacon_err_final`` are measured after the best rotation/reflection about
   the start (one per run, fitted on path and final beacons together, like ATE alignment);
   the unaligned numbers are given as ``*_raw``. ``startup_fix`` compares, on the same data,
   the old one-point-per-beacon start-up (``ring_hypotheses=0``, no gauge alignment).
B. **Operator default** (``layout_hint_3m``): the same, but the operator's layout known to
   +-3 m fixes the frame (``hint_sigma_m=3``): absolute errors, no alignment.

Every summary also gives the *shape* error (``path_rmse_shape``, ``err_over_time_shape_mean``:
after the best rotation/reflection about the start): range-only data do not observe a common
rotation of camera and map, so in setting B the absolute error grows with the distance from
the start (the rotation drifts away from the hint's) even while the map converges.

Further: path error over time with and without Map Adjustment (eq. 12), averaged over seeds
(PNG); the particle count needed for "the paper's accuracy" with and without MA. The paper
states no number (figs. 7-8 are plots; the text says the error "converge[s]" and that MA
keeps "the same accuracy with fewer particles" than 200 particles without it), so we define
the paper's accuracy as the mean path RMSE (over seeds) of the filter *without* MA at the
paper's 200 particles in this same run, +10 %, and find the smallest particle count of a grid
whose mean reaches it, in setting A (and B for reference); the sweeps use at most 20 seeds
and counts up to 500 (time), and the target is taken from the sweep's own 200-particle run;
the same is done for the final beacon error (the paper's claim for MA is about the features).
Then steps per second at 200 particles (tracker adapter and bare filter, medians of
repeats) and robustness to 10 % outlier ranges (setting B: plain Gaussian weighting as in the
paper vs robust weighting).

Part 2 (:mod:`engine.bench.beacon_paper`): the paper's method as published (``preset=paper``)
beside ours on a studio-like simulation (``paper``, ``default``, ``studio``), on the paper's
own experiment (``paper_experiment_sets``), the particles each needs for the paper's accuracy
on a 75th-percentile metric with bootstrap intervals (``particles_for_accuracy``) and the
ablation of every extension (``ablation``). ``--tune-p`` only chooses the Map Adjustment gain
of both sets on training seeds.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from engine.bench import BenchSpec
from engine.bench import beacon_paper as bp
from engine.bench.beacon_paper import run_sim
from engine.bench.plots import save_figure
from engine.progress import log

HELP = "range-beacon SLAM (Yang 2007): paper experiment, Map Adjustment, particles, speed"

PARTICLE_GRID = (10, 20, 50, 100, 200, 500)
SWEEP_SEEDS = 20
TOLERANCE = 1.10
LABELS = {"with_ma": "with MA", "without_ma": "without MA"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seeds", type=int, default=30, help="seeds per setting (default 30)")
    parser.add_argument("--plots", type=Path, default=None, help="folder for PNG plots")
    parser.add_argument("--quick", action="store_true", help="fewer seeds and particle counts")
    parser.add_argument("--tune-p", action="store_true",
                        help="only choose the Map Adjustment gain p of the paper and default "
                        "sets on training seeds (1000+), print the objective per p")


def run_once(params: Any, seed: int, sim_cfg: Any, layout: dict[str, tuple[float, float]]
             ) -> dict[str, Any]:
    """One run of the paper's experiment (seed ``seed``, filter seed 1000 + seed)."""
    from engine.beacons.simulator import simulate

    return run_sim(params, simulate(layout, replace(sim_cfg, seed=seed)), layout, 1000 + seed)


def _summary(runs: list[dict[str, Any]], aligned: bool) -> dict[str, Any]:
    """Means over seeds (medians alongside); ``path_rmse`` is aligned or raw (module doc)."""

    def mean(key: str) -> float:
        return float(np.mean([r[key] for r in runs]))

    sfx = "_aligned" if aligned else ""
    curve = np.mean([r["err_t" + sfx] for r in runs], axis=0)
    curve_al = np.mean([r["err_t_aligned"] for r in runs], axis=0)
    return {
        "metric": "after best rotation/reflection about the start" if aligned
        else "absolute (no alignment)",
        "path_rmse_shape": mean("path_rmse_aligned"),
        "beacon_err_final_shape": mean("beacon_err_final_aligned"),
        "err_over_time_shape_mean": curve_al,
        "path_rmse": mean("path_rmse" + sfx),
        "beacon_err_final": mean("beacon_err_final" + sfx),
        "beacon_err_final_median": float(np.median([r["beacon_err_final" + sfx] for r in runs])),
        "final20_mean_err": float(np.mean([np.mean(r["err_t" + sfx][-20:]) for r in runs])),
        "path_rmse_raw": mean("path_rmse"),
        "beacon_err_final_raw": mean("beacon_err_final"),
        "path_rmse_median": float(np.median([r["path_rmse" + sfx] for r in runs])),
        "path_rmse_p90": float(np.percentile([r["path_rmse" + sfx] for r in runs], 90)),
        "err_over_time_mean": curve,
    }


def _series(d: dict[str, Any]) -> dict[str, Any]:
    """JSON copy: the error-over-time curve rounded to cm, every 10th step."""
    o = dict(d)
    for k in ("err_over_time_mean", "err_over_time_shape_mean"):
        o[k] = [round(float(v), 2) for v in d[k][::10]]
    return o


def _steps_per_s(params: Any, repeats: int = 5, n_steps: int = 600) -> tuple[float, float]:
    """Median steps/s of the tracker adapter and of the bare filter at ``params``."""
    from engine.beacons.filter import BeaconSlamFilter
    from engine.beacons.simulator import PAPER_LAYOUT, SimConfig, simulate
    from engine.sources.beacons import BeaconSimSource
    from engine.trackers.beacon_slam import BeaconSlamTracker

    src = BeaconSimSource(PAPER_LAYOUT, SimConfig(n_steps=n_steps, speed_m=0.02, seed=7))
    frames = list(src.frames())
    sim = simulate(PAPER_LAYOUT, SimConfig(n_steps=n_steps, speed_m=0.02, seed=7))
    tr_rates, f_rates = [], []
    for _ in range(repeats):
        tr = BeaconSlamTracker(params)
        t0 = time.perf_counter()
        for fr in frames:
            tr.track(fr)
        tr_rates.append(len(frames) / (time.perf_counter() - t0))
        f = BeaconSlamFilter(sim.ids, params, layout_xy=PAPER_LAYOUT)
        t0 = time.perf_counter()
        for t in range(len(sim.ranges_m)):
            f.step(sim.ranges_m[t])
        f_rates.append(len(sim.ranges_m) / (time.perf_counter() - t0))
    return float(np.median(tr_rates)), float(np.median(f_rates))


def _plots(folder: Path, settings: dict[str, dict[str, Any]],
           example: dict[str, dict[str, Any]], sweeps: dict[str, dict[str, Any]]) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    out: list[str] = []
    titles = {"paper": "A: paper init (quadrant), error after rotation/reflection",
              "hint": "B: layout known to 3 m, absolute error"}

    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    for ax, (name, res) in zip(axes, settings.items(), strict=True):
        for key, label in (("without_ma", "without Map Adjustment"),
                           ("with_ma", "with Map Adjustment")):
            y = res[key]["err_over_time_mean"]
            line, = ax.plot(np.arange(len(y)), y, label=label)
            if name == "hint":
                ys = res[key]["err_over_time_shape_mean"]
                ax.plot(np.arange(len(ys)), ys, ls="--", color=line.get_color(),
                        label=f"{label}, after rotation about start")
        ax.set_xlabel("time step")
        ax.set_ylabel("camera position error (m), mean over seeds")
        ax.set_title(titles[name], fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle("Path error over time, 200 particles (cf. paper fig. 7/8)")
    out.append(save_figure(fig, folder, "beacon_error_over_time.png"))

    fig, axes = plt.subplots(1, 2, figsize=(11, 5))
    for ax, key in zip(axes, ("without_ma", "with_ma"), strict=True):
        r = example[key]
        ax.plot(r["truth"][:, 0], r["truth"][:, 1], "k-", label="true path")
        ax.plot(r["path"][:, 0], r["path"][:, 1], "b-", label="estimated path")
        ax.plot(r["truth_beacons"][:, 0], r["truth_beacons"][:, 1], "k^", ms=9,
                label="true beacons")
        ax.plot(r["beacons"][:, 0], r["beacons"][:, 1], "rx", ms=9, label="estimated beacons")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_title(f"B, seed 0, {LABELS[key]}: path RMSE {r['path_rmse']:.2f} m",
                     fontsize=10)
        ax.legend(fontsize=8)
    out.append(save_figure(fig, folder, "beacon_trajectory.png"))

    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    for ax, (name, sw) in zip(axes, sweeps.items(), strict=True):
        for key in ("with_ma", "without_ma"):
            curve = sw["curves"][key]
            ns = sorted(curve)
            ax.plot(ns, [curve[n] for n in ns], "o-", label=LABELS[key])
        ax.axhline(sw["target"], color="k", ls="--", label="paper's accuracy (our definition)")
        ax.set_xscale("log")
        ax.set_xlabel("particles")
        ax.set_ylabel("mean path RMSE over seeds (m)")
        ax.set_title(titles[name], fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    out.append(save_figure(fig, folder, "beacon_particles.png"))
    return out


def _sweep(base: Any, grid: tuple[int, ...], seeds: range, sim_cfg: Any,
           layout: dict[str, tuple[float, float]], aligned: bool, name: str
           ) -> dict[str, Any]:
    """Mean path RMSE (and final beacon error, the paper's MA claim is about the features)
    per particle count with/without MA; the counts reaching the target (the no-MA mean at
    the paper's 200 particles, +10 %)."""
    sfx = "_aligned" if aligned else ""
    metrics = {"path": "path_rmse" + sfx, "beacon": "beacon_err_final" + sfx}
    curves: dict[str, dict[str, dict[int, float]]] = {
        m: {"with_ma": {}, "without_ma": {}} for m in metrics}
    std_err: dict[str, dict[str, dict[int, float]]] = {
        m: {"with_ma": {}, "without_ma": {}} for m in metrics}
    for n in grid:
        for key, mk in (("with_ma", True), ("without_ma", False)):
            pn = replace(base, n_particles=n, map_adjustment=mk)
            rs = [run_once(pn, s, sim_cfg, layout) for s in seeds]
            for m, k in metrics.items():
                v = np.array([r[k] for r in rs])
                curves[m][key][n] = float(np.mean(v))
                std_err[m][key][n] = float(np.std(v, ddof=1) / math.sqrt(len(v)))
        c = curves["path"]
        cb = curves["beacon"]
        log(f"  {name} {n:4d} particles: path with MA {c['with_ma'][n]:.2f} m, without "
             f"{c['without_ma'][n]:.2f} m; beacons with MA {cb['with_ma'][n]:.2f} m, without "
             f"{cb['without_ma'][n]:.2f} m")

    out: dict[str, Any] = {}
    for m in metrics:
        target = curves[m]["without_ma"][200] * TOLERANCE

        def needed(curve: dict[int, float], target: float = target) -> int | None:
            return next((n for n in sorted(curve) if curve[n] <= target), None)

        need = {"with_ma": needed(curves[m]["with_ma"]),
                "without_ma": needed(curves[m]["without_ma"])}
        ratio = (need["without_ma"] / need["with_ma"]
                 if need["with_ma"] and need["without_ma"] else None)
        log(f"  {name} {m}: accuracy target {target:.2f} m reached with MA at "
             f"{need['with_ma']}, without at {need['without_ma']} particles")
        out[m] = {"need": need, "ratio": ratio, "target": target, "curves": curves[m],
                  "std_err": std_err[m]}
    return {**out["path"], "beacon": out["beacon"]}


def run(args: argparse.Namespace) -> dict[str, Any]:
    from engine.beacons.params import BeaconFilterParams
    from engine.beacons.simulator import PAPER_LAYOUT, SimConfig

    n_seeds = max(2, int(args.seeds) if not args.quick else min(int(args.seeds), 4))
    if args.tune_p:
        log(f"beacon bench: choosing p on training seeds ({n_seeds} seeds from "
            f"{bp.TRAIN_SEED0})")
        return {"bench": "beacon", "map_adjust_p_tuning": bp.tune_map_adjust_p(n_seeds)}
    seeds = range(n_seeds)
    grid = PARTICLE_GRID if not args.quick else (20, 50, 200)
    sweep_seeds = range(min(n_seeds, SWEEP_SEEDS))
    paper = BeaconFilterParams(n_particles=200, hint_sigma_m=0.0)
    hint = replace(paper, hint_sigma_m=3.0)
    sim_cfg = SimConfig()
    layout = dict(PAPER_LAYOUT)
    t_start = time.perf_counter()

    runs: dict[str, dict[str, list[dict[str, Any]]]] = {}
    settings: dict[str, dict[str, Any]] = {}
    for name, base, aligned in (("paper", paper, True), ("hint", hint, False)):
        log(f"beacon bench: setting {'A (paper init)' if name == 'paper' else 'B (hint 3 m)'}"
             f", 120 steps, 200 particles, {n_seeds} seeds")
        runs[name] = {
            "with_ma": [run_once(base, s, sim_cfg, layout) for s in seeds],
            "without_ma": [run_once(replace(base, map_adjustment=False), s, sim_cfg, layout)
                           for s in seeds],
        }
        settings[name] = {k: _summary(v, aligned) for k, v in runs[name].items()}
        for k, v in settings[name].items():
            log(f"  {k:11s} path RMSE {v['path_rmse']:.2f} m ({v['metric']}; raw "
                 f"{v['path_rmse_raw']:.2f} m), final beacon error {v['beacon_err_final']:.2f} m")

    log("beacon bench: start-up fix, setting A with MA: old point start-up on the same data")
    old = replace(paper, ring_hypotheses=0, gauge_aligned_estimate=False)
    old_runs = [run_once(old, s, sim_cfg, layout) for s in seeds]
    startup_json: dict[str, Any] = {}
    for key in ("path_rmse_aligned", "beacon_err_final_aligned"):
        d = np.array([a[key] - b[key] for a, b in
                      zip(runs["paper"]["with_ma"], old_runs, strict=True)])
        startup_json[key] = {
            "ring_mean": float(np.mean([r[key] for r in runs["paper"]["with_ma"]])),
            "ring_median": float(np.median([r[key] for r in runs["paper"]["with_ma"]])),
            "point_mean": float(np.mean([r[key] for r in old_runs])),
            "point_median": float(np.median([r[key] for r in old_runs])),
            "paired_mean_diff_m": float(np.mean(d)),
            "paired_std_err_m": float(np.std(d, ddof=1) / math.sqrt(len(d))),
        }
        log(f"  {key}: ring start-up {startup_json[key]['ring_mean']:.2f} m, point start-up "
             f"{startup_json[key]['point_mean']:.2f} m (paired diff "
             f"{startup_json[key]['paired_mean_diff_m']:+.2f} ± "
             f"{startup_json[key]['paired_std_err_m']:.2f} m)")

    log(f"beacon bench: particle sweeps {grid}, {len(sweep_seeds)} seeds")
    sweeps = {
        "paper": _sweep(paper, grid, sweep_seeds, sim_cfg, layout, True, "A"),
        "hint": _sweep(hint, grid, sweep_seeds, sim_cfg, layout, False, "B"),
    }

    log("beacon bench: 10 % outlier ranges (setting B)")
    out_cfg = replace(sim_cfg, outlier_prob=0.10)
    outl = {
        "clean_robust": _summary([run_once(hint, s, sim_cfg, layout) for s in seeds], False),
        "outliers_paper_weighting": _summary(
            [run_once(replace(hint, outlier_prob=0.0), s, out_cfg, layout) for s in seeds],
            False),
        "outliers_robust": _summary([run_once(hint, s, out_cfg, layout) for s in seeds],
                                    False),
    }
    for k, v in outl.items():
        log(f"  {k:25s} path RMSE {v['path_rmse']:.2f} m, beacons {v['beacon_err_final']:.2f} m")

    log(f"beacon bench: studio simulation, paper and default sets, {n_seeds} seeds")
    studio = bp.studio_scene(n_seeds)
    s_grid = bp.GRID if not args.quick else bp.QUICK_GRID
    sweep = bp.particle_sweep(studio, s_grid)
    side = bp.side_by_side(sweep, studio)
    log("beacon bench: the paper's experiment (4 beacons, 120 steps), paper and default sets")
    paper_scene = bp.paper_scene(n_seeds)
    paper_sweep = bp.particle_sweep(paper_scene, (200,))
    side_paper = bp.side_by_side(paper_sweep, paper_scene)
    need = bp.particles_needed(s_grid, sweep, "beacon_err_final", "paper", bp.SETS)
    need_path = bp.particles_needed(s_grid, sweep, "path_rmse", "paper", bp.SETS)
    need_own = bp.particles_needed(s_grid, sweep, "beacon_err_final", "default", ("default",))
    for s_name in bp.SETS:
        nd = need[s_name]
        log(f"  particles for the paper's accuracy ({need['target_m']:.2f} m, p75 beacon "
            f"error): {s_name} with MA {nd['with_ma']} {nd['ci95']['with_ma']}, without "
            f"{nd['without_ma']} {nd['ci95']['without_ma']}")
    log("beacon bench: ablation on the studio (200 particles, with MA)")
    abl = bp.ablation(studio)

    log("beacon bench: speed at 200 particles (medians of 5 repeats, shared CPU)")
    tracker_rate, filter_rate = (_steps_per_s(hint, 3, 200) if args.quick
                                 else _steps_per_s(hint))
    log(f"  tracker {tracker_rate:.0f} steps/s, filter alone {filter_rate:.0f} steps/s")

    plots: list[str] = []
    if args.plots is not None:
        example = {k: runs["hint"][k][0] for k in runs["hint"]}
        plots = _plots(Path(args.plots), settings, example, sweeps)
        plots += bp.plots(Path(args.plots), side, {k: v[200] for k, v in sweep.items()},
                          need, abl)
        log(f"  plots: {', '.join(plots)}")

    def sweep_json(sw: dict[str, Any]) -> dict[str, Any]:
        def table(c: dict[str, dict[int, float]]) -> dict[str, dict[str, float]]:
            return {k: {str(n): v for n, v in cc.items()} for k, cc in c.items()}

        bw = sw["beacon"]
        return {
            **sw["need"],
            "ratio_without_over_with": sw["ratio"],
            "target_path_rmse_m": sw["target"],
            "sweep_mean_path_rmse": table(sw["curves"]),
            "sweep_std_err_path_rmse": table(sw["std_err"]),
            "by_final_beacon_error": {
                **bw["need"], "ratio_without_over_with": bw["ratio"],
                "target_beacon_err_m": bw["target"],
                "sweep_mean_beacon_err": table(bw["curves"]),
                "sweep_std_err_beacon_err": table(bw["std_err"])},
        }

    def ma_effect(name: str, key: str) -> dict[str, float]:
        """Paired per-seed difference of path RMSE, with MA minus without (same data)."""
        d = np.array([a[key] - b[key] for a, b in
                      zip(runs[name]["with_ma"], runs[name]["without_ma"], strict=True)])
        return {"mean_diff_m": float(np.mean(d)),
                "std_err_m": float(np.std(d, ddof=1) / math.sqrt(len(d))),
                "fraction_of_seeds_ma_better": float(np.mean(d < 0.0))}

    # the path metric alone saturates in setting A (its floor is the straight-leg / turn error,
    # reached with 10-50 particles), so the goal counts only if the final beacon error, the
    # paper's own claim for MA, agrees
    ratio = sweeps["paper"]["ratio"]
    ratio_b = sweeps["paper"]["beacon"]["ratio"]
    return {
        "bench": "beacon",
        "setup": {"steps": sim_cfg.n_steps, "beacons": layout, "particles": 200,
                  "seeds": n_seeds, "range_noise_m": sim_cfg.noise_sigma_m,
                  "step_m": sim_cfg.speed_m, "motion_sigma_m": paper.motion_sigma_m,
                  "range_sigma_m": paper.range_sigma_m, "map_adjust_p": paper.map_adjust_p,
                  "map_spread_weighting": paper.map_spread_weighting,
                  "roughen_h": paper.roughen_h,
                  "ring_hypotheses_per_90deg": paper.ring_hypotheses,
                  "ring_commit": paper.ring_commit,
                  "gauge_aligned_estimate_setting_a": paper.gauge_aligned_estimate,
                  "statistic": "mean over seeds (medians as *_median)"},
        "with_ma": _series(settings["paper"]["with_ma"]),
        "without_ma": _series(settings["paper"]["without_ma"]),
        "layout_hint_3m": {k: _series(v) for k, v in settings["hint"].items()},
        "ma_effect_paired": {
            "paper_aligned": ma_effect("paper", "path_rmse_aligned"),
            "layout_hint_3m": ma_effect("hint", "path_rmse"),
        },
        "startup_fix": {**startup_json, "seeds": n_seeds,
                        "what": "setting A with MA, after best rotation/reflection: ring "
                        "start-up + gauge-aligned estimate (now) minus the point start-up "
                        "(before), same data and filter seeds"},
        "particles_for_paper_accuracy": {
            **sweep_json(sweeps["paper"]),
            "definition": "mean path RMSE (setting A, aligned) of the no-MA filter at the "
            "paper's 200 particles +10 % (same sweep seeds), since the paper reports no "
            "number; smallest count of the grid whose mean reaches it",
            "sweep_seeds": len(sweep_seeds),
        },
        "particles_for_accuracy_layout_hint_3m": sweep_json(sweeps["hint"]),
        "outliers_10pct": {k: {kk: vv for kk, vv in v.items()
                               if not kk.startswith("err_over_time")}
                           for k, v in outl.items()},
        "paper": {**side["paper"], "scene": "studio",
                  "params": _params_json(bp.for_scene(bp.set_params("paper"), studio))},
        "default": {**side["default"], "scene": "studio",
                    "params": _params_json(bp.for_scene(bp.set_params("default"), studio))},
        "studio": {
            "scene": _studio_json(n_seeds),
            "metric": "path_rmse / beacon_err_final after the best rotation/reflection "
            "about the start (range-only data do not observe it), *_abs without; means over "
            "seeds with 95 % bootstrap intervals (ci95), p75 = 75th percentile",
            "paper": side["paper"], "default": side["default"],
        },
        "paper_experiment_sets": {
            "scene": "the paper's sec. IV: beacons A-D, 120 steps, 200 particles, each set at "
            "its own motion std",
            "paper": side_paper["paper"], "default": side_paper["default"]},
        "particles_for_accuracy": {
            "metric": need["metric"], "scene": "studio",
            "with_ma": need["paper"]["with_ma"], "without_ma": need["paper"]["without_ma"],
            "ci95": need["paper"]["ci95"],
            "ratio_without_over_with": need["paper"]["ratio_without_over_with"],
            "target_m": need["target_m"], "target_ci95_m": need["target_ci95_m"],
            "definition": "the paper's accuracy = " + need["target_definition"] + " (p75 of "
            "the final beacon error over seeds); particles needed = where the p75 curve over "
            "the grid first reaches it (log-interpolated); ci95 by resampling the seeds",
            "grid": need["grid"], "sets": {k: need[k] for k in bp.SETS},
            "default_to_its_own_accuracy": need_own["default"],
            "default_own_target_m": need_own["target_m"],
            "by_path_rmse": {"metric": need_path["metric"], "target_m": need_path["target_m"],
                             **{k: need_path[k] for k in bp.SETS}},
            "ok_2x_paper_set": bool(need["paper"]["ratio_without_over_with"] is not None
                                    and need["paper"]["ratio_without_over_with"] >= 2.0),
            "ok_2x_default_set": bool(
                need_own["default"]["ratio_without_over_with"] is not None
                and need_own["default"]["ratio_without_over_with"] >= 2.0),
        },
        "ablation": abl,
        "steps_per_s": tracker_rate,
        "steps_per_s_filter_only": filter_rate,
        "plots": plots,
        "elapsed_s": time.perf_counter() - t_start,
        "ok_particles_2x": bool(ratio is not None and ratio >= 2.0
                                and ratio_b is not None and ratio_b >= 2.0),
        "ok_speed_1000": bool(tracker_rate >= 1000.0 and math.isfinite(tracker_rate)),
    }


def _params_json(p: Any) -> dict[str, Any]:
    from dataclasses import asdict

    return {k: v for k, v in asdict(p).items() if k != "seed"}


def _studio_json(n_seeds: int) -> dict[str, Any]:
    from dataclasses import asdict

    from engine.beacons.studio_sim import (
        STUDIO_BEACONS_XYZ,
        StudioRangingConfig,
        studio_camera_path,
    )

    path = studio_camera_path()
    speed = np.linalg.norm(np.diff(path, axis=0), axis=1) * StudioRangingConfig().rate_hz
    return {"beacons_xyz_m": {k: list(v) for k, v in STUDIO_BEACONS_XYZ.items()},
            "steps": len(path), "seeds": n_seeds, "max_speed_m_s": float(speed.max()),
            "camera_height_m": [float(path[:, 2].min()), float(path[:, 2].max())],
            "ranging": {k: v for k, v in asdict(StudioRangingConfig()).items() if k != "seed"},
            "motion_sigma_m": bp.STUDIO_MOTION_SIGMA_M}


BENCHES = (BenchSpec(name="beacon", help=HELP, add_arguments=add_arguments, run=run),)
