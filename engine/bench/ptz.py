"""``studiotrack bench ptz``: the pan-tilt target tracker of Gaspar 2009 and its calibration.

- circle: a red ball on a 2.5 m circle (period 50 s, the paper's model 1; 2-7 m from the
  camera) seen by the simulated stepping pan-tilt camera; position/velocity/acceleration
  error over time, final model probabilities and updates per second (tracker time only,
  median; timings on a shared machine are noisy).
- dlt: synthetic correspondences with 0.5 px noise (median over trials).
- distortion: synthetic distorted grids (recovered k vs true) and real images
  (opencv_samples: chessboard rows of the left images and calib_radial.jpg).
- chessboard: OpenCV calibration of opencv_samples left images vs left_intrinsics.yml.
- visca_loop: the circle with the head a loopback VISCA-over-IP camera (real byte protocol,
  finite speed) commanded through the VISCA driver, the head reading from the camera's
  FreeD output; same error figures, plus the driver's and the FreeD input's counts.
- calibrated_chain: the circle seen through a distorting lens (inverse radial k3 = 0.12)
  by a head without encoder, tracked with only what the calibration tools estimated
  (:func:`engine.ptz.sim_calibration.calibrate_sim`: line-based distortion, DLTs at four
  motor poses -> head geometry, pan/tilt from the reference markers every frame).
- the published experiment (:mod:`engine.bench.ptz_paper`): ``paper_experiment.*`` (the
  paper's method, ``preset=paper``) and ``paper_experiment_default.*`` (ours) on the circle of
  sec. 6.2 (turn rate 2 pi 0.0217 rad/s between the models, 140 s, 0.5 s sampling),
  ``paper_range*`` (7 m to 40 cm), ``paper_q_in_metres``, ``harder_*``; ``--plots DIR``.
- ablation (:mod:`engine.bench.ptz_ablation`): each extension of
  :data:`engine.trackers.ptz.EXTENSIONS` off at a time in our set and on at a time in the
  paper's, on the paper experiment, the range run and the harder cases, same seeds.

Each experiment is one function taking the parsed arguments and returning a dict; they run
in :data:`EXPERIMENTS` order and their keys are flattened as ``experiment.key``.
"""

from __future__ import annotations

import argparse
import glob
import math
from pathlib import Path
from typing import Any

import numpy as np

from engine.arrays import U8, f64, u8
from engine.bench import BenchSpec
from engine.geometry import rotation_angle_rad
from engine.progress import log
from engine.shared_data import shared_data_dir

HELP = "pan-tilt target tracker (Gaspar 2009): circle scenario, DLT, distortion, chessboard"

#: ablation seeds of the full run (the reported intervals) and of ``--quick``
FULL_ABLATION_SEEDS = 4
QUICK_ABLATION_SEEDS = 1
#: ``--quick``: circle / VISCA loop / calibrated chain length, the paper group's harder cases
QUICK_DURATION_S = 20.0
QUICK_HARDER_S = 40.0
QUICK_ABLATION_SCENARIOS = ("paper_experiment",)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--duration", type=float, default=None,
                   help=f"circle scenario length (s; default 60, --quick {QUICK_DURATION_S:.0f})")
    p.add_argument("--period", type=float, default=50.0, help="circle period (s)")
    p.add_argument("--trials", type=int, default=20, help="DLT trials")
    p.add_argument("--data", type=Path, default=None, help="shared data folder")
    p.add_argument("--skip-circle", action="store_true",
                   help="calibration parts only (no circle, VISCA loop or calibrated chain)")
    p.add_argument("--skip-visca", action="store_true", help="no VISCA loop")
    p.add_argument("--skip-chain", action="store_true", help="no calibrated chain")
    p.add_argument("--skip-paper", action="store_true",
                   help="skip the published experiment (paper_experiment.*, paper_range.*)")
    p.add_argument("--skip-ablation", action="store_true",
                   help="skip the ablation of the extensions (ablation.*)")
    p.add_argument("--ablation-seeds", type=int, default=None,
                   help=f"image-noise seeds of the ablation (3, 4, ...; default "
                   f"{FULL_ABLATION_SEEDS}, --quick {QUICK_ABLATION_SEEDS})")
    p.add_argument("--ablation-scenarios", default=None,
                   help="comma-separated scenarios of the ablation (default all: "
                   "paper_experiment, paper_range, harder_30hz, harder_beyond_bank; --quick "
                   "paper_experiment)")
    p.add_argument("--quick", action="store_true",
                   help=f"a check in a few CPU minutes, the same keys: the circle, VISCA loop "
                   f"and calibrated chain {QUICK_DURATION_S:.0f} s, the paper group's harder "
                   f"cases {QUICK_HARDER_S:.0f} s, the ablation on {QUICK_ABLATION_SEEDS} seed "
                   "of the paper's circle (no intervals); without it the full run "
                   "(the figures the README reports)")
    p.add_argument("--plots", type=Path, default=None, help="folder for PNG plots")


def track_circle(src: Any, tracker: Any, duration_s: float) -> dict[str, Any]:
    """Run ``tracker`` over a ptz-sim circle source and measure it against the truth."""
    from engine.loop import run_tracking
    from engine.ptz.sim import PtzTargetTruth
    from engine.trackers.ptz import PtzDetails

    t_s, ep, ev, ea, dist, probs, omg, tms, pt_err = [], [], [], [], [], [], [], [], []
    sources: dict[str, int] = {}
    resets = 0
    # the pipeline closes the loop: the source's head sink moves the camera on each command
    for rec in run_tracking(src, tracker):
        f, r = rec.frame, rec.result
        tms.append(rec.process_ms / 1000.0)
        d = r.details_as(PtzDetails)
        truth = f.payload(PtzTargetTruth)
        if d is not None:
            sources[d.pan_tilt_source] = sources.get(d.pan_tilt_source, 0) + 1
            if truth is not None and truth.pan_tilt_deg is not None:
                pt_err.append(max(abs(d.pan_tilt_deg[0] - truth.pan_tilt_deg[0]),
                                  abs(d.pan_tilt_deg[1] - truth.pan_tilt_deg[1])))
        if d is None or d.target_xyz is None or truth is None or f.gt_T_world_cam is None:
            continue
        assert d.target_vel is not None
        assert d.target_acc is not None
        t_s.append(f.timestamp_s)
        ep.append(float(np.linalg.norm(d.target_xyz - np.asarray(truth.xyz_world))))
        ev.append(float(np.linalg.norm(d.target_vel - np.asarray(truth.vel_world))))
        ea.append(float(np.linalg.norm(d.target_acc - np.asarray(truth.acc_world))))
        dist.append(float(np.linalg.norm(np.asarray(truth.xyz_world)
                                         - f.gt_T_world_cam[:3, 3])))
        probs.append(d.model_probs)
        omg.append(d.omega_rad_s)
        resets = int(d.resets)
        if f.index % 300 == 0:
            log(f"  t={f.timestamp_s:5.1f}s d={dist[-1]:.2f}m pos err={ep[-1]*100:.1f}cm "
                f"p={np.round(np.asarray(d.model_probs), 3).tolist()}")
    if not t_s:
        return {"pos_err_m_steady": None, "frames": len(tms), "note": "never initialised"}
    t = np.asarray(t_s)
    ep_a, ev_a, ea_a, d_a = map(np.asarray, (ep, ev, ea, dist))
    steady = t >= min(20.0, 0.3 * duration_s)
    far = steady & (d_a >= 6.0)
    omegas = np.asarray(tracker.params.omegas)
    omega_true = src.sc.omega_rad_s
    true_j = int(np.argmin(np.abs(omegas - omega_true)))
    p_final = np.asarray(probs[-1])
    med_ms = float(np.median(tms) * 1e3)
    return {
        "pos_err_m_steady": float(np.median(ep_a[steady])),
        "pos_err_m_steady_p95": float(np.percentile(ep_a[steady], 95)),
        "pos_err_m_at_7m": float(np.median(ep_a[far])) if far.any() else None,
        "vel_err_m_s_steady": float(np.median(ev_a[steady])),
        "acc_err_m_s2_steady": float(np.median(ea_a[steady])),
        "range_m": [float(d_a.min()), float(d_a.max())],
        "true_model": true_j,
        "true_omega_rad_s": omega_true,
        "omega_est_final_rad_s": None if omg[-1] is None else float(omg[-1]),
        "true_model_prob_final": float(p_final[true_j]),
        "model_probs_final": p_final.tolist(),
        "updates_per_s": 1000.0 / med_ms,
        "tracker_ms_median": med_ms,
        "resets": resets,
        "frames": len(tms),
        "pan_tilt_source_frames": sources,
        "pan_tilt_err_deg_median": float(np.median(pt_err)) if pt_err else None,
        # 1 s resolution error curves (median per second)
        "pos_err_m_per_s": [float(np.median(ep_a[(t >= s) & (t < s + 1)]))
                            for s in range(int(duration_s)) if ((t >= s) & (t < s + 1)).any()],
    }


def _params_for(sc: Any) -> Any:
    from engine.trackers.ptz import PtzParams

    return PtzParams(target_b=sc.ball_bgr[0], target_g=sc.ball_bgr[1],
                     target_r=sc.ball_bgr[2], target_radius_m=sc.ball_radius_m)


def run_circle(duration_s: float, period_s: float) -> dict[str, Any]:
    from engine.ptz.sim import CircleScenario, PtzSimSource
    from engine.trackers.ptz import PtzTracker

    sc = CircleScenario(duration_s=duration_s, period_s=period_s)
    return track_circle(PtzSimSource(sc), PtzTracker(_params_for(sc)), duration_s)


def run_visca_loop(duration_s: float, period_s: float) -> dict[str, Any]:
    """The circle through the loopback VISCA camera (module docstring)."""
    from engine.ptz.sim import CircleScenario, PtzSimSource
    from engine.trackers.ptz import PtzTracker

    sc = CircleScenario(duration_s=duration_s, period_s=period_s)
    src = PtzSimSource(sc, head="visca", position="freed")
    try:
        out = track_circle(src, PtzTracker(_params_for(sc)), duration_s)
        cam, driver, listener = src._ensure_visca()
        out.update({
            "visca_commands_received": cam.commands, "visca_inquiries_answered": cam.inquiries,
            "driver_sent": driver.sent, "driver_acks": driver.acks,
            "driver_timeouts": driver.timeouts, "driver_garbage": driver.garbage,
            "freed_packets_received": listener.count, "freed_errors": listener.errors,
        })
    finally:
        src.close()
    return out


def run_calibrated_chain(duration_s: float, period_s: float, k3: float = 0.12
                         ) -> dict[str, Any]:
    """The circle tracked with only the calibration tools' estimates (module docstring)."""
    from engine.ptz.sim import CircleScenario, PtzSimSource
    from engine.ptz.sim_calibration import calibrate_sim
    from engine.trackers.ptz import PtzTracker

    sc = CircleScenario(duration_s=duration_s, period_s=period_s, markers=True,
                        distortion_k3=k3, encoder=False)
    src = PtzSimSource(sc)
    cal, report = calibrate_sim(src)
    assert cal.head is not None
    truth = sc.head()
    centre_err = float(np.linalg.norm(cal.head.optical_centre_world(0, 0)
                                      - truth.optical_centre_world(0, 0)))
    log(f"  calibration: {report['lines']} lines, straightness "
        f"{report['straightness_before_px']:.2f} -> {report['straightness_after_px']:.2f} px; "
        f"{report['dlt_views']} DLT views, optical centre err {centre_err * 1000:.1f} mm")
    out = track_circle(src, PtzTracker(_params_for(sc), calibration=cal), duration_s)
    out.update({"lens_k3_true": k3, "calibration": report,
                "optical_centre_err_m": centre_err,
                "focal_err_px": float(cal.head.K[0, 0] - truth.K[0, 0])})
    return out


def run_dlt(trials: int, noise_px: float = 0.5) -> dict[str, Any]:
    from engine.geometry import R_from_pan_tilt_roll_deg
    from engine.ptz.dlt import calibrate_dlt, compose_P, project_P

    rng = np.random.default_rng(5)
    K = np.array([[800.0, 0, 330.0], [0, 790.0, 245.0], [0, 0, 1]])
    R_wc = R_from_pan_tilt_roll_deg(10.0, -8.0, 2.0)
    c = np.array([0.3, -0.5, 1.6])
    R = R_wc.T
    t = -R @ c
    P = compose_P(K, R, t)
    rm, au, u0, rot, cen = [], [], [], [], []
    for _ in range(trials):
        X = np.column_stack([rng.uniform(-2, 2, 30), rng.uniform(3, 7, 30),
                             rng.uniform(0, 2.5, 30)])
        uv = project_P(P, X) + rng.normal(0, noise_px, (30, 2))
        res = calibrate_dlt(X, uv)
        d = res.decomposition
        rm.append(res.rmse_px)
        au.append(abs(d.alpha_u - 800.0) / 800.0)
        u0.append(float(np.hypot(d.u0 - 330.0, d.v0 - 245.0)))
        rot.append(math.degrees(rotation_angle_rad(d.R_cam_world @ R.T)))
        cen.append(float(np.linalg.norm(d.camera_centre_world - c)))
    return {
        "reproj_rmse_px": float(np.median(rm)),
        "alpha_u_rel_err": float(np.median(au)),
        "principal_point_err_px": float(np.median(u0)),
        "rotation_err_deg": float(np.median(rot)),
        "centre_err_m": float(np.median(cen)),
        "noise_px": noise_px,
        "points": 30,
        "trials": trials,
    }


def _read_gray(path: str) -> U8:
    import cv2

    from engine.errors import CalibrationError

    g = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if g is None:
        raise CalibrationError(f"{path}: cannot read image")
    return u8(g)


def run_distortion(data: Path) -> dict[str, Any]:
    import cv2

    from engine.ptz.distortion import (
        RadialModel,
        estimate_radial_from_lines,
        propose_lines_chessboard,
        straightness_rms_px,
        synthetic_distorted_grid,
    )

    out: dict[str, Any] = {}
    true = RadialModel(k=(0.2, 0.05), centre_px=(330.0, 235.0), r_norm_px=400.0)
    grid = synthetic_distorted_grid(true, (640, 480), noise_px=0.3, seed=1)
    fit = estimate_radial_from_lines(grid, (640, 480))
    out["synthetic_k_true"] = list(true.k)
    out["synthetic_k_est"] = list(fit.model.k)
    out["k_rel_err"] = abs(fit.model.k[0] - true.k[0]) / abs(true.k[0])
    out["synthetic_centre_err_px"] = float(np.hypot(fit.model.centre_px[0] - 330.0,
                                                    fit.model.centre_px[1] - 235.0))
    u, v = np.meshgrid(np.linspace(0, 639, 17), np.linspace(0, 479, 13))
    pts = np.stack([u.ravel(), v.ravel()], axis=1)
    out["synthetic_max_correction_err_px"] = float(np.max(np.linalg.norm(
        fit.model.undistort_px(pts) - true.undistort_px(pts), axis=1)))
    # real: chessboard rows/columns of OpenCV's left images, vs OpenCV's reference model
    cb = data / "opencv_samples" / "chessboard_stereo"
    files = sorted(glob.glob(str(cb / "left*.jpg")))
    if files:
        from engine.ptz.chessboard import read_opencv_yaml_intrinsics

        lines: list[np.ndarray] = []
        for fpath in files:
            lines += propose_lines_chessboard(_read_gray(fpath), (9, 6))
        fitr = estimate_radial_from_lines(lines, (640, 480))
        ref = read_opencv_yaml_intrinsics(cb / "left_intrinsics.yml")
        Kr, dr = ref["K"], ref["dist"]
        ref_und = []
        for ln in lines:
            und = f64(cv2.undistortPoints(ln.reshape(-1, 1, 2), Kr, dr, P=Kr)).reshape(-1, 2)
            ref_und.append(und)
        out["left_lines"] = len(lines)
        out["left_straightness_before_px"] = fitr.rms_before_px
        out["left_straightness_after_px"] = fitr.rms_after_px
        out["left_straightness_opencv_ref_px"] = straightness_rms_px(ref_und)
        out["left_k"] = list(fitr.model.k)
        out["left_centre_px"] = list(fitr.model.centre_px)
    radial = data / "opencv_samples" / "lines_distortion" / "calib_radial.jpg"
    if radial.exists():
        g = _read_gray(str(radial))
        lines = propose_lines_chessboard(g, (9, 6))
        if lines:
            fr = estimate_radial_from_lines(lines, (g.shape[1], g.shape[0]))
            out["calib_radial_straightness_before_px"] = fr.rms_before_px
            out["calib_radial_straightness_after_px"] = fr.rms_after_px
            out["calib_radial_k"] = list(fr.model.k)
    return out


def run_chessboard(data: Path) -> dict[str, Any]:
    from engine.ptz.chessboard import calibrate_chessboard, read_opencv_yaml_intrinsics

    cb = data / "opencv_samples" / "chessboard_stereo"
    files = sorted(glob.glob(str(cb / "left*.jpg")))
    if not files:
        return {"fx": None, "k1": None, "rms_px": None, "note": f"{cb} absent"}
    res = calibrate_chessboard(files, (9, 6), 0.025)
    ref = read_opencv_yaml_intrinsics(cb / "left_intrinsics.yml")
    c = res.intrinsics
    return {
        "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy, "k1": c.dist_k1k2p1p2k3[0],
        "k2": c.dist_k1k2p1p2k3[1], "rms_px": res.rms_px, "images": len(res.used_images),
        "ref_fx": float(ref["K"][0, 0]), "ref_k1": float(ref["dist"][0]),
        "ref_rms_px": ref["rms_px"],
        "fx_rel_diff": abs(c.fx - float(ref["K"][0, 0])) / float(ref["K"][0, 0]),
    }


def run_pan_tilt_from_points(trials: int = 20) -> dict[str, Any]:
    from engine.ptz.dlt import project_P
    from engine.ptz.kinematics import estimate_pan_tilt
    from engine.ptz.sim import CircleScenario

    head = CircleScenario().head()
    rng = np.random.default_rng(9)
    errs = []
    for _ in range(trials):
        pan, tilt = rng.uniform(-40, 40), rng.uniform(-20, 10)
        rays = np.vstack([rng.uniform(-0.3, 0.3, 6), rng.uniform(-0.2, 0.2, 6), np.ones(6)])
        X = (head.optical_centre_world(pan, tilt)[:, None]
             + 5.0 * head.R_world_cam(pan, tilt) @ rays).T
        uv = project_P(head.P(pan, tilt), X) + rng.normal(0, 0.5, (6, 2))
        pe, te, _ = estimate_pan_tilt(head, X, uv, (pan + rng.normal(0, 3), tilt))
        errs.append(max(abs(pe - pan), abs(te - tilt)))
    return {"max_angle_err_deg_median": float(np.median(errs)), "points": 6, "noise_px": 0.5}


def _ablation_plan(args: argparse.Namespace) -> tuple[range, list[str] | None]:
    """Seeds and scenario names of the ablation (module docstring; ``--quick`` reduces)."""
    from engine.bench.ptz_ablation import scenarios
    from engine.errors import ParamsError

    n = args.ablation_seeds
    if n is None:
        n = QUICK_ABLATION_SEEDS if args.quick else FULL_ABLATION_SEEDS
    names: list[str] | None = None
    if args.ablation_scenarios:
        names = [s.strip() for s in str(args.ablation_scenarios).split(",") if s.strip()]
        known = list(scenarios())
        bad = [s for s in names if s not in known]
        if bad:
            raise ParamsError(f"--ablation-scenarios: unknown {', '.join(bad)}; available: "
                              f"{', '.join(known)}")
    elif args.quick:
        names = list(QUICK_ABLATION_SCENARIOS)
    return range(3, 3 + max(1, int(n))), names


def run(args: argparse.Namespace) -> dict[str, Any]:
    data = args.data or shared_data_dir()
    if args.duration is None:
        args.duration = QUICK_DURATION_S if args.quick else 60.0
    out: dict[str, Any] = {"run": {"quick": bool(args.quick), "duration_s": args.duration}}
    if not args.skip_circle:
        log(f"circle scenario: {args.duration:.0f} s, period {args.period:.0f} s")
        out["circle"] = run_circle(args.duration, args.period)
        c = out["circle"]
        log(f"  steady pos err {c['pos_err_m_steady']*100:.1f} cm (median), at >=6 m "
             f"{(c['pos_err_m_at_7m'] or float('nan'))*100:.1f} cm, true model p="
             f"{c['true_model_prob_final']:.3f}, {c['updates_per_s']:.0f} updates/s")
    log("DLT on synthetic correspondences (0.5 px noise)")
    out["dlt"] = run_dlt(args.trials)
    log(f"  reprojection RMSE {out['dlt']['reproj_rmse_px']:.3f} px")
    log("line-based distortion")
    out["distortion"] = run_distortion(data)
    log(f"  synthetic k3 rel err {out['distortion']['k_rel_err']:.4f}")
    log("chessboard calibration of opencv_samples left images")
    out["chessboard"] = run_chessboard(data)
    log(f"  fx {out['chessboard']['fx']}, k1 {out['chessboard']['k1']}, "
         f"rms {out['chessboard']['rms_px']}")
    out["pan_tilt_from_points"] = run_pan_tilt_from_points()
    if not args.skip_circle and not args.skip_visca:
        log(f"VISCA loop: {args.duration:.0f} s through the loopback VISCA camera")
        out["visca_loop"] = run_visca_loop(args.duration, args.period)
        _log_loop(out["visca_loop"])
    if not args.skip_circle and not args.skip_chain:
        log(f"calibrated chain: {args.duration:.0f} s, no simulator truth in the tracker")
        out["calibrated_chain"] = run_calibrated_chain(args.duration, args.period)
        _log_loop(out["calibrated_chain"])
    if not args.skip_paper:
        from engine.bench import ptz_paper

        groups, files = ptz_paper.run(args.plots,
                                      harder_duration_s=QUICK_HARDER_S if args.quick else None)
        out.update(groups)
        out["plots"] = {"files": files}
    if not args.skip_ablation:
        from engine.bench import ptz_ablation

        seeds, names = _ablation_plan(args)
        log(f"ablation: each extension off in the default set, on in the paper set, "
            f"{len(seeds)} seeds, {', '.join(names or ['all scenarios'])}")
        out["ablation"] = ptz_ablation.ablation(names, seeds=seeds)
        if args.plots is not None:
            out.setdefault("plots", {"files": []})["files"].append(
                ptz_ablation.plot(out["ablation"], Path(args.plots)))
    flat: dict[str, Any] = {}
    for group, vals in out.items():
        for k, v in vals.items():
            flat[f"{group}.{k}"] = v
    return flat


def _log_loop(c: dict[str, Any]) -> None:
    if c.get("pos_err_m_steady") is None:
        log(f"  {c.get('note', 'no estimate')}")
        return
    log(f"  steady pos err {c['pos_err_m_steady'] * 100:.1f} cm (median), "
        f"{c['updates_per_s']:.0f} updates/s, pan/tilt from {c['pan_tilt_source_frames']}")


BENCHES = (BenchSpec(name="ptz", help=HELP, add_arguments=add_arguments, run=run),)
