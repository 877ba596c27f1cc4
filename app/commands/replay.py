"""``studiotrack replay SESSION_DIR --out TRAJ.txt [--json]``: replay a recorded session.

Runs the recorded frames through the recorded tracker (same parameters) and reports whether
every pose is identical bit for bit to the recording; ``identical`` is only true when the
records are whole (the count the index states, frames 0..N-1) and every frame was replayed,
otherwise ``integrity`` says what is wrong. A session without records is an error.
``--out`` writes the replayed trajectory as TUM (.txt), CSV (.csv) or JSON (.json); poses
that are not finite are left out and counted; ``--recorded`` exports the recorded poses
instead of replaying.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from app.commands import CommandSpec
from app.commands._common import emit_json, log, number_arg, warn


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
    p.add_argument("--max-frames", type=number_arg(integer=True, lo=1), default=None, metavar="N")
    p.add_argument("--json", action="store_true", help="end with one JSON line of results")
    p.add_argument("--force", action="store_true", help="replace --out if it is read-only")


def _run(args: argparse.Namespace) -> int:
    from app.commands._interrupt import StopSignals
    from engine.persist import check_output_file
    from engine.session import SessionError
    from engine.session.export import export_trajectory, nonfinite_poses
    from engine.session.reader import read_index, read_records
    from engine.session.replay import replay_session

    idx = read_index(args.session)
    if args.out is not None:
        check_output_file(args.out, error=SessionError, label="--out", force=args.force,
                          inputs=[args.session], make_parents=True)
    result: dict[str, object] = {"session": str(args.session), "tracker": idx.tracker_name,
                                 "recorded_status": idx.status}
    stop = StopSignals("the replay")
    if args.recorded:
        records = read_records(args.session)
        if not records:
            raise SessionError(f"{args.session}: the session holds no frame records "
                               "(records.jsonl missing or empty)")
        result.update(frames=len(records))
    else:
        tracker = None
        if args.tracker:
            from engine.trackers import create_tracker

            tracker = create_tracker(args.tracker)
            result["tracker"] = args.tracker
        log(f"replaying {args.session} with {args.tracker or idx.tracker_name} ...")
        with stop:
            res = replay_session(args.session, tracker, max_frames=args.max_frames,
                                 should_stop=stop)
        records = res.records
        result.update(frames=res.frames, identical=res.identical, mismatches=res.mismatches,
                      max_abs_diff=res.max_abs_diff, params_restored=res.params_restored,
                      integrity=list(res.integrity), partial=stop(),
                      stop_reason=stop.reason)
        for problem in res.integrity:
            warn(f"{args.session}: {problem}; not claiming identity")
        log(f"{res.frames} frames, identical={res.identical} (mismatches {res.mismatches})")
    bad = nonfinite_poses(records)
    result["nonfinite_poses"] = len(bad)
    if bad:
        warn(f"{len(bad)} record(s) with a non-finite pose left out of the export "
             f"(first: frame {bad[0]})")
    if args.out is not None:
        result["format"] = export_trajectory(records, args.out, args.format)
        result["out"] = str(args.out)
    if args.json:
        emit_json(result)
    else:
        for k, v in result.items():
            print(f"{k}: {v}")
    return stop.exit_code if stop() else 0


COMMANDS = (
    CommandSpec(
        name="replay",
        help="replay a recorded session; export TUM/CSV/JSON",
        add_arguments=add_arguments,
        run=_run,
    ),
)
