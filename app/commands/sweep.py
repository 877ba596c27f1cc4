"""``studiotrack sweep SRC --out KEYFRAMES_DIR [--json]``: build a keyframe store.

Sweep the empty studio with the RGB-D camera (a recording or the built-in studio); the dense
tracker builds keyframes as it goes (Tykkälä 2014 sec. 6.1). Track later with
``studiotrack track SRC --tracker dense --keyframes KEYFRAMES_DIR``.

KEYFRAMES_DIR must be new or empty; an existing keyframe store is replaced only with
``--force`` (completely: the new store is written aside and swapped in). Ctrl-C / SIGTERM
stop the sweep and save the keyframes made so far (``"partial": true``).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shutil

from app.commands import CommandSpec
from app.commands._common import emit_json, log, number_arg, run_inputs


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", metavar="SRC", help="TUM folder, synthetic:..., camera:N")
    p.add_argument("--out", required=True, metavar="KEYFRAMES_DIR", help="store folder")
    p.add_argument("--frames", type=number_arg(integer=True, lo=0), default=None,
                   help="use at most this many frames (default and 0: all)")
    p.add_argument("--kf-dist", type=number_arg(gt=0, hi=1e3), default=None,
                   help="new keyframe when this far (m) from all others (default 0.15)")
    p.add_argument("--kf-angle", type=number_arg(gt=0, hi=180), default=None,
                   help="...or turned this much (deg) from all others (default 10)")
    p.add_argument("--points", type=number_arg(integer=True, lo=1), default=None,
                   help="reference points (default 8192)")
    p.add_argument("--json", action="store_true", help="end with one JSON line of results")
    p.add_argument("--force", action="store_true",
                   help="replace KEYFRAMES_DIR if it is a keyframe store already")


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from app.commands._interrupt import StopSignals
    from engine.dense.params import DenseParams
    from engine.errors import TrackerError
    from engine.keyframes.sweep import SweepParams, SweepProgress, record_sweep
    from engine.persist import check_output_dir, replace_dir
    from engine.sources import open_source

    out = Path(args.out)

    def check(inputs: list[Path]) -> None:
        check_output_dir(out, error=TrackerError, label="--out", kind="keyframe store",
                         marker="keyframes.json", force=args.force, inputs=inputs)

    check([])
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
        check(run_inputs(args, source))
        with StopSignals("the sweep") as stop:
            res = record_sweep(source, params, dense_params=dense, on_progress=progress,
                               should_stop=stop)
    # written aside, then swapped in: an old store is replaced whole (no stale images)
    tmp = out.with_name(f".{out.name}.new-{os.getpid()}")
    try:
        index = out / res.store.save(tmp).name
        replace_dir(tmp, out)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        raise TrackerError(f"--out {out}: cannot write the keyframe store "
                           f"({exc.strerror or exc})") from None
    log(
        f"{len(res.store)} keyframes from {res.frames_processed} frames "
        f"({res.lost_frames} lost) -> {index}" + (f" (partial: {stop.reason})" if stop() else "")
    )
    if args.json:
        emit_json(
            {
                "keyframes": len(res.store),
                "frames": res.frames_processed,
                "lost_frames": res.lost_frames,
                "seconds": round(res.seconds, 3),
                "out": str(args.out),
                "partial": stop(),
                "stop_reason": stop.reason,
            }
        )
    return stop.exit_code if stop() and not source.live else 0


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
