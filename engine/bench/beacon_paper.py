"""Beacon bench, part 2: the paper's method as published beside ours on a studio simulation.

Used by :mod:`engine.bench.beacon` (``studiotrack bench beacon``). Two parameter sets run on
the same data: ``paper`` (``BeaconFilterParams().with_preset("paper")``: Yang 2007 as
published, no extension) and ``default`` (``BeaconFilterParams()``: ours, the layout known to
+-3 m and every extension of ``EXTENSIONS`` that is on by default), each with and without Map
Adjustment (eq. 12), on

- the studio simulation (:mod:`engine.beacons.studio_sim`: a crane/dolly move in a 3D studio,
  six beacons on walls and rig at 2.2-7 m, UWB-like noise, non-line-of-sight bias and bursty
  dropouts, ranges projected to the floor plane), 356 steps at 10 Hz; the motion std is set
  for the rig (0.1 m per step: ~1 m/s at 10 Hz) in both sets;
- the paper's own experiment (sec. IV: four beacons A-D, 120 steps, fig. 6-8), both sets at
  their own motion std.

Errors are measured after the best rotation/reflection about the start (range-only data do
not observe it, and the paper's set has nothing that fixes it), absolute errors alongside
(``*_abs``). Statistics over seeds: means with 95 % percentile-bootstrap intervals
(``ci95``), and the 75th percentile (a metric that keeps the failures in view).

**Particles for the paper's accuracy** (``particles_for_accuracy``): the paper states no
number; figs. 7-8 compare 200 particles with and without MA and the text says MA keeps "the
same accuracy [...] with fewer particles". So: *the paper's accuracy* is the 75th percentile
over seeds of the final beacon error of the paper's set without MA at 200 particles; the
particles needed are where the curve over the particle grid first reaches it (interpolated in
log N); intervals by resampling the seeds (the same resample for every count and setting).
The path metric is given the same way (``by_path_rmse``).

**Ablation** (``ablation``): the default set on the studio with MA at 200 particles, one
extension switched off at a time (its ``EXTENSIONS`` values), paired per-seed differences
with intervals; and the paper's set with one extension switched on.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from engine.beacons.params import EXTENSIONS, BeaconFilterParams
from engine.beacons.simulator import SimRun
from engine.bench.plots import save_figure
from engine.bench.stats import (
    boot_indices,
    bootstrap_ci,
    first_crossing,
    paired_difference,
    quantile_stat,
)
from engine.progress import log

F64 = NDArray[np.float64]

#: motion std per step for the studio rig (~1 m/s at the 10 Hz ranging rate), both sets
STUDIO_MOTION_SIGMA_M = 0.1
GRID = (10, 20, 50, 100, 200, 500, 1000)
QUICK_GRID = (20, 50, 200)
QUANTILE = 75.0
#: training seeds (for choosing p): disjoint from the reported seeds 0..S-1
TRAIN_SEED0 = 1000
TUNE_P = (0.0, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3)
#: the 'kalman' Map Adjustment's kernel width (fraction of a new beacon's cloud covariance)
TUNE_KERNEL_FRAC = (0.09, 0.25, 0.5, 1.0)
SETS = ("paper", "default")
MA = ("with_ma", "without_ma")
METRICS = ("beacon_err_final", "path_rmse")


def align_rot_reflect(est: F64, gt: F64) -> F64:
    """Best orthogonal map (rotation or reflection) about the origin taking est onto gt."""
    U, _, Vt = np.linalg.svd(est.T @ gt)
    return np.asarray(est @ (U @ Vt), dtype=np.float64)


def run_sim(params: BeaconFilterParams, sim: SimRun, layout: Mapping[str, Sequence[float]],
            filter_seed: int) -> dict[str, Any]:
    """One filter run over ``sim``: errors absolute and after the best rotation/reflection
    about the start (one per run, fitted on path and final beacons together)."""
    from engine.beacons.filter import BeaconSlamFilter

    f = BeaconSlamFilter(sim.ids, replace(params, seed=filter_seed), layout_xy=layout)
    path = np.empty_like(sim.path_xy)
    est = None
    for t in range(len(sim.path_xy)):
        est = f.step(sim.ranges_m[t])
        path[t] = est.cam_xy
    assert est is not None
    beacons = np.where(np.isfinite(est.beacons_xy), est.beacons_xy, 0.0)
    err_t = np.linalg.norm(path - sim.path_xy, axis=1)
    b_err = np.linalg.norm(beacons - sim.beacons_xy, axis=1)
    n = len(path)
    aligned = align_rot_reflect(np.vstack([path, beacons]),
                                np.vstack([sim.path_xy, sim.beacons_xy]))
    err_al = np.linalg.norm(aligned[:n] - sim.path_xy, axis=1)
    b_al = np.linalg.norm(aligned[n:] - sim.beacons_xy, axis=1)
    return {
        "err_t": err_t,
        "err_t_aligned": err_al,
        "path_rmse": float(np.sqrt(np.mean(err_t**2))),
        "final20": float(np.mean(err_t[-20:])),
        "beacon_err_final": float(np.mean(b_err)),
        "path_rmse_aligned": float(np.sqrt(np.mean(err_al**2))),
        "beacon_err_final_aligned": float(np.mean(b_al)),
        "path": path,
        "truth": sim.path_xy,
        "beacons": est.beacons_xy,
        "truth_beacons": sim.beacons_xy,
    }


@dataclass(frozen=True, slots=True)
class Scene:
    """Simulated runs (one per seed) with the layout the operator gives the filter and the
    motion std for the scene (None: keep the set's own)."""

    name: str
    sims: tuple[SimRun, ...]
    layout: Mapping[str, tuple[float, float]]
    motion_sigma_m: float | None


@dataclass(frozen=True, slots=True)
class Runs:
    """Per-seed results of one setting on one scene."""

    path_rmse: F64  # after alignment
    beacon_err_final: F64
    path_rmse_abs: F64
    beacon_err_final_abs: F64
    err_t: F64  # (S, T) aligned error over time
    examples: tuple[dict[str, Any], ...]  # the first run's full record


def studio_scene(n_seeds: int, seed0: int = 0) -> Scene:
    from engine.beacons.studio_sim import StudioRangingConfig, simulate_studio, studio_layout_xy

    sims = tuple(simulate_studio(StudioRangingConfig(seed=seed0 + s)).floor
                 for s in range(n_seeds))
    return Scene("studio", sims, studio_layout_xy(), STUDIO_MOTION_SIGMA_M)


def paper_scene(n_seeds: int) -> Scene:
    from engine.beacons.simulator import PAPER_LAYOUT, SimConfig, simulate

    sims = tuple(simulate(PAPER_LAYOUT, SimConfig(seed=s)) for s in range(n_seeds))
    return Scene("paper_experiment", sims, dict(PAPER_LAYOUT), None)


def with_values(params: BeaconFilterParams, values: Mapping[str, object]
                ) -> BeaconFilterParams:
    """``params`` with the fields in ``values`` replaced (validated)."""
    return cast(BeaconFilterParams, replace(cast(Any, params), **values))


def set_params(name: str, base: BeaconFilterParams | None = None) -> BeaconFilterParams:
    """``paper`` (the preset over the defaults) or ``default``."""
    b = base or BeaconFilterParams()
    return b.with_preset("paper") if name == "paper" else b


def for_scene(params: BeaconFilterParams, scene: Scene) -> BeaconFilterParams:
    if scene.motion_sigma_m is None:
        return params
    return replace(params, motion_sigma_m=scene.motion_sigma_m)


def run_scene(params: BeaconFilterParams, scene: Scene, seed0: int = 0) -> Runs:
    """Every seed of the scene; the filter seed of seed s is 1000 + seed0 + s."""
    p = for_scene(params, scene)
    rs = [run_sim(p, sim, scene.layout, 1000 + seed0 + s) for s, sim in enumerate(scene.sims)]

    def arr(key: str) -> F64:
        return np.array([r[key] for r in rs], dtype=np.float64)

    return Runs(path_rmse=arr("path_rmse_aligned"),
                beacon_err_final=arr("beacon_err_final_aligned"),
                path_rmse_abs=arr("path_rmse"), beacon_err_final_abs=arr("beacon_err_final"),
                err_t=np.array([r["err_t_aligned"] for r in rs]), examples=(rs[0],))


def summary(r: Runs) -> dict[str, Any]:
    """Means with bootstrap intervals, medians and 75th percentiles over the seeds."""
    out: dict[str, Any] = {"seeds": len(r.path_rmse), "ci95": {}, "ci95_abs": {}}
    q = quantile_stat(QUANTILE)
    for key in METRICS:
        v = getattr(r, key)
        va = getattr(r, key + "_abs")
        out[key] = float(np.mean(v))
        out["ci95"][key] = list(bootstrap_ci(v))
        out[f"{key}_median"] = float(np.median(v))
        out[f"{key}_p75"] = float(np.percentile(v, QUANTILE))
        out["ci95"][f"{key}_p75"] = list(bootstrap_ci(v, q))
        out[f"{key}_abs"] = float(np.mean(va))
        out["ci95_abs"][key] = list(bootstrap_ci(va))
    return out


def _fmt(s: Mapping[str, Any]) -> str:
    c = s["ci95"]
    return (f"path {s['path_rmse']:.2f} m [{c['path_rmse'][0]:.2f}, {c['path_rmse'][1]:.2f}]"
            f", beacons {s['beacon_err_final']:.2f} m [{c['beacon_err_final'][0]:.2f}, "
            f"{c['beacon_err_final'][1]:.2f}] (p75 {s['beacon_err_final_p75']:.2f}; absolute "
            f"{s['path_rmse_abs']:.2f} / {s['beacon_err_final_abs']:.2f} m)")


def side_by_side(sweep: Mapping[str, Mapping[int, Runs]], scene: Scene, particles: int = 200
                 ) -> dict[str, Any]:
    """paper and default, with and without MA, at ``particles`` (from the sweep's runs)."""
    out: dict[str, Any] = {}
    for name in SETS:
        out[name] = {}
        for ma in MA:
            out[name][ma] = summary(sweep[f"{name}.{ma}"][particles])
            log(f"  {scene.name} {name:7s} {ma:10s} {_fmt(out[name][ma])}")
        w, wo = sweep[f"{name}.with_ma"][particles], sweep[f"{name}.without_ma"][particles]
        out[name]["ma_effect_paired"] = {
            key: paired_difference(getattr(w, key), getattr(wo, key)) for key in METRICS}
    return out


# ---------------------------------------------------------------- particles for accuracy
def particle_sweep(scene: Scene, grid: Sequence[int]) -> dict[str, dict[int, Runs]]:
    """Every set x MA setting at every particle count of ``grid`` on the scene's seeds."""
    out: dict[str, dict[int, Runs]] = {}
    for name in SETS:
        for ma in MA:
            p = replace(set_params(name), map_adjustment=ma == "with_ma")
            t0 = time.process_time()
            out[f"{name}.{ma}"] = {n: run_scene(replace(p, n_particles=n), scene) for n in grid}
            q = [np.percentile(r.beacon_err_final, QUANTILE) for r in out[f"{name}.{ma}"].values()]
            log(f"  {scene.name} sweep {name:7s} {ma:10s} p75 beacon error "
                + " ".join(f"{n}:{x:.2f}" for n, x in zip(grid, q, strict=True))
                + f" ({time.process_time() - t0:.0f} s CPU)")
    return out


def sweep_values(sweep: Mapping[str, Mapping[int, Runs]], metric: str
                 ) -> dict[str, F64]:
    """(len(grid), S) array of ``metric`` per set x MA key."""
    return {k: np.stack([getattr(r, metric) for r in by_n.values()])
            for k, by_n in sweep.items()}


def _needed(grid: Sequence[int], values: Mapping[str, F64], target_key: str, ma_keys:
            Sequence[str], idx: NDArray[np.intp] | None) -> tuple[float, dict[str, float]]:
    """Target (``target_key`` at 200 particles) and the particles each of ``ma_keys`` needs,
    on the seeds ``idx`` (None: all)."""
    def curve(key: str) -> F64:
        v = values[key] if idx is None else values[key][:, idx]
        return np.asarray(np.percentile(v, QUANTILE, axis=1), dtype=np.float64)

    target = float(curve(target_key)[list(grid).index(200)])
    return target, {k: first_crossing(grid, curve(k), target) for k in ma_keys}


def particles_needed(grid: Sequence[int], sweep: Mapping[str, Mapping[int, Runs]],
                     metric: str, target_set: str, sets: Sequence[str]) -> dict[str, Any]:
    """Particles each of ``sets`` x MA needs to reach the accuracy of ``target_set`` without
    MA at 200 particles (``metric``'s 75th percentile), with bootstrap intervals."""
    values = sweep_values(sweep, metric)
    keys = [f"{s}.{ma}" for s in sets for ma in MA]
    target, need = _needed(grid, values, f"{target_set}.without_ma", keys, None)
    n_seeds = next(iter(values.values())).shape[1]
    reps: dict[str, list[float]] = {k: [] for k in keys}
    tgt_reps = []
    for idx in boot_indices(n_seeds, 1000, seed=1):
        t, nd = _needed(grid, values, f"{target_set}.without_ma", keys, idx)
        tgt_reps.append(t)
        for k in keys:
            reps[k].append(nd[k])

    def ci(x: Sequence[float]) -> list[float | None]:
        a = np.sort(np.asarray(x, dtype=np.float64))  # may hold inf: order statistics only
        lo = float(a[math.floor(0.025 * (a.size - 1))])
        hi = float(a[math.ceil(0.975 * (a.size - 1))])
        return [float(lo) if math.isfinite(lo) else None, float(hi) if math.isfinite(hi)
                else None]

    def val(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    out: dict[str, Any] = {
        "metric": f"p{QUANTILE:.0f} over seeds of {metric} (after best rotation/reflection)",
        "target_m": target, "target_ci95_m": list(np.percentile(tgt_reps, [2.5, 97.5])),
        "target_definition": f"{target_set} set without MA at 200 particles",
        "grid": list(grid),
    }
    for s in sets:
        w, wo = need[f"{s}.with_ma"], need[f"{s}.without_ma"]
        ratios = [a / b if math.isfinite(a) and b > 0 and math.isfinite(b) else math.inf
                  for a, b in zip(reps[f"{s}.without_ma"], reps[f"{s}.with_ma"], strict=True)]
        out[s] = {
            "with_ma": val(w), "without_ma": val(wo),
            "ci95": {"with_ma": ci(reps[f"{s}.with_ma"]),
                     "without_ma": ci(reps[f"{s}.without_ma"]), "ratio": ci(ratios)},
            "ratio_without_over_with": (wo / w if math.isfinite(w) and math.isfinite(wo)
                                        else None),
            "curve_p75": {ma: {str(n): float(x) for n, x in zip(
                grid, np.percentile(values[f"{s}.{ma}"], QUANTILE, axis=1), strict=True)}
                for ma in MA},
            "curve_p75_ci95": {ma: {str(n): list(bootstrap_ci(values[f"{s}.{ma}"][gi],
                                                              quantile_stat(QUANTILE)))
                                    for gi, n in enumerate(grid)} for ma in MA},
            "curve_mean": {ma: {str(n): float(x) for n, x in zip(
                grid, np.mean(values[f"{s}.{ma}"], axis=1), strict=True)} for ma in MA},
            "ma_effect_paired_by_particles": {
                str(n): paired_difference(values[f"{s}.with_ma"][gi],
                                          values[f"{s}.without_ma"][gi])
                for gi, n in enumerate(grid)},
        }
    return out


# ---------------------------------------------------------------- ablation
def _ma_effect(params: BeaconFilterParams, scene: Scene, with_ma: Runs) -> dict[str, Any]:
    """Map Adjustment's paired effect on a variant: with MA minus without (same seeds)."""
    without = run_scene(replace(params, map_adjustment=False), scene)
    return {k: paired_difference(getattr(with_ma, k), getattr(without, k)) for k in METRICS}


def ablation(scene: Scene, particles: int = 200, ma_effect: bool = True) -> dict[str, Any]:
    """Default with MA, one extension off at a time; paper with one extension on. With
    ``ma_effect`` each row also runs without MA: its ``ma_effect_paired`` (with minus without
    MA, < 0: MA helps) shows which extension takes over what MA does."""
    default = replace(BeaconFilterParams(), n_particles=particles)
    paper = replace(default.with_preset("paper"), n_particles=particles)
    ref = run_scene(default, scene)
    ref_p = run_scene(paper, scene)

    def ma(params: BeaconFilterParams, runs: Runs) -> dict[str, Any]:
        return {"ma_effect_paired": _ma_effect(params, scene, runs)} if ma_effect else {}

    rows: list[dict[str, Any]] = [{"name": "default (all on)", **summary(ref),
                                   **ma(default, ref)}]
    added: list[dict[str, Any]] = [{"name": "paper (all off)", **summary(ref_p),
                                    **ma(paper, ref_p)}]
    defaults = BeaconFilterParams()
    for name, ext in EXTENSIONS.items():
        off = with_values(default, ext.values)
        on_by_default = off != default
        row: dict[str, Any] = {"name": f"without {name}", "extension": name,
                               "help": ext.help, "on_by_default": on_by_default}
        if on_by_default:
            r = run_scene(off, scene)
            row.update(summary(r))
            row["minus_default"] = {k: paired_difference(getattr(r, k), getattr(ref, k))
                                    for k in METRICS}
            row["active"] = bool(not (np.array_equal(r.path_rmse, ref.path_rmse)
                                      and np.array_equal(r.beacon_err_final,
                                                         ref.beacon_err_final)))
            row.update(ma(off, r))
            d = row["minus_default"]["beacon_err_final"]
            log(f"  ablation {row['name']:34s} beacons {row['beacon_err_final']:.2f} m "
                f"(minus default {d['mean_diff']:+.2f} [{d['ci95'][0]:+.2f}, "
                f"{d['ci95'][1]:+.2f}]), path {row['path_rmse']:.2f} m"
                + (f", MA effect {row['ma_effect_paired']['beacon_err_final']['mean_diff']:+.2f}"
                   " m" if ma_effect else ""))
            # the paper's set with this extension switched on (the default's values)
            on = with_values(paper, {k: getattr(defaults, k) for k in ext.values})
            if on != paper:
                rp = run_scene(on, scene)
                added.append({"name": f"paper + {name}", "extension": name, **summary(rp),
                              "minus_paper": {k: paired_difference(getattr(rp, k),
                                                                   getattr(ref_p, k))
                                              for k in METRICS}, **ma(on, rp)})
                log(f"  ablation {added[-1]['name']:34s} beacons "
                    f"{added[-1]['beacon_err_final']:.2f} m, path {added[-1]['path_rmse']:.2f} m"
                    + (f", MA effect "
                       f"{added[-1]['ma_effect_paired']['beacon_err_final']['mean_diff']:+.2f} m"
                       if ma_effect else ""))
        rows.append(row)
    return {"scene": scene.name, "particles": particles, "map_adjustment": True,
            "seeds": len(scene.sims),
            "what": "default with MA, one extension off at a time (paired per-seed "
            "differences, 'minus_default' < 0: better without it); extensions off by default "
            "are listed without numbers. 'added': the paper's set with one extension on. "
            "Each row's 'ma_effect_paired': that variant with MA minus without MA, same seeds "
            "(< 0: MA helps), each set at its own p",
            "rows": rows, "added": added}


# ---------------------------------------------------------------- choosing p
def tune_map_adjust_p(n_seeds: int = 30, particles: int = 200) -> dict[str, Any]:
    """The Map Adjustment gain of each set on training seeds (``TRAIN_SEED0`` +): the p75
    over seeds of path RMSE plus the p75 of the final beacon error (aligned)."""
    scene = studio_scene(n_seeds, TRAIN_SEED0)
    out: dict[str, Any] = {"seeds": f"{TRAIN_SEED0}-{TRAIN_SEED0 + n_seeds - 1}",
                           "particles": particles,
                           "objective": "p75 path RMSE + p75 final beacon error (aligned), m"}
    for name in SETS:
        base = set_params(name)
        # the 'kalman' gain has no p to choose (p > 0 only switches it on): its kernel
        # width instead; 0 = without Map Adjustment, in both
        knob, values = (("kernel_frac", (0.0, *TUNE_KERNEL_FRAC))
                        if base.map_adjust_gain == "kalman" else ("map_adjust_p", TUNE_P))
        rows = {}
        for v in values:
            params = with_values(base, {"n_particles": particles, "map_adjustment": v > 0,
                                        knob: v if v > 0 else getattr(base, knob)})
            r = run_scene(params, scene, seed0=TRAIN_SEED0)
            obj = float(np.percentile(r.path_rmse, QUANTILE)
                        + np.percentile(r.beacon_err_final, QUANTILE))
            rows[str(v)] = obj
            log(f"  tune {name:7s} {knob}={v:<5} objective {obj:.3f} m")
        out[name] = rows
        out[f"{name}_knob"] = knob
        out[f"{name}_best_{'p' if knob == 'map_adjust_p' else knob}"] = float(
            min(rows, key=lambda k: rows[k]))
    return out


# ---------------------------------------------------------------- plots
def plots(folder: Path, side: Mapping[str, Any], runs: Mapping[str, Runs],
          particles: Mapping[str, Any], abl: Mapping[str, Any] | None) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from engine.beacons.studio_sim import STUDIO_BEACONS_XYZ, studio_camera_path

    folder.mkdir(parents=True, exist_ok=True)
    out: list[str] = []
    colours = {"paper": "tab:red", "default": "tab:blue"}

    # the scene and one run of each set
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5), gridspec_kw={"width_ratios": [1.2, 1]})
    ax = axes[0]
    path3 = studio_camera_path()
    ax.plot(path3[:, 0], path3[:, 1], "k-", lw=2, label="true camera path")
    for name in SETS:
        ex = runs[f"{name}.with_ma"].examples[0]
        ax.plot(ex["path"][:, 0], ex["path"][:, 1], "-", color=colours[name], lw=1,
                label=f"{name} set, with MA (seed 0, absolute)")
        ax.plot(ex["beacons"][:, 0], ex["beacons"][:, 1], "x", color=colours[name], ms=9)
    bx = np.array(list(STUDIO_BEACONS_XYZ.values()))
    ax.scatter(bx[:, 0], bx[:, 1], marker="^", c="k", s=70, label="true beacons")
    for k, xyz in STUDIO_BEACONS_XYZ.items():
        ax.annotate(f"{k} ({xyz[2]:.1f} m)", (xyz[0], xyz[1]), textcoords="offset points",
                    xytext=(5, 5), fontsize=8)
    ax.add_patch(Rectangle((-12, -4), 24, 24, fill=False, ls="--", color="grey"))
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m), blue screen at y = 20")
    ax.set_title("Studio simulation (top view), x = estimated beacons", fontsize=10)
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(alpha=0.3)
    ax = axes[1]
    t = np.arange(len(path3)) / 10.0
    ax.plot(t, path3[:, 2], "k-", label="camera height (crane)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("height (m)")
    ax.set_title("Crane height over the move; beacon heights 2.2-7 m", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    out.append(save_figure(fig, folder, "beacon_studio_scene.png"))

    # error over time (cf. fig. 7/8)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4), sharey=False)
    for ax, name in zip(axes, SETS, strict=True):
        for ma, ls in (("without_ma", "--"), ("with_ma", "-")):
            e = runs[f"{name}.{ma}"].err_t
            m = np.mean(e, axis=0)
            lo, hi = np.percentile(e, [25, 75], axis=0)
            x = np.arange(len(m))
            ax.plot(x, m, ls, color=colours[name],
                    label=f"{ma.replace('_', ' ').replace('ma', 'MA')} (mean)")
            ax.fill_between(x, lo, hi, color=colours[name], alpha=0.12 if ma == "with_ma"
                            else 0.06)
        ax.set_title(f"{name} set: camera error over time, 200 particles "
                     f"({len(runs[f'{name}.with_ma'].path_rmse)} seeds, band: quartiles)",
                     fontsize=9)
        ax.set_xlabel("time step (10 Hz)")
        ax.set_ylabel("camera position error after alignment (m)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Studio simulation, cf. paper fig. 7/8", fontsize=10)
    out.append(save_figure(fig, folder, "beacon_studio_error_over_time.png"))

    # particles for the paper's accuracy
    fig, ax = plt.subplots(figsize=(8, 5))
    grid = particles["grid"]
    for name in SETS:
        for ma, ls in (("with_ma", "-"), ("without_ma", "--")):
            c = particles[name]["curve_p75"][ma]
            ci = particles[name]["curve_p75_ci95"][ma]
            y = [c[str(n)] for n in grid]
            ax.plot(grid, y, ls, marker="o", color=colours[name],
                    label=f"{name}, {ma.replace('_', ' ').replace('ma', 'MA')}")
            ax.fill_between(grid, [ci[str(n)][0] for n in grid], [ci[str(n)][1] for n in grid],
                            color=colours[name], alpha=0.08)
    ax.axhline(particles["target_m"], color="k", ls=":",
               label=f"paper's accuracy: paper set w/o MA at 200 ({particles['target_m']:.2f} m)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("particles")
    ax.set_ylabel("final beacon error, p75 over seeds (m)")
    pw = particles["paper"]

    def count(x: float | None) -> str:
        return "not reached" if x is None else f"{x:.0f}"

    ax.set_title(f"Particles for the paper's accuracy: paper set with MA {count(pw['with_ma'])}"
                 f", without {count(pw['without_ma'])}", fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    out.append(save_figure(fig, folder, "beacon_studio_particles.png"))

    if abl is not None:
        rows = [r for r in abl["rows"] if "minus_default" in r]
        added = [r for r in abl["added"] if "minus_paper" in r]
        fig, axes = plt.subplots(1, 2, figsize=(13, 4.5))
        for ax, rr, key, title in ((axes[0], rows, "minus_default",
                                    "default minus one extension (> 0: the extension helps)"),
                                   (axes[1], added, "minus_paper",
                                    "paper plus one extension (< 0: the extension helps)")):
            names = [r["extension"] for r in rr]
            d = [r[key]["beacon_err_final"]["mean_diff"] for r in rr]
            lo = [r[key]["beacon_err_final"]["ci95"][0] for r in rr]
            hi = [r[key]["beacon_err_final"]["ci95"][1] for r in rr]
            rows_y = np.arange(len(names))
            ax.barh(rows_y, d, color="tab:gray")
            ax.errorbar(d, rows_y, xerr=[np.subtract(d, lo), np.subtract(hi, d)], fmt="none",
                        ecolor="k", capsize=3)
            ax.set_yticks(rows_y, names, fontsize=8)
            ax.axvline(0, color="k", lw=0.8)
            ax.set_xlabel("change of final beacon error (m), mean over seeds, 95 % CI")
            ax.set_title(title, fontsize=9)
            ax.grid(alpha=0.3, axis="x")
        out.append(save_figure(fig, folder, "beacon_ablation.png"))
    return out
