"""``studiotrack sweep SRC --out KEYFRAMES_DIR [--json]``: build a keyframe store.

Sweep the empty studio with the RGB-D camera (a recording or the built-in studio); the dense
tracker builds keyframes as it goes (Tykkälä 2014 sec. 6.1). Track later with
``studiotrack track SRC --tracker dense --keyframes KEYFRAMES_DIR``.
"""

from __future__ import annotations

import argparse
import dataclasses

from app.commands import CommandSpec
from app.commands._common import emit_json, log


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", metavar="SRC", help="TUM folder, synthetic:..., camera:N")
    p.add_argument("--out", required=True, metavar="KEYFRAMES_DIR", help="store folder")
    p.add_argument("--frames", type=int, default=None, help="use at most this many frames")
    p.add_argument("--kf-dist", type=float, default=None,
                   help="new keyframe when this far (m) from all others (default 0.15)")
    p.add_argument("--kf-angle", type=float, default=None,
                   help="...or turned this much (deg) from all others (default 10)")
    p.add_argument("--points", type=int, default=None, help="reference points (default 8192)")
    p.add_argument("--json", action="store_true", help="end with one JSON line of results")


def _run(args: argparse.Namespace) -> int:
    from engine.dense.sweep import sweep
    from engine.sources import open_source
    from engine.trackers.dense import DenseParams

    upd: dict[str, object] = {}
    if args.kf_dist is not None:
        upd["kf_add_dist_m"] = args.kf_dist
    if args.kf_angle is not None:
        upd["kf_add_angle_deg"] = args.kf_angle
    if args.points is not None:
        upd["n_points"] = args.points
    params = dataclasses.replace(DenseParams(), **upd)
    source = open_source(args.source)
    last = [-1]

    def progress(index: int, kfs: int, lost: int) -> None:
        if index - last[0] >= 50:
            last[0] = index
            log(f"frame {index}: {kfs} keyframes, {lost} lost")

    with source:
        res = sweep(source, params, max_frames=args.frames, progress=progress)
    index = res.store.save(args.out)
    log(f"{len(res.store)} keyframes from {res.frames} frames ({res.lost_frames} lost) -> {index}")
    if args.json:
        emit_json(
            {
                "keyframes": len(res.store),
                "frames": res.frames,
                "lost_frames": res.lost_frames,
                "seconds": round(res.seconds, 3),
                "out": str(args.out),
            }
        )
    return 0


COMMANDS = (
    CommandSpec(
        name="sweep",
        help="build a keyframe store for the dense tracker from a sweep of the empty studio",
        description=__doc__,
        raw_description=True,
        add_arguments=add_arguments,
        run=_run,
    ),
)
