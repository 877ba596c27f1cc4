"""``studiotrack bench keyframes``: speed and effect of the keyframe-model refinement
(Tykkälä 2014 sec. 6.1): sparse bundle adjustment and depth map fusion.

- SBA: generated keyframes on a 3 m rail (``--sba-keyframes`` x ``--sba-points``, default
  30 x 40, every point seen where it projects into the image), pixel noise 0.2 px, depth
  noise 0.2 %; the last 5 keyframes carry a growing injected pose error (up to 10 cm, 2 deg,
  the drift at the end of a sweep, Fig. 11). Reports the median solve time over
  ``--repeats`` runs, reprojection RMSE before/after and the reduction of the injected error
  (mean camera-centre error of the perturbed keyframes). Goal: <= 2 s.
- Fusion: the built-in studio (rail, Kinect noise and dropouts), ``--frames`` frames
  (300), ``--keyframes`` of them (20, evenly spaced) as keyframes with ground-truth poses;
  the others are fused into their nearest keyframe (Fig. 10). Frames are rendered before the
  clock starts; numba compilation is warmed up first. Reports seconds, hole fraction and
  depth error against the noise-free depth before/after. Goal: <= 20 s.
- Paper beside default: ``sba_paper`` (``SBAParams`` ``preset=paper``: plain least squares,
  as Lourakis' SBA that the paper uses) on the same problem, and ``sba_ablation`` (the
  default with one of its extensions set to the paper's value: ``default-loss``,
  ``default-robust_k``; also with a misclick, 25 px, where the robust loss matters:
  ``*_misclick``). The fusion is the paper's own procedure (Fig. 10, no extension):
  ``fusion_paper`` says so instead of running it twice.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8
from engine.bench import BenchSpec
from engine.camera import Intrinsics, project
from engine.geometry import invert, se3_exp
from engine.keyframes.sba import Observation

F64 = NDArray[np.float64]

HELP = "SBA and depth fusion of the keyframe model (seconds, error reduction, holes)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--sba-keyframes", type=int, default=30, help="SBA keyframes (30)")
    p.add_argument("--sba-points", type=int, default=40, help="SBA annotated points (40)")
    p.add_argument("--repeats", type=int, default=3, help="SBA runs, median time (3)")
    p.add_argument("--frames", type=int, default=300, help="fusion: sweep frames (300)")
    p.add_argument("--keyframes", type=int, default=20, help="fusion: keyframes (20)")
    p.add_argument("--width", type=int, default=640, help="fusion image width (640)")
    p.add_argument("--height", type=int, default=480, help="fusion image height (480)")
    p.add_argument("--seed", type=int, default=0, help="random seed (0)")


@dataclass(frozen=True)
class SyntheticProblem:
    """Generated SBA test case: true and perturbed poses, points and observations."""

    intrinsics: Intrinsics
    T_world_cam_true: dict[int, F64]
    T_world_cam_noisy: dict[int, F64]
    X_world_true: dict[int, F64]
    observations: list[Observation]
    depth_maps: dict[int, NDArray[np.float32]]


def synthetic_problem(
    n_keyframes: int = 30,
    n_points: int = 40,
    *,
    seed: int = 0,
    n_perturbed: int = 5,
    err_m: float = 0.05,
    err_deg: float = 1.5,
    pixel_noise: float = 0.3,
    depth_noise_rel: float = 0.003,
    intrinsics: Intrinsics | None = None,
) -> SyntheticProblem:
    """Keyframes on a 3 m rail looking at a studio-sized point set; the last
    ``n_perturbed`` keyframes get a growing pose error (drift at the end of a sweep, Fig. 11).
    Also the test problem of ``tests/engine/test_sba.py``."""

    rng = np.random.default_rng(seed)
    intr = intrinsics or Intrinsics()
    X = np.column_stack(
        [
            rng.uniform(-2.0, 2.0, n_points),
            rng.uniform(-1.2, 0.8, n_points),
            rng.uniform(3.0, 5.5, n_points),
        ]
    )
    T_true, T_noisy = {}, {}
    for i in range(n_keyframes):
        s = i / max(1, n_keyframes - 1)
        yaw = math.radians(-12.0 + 24.0 * s)
        R = np.array(
            [[math.cos(yaw), 0, math.sin(yaw)], [0, 1, 0], [-math.sin(yaw), 0, math.cos(yaw)]]
        )
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = [-1.5 + 3.0 * s, 0.05 * math.sin(3 * s), 0.0]
        T_true[i] = T
        k = i - (n_keyframes - n_perturbed)
        if k >= 0:
            g = (k + 1) / n_perturbed
            d = rng.normal(size=6)
            d[:3] *= err_m * g / np.linalg.norm(d[:3])
            d[3:] *= math.radians(err_deg) * g / np.linalg.norm(d[3:])
            T_noisy[i] = T @ se3_exp(d)
        else:
            T_noisy[i] = T.copy()
    obs, depths = [], {}
    for i, T in T_true.items():
        T_cw = invert(T)
        pc = X @ T_cw[:3, :3].T + T_cw[:3, 3]
        uv = project(intr, pc)
        dm = np.zeros((intr.height, intr.width), np.float32)
        for j in range(n_points):
            u, v = uv[j] + rng.normal(scale=pixel_noise, size=2)
            if pc[j, 2] > 0.1 and 1 <= u < intr.width - 2 and 1 <= v < intr.height - 2:
                obs.append(Observation(j, i, float(u), float(v)))
                # independent noise per depth pixel, as a sensor has
                dm[round(v) - 1 : round(v) + 2, round(u) - 1 : round(u) + 2] = pc[j, 2] * (
                    1.0 + depth_noise_rel * rng.normal(size=(3, 3))
                )
        depths[i] = dm
    return SyntheticProblem(intr, T_true, T_noisy, {j: X[j] for j in range(n_points)}, obs, depths)


def _bench_sba(args: argparse.Namespace, params: Any = None, misclick: bool = False,
               repeats: int | None = None) -> dict[str, Any]:
    import scipy.optimize  # noqa: F401  (import time is not solve time)

    from engine.keyframes.sba import bundle_adjust
    from engine.progress import log

    n_pert = min(5, args.sba_keyframes - 1)
    pr = synthetic_problem(
        args.sba_keyframes,
        args.sba_points,
        seed=args.seed,
        n_perturbed=n_pert,
        err_m=0.10,
        err_deg=2.0,
        pixel_noise=0.2,
        depth_noise_rel=0.002,
    )
    obs = list(pr.observations)
    if misclick:
        import dataclasses

        obs[len(obs) // 2] = dataclasses.replace(obs[len(obs) // 2],
                                                 u=obs[len(obs) // 2].u + 25.0)
    times, res = [], None
    for r in range(max(1, args.repeats if repeats is None else repeats)):
        t = time.perf_counter()
        res = bundle_adjust(
            pr.intrinsics, pr.T_world_cam_noisy, obs, depth_maps=pr.depth_maps, params=params
        )
        times.append(time.perf_counter() - t)
        log(f"sba run {r + 1}: {times[-1]:.2f} s")
    assert res is not None
    pert = sorted(pr.T_world_cam_true)[-n_pert:]

    def err(T: dict[int, np.ndarray]) -> float:
        return float(
            np.mean([np.linalg.norm(T[k][:3, 3] - pr.T_world_cam_true[k][:3, 3]) for k in pert])
        )

    e0, e1 = err(pr.T_world_cam_noisy), err(res.T_world_cam_after)
    return {
        "keyframes": args.sba_keyframes,
        "points": args.sba_points,
        "observations": len(pr.observations),
        "seconds": round(float(np.median(times)), 3),
        "seconds_all": [round(t, 3) for t in times],
        "rmse_before_px": round(res.rmse_before_px, 3),
        "rmse_after_px": round(res.rmse_after_px, 3),
        "pose_err_before_m": round(e0, 4),
        "pose_err_after_m": round(e1, 4),
        "pose_err_reduction": round(1.0 - e1 / e0, 4),
        "nfev": res.nfev,
        "goal_seconds": 2.0,
    }


def _bench_fusion(args: argparse.Namespace) -> dict[str, Any]:
    import cv2

    from engine.keyframes.fusion import FusionParams, PosedFrame, fuse_depth
    from engine.keyframes.store import KeyframeStore
    from engine.progress import log
    from engine.sources.synthetic import SyntheticSource, config_from_options
    from engine.studio.sim import StudioLabels

    src = SyntheticSource(
        config_from_options(
            {
                "frames": str(args.frames),
                "width": str(args.width),
                "height": str(args.height),
                "noise": "1",
                "dropouts": "1",
                "seed": str(args.seed),
                "path": "rail",
            }
        )
    )
    kf_idx = set(np.linspace(0, args.frames - 1, args.keyframes).round().astype(int).tolist())
    store = KeyframeStore(src.intrinsics)
    exact: dict[int, np.ndarray] = {}
    posed = []
    t = time.perf_counter()
    for i in range(args.frames):
        f = src.frame(i)
        # the built-in studio renders colour, depth and the true pose for every frame
        assert f.color_bgr is not None
        assert f.depth_m is not None
        assert f.gt_T_world_cam is not None
        gray = u8(cv2.cvtColor(f.color_bgr, cv2.COLOR_BGR2GRAY))
        if i in kf_idx:
            kf = store.add(f.gt_T_world_cam, gray, np.array(f.depth_m))
            labels = f.payload(StudioLabels)
            assert labels is not None
            assert labels.depth_exact_m is not None
            exact[kf.id] = labels.depth_exact_m
        else:
            posed.append(PosedFrame(i, gray, f.depth_m, f.gt_T_world_cam))
        if i % 50 == 0:
            log(f"rendered {i}/{args.frames}")
    render_s = time.perf_counter() - t
    # warm-up: numba compilation (cached on disk after the first run)
    t = time.perf_counter()
    fuse_depth(store.subset([store.keyframes[0].id]), posed[:1])
    warm_s = time.perf_counter() - t
    params = FusionParams()
    t = time.perf_counter()
    res = fuse_depth(
        store, posed, params, progress=lambda d, n: log(f"fused {d}/{n}") if d % 50 == 0 else None
    )
    secs = time.perf_counter() - t

    def med_err(depths: dict[int, np.ndarray]) -> float:
        errs = []
        for k, ex in exact.items():
            d = depths[k]
            m = (d > 0) & (ex > 0)
            errs.append(np.abs(d[m] - ex[m]))
        return float(np.median(np.concatenate(errs)))

    before = {k.id: k.depth_m for k in store.keyframes}
    return {
        "frames": args.frames,
        "keyframes": len(store),
        "fused_frames": res.frames_used,
        "size": f"{args.width}x{args.height}",
        "seconds": round(secs, 3),
        "render_seconds": round(render_s, 2),
        "warmup_seconds": round(warm_s, 2),
        "hole_fraction_before": round(res.hole_fraction_before, 5),
        "hole_fraction_after": round(res.hole_fraction_after, 5),
        "noise_before_mm": round(
            1e3 * float(np.nanmedian([s.noise_before_m for s in res.stats])), 2
        ),
        "noise_after_mm": round(
            1e3 * float(np.nanmedian([s.noise_after_m for s in res.stats])), 2
        ),
        "median_abs_err_before_mm": round(1e3 * med_err(before), 2),
        "median_abs_err_after_mm": round(1e3 * med_err(res.depth_m), 2),
        "delta_inv_m": params.delta_inv_m,
        "color_tol": params.color_tol,
        "goal_seconds": 20.0,
    }


def run(args: argparse.Namespace) -> dict[str, Any]:
    from engine.progress import log

    log("SBA ...")
    sba = _bench_sba(args)
    log(
        f"SBA: {sba['seconds']} s, injected error reduced by "
        f"{100 * sba['pose_err_reduction']:.1f} %"
    )
    from engine.keyframes.fusion import FusionParams
    from engine.keyframes.sba import SBAParams

    paper = SBAParams().with_preset("paper")
    sba_paper = _bench_sba(args, paper)
    log(f"SBA (paper preset): {sba_paper['seconds']} s, injected error reduced by "
        f"{100 * sba_paper['pose_err_reduction']:.1f} %")
    ablation: dict[str, Any] = {}
    d = SBAParams()
    for k in SBAParams.PRESETS["paper"].values:
        if getattr(d, k) == getattr(paper, k):
            continue
        v = dataclasses.replace(d, **{k: getattr(paper, k)})
        ablation[f"default-{k}"] = _bench_sba(args, v, repeats=1)
        ablation[f"default-{k}_misclick"] = _bench_sba(args, v, misclick=True, repeats=1)
    ablation["default_misclick"] = _bench_sba(args, d, misclick=True, repeats=1)
    ablation["paper_misclick"] = _bench_sba(args, paper, misclick=True, repeats=1)
    for name, r in ablation.items():
        log(f"SBA ablation {name:28s} error {1e3 * r['pose_err_before_m']:.1f} -> "
            f"{1e3 * r['pose_err_after_m']:.1f} mm, {r['seconds']} s")
    fp = FusionParams()
    fusion_paper: dict[str, Any] = {
        "same_as_default": fp.with_preset("paper") == fp,
        "note": "the fusion is the paper's procedure (Fig. 10: median, +-delta inverse-depth "
                "window, colour test); preset=paper only names the values the paper leaves open",
    }
    log("fusion ...")
    fusion = _bench_fusion(args)
    log(
        f"fusion: {fusion['seconds']} s, holes {fusion['hole_fraction_before']:.4f} -> "
        f"{fusion['hole_fraction_after']:.4f}"
    )
    return {
        "bench": "keyframes",
        "sba": sba,
        "sba_paper": sba_paper,
        "sba_ablation": ablation,
        "fusion": fusion,
        "fusion_paper": fusion_paper,
        "note": "wall times on a shared 2-core machine; SBA median of --repeats runs",
    }


BENCHES = (BenchSpec(name="keyframes", help=HELP, add_arguments=add_arguments, run=run),)
