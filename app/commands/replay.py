"""``studiotrack replay SESSION_DIR --out TRAJ.txt [--json]``: replay a recorded session.

Runs the recorded frames through the recorded tracker (same parameters) and reports whether
every pose is identical bit for bit to the recording. ``--out`` writes the replayed
trajectory as TUM (.txt), CSV (.csv) or JSON (.json); ``--recorded`` exports the recorded
poses instead of replaying.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from app.commands import CommandSpec
from app.commands._common import emit_json, log


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("session", type=Path, metavar="SESSION_DIR")
    p.add_argument("--out", type=Path, default=None, metavar="TRAJ.txt",
                   help="trajectory file: .txt/.tum (TUM), .csv or .json")
    p.add_argument("--format", choices=("tum", "csv", "json"), default=None,
                   help="trajectory format (default from the --out suffix)")
    p.add_argument("--recorded", action="store_true",
                   help="export the recorded poses without replaying")
    p.add_argument("--tracker", default=None, metavar="NAME",
                   help="replay with another tracker (default parameters) instead of the "
                   "recorded one; 'identical' then compares against the recorded poses")
    p.add_argument("--max-frames", type=int, default=None, metavar="N")
    p.add_argument("--json", action="store_true", help="end with one JSON line of results")


def _run(args: argparse.Namespace) -> int:
    from engine.session.export import export_trajectory
    from engine.session.reader import read_index, read_records
    from engine.session.replay import replay_session

    idx = read_index(args.session)
    result: dict[str, object] = {"session": str(args.session), "tracker": idx.tracker_name,
                                 "recorded_status": idx.status}
    if args.recorded:
        records = read_records(args.session)
        result.update(frames=len(records))
    else:
        tracker = None
        if args.tracker:
            from engine.trackers import create_tracker

            tracker = create_tracker(args.tracker)
            result["tracker"] = args.tracker
        log(f"replaying {args.session} with {args.tracker or idx.tracker_name} ...")
        res = replay_session(args.session, tracker, max_frames=args.max_frames)
        records = res.records
        result.update(frames=res.frames, identical=res.identical, mismatches=res.mismatches,
                      max_abs_diff=res.max_abs_diff, params_restored=res.params_restored)
        log(f"{res.frames} frames, identical={res.identical} (mismatches {res.mismatches})")
    if args.out is not None:
        result["format"] = export_trajectory(records, args.out, args.format)
        result["out"] = str(args.out)
    if args.json:
        emit_json(result)
    else:
        for k, v in result.items():
            print(f"{k}: {v}")
    return 0


COMMANDS = (
    CommandSpec(
        name="replay",
        help="replay a recorded session; export TUM/CSV/JSON",
        add_arguments=add_arguments,
        run=_run,
    ),
)
