"""Dense bench, part 2: Tykkälä 2014's own experiments (Figs. 13-14) with ``preset=paper``
beside our defaults, and an ablation of our extensions.

Used by :mod:`engine.bench.dense` (``studiotrack bench dense``). Two parameter sets:
``paper`` (``DenseParams().with_preset("paper")``: Algorithms 1-3 as published) and
``default`` (ours). Errors are per frame against the studio's true pose: translation (m,
camera centre) and rotation (deg, angle of ``R_est^T R_true``), as in Fig. 14 ("the
translation and rotation error").

- **Fig. 14** (:func:`fig14`): the sweep's keyframes thinned evenly to the paper's counts
  (all, 14, 9, 7, 5), tracked on an empty-studio cycle, with three kinds of keyframe poses:
  ``sweep`` (the poses the sweep tracked), ``true_poses`` (the truth: keyframe switching
  alone) and ``sba`` (:func:`fig14_sba`: the paper's reference, "bundle adjustment [applied]
  to 27 keyframes which are initialized by dense tracking": the sweep's poses refined by
  :func:`engine.keyframes.sba.bundle_adjust` from simulated clicks on studio points, 0.5 px
  noise). For ``sba`` the error is also measured the paper's way, against the pose tracked
  with every SBA keyframe (``vs_full_*``: the paper's per-frame "ground truth pose").
- **Fig. 13 with a dirty sweep** (:func:`dirty_sweep`): the keyframes are recorded on a
  sweep with the presenter walking through it (the paper's sweep "must not contain moving
  actors"), then the rail is tracked as with the clean store.
- **Ablation** (:func:`ablation`): the default set with one extension switched back to the
  paper's value at a time, and the paper's set with one extension switched on, on the rail
  (2 cycles, the presenter in the last) against the dirty sweep's store (with the clean store
  the two sets do not differ on the rail: ``rail.rows``), and on
  ``tum_fr1_xyz_37`` (real Kinect data, incremental tracker) when present. An *extension*
  is a field that ``preset=paper`` sets to another value than the default
  (:func:`extensions`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.bench.plots import save_figure
from engine.progress import log

F64 = NDArray[np.float64]

#: Fig. 14: "a sparsified number of ground truth keyframes (14, 9, 7, 5)" (0: all of them)
PAPER_COUNTS = (0, 14, 9, 7, 5)
SETS = ("paper", "default")
#: simulated SBA clicks: points, click noise (px), seed
SBA_POINTS = 48
SBA_CLICK_NOISE_PX = 0.5
SBA_SEED = 17


def set_params(name: str, points: int) -> Any:
    from engine.dense.params import DenseParams

    base = DenseParams(n_points=points)
    return base.with_preset("paper") if name == "paper" else base


def extensions() -> dict[str, tuple[object, object]]:
    """Fields where ``preset=paper`` differs from the default: name -> (default, paper)."""
    from engine.dense.params import DenseParams

    d = DenseParams()
    p = d.with_preset("paper")
    return {k: (getattr(d, k), getattr(p, k)) for k in DenseParams.PRESETS["paper"].values
            if getattr(d, k) != getattr(p, k)}


def pose_errors(T: Any, gt: Any) -> tuple[float, float]:
    """(translation m, rotation deg) of an estimate against the truth (NaN without one)."""
    from engine.geometry import rotation_angle_rad

    if T is None or gt is None:
        return math.nan, math.nan
    A, B = np.asarray(T, dtype=np.float64), np.asarray(gt, dtype=np.float64)
    return (float(np.linalg.norm(A[:3, 3] - B[:3, 3])),
            math.degrees(rotation_angle_rad(A[:3, :3].T @ B[:3, :3])))


def thin(ids: Sequence[int], count: int) -> list[int]:
    """``count`` ids spread evenly over ``ids`` (first and last kept; 0: all)."""
    if count <= 0 or count >= len(ids):
        return list(ids)
    return [ids[int(i)] for i in np.linspace(0, len(ids) - 1, count).round()]


def keyframe_truth(store: Any, spec: str) -> tuple[dict[int, F64], dict[int, F64]]:
    """True poses and noise-free depths of a sweep's keyframes: each keyframe image is found
    again in the sweep pass ``spec`` (the built-in studio renders both for every frame)."""
    import cv2

    from engine.arrays import u8
    from engine.sources import open_source
    from engine.studio.sim import StudioLabels

    want = {k.id: k for k in store.keyframes}
    poses: dict[int, F64] = {}
    depths: dict[int, F64] = {}
    for f in open_source(spec).frames():
        if f.color_bgr is None or f.gt_T_world_cam is None or len(poses) == len(want):
            continue
        gray = None
        for kid, k in want.items():
            if kid in poses or float(np.linalg.norm(
                    k.T_world_cam[:3, 3] - f.gt_T_world_cam[:3, 3])) > 0.05:
                continue
            if gray is None:
                gray = (f.color_bgr if f.color_bgr.ndim == 2
                        else u8(cv2.cvtColor(f.color_bgr, cv2.COLOR_BGR2GRAY)))
            if np.array_equal(gray, k.gray):
                poses[kid] = np.array(f.gt_T_world_cam, dtype=np.float64)
                lab = f.payload(StudioLabels)
                # (the studio sends no separate noise-free depth when its depth is noise-free)
                exact = lab.depth_exact_m if lab is not None else None
                depths[kid] = np.asarray(exact if exact is not None else f.depth_m,
                                         dtype=np.float64)
    return poses, depths


def simulated_clicks(store: Any, T_true: Mapping[int, F64], depth_exact: Mapping[int, F64],
                     n_points: int = SBA_POINTS, noise_px: float = SBA_CLICK_NOISE_PX,
                     seed: int = SBA_SEED) -> list[Any]:
    """The operator's annotations (sec. 6.1: "few 3D points and their 2D correspondence"):
    studio surface points at textured pixels of evenly spread keyframes (noise-free depth,
    true pose), observed in every keyframe where they are in view and not occluded (true
    pose, ``noise_px`` click noise)."""
    import cv2

    from engine.camera import backproject, project
    from engine.geometry import invert
    from engine.keyframes.sba import Observation

    rng = np.random.default_rng(seed)
    intr = store.intrinsics
    ids = [k for k in (kf.id for kf in store.keyframes) if k in T_true and k in depth_exact]
    if len(ids) < 2:
        return []
    src_ids = thin(ids, min(len(ids), max(2, n_points // 4)))
    per = max(1, n_points // len(src_ids))
    X: list[F64] = []
    for kid in src_ids:
        g = store.by_id(kid).gray.astype(np.float32)
        mag = np.abs(cv2.Sobel(g, cv2.CV_32F, 1, 0)) + np.abs(cv2.Sobel(g, cv2.CV_32F, 0, 1))
        d = depth_exact[kid]
        m = 20
        ok = np.zeros_like(mag, dtype=bool)
        ok[m:-m, m:-m] = True
        ok &= (d > 0.5) & (d < 7.0) & (mag > np.percentile(mag[ok], 90))
        vv, uu = np.nonzero(ok)
        if uu.size == 0:
            continue
        pick = rng.choice(uu.size, size=min(per, uu.size), replace=False)
        uv = np.stack([uu[pick], vv[pick]], axis=1).astype(np.float64)
        pc = backproject(intr, uv, d[vv[pick], uu[pick]])
        T = T_true[kid]
        X += list(pc @ T[:3, :3].T + T[:3, 3])
    obs = []
    for pid, Xw in enumerate(X):
        for kid in ids:
            T_cw = invert(T_true[kid])
            pc = T_cw[:3, :3] @ Xw + T_cw[:3, 3]
            if pc[2] < 0.3:
                continue
            u, v = project(intr, pc[None])[0]
            if not (8 <= u < intr.width - 8 and 8 <= v < intr.height - 8):
                continue
            z = depth_exact[kid][round(v), round(u)]
            if not (z > 0 and abs(z - pc[2]) < 0.03 * pc[2]):
                continue  # occluded there
            du, dv = rng.normal(0.0, noise_px, 2)
            obs.append(Observation(pid, kid, float(u + du), float(v + dv)))
    return obs


def sba_reference(store: Any, T_true: Mapping[int, F64], depth_exact: Mapping[int, F64],
                  preset: str, click_seed: int = SBA_SEED) -> tuple[Any, dict[str, Any]]:
    """The sweep's store with SBA-refined poses (SBAParams ``preset``: "paper" or
    "default"; ``click_seed``: the simulated clicks' draw), and a report: reprojection RMSE
    and keyframe pose error against the truth before / after."""
    from engine.keyframes.sba import SBAParams, bundle_adjust

    obs = simulated_clicks(store, T_true, depth_exact, seed=click_seed)
    p = SBAParams()
    if preset == "paper":
        p = p.with_preset("paper")
    T0 = {k.id: np.asarray(k.T_world_cam, dtype=np.float64) for k in store.keyframes}
    depths = {k.id: k.depth_m for k in store.keyframes}
    res = bundle_adjust(store.intrinsics, T0, obs, depth_maps=depths, params=p,
                        gauge_id=min(T0))

    def errs(T: Mapping[int, F64]) -> tuple[list[float], list[float]]:
        e = [pose_errors(T[k], T_true[k]) for k in T if k in T_true]
        return [a for a, _ in e], [b for _, b in e]

    tb, rb = errs(T0)
    ta, ra = errs(res.T_world_cam_after)
    rep = {"preset": preset, "keyframes": len(T0), "points": len({o.point_id for o in obs}),
           "observations": len(obs), "click_noise_px": SBA_CLICK_NOISE_PX,
           "rmse_before_px": res.rmse_before_px, "rmse_after_px": res.rmse_after_px,
           "kf_trans_err_m_before": {"mean": float(np.mean(tb)), "max": float(np.max(tb))},
           "kf_trans_err_m_after": {"mean": float(np.mean(ta)), "max": float(np.max(ta))},
           "kf_rot_err_deg_before": {"mean": float(np.mean(rb)), "max": float(np.max(rb))},
           "kf_rot_err_deg_after": {"mean": float(np.mean(ra)), "max": float(np.max(ra))},
           "unadjusted_keyframes": len(res.unadjusted_ids), "seconds": res.seconds}
    return store.with_poses(res.T_world_cam_after), rep


def _track_all(frames: Iterable[Any], trackers: Mapping[Any, Any],
               on_frame: Callable[[Any], None] | None = None
               ) -> tuple[dict[Any, list[Any]], dict[Any, int], dict[Any, list[float]]]:
    """Every tracker on every frame, interleaved: poses, lost frames, CPU ms per frame."""
    poses: dict[Any, list[Any]] = {k: [] for k in trackers}
    lost: dict[Any, int] = dict.fromkeys(trackers, 0)
    cpu: dict[Any, list[float]] = {k: [] for k in trackers}
    for f in frames:
        if on_frame is not None:
            on_frame(f)
        for key, tr in trackers.items():
            c0 = time.process_time()
            r = tr.track(f)
            cpu[key].append((time.process_time() - c0) * 1e3)
            poses[key].append(None if r.T_world_cam is None else np.array(r.T_world_cam))
            lost[key] += 0 if r.state.is_good else 1
    return poses, lost, cpu


def _row(poses: Sequence[Any], gts: Sequence[Any]) -> dict[str, float]:
    e = np.array([pose_errors(T, g) for T, g in zip(poses, gts, strict=True)])
    return {"max_err_m": float(np.nanmax(e[:, 0])), "mean_err_m": float(np.nanmean(e[:, 0])),
            "rot_err_deg_max": float(np.nanmax(e[:, 1])),
            "rot_err_deg_mean": float(np.nanmean(e[:, 1]))}


def fig14(store: Any, sweep_spec: str, cycle_spec: str, points: int) -> dict[str, Any]:
    """Fig. 14 with rotation error, both sets, the three kinds of keyframe poses (module
    docstring). Returns ``{"fig14": ..., "fig14_sba": ..., "keyframe_count": ...}``."""
    from engine.dense.tracking import DenseKeyframeTracker
    from engine.sources import open_source

    T_true, d_exact = keyframe_truth(store, sweep_spec)
    log(f"fig14: {len(T_true)} of {len(store)} sweep keyframes matched to their truth")
    known = [k.id for k in store.keyframes if k.id in T_true]
    families: dict[tuple[str, str], Any] = {}
    sba_rep: dict[str, Any] = {}
    for name in SETS:
        families[(name, "sweep")] = store.subset(known)
        families[(name, "true_poses")] = store.subset(known).with_poses(
            {k: T_true[k] for k in known})
        ref, rep = sba_reference(store.subset(known), T_true, d_exact, name)
        families[(name, "sba")] = ref
        sba_rep[name] = rep
        log(f"fig14 SBA ({name}): keyframe error {rep['kf_trans_err_m_before']['mean'] * 1e3:.1f}"
            f" -> {rep['kf_trans_err_m_after']['mean'] * 1e3:.1f} mm mean, "
            f"{rep['kf_rot_err_deg_before']['mean']:.3f} -> "
            f"{rep['kf_rot_err_deg_after']['mean']:.3f} deg ({rep['observations']} clicks)")
    trackers = {}
    for (name, fam), st in families.items():
        for count in PAPER_COUNTS:
            ids = thin([k.id for k in st.keyframes], count)
            key = (name, fam, len(ids))
            if key not in trackers:
                trackers[key] = DenseKeyframeTracker(set_params(name, points),
                                                     store=st.subset(ids))
    gts: list[Any] = []
    poses, lost, _ = _track_all(open_source(cycle_spec).frames(), trackers,
                                lambda f: gts.append(f.gt_T_world_cam))
    rows = []
    for key in sorted(trackers, key=lambda k: (k[0], k[1], -k[2])):
        name, fam, n = key
        row: dict[str, Any] = {"set": name, "poses": fam, "keyframes": n,
                               **_row(poses[key], gts), "lost_frames": lost[key]}
        if fam == "sba":
            full = max(k[2] for k in trackers if k[:2] == (name, "sba"))
            vs = _row(poses[key], poses[(name, "sba", full)])
            row.update({f"vs_full_{k}": v for k, v in vs.items()})
        rows.append(row)
        log(f"fig14 {name:7s} {fam:10s} {n:3d} kf: max {row['max_err_m'] * 1e3:7.2f} mm "
            f"{row['rot_err_deg_max']:6.3f} deg, mean {row['mean_err_m'] * 1e3:6.2f} mm "
            f"{row['rot_err_deg_mean']:6.3f} deg, lost {lost[key]}")

    def worst(name: str, fam: str) -> dict[str, Any]:
        sel = [r for r in rows if r["set"] == name and r["poses"] == fam]
        return {"trans_err_m_max": max(r["max_err_m"] for r in sel),
                "rot_err_deg_max": max(r["rot_err_deg_max"] for r in sel),
                "rot_err_deg_max_by_count": {str(r["keyframes"]): r["rot_err_deg_max"]
                                             for r in sel},
                "trans_err_m_max_by_count": {str(r["keyframes"]): r["max_err_m"] for r in sel}}

    fig = {"sequence": cycle_spec, "counts": [len(known), *PAPER_COUNTS[1:]],
           **worst("default", "sweep"), "paper": worst("paper", "sweep"),
           "true_poses": worst("default", "true_poses"),
           "true_poses_paper": worst("paper", "true_poses"),
           "rows": [r for r in rows if r["poses"] != "sba"]}
    sba_rows = [r for r in rows if r["poses"] == "sba"]
    fig_sba = {"sequence": cycle_spec, "reference": sba_rep, **worst("default", "sba"),
               "paper": worst("paper", "sba"),
               "vs_full_trans_err_m_max": max(r["vs_full_max_err_m"] for r in sba_rows
                                              if r["set"] == "default"),
               "vs_full_rot_err_deg_max": max(r["vs_full_rot_err_deg_max"] for r in sba_rows
                                              if r["set"] == "default"),
               "rows": sba_rows}
    legacy = [{"poses": r["poses"], "keyframes": r["keyframes"], "max_err_m": r["max_err_m"],
               "mean_err_m": r["mean_err_m"], "rot_err_deg_max": r["rot_err_deg_max"],
               "lost_frames": r["lost_frames"]}
              for r in rows if r["set"] == "default" and r["poses"] != "sba"]
    return {"fig14": fig, "fig14_sba": fig_sba, "keyframe_count": {"rows": legacy}}


def rail_trackers(points: int, clean: Any, dirty: Any | None) -> dict[str, Any]:
    """The extra trackers of the Fig. 13 rail: the paper's set on the clean store, both sets
    on the dirty store (recorded with the presenter walking through the sweep), the paper's
    incremental tracker."""
    from engine.dense.tracking import DenseIncrementalTracker, DenseKeyframeTracker

    out: dict[str, Any] = {
        "paper_keyframe": DenseKeyframeTracker(set_params("paper", points), store=clean),
        "paper_incremental": DenseIncrementalTracker(set_params("paper", points)),
    }
    if dirty is not None:
        out["dirty_sweep_keyframe"] = DenseKeyframeTracker(set_params("default", points),
                                                           store=dirty)
        out["paper_dirty_sweep_keyframe"] = DenseKeyframeTracker(set_params("paper", points),
                                                                 store=dirty)
    return out


def rail_rows(series: Mapping[str, Sequence[Any]], gts: Sequence[Any], lost: Mapping[str, int],
              n_cycles: int) -> tuple[dict[str, Any], dict[str, F64]]:
    """Per rail tracker: max / mean / final translation and rotation error, per cycle max,
    lost frames; and the per-frame translation errors."""
    out: dict[str, Any] = {}
    err: dict[str, F64] = {}
    n = len(gts)
    per = max(1, n // max(1, n_cycles))
    for name, poses in series.items():
        e = np.array([pose_errors(T, g) for T, g in zip(poses, gts, strict=True)])
        err[name] = e[:, 0]
        out[name] = {**_row(poses, gts), "final_err_m": float(e[-1, 0]),
                     "max_err_per_cycle_m": [float(np.nanmax(e[k:k + per, 0]))
                                             for k in range(0, n, per)],
                     "lost_frames": int(lost[name])}
    return out, err


def dirty_sweep(points: int, kf_dist: float, spec: str) -> Any:
    """A sweep recorded with the presenter walking through it (Fig. 13's test, not clean)."""
    from engine.dense.params import DenseParams
    from engine.keyframes.sweep import SweepParams, record_sweep
    from engine.sources import open_source

    res = record_sweep(open_source(spec), SweepParams(kf_add_dist_m=kf_dist, max_kept_frames=0),
                       dense_params=DenseParams(n_points=points))
    log(f"dirty sweep: {len(res.store)} keyframes from {res.frames_processed} frames with the "
        f"presenter ({res.lost_frames} lost)")
    return res.store


def ablation(frames: Iterable[Any], store: Any, points: int,
             tum_frames: Sequence[Any] | None = None) -> dict[str, Any]:
    """One extension at a time (module docstring): per variant max / mean translation and
    rotation error, lost frames, median CPU ms per frame, and the differences to its set."""
    from engine.dense.tracking import DenseIncrementalTracker, DenseKeyframeTracker

    ext = extensions()
    variants: dict[str, Any] = {"default": set_params("default", points),
                                "paper": set_params("paper", points)}
    for k, (dv, pv) in ext.items():
        variants[f"default-{k}"] = replace(variants["default"], **{k: pv})
        variants[f"paper+{k}"] = replace(variants["paper"], **{k: dv})
    out: dict[str, Any] = {"extensions": {k: {"default": d, "paper": p}
                                          for k, (d, p) in ext.items()}}
    parts: list[tuple[str, Iterable[Any], Callable[[Any], Any]]] = [
        ("rail_dirty_sweep", frames, lambda p: DenseKeyframeTracker(p, store=store))]
    if tum_frames:
        parts.append(("tum_fr1_xyz", tum_frames, DenseIncrementalTracker))
    for part, frs, make in parts:
        trackers = {name: make(p) for name, p in variants.items()}
        gts: list[Any] = []

        def keep(f: Any, g: list[Any] = gts) -> None:
            g.append(f.gt_T_world_cam)

        poses, lost, cpu = _track_all(frs, trackers, keep)
        rows = {}
        for name in variants:
            rows[name] = {**_row(poses[name], gts), "lost_frames": lost[name],
                          "cpu_ms_median": float(np.median(cpu[name][1:]))}
        for name, r in rows.items():
            if name in ("default", "paper"):
                continue
            ref = rows["default" if name.startswith("default") else "paper"]
            r["delta_mean_err_m"] = r["mean_err_m"] - ref["mean_err_m"]
            r["delta_max_err_m"] = r["max_err_m"] - ref["max_err_m"]
            r["delta_rot_err_deg_mean"] = r["rot_err_deg_mean"] - ref["rot_err_deg_mean"]
            r["delta_cpu_ms"] = r["cpu_ms_median"] - ref["cpu_ms_median"]
        out[part] = rows
        for name, r in rows.items():
            log(f"ablation {part} {name:36s} mean {r['mean_err_m'] * 1e3:7.2f} mm "
                f"max {r['max_err_m'] * 1e3:7.2f} mm rot {r['rot_err_deg_mean']:.3f} deg "
                f"lost {r['lost_frames']:3d} cpu {r['cpu_ms_median']:.1f} ms")
    return out


def plots(folder: Any, fig: Mapping[str, Any] | None, rail: Mapping[str, Any] | None,
          cycle_frames: int) -> list[str]:
    """``fig14.png`` (translation and rotation error against the keyframe count: both sets,
    sweep / true / SBA poses) and ``fig13_dirty_sweep.png`` (the rail with the clean and the
    dirty store, both sets)."""
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written: list[str] = []
    if fig is not None:
        rows = [*fig["fig14"]["rows"], *fig["fig14_sba"]["rows"]]
        f, axes = plt.subplots(1, 2, figsize=(12, 4.5))
        styles = {"sweep": "o-", "true_poses": "s--", "sba": "^-."}
        colours = {"default": "tab:green", "paper": "tab:purple"}
        for name in SETS:
            for fam, st in styles.items():
                sel = sorted((r for r in rows if r["set"] == name and r["poses"] == fam),
                             key=lambda r: r["keyframes"])
                if not sel:
                    continue
                n = [r["keyframes"] for r in sel]
                lab = f"{name}, " + {"sweep": "sweep poses", "true_poses": "true poses",
                                     "sba": "SBA poses"}[fam]
                axes[0].plot(n, [r["max_err_m"] * 100 for r in sel], st, color=colours[name],
                             label=lab)
                axes[1].plot(n, [r["rot_err_deg_max"] for r in sel], st, color=colours[name],
                             label=lab)
        axes[0].set_ylabel("max translation error (cm)")
        axes[1].set_ylabel("max rotation error (deg)")
        for ax in axes:
            ax.set_xlabel("keyframes")
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=7)
        f.suptitle("Keyframe count vs switching error, translation and rotation (cf. Fig. 14)",
                   fontsize=10)
        written.append(save_figure(f, folder, "fig14.png"))
    if rail is not None and "_series_all" in rail:
        s = rail["_series_all"]
        f, ax = plt.subplots(figsize=(11, 4.5))
        for key, colour, lab in (
                ("default_keyframe", "tab:green", "default, clean sweep"),
                ("dirty_sweep_keyframe", "tab:olive", "default, sweep with the presenter"),
                ("paper_keyframe", "tab:purple", "paper, clean sweep"),
                ("paper_dirty_sweep_keyframe", "tab:pink", "paper, sweep with the presenter"),
                ("default_incremental", "tab:red", "default, incremental"),
                ("paper_incremental", "tab:orange", "paper, incremental")):
            if key in s:
                ax.plot(np.asarray(s[key]) * 100, color=colour, lw=1, label=lab)
        pres = np.asarray(rail["_series"]["presenter"])
        if pres.any():
            on = np.flatnonzero(pres)
            ax.axvspan(on[0], on[-1], color="0.9", label="presenter in view")
        for c in range(cycle_frames, len(pres), cycle_frames):
            ax.axvline(c, color="0.7", lw=0.5)
        ax.set_yscale("log")
        ax.set_ylim(bottom=1e-2)
        ax.set_xlabel("frame")
        ax.set_ylabel("translation error (cm)")
        ax.set_title("Studio rail back and forth, keyframes from a clean sweep and from one "
                     "with the presenter (cf. Fig. 13)", fontsize=10)
        ax.legend(fontsize=7, loc="upper left")
        written.append(save_figure(f, folder, "fig13_dirty_sweep.png"))
    return written
