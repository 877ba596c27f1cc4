"""``studiotrack bench render``: speed of the built-in studio renderer.

Side by side in one run, on the same camera poses (rail path): rendering the empty set
(``empty``), rendering the set with the walking presenter and the ball (``presenter``, the
headline numbers), whole source frames (render + truth extraction + Frame record,
``frame``) and the same with Kinect depth noise and dropouts (``frame_noisy``); as a peer, the
presenter case with the ray caster sampling the textures itself (``raycast``, the renderer
before ``cv2.remap`` took the texture fetch; ``ratio_raycast_over_presenter``) and how far its
images are from the default's on every timed pose (``raycast_agreement``: colour differences
in grey levels, depth and label differences); and the presenter case seen by a camera that
stands still (``still``: the renderer keeps the set and traces only where the people and the
ball are). Reports
median/p95 wall ms per frame, frames/s (1000 / median) and the process CPU time per frame
(robust to other processes competing for the cores). Goal: >= 60 frames/s at 640x480 on a
2-core CPU.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from engine.bench import BenchSpec

HELP = "speed of the built-in studio renderer (ms/frame, frames/s)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", type=int, default=150, help="frames timed per case (150)")
    p.add_argument("--width", type=int, default=640, help="image width (640)")
    p.add_argument("--height", type=int, default=480, help="image height (480)")
    p.add_argument(
        "--threads",
        type=int,
        default=1,
        help="renderer threads per frame (1, the source's default; 0: all cores); "
        "the presenter case is also timed with all cores as a peer",
    )
    p.add_argument(
        "--no-peer",
        action="store_true",
        help="skip the open3d RaycastingScene peer (depth-only ray casting of the same set)",
    )
    p.add_argument(
        "--preview",
        default="",
        metavar="PNG",
        help="also write a preview picture (colour + depth, presenter and ball; pan, hand-held)",
    )


def _stats(times_s: list[float]) -> dict[str, float]:
    ms = np.asarray(times_s) * 1e3
    med = float(np.median(ms))
    return {
        "ms_median": med,
        "ms_p95": float(np.percentile(ms, 95)),
        "ms_min": float(ms.min()),
        "fps_median": 1000.0 / med,
    }


def run(args: argparse.Namespace) -> dict[str, Any]:
    from engine.progress import log
    from engine.sources.synthetic import SyntheticSource
    from engine.studio.presenter import concat_prims
    from engine.studio.render import Renderer, numba_max_threads

    n = max(2, args.frames)
    t0 = time.perf_counter()
    opts = {
        "frames": str(n),
        "presenter": "1",
        "ball": "1",
        "width": str(args.width),
        "height": str(args.height),
        "cycles": "1",
        "threads": str(max(0, args.threads)),
    }
    src = SyntheticSource.from_options(opts)
    noisy = SyntheticSource.from_options({**opts, "noise": "1", "dropouts": "1"}).studio
    t_build = time.perf_counter() - t0
    studio = src.studio
    t0 = time.perf_counter()
    studio.frame(0)  # compiles or loads the numba cache
    t_first = time.perf_counter() - t0
    all_threads = numba_max_threads()
    threads = all_threads if args.threads <= 0 else min(args.threads, all_threads)
    log(
        f"bench render: {args.width}x{args.height}, {n} frames per case, "
        f"{threads} renderer thread(s), {os.cpu_count()} CPUs "
        f"(scene {t_build:.2f} s, first frame {t_first:.2f} s)"
    )
    # one renderer per case: a renderer that sees the same pose twice running keeps the set
    # (a still camera), which cases sharing one on the same poses would set off
    renderer = Renderer(studio.scene, studio.intrinsics, threads=studio.renderer.threads)
    renderer_empty = Renderer(studio.scene, studio.intrinsics, threads=renderer.threads)
    renderer_still = Renderer(studio.scene, studio.intrinsics, threads=renderer.threads)
    T_still = studio.T_world_cam(0)

    renderer_all = Renderer(studio.scene, studio.intrinsics, threads=0)
    renderer_still.render(T_still)
    renderer_rc = Renderer(studio.scene, studio.intrinsics, threads=renderer.threads,
                           method="raycast")
    poses = [studio.T_world_cam(i) for i in range(n)]
    dyn = []
    cfg = studio.config
    for i in range(n):
        parts = []
        state = cfg.presenter.state(i) if cfg.presenter is not None else None
        if state is not None:
            from engine.studio.presenter import body_prims

            parts.append(body_prims(state, studio.scene)[0])
        if cfg.ball is not None:
            parts.append(cfg.ball.prims(cfg.ball.state(i / cfg.fps)[0], studio.scene))
        dyn.append(concat_prims(*parts))

    cases: dict[str, list[float]] = {"empty": [], "presenter": [], "frame": [], "frame_noisy": [],
                                     "raycast": [], "still": []}
    cpu: dict[str, list[float]] = {name: [] for name in cases}
    agree = _Agreement()
    jobs: dict[str, Callable[[int], object]] = {
        "empty": lambda i: renderer_empty.render(poses[i]),
        "presenter": lambda i: agree.keep(renderer.render(poses[i], dyn[i])),
        "frame": lambda i: studio.frame(i),
        "frame_noisy": lambda i: noisy.frame(i),
        "raycast": lambda i: agree.compare(renderer_rc.render(poses[i], dyn[i])),
        "still": lambda i: renderer_still.render(T_still, dyn[i]),
    }
    if all_threads != threads:
        cases[f"presenter_{all_threads}_threads"] = []
        cpu[f"presenter_{all_threads}_threads"] = []
        jobs[f"presenter_{all_threads}_threads"] = lambda i: renderer_all.render(poses[i], dyn[i])
    # interleave the cases so that machine load affects them alike
    for i in range(n):
        for name, job in jobs.items():
            c0, w0 = time.process_time(), time.perf_counter()
            job(i)
            cases[name].append(time.perf_counter() - w0)
            cpu[name].append(time.process_time() - c0)
    if not args.no_peer:
        peer = _open3d_peer(studio, poses)
        if peer is not None:
            cases["open3d_depth_only"], cpu["open3d_depth_only"] = peer
    res: dict[str, Any] = {name: _stats(t) for name, t in cases.items()}
    for name, st in list(res.items()):
        # CPU time of the whole process (all threads) per frame: robust to other processes
        # competing for the cores; 1000 / cpu_ms is the frame rate one idle core would give
        st["cpu_ms_median"] = float(np.median(cpu[name]) * 1e3)
    for name, st in res.items():
        if not isinstance(st, dict):
            continue
        log(
            f"  {name:13s} median {st['ms_median']:6.2f} ms  p95 {st['ms_p95']:6.2f} ms  "
            f"{st['fps_median']:6.1f} frames/s  (CPU {st['cpu_ms_median']:6.2f} ms/frame)"
        )
    if args.preview:
        write_preview(args.preview, args.width, args.height)
        log(f"  preview written to {args.preview}")
    try:
        load1 = os.getloadavg()[0]
    except OSError:
        load1 = float("nan")
    res["ratio_raycast_over_presenter"] = (
        res["raycast"]["ms_median"] / res["presenter"]["ms_median"])
    res["ratio_raycast_over_presenter_cpu"] = (
        res["raycast"]["cpu_ms_median"] / res["presenter"]["cpu_ms_median"])
    res["raycast_agreement"] = agree.summary()
    log(f"  raycast / presenter: {res['ratio_raycast_over_presenter']:.2f} (wall), "
        f"{res['ratio_raycast_over_presenter_cpu']:.2f} (CPU); images: "
        + ", ".join(f"{k} {v:g}" for k, v in res["raycast_agreement"].items()))
    if "open3d_depth_only" in res:
        res["ratio_open3d_over_presenter"] = (
            res["open3d_depth_only"]["ms_median"] / res["presenter"]["ms_median"]
        )
    out: dict[str, Any] = {
        "width": args.width,
        "height": args.height,
        "frames": n,
        "threads": threads,
        "cpus": os.cpu_count(),
        "load_avg_1min": load1,
        "scene_build_s": t_build,
        "first_frame_s": t_first,
        **res,
        # headline numbers: the set with the presenter and the ball
        "ms_median": res["presenter"]["ms_median"],
        "ms_p95": res["presenter"]["ms_p95"],
        "fps_median": res["presenter"]["fps_median"],
        "goal_fps": 60.0,
    }
    return out


class _Agreement:
    """Pixel-wise differences between the default renderer's images and the ray caster's
    (``raycast``) of the same pose, over all timed poses."""

    def __init__(self) -> None:
        self._last: Any = None
        self.colour_max = 0
        self.colour_sum = 0.0
        self.over_2 = 0
        self.pixels = 0
        self.depth_max_m = 0.0
        self.labels_differ = 0

    def keep(self, out: Any) -> Any:
        self._last = (out.color_bgr.copy(), out.depth_m.copy(), out.labels.copy())
        return out

    def compare(self, out: Any) -> Any:
        if self._last is None:
            return out
        bgr, depth, labels = self._last
        d = np.abs(out.color_bgr.astype(np.int16) - bgr.astype(np.int16))
        self.colour_max = max(self.colour_max, int(d.max()))
        self.colour_sum += float(d.mean()) * labels.size
        self.over_2 += int(np.count_nonzero(d.max(axis=2) > 2))
        self.pixels += labels.size
        self.depth_max_m = max(self.depth_max_m, float(np.abs(out.depth_m - depth).max()))
        self.labels_differ += int(np.count_nonzero(out.labels != labels))
        self._last = None
        return out

    def summary(self) -> dict[str, float]:
        n = max(self.pixels, 1)
        return {
            "colour_abs_max": float(self.colour_max),
            "colour_abs_mean": self.colour_sum / n,
            "colour_frac_over_2": self.over_2 / n,
            "depth_abs_max_m": self.depth_max_m,
            "labels_frac_differ": self.labels_differ / n,
        }


def write_preview(path: str, width: int = 640, height: int = 480) -> None:
    """2x2 picture: rail frame colour | depth (turbo, 0-6 m, black = no depth); pan frame |
    hand-held frame with depth noise and dropouts (depth shown in the lower-right half)."""
    import cv2

    from engine.frames import Frame
    from engine.persist import atomic_write_png
    from engine.sources.synthetic import SyntheticSource

    size = {"width": str(width), "height": str(height)}

    def depth_vis(d: np.ndarray) -> np.ndarray:
        vis = cv2.applyColorMap(np.clip(d / 6.0 * 255.0, 0, 255).astype(np.uint8), 2)
        vis[d <= 0] = 0
        return vis

    def images(f: Frame) -> tuple[np.ndarray, np.ndarray]:
        # the studio renders both
        assert f.color_bgr is not None
        assert f.depth_m is not None
        return f.color_bgr, f.depth_m

    rail_bgr, rail_d = images(SyntheticSource.from_options(
        {"frames": "180", "cycles": "1", "presenter": "1", "ball": "1", **size}
    ).frame(40))
    pan_bgr, _ = images(SyntheticSource.from_options(
        {"frames": "180", "path": "pan", "presenter": "1", "ball": "1", **size}
    ).frame(120))
    hand_bgr, hand_d = images(SyntheticSource.from_options(
        {
            "frames": "180",
            "path": "handheld",
            "presenter": "1",
            "noise": "1",
            "dropouts": "1",
            **size,
        }
    ).frame(100))
    hand_img = hand_bgr.copy()
    dv = depth_vis(hand_d)
    half = np.tri(height, width, k=-(width - height) // 2, dtype=bool)[:, ::-1][::-1]
    hand_img[half] = dv[half]
    top = np.hstack([rail_bgr, depth_vis(rail_d)])
    bottom = np.hstack([pan_bgr, hand_img])
    atomic_write_png(Path(path), np.vstack([top, bottom]))


def _open3d_peer(studio: Any, poses: list[np.ndarray]) -> tuple[list[float], list[float]] | None:
    """Depth-only ray casting of the static set with open3d's RaycastingScene (Embree):
    the same room and props as triangle meshes, one ray per pixel, t_hit -> z. A reference
    for the numba renderer, which also textures, labels and draws the presenter."""
    try:
        import open3d as o3d
    except ImportError:  # pragma: no cover - open3d is a dependency
        return None
    from engine.progress import log
    from engine.studio.scene import BOX, CYL, SPH

    sc = studio.scene
    meshes = []
    rg = sc.room_geom
    room = o3d.geometry.TriangleMesh.create_box(2 * rg[3], 2 * rg[4], 2 * rg[5])
    meshes.append(room.translate(rg[:3] - rg[3:6]))
    for typ, g in zip(sc.prim_type, sc.prim_geom, strict=True):
        if typ == BOX:
            m = o3d.geometry.TriangleMesh.create_box(2 * g[3], 2 * g[4], 2 * g[5])
            m.translate(-g[3:6])
            yaw = float(np.arctan2(g[7], g[6]))
            m.rotate(o3d.geometry.get_rotation_matrix_from_xyz((0.0, 0.0, yaw)), center=(0, 0, 0))
            m.translate(g[:3])
        elif typ == CYL:
            m = o3d.geometry.TriangleMesh.create_cylinder(g[2], g[4] - g[3], resolution=32)
            m.translate((g[0], g[1], (g[3] + g[4]) / 2))
        elif typ == SPH:
            m = o3d.geometry.TriangleMesh.create_sphere(g[3], resolution=20)
            m.translate(g[:3])
        else:
            continue
        meshes.append(m)
    scene = o3d.t.geometry.RaycastingScene()
    for m in meshes:
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(m))
    cam = studio.intrinsics
    r = studio.renderer
    dirs_cam = np.stack([r.xn, r.yn, np.ones_like(r.xn)], axis=-1).astype(np.float32)
    inv_norm = r.inv_norm.astype(np.float32)
    walls, cpus = [], []
    for T in poses:
        c0, w0 = time.process_time(), time.perf_counter()
        d_world = (dirs_cam.reshape(-1, 3) @ T[:3, :3].T.astype(np.float32)) * inv_norm.reshape(
            -1, 1
        )
        rays = np.empty((d_world.shape[0], 6), np.float32)
        rays[:, :3] = T[:3, 3]
        rays[:, 3:] = d_world
        t_hit = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
        depth = (t_hit * inv_norm.reshape(-1)).reshape(cam.height, cam.width)
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    assert depth.shape == (cam.height, cam.width)
    log(f"  open3d peer: {len(meshes)} meshes, depth only")
    return walls, cpus


BENCHES = (BenchSpec(name="render", help=HELP, add_arguments=add_arguments, run=run),)
