"""Write a frame source as a TUM RGB-D folder (Sturm et al. 2012 file formats).

Layout: ``rgb/<t>.png`` (8-bit BGR), ``depth/<t>.png`` (uint16, metres x depth_scale, 0 =
invalid), ``rgb.txt``, ``depth.txt``, ``groundtruth.txt`` (``timestamp tx ty tz qx qy qz qw``,
T_world_cam), ``camera.json`` (fx, fy, cx, cy, width, height, distortion[5], depth_scale) and,
when the source has a presenter box, ``presenter.txt`` (``timestamp x y w h``, NaN when not
visible). Timestamps are written with 6 decimals; every file is written atomically.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from engine.camera import Intrinsics, save_camera_json
from engine.errors import SourceError
from engine.frames import Frame
from engine.geometry import tum_from_T
from engine.persist import atomic_write_png, atomic_write_text
from engine.studio.sim import StudioTruth


def write_tum_folder(
    frames: Iterable[Frame],
    out_dir: Path,
    intrinsics: Intrinsics,
    progress: Callable[[int], None] | None = None,
    *,
    written_by: str = "studiotrack demo-data (built-in virtual studio)",
) -> dict[str, object]:
    """Write ``frames`` (with depth) as a TUM folder; returns a small summary."""
    out_dir = Path(out_dir)
    if out_dir.exists() and any(out_dir.iterdir()):
        raise SourceError(f"{out_dir}: output folder exists and is not empty")
    (out_dir / "rgb").mkdir(parents=True, exist_ok=True)
    (out_dir / "depth").mkdir(parents=True, exist_ok=True)
    head = f"# written by {written_by}\n"
    rgb_lines = [head + "# timestamp filename\n"]
    depth_lines = [head + "# timestamp filename\n"]
    gt_lines = [head + "# timestamp tx ty tz qx qy qz qw\n"]
    box_lines = [head + "# timestamp x y w h (presenter box, pixels; nan when not visible)\n"]
    has_box = False
    n = 0
    scale = intrinsics.depth_scale
    for frame in frames:
        if frame.color_bgr is None or frame.depth_m is None:
            raise SourceError(f"frame {frame.index}: TUM export needs colour and depth")
        ts = f"{frame.timestamp_s:.6f}"
        atomic_write_png(out_dir / "rgb" / f"{ts}.png", frame.color_bgr)
        depth_u16 = np.clip(np.round(frame.depth_m.astype(np.float64) * scale), 0, 65535)
        atomic_write_png(out_dir / "depth" / f"{ts}.png", depth_u16.astype(np.uint16))
        rgb_lines.append(f"{ts} rgb/{ts}.png\n")
        depth_lines.append(f"{ts} depth/{ts}.png\n")
        if frame.gt_T_world_cam is not None:
            row = tum_from_T(frame.gt_T_world_cam)
            gt_lines.append(ts + "".join(f" {v:.9f}" for v in row) + "\n")
        truth = frame.payload(StudioTruth)
        if truth is not None and truth.presenter_in_scene is not None:
            has_box = True
            b = frame.gt_box_xywh
            vals = b if b is not None else (float("nan"),) * 4
            box_lines.append(ts + "".join(f" {v:.1f}" for v in vals) + "\n")
        n += 1
        if progress is not None:
            progress(n)
    if n == 0:
        raise SourceError(f"{out_dir}: the source yielded no frames")
    atomic_write_text(out_dir / "rgb.txt", "".join(rgb_lines))
    atomic_write_text(out_dir / "depth.txt", "".join(depth_lines))
    if len(gt_lines) > 1:
        atomic_write_text(out_dir / "groundtruth.txt", "".join(gt_lines))
    if has_box:
        atomic_write_text(out_dir / "presenter.txt", "".join(box_lines))
    save_camera_json(intrinsics, out_dir / "camera.json")
    return {"out": str(out_dir), "frames": n, "groundtruth": len(gt_lines) > 1}
