"""PTZ bench, the published experiment (Gaspar & Oliveira 2009 sec. 6) beside our defaults.

Used by :mod:`engine.bench.ptz`. The paper's method (``PtzParams().with_preset("paper")``) and
ours (``PtzParams()``) track the same simulated scenarios (:mod:`engine.ptz.paper_sim`), the
head in the loop:

- ``paper_experiment`` / ``paper_experiment_default``: the circle of sec. 6.2 at the paper's
  turn rate 2 pi 0.0217 rad/s (between models 1 and 2 of the bank 2 pi / 50 [0..3]), 140 s,
  one image every 0.5 s. Position / velocity / acceleration error after the initial transient
  (t >= 20 s, medians: fig. 5 "beneath 20 cm, 4 cm/s and 0.5 cm/s^2"), the model probabilities
  over time (fig. 6 left: "the probability associated to the model closer to the real target
  tends to 1"), the estimated turn rate (fig. 6 right);
- ``paper_range`` / ``paper_range_default``: the same turn rate along the line of sight from
  7 m to 40 cm and back (sec. 6.2: accurate "for distances up to approximately 7 m", works
  down to 40 cm): error by distance band, closest and farthest distance tracked;
- the lens distorts (inverse radial k3 0.12) and the tracker corrects with the line-based
  model fitted to straight lines seen through it (sec. 3.3; the fit in ``*.lens``);
  ``paper_experiment_no_distortion``: the same without distortion (the paper's circle through
  the whole calibration chain, pan/tilt from reference markers, is not run: the studio's
  markers leave the view where the head tilts down to the near part of the circle);
- ``paper_q_in_metres``: the paper's process-noise PSD read in metres instead of mm;
- harder cases (``harder_*``, default set, 30 Hz): the paper's circle, and a target that turns
  faster than the bank's largest model (2 pi 0.08 rad/s on a 1.2 m circle).

``--plots DIR`` writes ``ptz_paper_fig6.png`` (model probabilities and turn rate over time),
``ptz_paper_errors.png`` (fig. 5's errors over time, both sets) and ``ptz_paper_range.png``.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.bench.plots import save_figure
from engine.progress import log

F64 = NDArray[np.float64]

STEADY_FROM_S = 20.0
RANGE_BANDS_M = ((0.3, 1.0), (1.0, 3.0), (3.0, 5.0), (5.0, 7.5))


def track(scenario: Any, params: Any, report: dict[str, Any] | None = None,
          calibration: Any = None) -> dict[str, F64]:
    """Run the tracker on the scenario through the pipeline (the head follows its commands);
    per-frame series (NaN where there is no estimate yet). A distorting lens is corrected
    with the line-based model (:func:`engine.ptz.paper_sim.lens_calibration`, or the given
    ``calibration`` of the same lens); ``report`` receives the lens calibration's figures."""
    from engine.loop import run_tracking
    from engine.ptz.paper_sim import lens_calibration
    from engine.ptz.sim import PtzSimSource, PtzTargetTruth
    from engine.trackers.ptz import PtzDetails, PtzTracker

    src = PtzSimSource(scenario)
    cal = calibration
    if cal is None and scenario.distortion_k3 != 0.0:
        cal, rep = lens_calibration(src)
        if report is not None:
            report.update(rep)
    tr = PtzTracker(params, calibration=cal)
    rows: dict[str, list[Any]] = {k: [] for k in (
        "t", "pos_err", "vel_err", "acc_err", "dist", "omega", "probs", "measured", "resets")}
    n_models = len(params.omegas)
    for rec in run_tracking(src, tr):
        f, r = rec.frame, rec.result
        d = r.details_as(PtzDetails)
        truth = f.payload(PtzTargetTruth)
        if truth is None or f.gt_T_world_cam is None or d is None:
            continue
        rows["t"].append(f.timestamp_s)
        rows["dist"].append(float(np.linalg.norm(np.asarray(truth.xyz_world)
                                                 - f.gt_T_world_cam[:3, 3])))
        rows["measured"].append(d.measurement is not None)
        rows["resets"].append(d.resets)
        if d.target_xyz is None or d.target_vel is None or d.target_acc is None:
            for k in ("pos_err", "vel_err", "acc_err", "omega"):
                rows[k].append(math.nan)
            rows["probs"].append(np.full(n_models, math.nan))
            continue
        rows["pos_err"].append(float(np.linalg.norm(d.target_xyz - np.asarray(truth.xyz_world))))
        rows["vel_err"].append(float(np.linalg.norm(d.target_vel - np.asarray(truth.vel_world))))
        rows["acc_err"].append(float(np.linalg.norm(d.target_acc - np.asarray(truth.acc_world))))
        rows["omega"].append(float(d.omega_rad_s) if d.omega_rad_s is not None else math.nan)
        rows["probs"].append(np.asarray(d.model_probs, dtype=np.float64))
    return {k: np.asarray(v, dtype=np.float64) for k, v in rows.items()}


def summary(s: dict[str, F64], omegas: tuple[float, ...], true_omega: float) -> dict[str, Any]:
    """Steady-state errors (medians from ``STEADY_FROM_S``), final probabilities, turn rate."""
    t = s["t"]
    steady = (t >= STEADY_FROM_S) & np.isfinite(s["pos_err"])
    true_j = int(np.argmin(np.abs(np.asarray(omegas) - true_omega)))
    p_final = s["probs"][-1]

    def med(key: str) -> float | None:
        v = s[key][steady]
        return float(np.median(v)) if v.size else None

    # the time after which the closest model keeps the highest probability
    best = np.argmax(np.nan_to_num(s["probs"], nan=-1.0), axis=1) == true_j
    wrong = np.flatnonzero(~best)
    settle = float(t[wrong[-1] + 1]) if wrong.size and wrong[-1] + 1 < t.size else (
        float(t[0]) if not wrong.size else None)
    return {
        "pos_err_m_steady": med("pos_err"),
        "pos_err_m_steady_p95": (float(np.percentile(s["pos_err"][steady], 95))
                                 if steady.any() else None),
        "vel_err_m_s_steady": med("vel_err"),
        "acc_err_m_s2_steady": med("acc_err"),
        "true_omega_rad_s": true_omega,
        "model_omegas_rad_s": list(omegas),
        "true_model": true_j,
        "true_model_prob_final": float(p_final[true_j]) if np.all(np.isfinite(p_final))
        else None,
        "model_probs_final": [float(x) for x in p_final],
        "omega_est_final_rad_s": float(s["omega"][-1]),
        "closest_model_on_top_from_s": settle,
        "range_m": [float(np.min(s["dist"])), float(np.max(s["dist"]))],
        "frames": int(t.size),
        "frames_measured": int(np.sum(s["measured"])),
        "resets": int(s["resets"][-1]) if s["resets"].size else 0,
        "sampling_s": float(np.median(np.diff(t))) if t.size > 1 else None,
        "duration_s": float(t[-1]) if t.size else 0.0,
    }


def range_summary(s: dict[str, F64]) -> dict[str, Any]:
    """Error by distance band (all frames after the first 10 s), closest/farthest tracked."""
    t, dist, err = s["t"], s["dist"], s["pos_err"]
    meas = s["measured"] > 0
    out: dict[str, Any] = {"range_m": [float(dist.min()), float(dist.max())],
                           "measured_fraction": float(np.mean(meas))}
    ok = (t >= 10.0) & np.isfinite(err)
    for lo, hi in RANGE_BANDS_M:
        sel = ok & (dist >= lo) & (dist < hi)
        out[f"pos_err_m_{lo:g}_{hi:g}m"] = float(np.median(err[sel])) if sel.any() else None
    good = meas & ok & (err < 0.2)
    out["closest_tracked_m"] = float(dist[good].min()) if good.any() else None
    out["farthest_tracked_m"] = float(dist[good].max()) if good.any() else None
    out["pos_err_m_median"] = float(np.median(err[ok])) if ok.any() else None
    out["frames_lost"] = int(np.sum(~meas))
    return out


def run(plots: Path | None = None, harder_duration_s: float | None = None
        ) -> tuple[dict[str, dict[str, Any]], list[str]]:
    """All the paper-experiment groups (``paper_experiment`` ...) and the PNGs written; the
    harder cases shortened to ``harder_duration_s`` if given (``bench ptz --quick``)."""
    from engine.ptz.paper_sim import PAPER_OMEGA_RAD_S, paper_circle, paper_range
    from engine.trackers.ptz import PtzParams

    circle, rng = paper_circle(), paper_range()

    def params_for(name: str, sc: Any) -> Any:
        base = PtzParams(target_b=sc.ball_bgr[0], target_g=sc.ball_bgr[1],
                         target_r=sc.ball_bgr[2], target_radius_m=sc.ball_radius_m)
        return base.with_preset("paper") if name == "paper" else base

    out: dict[str, dict[str, Any]] = {}
    series: dict[str, dict[str, F64]] = {}
    for name, key in (("paper", "paper_experiment"), ("default", "paper_experiment_default")):
        p = params_for(name, circle)
        log(f"paper experiment ({name} set): circle, omega 2 pi 0.0217 rad/s, 140 s, 2 Hz, "
            f"lens k3 {circle.distortion_k3} corrected by the line-based model")
        lens: dict[str, Any] = {}
        series[key] = track(circle, p, report=lens)
        out[key] = {**summary(series[key], p.omegas, PAPER_OMEGA_RAD_S), "set": name,
                    "q_jerk_psd": p.q_jerk_psd, "centre_method": p.centre_method,
                    "lens": lens}
        o = out[key]
        log(f"  steady pos err {100 * (o['pos_err_m_steady'] or math.nan):.1f} cm, closest "
            f"model p={o['true_model_prob_final']}, omega {o['omega_est_final_rad_s']:.4f} "
            f"rad/s (true {PAPER_OMEGA_RAD_S:.4f})")
    for name, key in (("paper", "paper_range"), ("default", "paper_range_default")):
        p = params_for(name, rng)
        log(f"paper range run ({name} set): 7 m to 40 cm along the line of sight")
        series[key] = track(rng, p)
        out[key] = {**range_summary(series[key]),
                    **{k: v for k, v in summary(series[key], p.omegas, PAPER_OMEGA_RAD_S).items()
                       if k in ("true_model_prob_final", "omega_est_final_rad_s", "resets")}}
        o = out[key]
        log(f"  range {o['range_m'][0]:.2f}-{o['range_m'][1]:.2f} m, tracked (< 20 cm) "
            f"{o['closest_tracked_m']}-{o['farthest_tracked_m']} m")
    pc = params_for("paper", circle)
    nolens = dataclasses.replace(circle, distortion_k3=0.0)
    log("paper experiment without lens distortion (paper set)")
    s_n = track(nolens, pc)
    out["paper_experiment_no_distortion"] = {
        k: v for k, v in summary(s_n, pc.omegas, PAPER_OMEGA_RAD_S).items()
        if k in ("pos_err_m_steady", "pos_err_m_steady_p95", "true_model_prob_final",
                 "omega_est_final_rad_s")}
    pm = dataclasses.replace(params_for("paper", circle), q_jerk_psd=0.1)
    log("paper experiment with the PSD read in metres (0.1 m^2/s^5)")
    s_m = track(circle, pm)
    out["paper_q_in_metres"] = {k: v for k, v in summary(s_m, pm.omegas, PAPER_OMEGA_RAD_S)
                                .items() if k in ("pos_err_m_steady", "true_model_prob_final",
                                                  "model_probs_final", "omega_est_final_rad_s")}
    # harder cases, our default
    fast = dataclasses.replace(circle, fps=30.0,
                               duration_s=harder_duration_s or circle.duration_s)
    log(f"harder: the paper's circle at 30 Hz, {fast.duration_s:.0f} s (default set)")
    s30 = track(fast, params_for("default", fast))
    out["harder_30hz"] = summary(s30, params_for("default", fast).omegas, PAPER_OMEGA_RAD_S)
    beyond = dataclasses.replace(fast, period_s=1.0 / 0.08, radius_m=1.2)
    log("harder: turning faster than the largest model (2 pi 0.08 rad/s, default set)")
    pb = params_for("default", beyond)
    s_b = track(beyond, pb)
    out["harder_beyond_bank"] = summary(s_b, pb.omegas, 2.0 * math.pi * 0.08)
    files: list[str] = []
    if plots is not None:
        files = _plots(Path(plots), series, params_for("paper", circle).omegas,
                       PAPER_OMEGA_RAD_S)
    return out, files


def _plots(folder: Path, series: dict[str, dict[str, F64]], omegas: tuple[float, ...],
           true_omega: float) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    out: list[str] = []
    fig, axes = plt.subplots(2, 2, figsize=(12, 7), sharex=True)
    for row, (key, name) in enumerate((("paper_experiment", "paper set"),
                                       ("paper_experiment_default", "default set"))):
        s = series[key]
        ax = axes[row, 0]
        for j in range(s["probs"].shape[1]):
            ax.plot(s["t"], s["probs"][:, j], label=f"p{j + 1} (w = {omegas[j]:.3f} rad/s)")
        ax.set_ylabel("a posteriori probability")
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(f"{name}: model probabilities (cf. fig. 6 left)", fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
        ax = axes[row, 1]
        ax.plot(s["t"], np.degrees(s["omega"]), "b-", label="w estimated")
        ax.axhline(math.degrees(true_omega), color="r", label="w real")
        for w in omegas:
            ax.axhline(math.degrees(w), color="grey", ls=":", lw=0.8)
        ax.set_ylabel("w (deg/s)")
        ax.set_title(f"{name}: turn rate (cf. fig. 6 right; dotted: the 4 models)",
                     fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("t (s)")
    out.append(save_figure(fig, folder, "ptz_paper_fig6.png"))

    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for key, name in (("paper_experiment", "paper set"),
                      ("paper_experiment_default", "default set")):
        s = series[key]
        for ax, k, scale, unit in ((axes[0], "pos_err", 1000.0, "|e_p| (mm)"),
                                   (axes[1], "vel_err", 1000.0, "|e_v| (mm/s)"),
                                   (axes[2], "acc_err", 1000.0, "|e_a| (mm/s^2)")):
            ax.plot(s["t"], s[k] * scale, label=name)
            ax.set_ylabel(unit)
            ax.set_xlabel("t (s)")
            ax.grid(alpha=0.3)
    axes[0].axhline(200.0, color="k", ls=":", label="paper: beneath 20 cm")
    axes[1].axhline(40.0, color="k", ls=":", label="paper: 4 cm/s")
    axes[2].axhline(5.0, color="k", ls=":", label="paper: 0.5 cm/s^2")
    for ax in axes:
        ax.set_yscale("log")
        ax.legend(fontsize=7)
    fig.suptitle("Estimation errors over time on the paper's circle (cf. fig. 5)", fontsize=10)
    out.append(save_figure(fig, folder, "ptz_paper_errors.png"))

    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    for key, name in (("paper_range", "paper set"), ("paper_range_default", "default set")):
        s = series[key]
        axes[0].plot(s["t"], s["dist"], "k-", lw=0.8)
        axes[1].scatter(s["dist"], s["pos_err"] * 100.0, s=8, label=name)
    axes[0].set_xlabel("t (s)")
    axes[0].set_ylabel("distance camera - target (m)")
    axes[0].set_title("Range run: 7 m to 40 cm along the line of sight", fontsize=9)
    axes[0].grid(alpha=0.3)
    axes[1].axhline(20.0, color="k", ls=":", label="paper: 20 cm")
    axes[1].set_xlabel("distance (m)")
    axes[1].set_ylabel("position error (cm)")
    axes[1].set_yscale("log")
    axes[1].set_title("Position error by distance", fontsize=9)
    axes[1].legend(fontsize=8)
    axes[1].grid(alpha=0.3)
    out.append(save_figure(fig, folder, "ptz_paper_range.png"))
    return out
