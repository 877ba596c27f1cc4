"""``studiotrack bench dense``: the dense RGB-D trackers (Tykkälä 2014) against their peers.

All parts run side by side in one process (timings on a shared machine: medians, noisy,
compare within one run):

- **rail** (Fig. 13): the built-in studio, rail back and forth for ``--cycles`` cycles, the
  presenter walking during the last ``--presenter-cycles``. A keyframe store is first built by
  ``sweep`` on an empty-studio pass (one slow cycle); then, frame by frame on the same
  rendered frames, ``dense`` (with that store) and ``dense-incremental`` are run and their
  per-frame translation error to the ground truth recorded. Both start at the first frame's
  known pose (the studio's start mark).
- **speed**: on the first ``--speed-frames`` rail frames, the whole per-frame ``track()`` of
  ``dense`` with the sweep store (pre-processing included, 8192 points, 2/3/10 iterations;
  also forced to 1 and 2 threads, and ``preset=paper``), ``dense-incremental`` and
  ``opencv-odometry``, interleaved frame by frame; median / p95 wall ms, process CPU ms, the
  speed-up, and ``stages_ms`` (median ms per stage of the tracker's ``timings_ms``).
- **real**: ``../shared/data/tum_fr1_xyz_37`` (fr1 intrinsics + distortion): ATE RMSE and RPE
  (1 s) of ``dense-incremental``, ``opencv-odometry`` (RGB_DEPTH), ``opencv-icp``
  (``opencv-odometry`` with ``algorithm=icp``), ``open3d-odometry`` (and ``dense`` building
  keyframes online, for information); ``rpe1_trans_m`` is the RMSE of the frame-to-frame
  translation error (35 pairs: less noisy than the 1 s RPE, which has only a few).
- **keyframes** (Fig. 14): stores with decreasing keyframe counts (every k-th keyframe of
  the sweep store) tracked on an empty-studio cycle: max/mean translation error per count.
- **memory**: peak RSS of a child process tracking with the sweep's store (at least 30
  keyframes; ``peak_rss_mb``), and against the keyframe count (``rss_mb_by_keyframes``: 10,
  30, 100, 200 keyframes thinned from a dense sweep). The tracker loads a store lazily and
  keeps per keyframe only its precomputed reference, at most ``max_resident_references``
  (64) of a loaded store's (:mod:`engine.dense.reference_cache`); the child builds every
  keyframe's, as a pass over the whole studio would.

- **paper** (:mod:`engine.bench.dense_paper`): ``preset=paper`` beside the default in every
  part: the rail's ``rail.rows`` (``default_*`` / ``paper_*``, keyframe and incremental, and
  ``*dirty_sweep_keyframe``: Fig. 13's test with keyframes from a sweep that had the presenter
  walking through it), ``fig14`` (Fig. 14 with rotation error: counts all/14/9/7/5, both
  sets; ``fig14.rot_err_deg_max`` is the default set's largest rotation error over the counts
  with the sweep's poses, ``fig14.paper.*`` the paper set's), ``fig14_sba`` (the same with
  SBA-refined keyframe poses as the reference, as the paper does, and its ``vs_full_*`` errors
  against tracking with every SBA keyframe), ``real.dense-incremental-paper``, and
  ``ablation`` (one extension off at a time on the rail and on TUM).

``--plots DIR`` writes ``rail_error.png``, ``keyframe_count.png``, ``fig14.png`` and
``fig13_dirty_sweep.png`` (matplotlib, Agg).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from engine.bench import BenchSpec
from engine.bench.plots import save_figure
from engine.progress import log
from engine.shared_data import shared_data_dir

HELP = "dense RGB-D trackers: speed, TUM accuracy, studio rail drift, keyframe count, memory"

SWEEP_CYCLE_S = 12.0  # the empty-studio sweep is a slow pass


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--cycles", type=int, default=10,
                        help="rail cycles (there and back) of the tracked run (paper: 10)")
    parser.add_argument("--presenter-cycles", type=float, default=2.0,
                        help="the presenter walks during the last N cycles")
    parser.add_argument("--cycle-s", type=float, default=6.0, help="seconds per rail cycle")
    parser.add_argument("--speed-frames", type=int, default=60,
                        help="rail frames timed for every tracker (opencv is slow)")
    parser.add_argument("--kf-dist", type=float, default=0.10,
                        help="sweep: new keyframe every this many metres (>= 30 keyframes)")
    parser.add_argument("--points", type=int, default=8192, help="reference points")
    parser.add_argument("--skip", default="",
                        help="comma list of parts to skip: real, speed, rail, keyframes, memory, "
                        "paper (the paper set's and dirty-sweep trackers), ablation")
    parser.add_argument("--plots", default=None, metavar="DIR", help="write PNG plots here")


def _stats(ms: list[float]) -> dict[str, float]:
    a = np.asarray(ms, dtype=np.float64)
    if a.size == 0:
        return {"ms_median": float("nan"), "ms_p95": float("nan"), "frames": 0}
    return {"ms_median": float(np.median(a)), "ms_p95": float(np.percentile(a, 95)),
            "frames": int(a.size)}


def _terr(T: np.ndarray | None, gt: np.ndarray | None) -> float:
    if T is None or gt is None:
        return float("nan")
    return float(np.linalg.norm(np.asarray(T)[:3, 3] - np.asarray(gt)[:3, 3]))


# ----------------------------------------------------------------------------- real data


def _frame_to_frame_error(frames: list[Any], poses: list[np.ndarray]) -> float | None:
    """RMSE (m) of the translation error of consecutive relative poses against the truth."""
    errs = []
    for f0, f1, p0, p1 in zip(frames, frames[1:], poses, poses[1:], strict=False):
        if f0.gt_T_world_cam is None or f1.gt_T_world_cam is None:
            continue
        g = np.linalg.inv(f0.gt_T_world_cam) @ f1.gt_T_world_cam
        e = np.linalg.inv(p0) @ p1
        errs.append(float(np.linalg.norm((np.linalg.inv(g) @ e)[:3, 3])))
    return float(np.sqrt(np.mean(np.square(errs)))) if errs else None


def _real(points: int) -> dict[str, Any]:
    from engine.bench.dense_paper import set_params
    from engine.evaluation.metrics import ate, rpe
    from engine.evaluation.trajectory import Trajectory, read_tum
    from engine.sources.tum import TumSource
    from engine.trackers import create_tracker

    folder = shared_data_dir() / "tum_fr1_xyz_37"
    if not folder.is_dir():
        log(f"real: {folder} is absent, skipped")
        return {"skipped": f"{folder} absent"}
    src = TumSource(folder)
    frames = list(src.frames())
    gt = read_tum(folder / "groundtruth.txt")
    out: dict[str, Any] = {"sequence": folder.name, "frames": len(frames)}
    for name, tracker, kw in (
        ("dense-incremental", "dense-incremental", {"n_points": points}),
        ("opencv-odometry", "opencv-odometry", {}),
        ("opencv-icp", "opencv-odometry", {"algorithm": "icp"}),
        ("open3d-odometry", "open3d-odometry", {}),
        ("dense", "dense", {"n_points": points}),
        ("dense-incremental-paper", "dense-incremental", {"n_points": points, "preset": "paper"}),
    ):
        preset = kw.pop("preset", None)
        tr = (create_tracker(tracker, params=set_params(str(preset), points)) if preset
              else create_tracker(tracker, **kw))
        poses, ms, lost = [], [], 0
        for f in frames:
            t0 = time.perf_counter()
            r = tr.track(f)
            ms.append((time.perf_counter() - t0) * 1e3)
            poses.append(np.array(r.T_world_cam))
            lost += 0 if r.state.is_good else 1
        est = Trajectory.from_poses([f.timestamp_s for f in frames], poses, name=name)
        a = ate(gt, est)
        p = rpe(gt, est)
        out[name] = {
            "ate_rmse_m": a.rmse_m,
            "rpe_trans_m_per_s": p.trans_rmse_m_per_s,
            "rpe_rot_deg_per_s": p.rot_rmse_deg_per_s,
            "rpe1_trans_m": _frame_to_frame_error(frames, poses),
            "lost_frames": lost,
            **_stats(ms[1:]),
        }
        log(f"real {name:18s} ATE {a.rmse_m * 1e3:6.2f} mm  RPE {p.trans_rmse_m_per_s * 1e3:6.2f}"
             f" mm/s  median {np.median(ms[1:]):6.1f} ms  lost {lost}")
    return out


# ------------------------------------------------------------------------------ the rail


def _rail_spec(cycles: float, cycle_s: float, presenter_cycles: float) -> str:
    spec = f"synthetic:seed=3,path=rail,cycles={cycles:g},cycle_s={cycle_s:g}"
    if presenter_cycles > 0:
        spec += f",presenter=1,presenter_last_cycles={presenter_cycles:g}"
    return spec


def _sweep_store(points: int, kf_dist: float, cycle_s: float = SWEEP_CYCLE_S) -> Any:
    from engine.dense.params import DenseParams
    from engine.keyframes.sweep import SweepParams, record_sweep
    from engine.sources import open_source

    src = open_source(_rail_spec(1, cycle_s, 0))
    res = record_sweep(
        src,
        SweepParams(kf_add_dist_m=kf_dist, max_kept_frames=0),
        dense_params=DenseParams(n_points=points),
    )
    log(f"sweep: {len(res.store)} keyframes from {res.frames_processed} empty-studio frames "
         f"({res.lost_frames} lost, {res.seconds:.1f} s)")
    return res


def _rail(args: argparse.Namespace, store: Any, extra: dict[str, Any] | None = None
          ) -> dict[str, Any]:
    """Fig. 13; ``extra``: more trackers run on the same frames (their rows in ``rows``)."""
    from engine.bench.dense_paper import rail_rows
    from engine.dense.details import DenseDetails
    from engine.dense.params import DenseParams
    from engine.dense.tracking import DenseKeyframeTracker
    from engine.results import TrackState
    from engine.sources import open_source
    from engine.studio.sim import StudioTruth
    from engine.trackers import create_tracker

    spec = _rail_spec(args.cycles, args.cycle_s, args.presenter_cycles)
    src = open_source(spec)
    n = len(src)
    log(f"rail: {spec} ({n} frames)")
    dense = DenseKeyframeTracker(DenseParams(n_points=args.points), store=store)
    incr = create_tracker("dense-incremental", n_points=args.points)
    err_d, err_i = [], []
    lost_d = lost_i = degraded_d = 0
    presenter = []
    relock = []
    poses: dict[str, list[Any]] = {k: [] for k in ("default_keyframe", "default_incremental",
                                                    *(extra or {}))}
    lost_x: dict[str, int] = {}
    gts: list[Any] = []
    for f in src.frames():
        rd = dense.track(f)
        ri = incr.track(f)
        poses["default_keyframe"].append(rd.T_world_cam)
        poses["default_incremental"].append(ri.T_world_cam)
        for name, tr in (extra or {}).items():
            rx = tr.track(f)
            poses[name].append(rx.T_world_cam)
            lost_x[name] = lost_x.get(name, 0) + (0 if rx.state.is_good else 1)
        gts.append(f.gt_T_world_cam)
        err_d.append(_terr(rd.T_world_cam, f.gt_T_world_cam))
        err_i.append(_terr(ri.T_world_cam, f.gt_T_world_cam))
        lost_d += 0 if rd.state.is_good else 1
        degraded_d += 1 if rd.state == TrackState.DEGRADED else 0
        lost_i += 0 if ri.state.is_good else 1
        dd = rd.details_as(DenseDetails)
        if dd is not None and dd.frames_to_relock is not None:
            relock.append(int(dd.frames_to_relock))
        truth = f.payload(StudioTruth)
        presenter.append(bool(truth is not None and truth.presenter_pixels))
        if f.index % 180 == 0:
            log(f"  frame {f.index}/{n}: dense {err_d[-1] * 1e3:.1f} mm, "
                 f"incremental {err_i[-1] * 1e3:.1f} mm")
    ed, ei = np.asarray(err_d), np.asarray(err_i)
    per_cycle = max(1, n // max(1, args.cycles))
    cyc_d = [float(np.nanmax(ed[k:k + per_cycle])) for k in range(0, n, per_cycle)]
    cyc_i = [float(np.nanmax(ei[k:k + per_cycle])) for k in range(0, n, per_cycle)]
    rail: dict[str, Any] = {
        "spec": spec,
        "frames": n,
        "keyframes": len(store),
        "keyframe_max_err_m": float(np.nanmax(ed)),
        "keyframe_mean_err_m": float(np.nanmean(ed)),
        "keyframe_final_err_m": float(ed[-1]),
        "keyframe_max_err_per_cycle_m": cyc_d,
        "keyframe_lost_frames": lost_d,
        "keyframe_degraded_frames": degraded_d,
        "keyframe_relocks": relock,
        "incremental_final_err_m": float(ei[-1]),
        "incremental_max_err_m": float(np.nanmax(ei)),
        "incremental_max_err_per_cycle_m": cyc_i,
        "incremental_lost_frames": lost_i,
    }
    log(f"rail: dense max {rail['keyframe_max_err_m'] * 1e3:.2f} mm, incremental final "
         f"{rail['incremental_final_err_m'] * 1e3:.2f} mm")
    rows, series_all = rail_rows(poses, gts, {"default_keyframe": lost_d,
                                               "default_incremental": lost_i, **lost_x},
                                 args.cycles)
    rail["rows"] = rows
    rail["keyframe_rot_err_deg_max"] = rows["default_keyframe"]["rot_err_deg_max"]
    for name, r in rows.items():
        log(f"rail {name:28s} max {r['max_err_m'] * 1e3:8.2f} mm {r['rot_err_deg_max']:6.3f} "
            f"deg, final {r['final_err_m'] * 1e3:8.2f} mm, lost {r['lost_frames']}")
    rail["_series"] = {"dense": ed, "incremental": ei, "presenter": np.asarray(presenter)}
    rail["_series_all"] = series_all
    return rail


#: the stages of the dense trackers' ``timings_ms`` reported by the speed part
STAGES = ("preprocess", "keyframe", "minimize", "select", "result", "total")


def _speed(args: argparse.Namespace, store: Any) -> dict[str, Any]:
    """The whole per-frame ``track()`` of each tracker on the same first ``--speed-frames``
    rail frames, interleaved frame by frame (load on a shared machine hits all alike).

    ``dense`` is the default tracker (its ``threads`` setting), ``dense_1thread`` and
    ``dense_2threads`` force the thread count, ``dense_paper`` is ``preset=paper``. Frame 0 is
    each tracker's initialisation (store references built, relocalisation) and not timed.
    ``stages_ms`` are per-stage medians of the trackers' own ``timings_ms``.
    """
    from engine.dense.details import DenseDetails
    from engine.dense.params import DenseParams
    from engine.dense.tracking import DenseKeyframeTracker
    from engine.sources import open_source
    from engine.trackers import create_tracker

    spec = _rail_spec(args.cycles, args.cycle_s, args.presenter_cycles)
    frames = []
    for f in open_source(spec).frames():
        if f.index >= args.speed_frames:
            break
        frames.append(f)
    base = DenseParams(n_points=args.points)
    configs = {
        "dense": base,
        "dense_1thread": dataclasses.replace(base, threads=1),
        "dense_2threads": dataclasses.replace(base, threads=2),
        "dense_paper": base.with_preset("paper"),
    }
    trackers: dict[str, Any] = {
        name: DenseKeyframeTracker(p, store=store) for name, p in configs.items()
    }
    trackers["dense_incremental"] = create_tracker("dense-incremental", n_points=args.points)
    trackers["opencv_odometry"] = create_tracker("opencv-odometry")
    wall: dict[str, list[float]] = {k: [] for k in trackers}
    cpu: dict[str, list[float]] = {k: [] for k in trackers}
    stages: dict[str, dict[str, list[float]]] = {k: {} for k in trackers}
    iters: dict[str, list[int]] = {k: [] for k in trackers}
    names = list(trackers)
    order_rng = np.random.default_rng(0)
    for f in frames:
        # a new (seeded) order each frame: every tracker runs as often right after the OpenCV
        # peer (whose ~70 ms leave the caches cold) as the others. In a fixed order, or one
        # turned by one place per frame (the same cycle), ``dense`` always followed it and was
        # ~0.5 ms slower than the same tracker in second place (dense vs dense_1thread)
        for name in [names[int(i)] for i in order_rng.permutation(len(names))]:
            tr = trackers[name]
            c0, t0 = time.process_time(), time.perf_counter()
            r = tr.track(f)
            t1, c1 = time.perf_counter(), time.process_time()
            if f.index == 0:
                continue
            wall[name].append((t1 - t0) * 1e3)
            cpu[name].append((c1 - c0) * 1e3)
            for k, v in r.timings_ms.items():
                stages[name].setdefault(k, []).append(float(v))
            dd = r.details_as(DenseDetails)
            if dd is not None and dd.iterations is not None:
                iters[name].append(int(dd.iterations))
    out: dict[str, Any] = {"frames": spec + f" (first {args.speed_frames})"}
    for name in trackers:
        st = _stats(wall[name])
        # CPU time of the whole process per frame (OpenCV's and numba's worker threads
        # included): less sensitive to other jobs on a shared machine than wall time
        st["cpu_ms_median"] = float(np.median(cpu[name])) if cpu[name] else float("nan")
        out[name] = st
    sd, so = out["dense"], out["opencv_odometry"]
    out["speedup_vs_opencv"] = so["ms_median"] / sd["ms_median"] if sd["ms_median"] > 0 else None
    out["cpu_speedup_vs_opencv"] = (
        so["cpu_ms_median"] / sd["cpu_ms_median"] if sd["cpu_ms_median"] > 0 else None
    )
    out["stages_ms"] = {}
    for name in ("dense", "dense_paper", "dense_incremental"):
        med = {k: float(np.median(v)) for k, v in stages[name].items() if k in STAGES}
        # frames without a stage (no reference built) count as 0 ms in its median
        n_fr = len(wall[name])
        for k, v in stages[name].items():
            if k in STAGES and len(v) < n_fr:
                med[k] = float(np.median(v + [0.0] * (n_fr - len(v))))
        if iters[name]:
            med["iterations"] = float(np.median(iters[name]))
            med["minimize_per_iteration"] = med.get("minimize", 0.0) / max(med["iterations"], 1)
        out["stages_ms"][name] = med
    log("speed (median wall ms / CPU ms / p95 wall):")
    for name in trackers:
        st = out[name]
        log(f"  {name:18s} {st['ms_median']:6.2f} / {st['cpu_ms_median']:6.2f} / "
             f"{st['ms_p95']:6.2f}")
    log(f"  dense vs opencv: x{out['speedup_vs_opencv']:.1f} (CPU x"
         f"{out['cpu_speedup_vs_opencv']:.1f})")
    log("  stages (median ms): " + ", ".join(
        f"{k} {v:.2f}" for k, v in out["stages_ms"]["dense"].items()))
    return out


_MEM_CHILD = r"""
import json, resource, sys
from pathlib import Path
import numpy as np
def rss():
    # VmHWM: peak RSS of this process image (ru_maxrss would carry the parent's peak
    # across fork + exec on Linux)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
from engine.camera import Intrinsics
from engine.dense.tracking import DenseKeyframeTracker
from engine.frames import Frame
from engine.dense.params import DenseParams
base = rss()
folder = Path(sys.argv[2])
intr = Intrinsics(**json.loads(sys.argv[3]))
tr = DenseKeyframeTracker(DenseParams(keyframes_dir=sys.argv[1]))
n = len(tr.store)
for i in range(int(sys.argv[4])):
    a = np.load(folder / f"f{i:04d}.npz")
    tr.track(Frame(i, i / 30.0, a["color"], intr, a["depth"], a["gt"]))
# every keyframe's reference built, as after a full pass over the studio (at most
# max_resident_references of them stay resident)
for kf in tr.store.keyframes:
    tr._reference(kf)
print(json.dumps({"peak_rss_mb": rss(), "after_imports_mb": base, "keyframes": n}))
"""


def _save_frames(frames: list[Any], folder: Path) -> str:
    for i, f in enumerate(frames):
        np.savez(folder / f"f{i:04d}.npz", color=np.asarray(f.color_bgr),
                 depth=np.asarray(f.depth_m), gt=np.asarray(f.gt_T_world_cam))
    return json.dumps(dataclasses.asdict(frames[0].intrinsics))


def _memory_child(store_dir: Path, frames_dir: Path, intr_json: str, n: int) -> dict[str, Any]:
    """Peak RSS of a fresh process tracking ``n`` saved frames with the store in
    ``store_dir`` (loaded by the tracker itself, as ``--keyframes DIR`` does)."""
    out = subprocess.run(
        [sys.executable, "-c", _MEM_CHILD, str(store_dir), str(frames_dir), intr_json, str(n)],
        capture_output=True, text=True, check=False, timeout=600,
    )
    if out.returncode != 0:
        log(f"memory: child failed: {out.stderr.strip().splitlines()[-1:]}")
        return {"peak_rss_mb": None, "error": out.stderr.strip()[-300:]}
    res: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return res


def _memory(store: Any, frames: list[Any]) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="studiotrack-bench-dense-") as tmp:
        store.save(Path(tmp) / "kf")
        intr = _save_frames(frames, Path(tmp))
        res = _memory_child(Path(tmp) / "kf", Path(tmp), intr, len(frames))
    if res.get("peak_rss_mb") is not None:
        log(f"memory: peak RSS {res['peak_rss_mb']:.0f} MB with {res['keyframes']} keyframes "
            f"({res['after_imports_mb']:.0f} MB after imports)")
    return res


#: keyframe counts of the RSS-against-model-size part
RSS_KEYFRAMES = (10, 30, 100, 200)


def _rss_by_keyframes(points: int, frames: list[Any]) -> dict[str, float | None]:
    """Peak RSS (MB) of a tracking process against the keyframe count: one very slow
    empty-studio sweep (24 s there and back, under 1.5 cm per frame) with keyframes every
    1 cm or frame (about 250 on the 3.3 m rail), thinned evenly to each count of
    :data:`RSS_KEYFRAMES` (a count the sweep did not reach is None)."""
    from engine.studio.paths import RAIL_LENGTH_M

    # a keyframe is added once the camera is kf_dist from all others, so where it moves
    # more than kf_dist per frame the spacing is a frame's motion (up to 1.4 cm here): at
    # 1 cm about 250 keyframes on the way out (at 1.6 cm there were 141, and no 200-row)
    big = _sweep_store(points, RAIL_LENGTH_M / 330.0, 2 * SWEEP_CYCLE_S).store
    ids = [k.id for k in big.keyframes]
    out: dict[str, float | None] = {}
    with tempfile.TemporaryDirectory(prefix="studiotrack-bench-dense-rss-") as tmp:
        intr = _save_frames(frames, Path(tmp))
        for count in RSS_KEYFRAMES:
            if len(ids) < count:
                out[str(count)] = None
                continue
            pick = [ids[int(i)] for i in np.linspace(0, len(ids) - 1, count).round()]
            folder = Path(tmp) / f"kf{count}"
            big.subset(pick).save(folder)
            res = _memory_child(folder, Path(tmp), intr, len(frames))
            out[str(count)] = res.get("peak_rss_mb")
            shutil.rmtree(folder, ignore_errors=True)
    log("memory: peak RSS by keyframes " + ", ".join(
        f"{k}: {'-' if v is None else f'{v:.0f} MB'}" for k, v in out.items()))
    return out


def _plots(folder: Path, rail: dict[str, Any] | None, kfc: dict[str, Any] | None,
           cycle_frames: int) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    if rail is not None:
        s = rail["_series"]
        fig, ax = plt.subplots(figsize=(10, 4))
        x = np.arange(len(s["dense"]))
        ax.plot(x, s["incremental"] * 100, color="tab:red", lw=1, label="incremental (Alg. 2)")
        ax.plot(x, s["dense"] * 100, color="tab:green", lw=1,
                label=f"keyframes (Alg. 3, {rail['keyframes']} keyframes)")
        if s["presenter"].any():
            on = np.flatnonzero(s["presenter"])
            ax.axvspan(on[0], on[-1], color="0.9", label="presenter in view")
        for c in range(cycle_frames, len(x), cycle_frames):
            ax.axvline(c, color="0.7", lw=0.5)
        ax.set_xlabel("frame")
        ax.set_ylabel("translation error (cm)")
        ax.set_title("Studio rail back and forth (cf. Tykkälä 2014 Fig. 13)")
        ax.legend(loc="upper left")
        written.append(save_figure(fig, folder, "rail_error.png", dpi=110))
    if kfc is not None and kfc["rows"]:
        fig, ax = plt.subplots(figsize=(6, 4))
        for family, colour in (("sweep", "tab:blue"), ("true_poses", "tab:orange")):
            rows = [r for r in kfc["rows"] if r["poses"] == family]
            if not rows:
                continue
            cnt = [r["keyframes"] for r in rows]
            label = "tracked poses" if family == "sweep" else "true poses"
            ax.plot(cnt, [r["max_err_m"] * 100 for r in rows], "o-", color=colour,
                    label=f"max, {label}")
            ax.plot(cnt, [r["mean_err_m"] * 100 for r in rows], "s--", color=colour,
                    label=f"mean, {label}")
        ax.set_xlabel("keyframes")
        ax.set_ylabel("translation error (cm)")
        ax.set_title("Keyframe count vs switching error (cf. Fig. 14)")
        ax.legend()
        written.append(save_figure(fig, folder, "keyframe_count.png", dpi=110))
    return written


def _dirty_sweep_spec() -> str:
    """The sweep pass with the presenter walking in from the start (Fig. 13, not clean)."""
    return _rail_spec(1, SWEEP_CYCLE_S, 0) + ",presenter=1,presenter_start=0"


def run(args: argparse.Namespace) -> dict[str, Any]:
    from engine.bench import dense_paper
    from engine.sources import open_source

    skip = {s.strip() for s in str(args.skip).split(",") if s.strip()}
    t_start = time.perf_counter()
    out: dict[str, Any] = {"points": args.points, "iterations": [2, 3, 10]}
    rail = kfc = None
    figs: dict[str, Any] = {}
    if "real" not in skip:
        out["real"] = _real(args.points)
    sw = _sweep_store(args.points, args.kf_dist)
    out["sweep"] = {
        "keyframes": len(sw.store), "frames": sw.frames_processed, "lost": sw.lost_frames
    }
    if "speed" not in skip:
        out["speed"] = _speed(args, sw.store)
        out["stages_ms"] = out["speed"]["stages_ms"]["dense"]
    paper = "paper" not in skip
    dirty = None
    if paper and not {"rail", "ablation"} <= skip:
        dirty = dense_paper.dirty_sweep(args.points, args.kf_dist, _dirty_sweep_spec())
        out["sweep"]["dirty_keyframes"] = len(dirty)
    if "rail" not in skip:
        extra = dense_paper.rail_trackers(args.points, sw.store, dirty) if paper else None
        rail = _rail(args, sw.store, extra)
        out["rail"] = {k: v for k, v in rail.items() if not k.startswith("_")}
    if "keyframes" not in skip:
        figs = dense_paper.fig14(sw.store, _rail_spec(1, SWEEP_CYCLE_S, 0),
                                 _rail_spec(1, args.cycle_s, 0), args.points)
        kfc = figs["keyframe_count"]
        out.update(figs)
    if paper and "ablation" not in skip:
        frames_abl = open_source(_rail_spec(2, args.cycle_s, 1)).frames()
        tum = shared_data_dir() / "tum_fr1_xyz_37"
        tum_frames = None
        if tum.is_dir():
            from engine.sources.tum import TumSource

            tum_frames = list(TumSource(tum).frames())
        out["ablation"] = dense_paper.ablation(frames_abl, dirty, args.points, tum_frames)
    if "memory" not in skip:
        src = open_source(_rail_spec(1, args.cycle_s, 0))
        frames = []
        for f in src.frames():
            frames.append(f)
            if len(frames) >= 30:
                break
        mem = _memory(sw.store, frames)
        out["peak_rss_mb"] = mem.get("peak_rss_mb")
        out["memory"] = mem
        out["rss_mb_by_keyframes"] = _rss_by_keyframes(args.points, frames)
    if args.plots:
        per_cycle = round(args.cycle_s * 30)
        out["plots"] = _plots(Path(args.plots), rail, kfc, per_cycle)
        out["plots"] += dense_paper.plots(Path(args.plots), figs if kfc else None, rail,
                                          per_cycle)
    out["seconds"] = time.perf_counter() - t_start
    return out


BENCHES = (BenchSpec(name="dense", help=HELP, add_arguments=add_arguments, run=run),)
