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
    p.add_argument("--frames", type=int, default=None,
                   help="use at most this many frames (default and 0: all)")
    p.add_argument("--kf-dist", type=float, default=None,
                   help="new keyframe when this far (m) from all others (default 0.15)")
    p.add_argument("--kf-angle", type=float, default=None,
                   help="...or turned this much (deg) from all others (default 10)")
    p.add_argument("--points", type=int, default=None, help="reference points (default 8192)")
    p.add_argument("--json", action="store_true", help="end with one JSON line of results")


def _run(args: argparse.Namespace) -> int:
    from engine.dense.params import DenseParams
    from engine.keyframes.sweep import SweepParams, SweepProgress, record_sweep
    from engine.sources import open_source

    kf: dict[str, float] = {}
    if args.kf_dist is not None:
        kf["kf_add_dist_m"] = args.kf_dist
    if args.kf_angle is not None:
        kf["kf_add_angle_deg"] = args.kf_angle
    # no frames kept for depth fusion (the page's fusion step): the store is the result
    params = dataclasses.replace(
        SweepParams(max_frames=args.frames or 0, max_kept_frames=0), **kf
    )
    dense = DenseParams() if args.points is None else DenseParams(n_points=args.points)
    source = open_source(args.source)
    last = [-1]

    def progress(rec: SweepProgress) -> None:
        if rec.frame_index - last[0] >= 50:
            last[0] = rec.frame_index
            log(f"frame {rec.frame_index}: {rec.keyframes} keyframes, {rec.lost_frames} lost")

    with source:
        res = record_sweep(source, params, dense_params=dense, on_progress=progress)
    index = res.store.save(args.out)
    log(
        f"{len(res.store)} keyframes from {res.frames_processed} frames "
        f"({res.lost_frames} lost) -> {index}"
    )
    if args.json:
        emit_json(
            {
                "keyframes": len(res.store),
                "frames": res.frames_processed,
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
