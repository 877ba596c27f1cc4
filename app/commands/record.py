"""``studiotrack record SRC --tracker NAME --out SESSION_DIR``: track headless and record.

Records input frames (lossless PNG, 16-bit depth; video files copied as-is), one JSON record
per frame (pose, state, residuals, timings, outputs sent) and the parameters in force. Pose
outputs (``--freed``, ``--opentrackio``) can run at the same time. Ends with one JSON line.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from app.commands import CommandSpec
from app.commands._common import emit_json, log
from app.commands._outputs_cli import add_output_arguments, describe, output_sink, report


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", metavar="SRC", help="source spec (synthetic:..., folder, video)")
    p.add_argument("--tracker", default=None, help="tracker name (default: the app's default)")
    p.add_argument("--out", required=True, type=Path, metavar="SESSION_DIR",
                   help="session folder to create")
    p.add_argument("--max-frames", type=int, default=None, metavar="N")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing session folder")
    add_output_arguments(p)


def _run(args: argparse.Namespace) -> int:
    from engine.session.recorder import SessionRecorder, record_session
    from engine.sources import open_source
    from engine.trackers import create_tracker, default_tracker_name

    name = args.tracker or default_tracker_name()
    source = open_source(args.source)
    tracker = create_tracker(name)
    outputs = output_sink(args)
    if outputs is not None:
        log(f"outputs: {describe(outputs)}")
    n = 0
    try:
        rec = SessionRecorder(args.out, source=source, source_spec=args.source,
                              tracker_name=name, tracker_params=tracker.params,
                              outputs_config=outputs.config if outputs else None,
                              overwrite=args.overwrite)
        for r in record_session(source, tracker, rec, max_frames=args.max_frames,
                                outputs=outputs):
            n += 1
            if n % 100 == 0:
                log(f"recorded {n} frames ({r.fps:.1f} fps, {r.result.state.value})")
    finally:
        if outputs is not None:
            report(outputs)
        source.close()
    log(f"session {args.out}: {n} frames")
    emit_json({"frames": n, "session": str(args.out), "tracker": name, "status": "complete"})
    return 0


COMMANDS = (
    CommandSpec(
        name="record",
        help="track a source headless and record a replayable session",
        add_arguments=add_arguments,
        run=_run,
    ),
)
