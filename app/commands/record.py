"""``studiotrack record SRC --tracker NAME --out SESSION_DIR``: track headless and record.

Records input frames (lossless PNG, 16-bit depth; video files copied as-is), one JSON record
per frame (pose, state, residuals, timings, outputs sent) and the parameters in force. Pose
outputs (``--freed``, ``--opentrackio``) can run at the same time. Ends with one JSON line.

SESSION_DIR must be new or empty; an existing session is replaced only with ``--force``.
Ctrl-C / SIGTERM end the recording cleanly: what was recorded stays readable and the index
says ``"status": "interrupted"`` with the reason.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from app.commands import CommandSpec
from app.commands._common import emit_json, log, number_arg
from app.commands._outputs_cli import (
    add_output_arguments,
    add_setup_arguments,
    describe,
    output_sink,
    report,
    setup_source,
    timecode_clock,
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", metavar="SRC", help="source spec (synthetic:..., folder, video)")
    p.add_argument("--tracker", default=None, help="tracker name (default: the app's default)")
    p.add_argument("--out", required=True, type=Path, metavar="SESSION_DIR",
                   help="session folder to create")
    p.add_argument("--max-frames", type=number_arg(integer=True, lo=1), default=None, metavar="N")
    p.add_argument("--force", "--overwrite", dest="overwrite", action="store_true",
                   help="replace an existing session folder")
    add_output_arguments(p)
    add_setup_arguments(p)


def _run(args: argparse.Namespace) -> int:
    from app.commands._common import run_inputs
    from app.commands._interrupt import StopSignals
    from engine.persist import check_output_dir
    from engine.session import SessionError
    from engine.session.recorder import SessionRecorder, record_session
    from engine.sources import open_source
    from engine.trackers import create_tracker, default_tracker_name

    def check(inputs: list[Path]) -> None:
        check_output_dir(args.out, error=SessionError, label="--out", kind="session",
                         marker="index.json", force=args.overwrite, inputs=inputs)

    check([])
    name = args.tracker or default_tracker_name()
    tracker = create_tracker(name)
    source = setup_source(args, open_source(args.source))
    try:
        clock = timecode_clock(args, source)  # a bad timecode option fails before any file
    except Exception:
        source.close()
        raise
    outputs = None
    summary = None
    n = 0
    stop = StopSignals("the recording")
    try:
        check(run_inputs(args, source))
        outputs = output_sink(args)
        if outputs is not None:
            log(f"outputs: {describe(outputs)}")
        rec = SessionRecorder(args.out, source=source, source_spec=args.source,
                              tracker_name=name, tracker_params=tracker.params,
                              outputs_config=outputs.config if outputs else None,
                              overwrite=args.overwrite)
        with stop:
            for r in record_session(source, tracker, rec, max_frames=args.max_frames,
                                    outputs=outputs, should_stop=stop,
                                    timecode=clock):
                n += 1
                if n % 100 == 0:
                    log(f"recorded {n} frames ({r.fps:.1f} fps, {r.result.state.value})")
    finally:
        if outputs is not None:
            summary = report(outputs)
        source.close()
    status = "interrupted" if stop() else "complete"
    log(f"session {args.out}: {n} frames" + (f" ({stop.reason})" if stop() else ""))
    result: dict[str, object] = {"frames": n, "session": str(args.out), "tracker": name,
                                 "status": status, "partial": stop(),
                                 "stop_reason": stop.reason}
    if summary is not None:
        result["outputs"] = summary
    emit_json(result)
    if summary is not None and summary.get("nothing_sent"):
        raise SessionError(f"outputs: nothing could be sent ({summary['problem']}); the "
                           f"session was recorded in {args.out}")
    return stop.exit_code if stop() and not source.live else 0


COMMANDS = (
    CommandSpec(
        name="record",
        help="track a source headless and record a replayable session",
        add_arguments=add_arguments,
        run=_run,
    ),
)
