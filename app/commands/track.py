"""``studiotrack track SRC --tracker NAME --out FILE [--json] [--max-frames N] [--param k=v ...]``.

Tracks a source to the end and writes the result:

- pose trackers: a TUM trajectory (``timestamp tx ty tz qx qy qz qw``, ``T_world_cam``), one
  line per frame that has a pose; LOST frames get a line too, holding the last good pose
  (what the operator's outputs sent), so the file has a line for every frame after the first;
- box trackers: one ``x,y,w,h`` line per frame (OTB style; ``0,0,0,0`` where there is no box).

The summary (frames, tracked, lost_frames, ms_per_frame, ATE/RPE against the source's ground
truth, or success AUC / precision at 20 px for box trackers) goes to stdout; with ``--json``
its last line is one JSON object. Tracker options: each registered tracker may add its own
(``TrackerSpec.add_cli_arguments``); ``--param key=value`` sets any field of the tracker's
parameter dataclass.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

from app.commands import CommandSpec
from app.commands._common import emit_json, log, number_arg, run_inputs, warn
from app.commands._interrupt import StopSignals
from app.commands._outputs_cli import (
    add_output_arguments,
    add_setup_arguments,
    sending,
    setup_source,
    timecode_clock,
)
from engine.errors import TrackerError

if TYPE_CHECKING:
    from engine.loop import FrameRecord
    from engine.sources.base import StopOnError
    from engine.tracking_run import TrackingRun

_DISCOVERY_ERROR: list[str] = []


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", metavar="SRC", help="TUM folder, OTB folder, video, camera:N, "
                   "synthetic[:key=value,...]")
    p.add_argument("--tracker", metavar="NAME", default=None,
                   help="tracker name (default: the app's default tracker)")
    p.add_argument("--out", metavar="FILE", default=None,
                   help="output file: TUM trajectory for pose trackers, x,y,w,h lines for boxes")
    p.add_argument("--json", action="store_true", help="end with one JSON line of results")
    p.add_argument("--max-frames", type=number_arg(integer=True, lo=1), default=None, metavar="N",
                   help="stop after N frames")
    p.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                   help="set a field of the tracker's parameters (repeatable)")
    p.add_argument("--list-params", action="store_true",
                   help="print the chosen tracker's parameters with defaults and exit")
    p.add_argument("--force", action="store_true",
                   help="replace --out even if it is a read-only file")
    _add_tracker_arguments(p)
    add_output_arguments(p)
    add_setup_arguments(p)


def _add_tracker_arguments(p: argparse.ArgumentParser) -> None:
    """Let every registered tracker add its own options (e.g. ``--keyframes DIR``)."""
    try:
        from engine.trackers import available_trackers

        specs = available_trackers()
    except Exception as exc:  # a broken tracker module must not break the whole CLI
        _DISCOVERY_ERROR.append(f"tracker discovery failed: {type(exc).__name__}: {exc}")
        return
    for spec in specs.values():
        if spec.add_cli_arguments is not None:
            spec.add_cli_arguments(p)


def _params_text(params: object) -> str:
    """``name = value  # help [range or choices]`` per field, then the class's presets."""
    import dataclasses

    from engine.params import PRESET_KEY, Params

    lines = []
    for f in dataclasses.fields(params):  # type: ignore[arg-type]
        md = f.metadata
        help_ = str(md.get("help", ""))
        if "choices" in md:
            help_ += f" [{'|'.join(map(str, md['choices']))}]"
        elif "min" in md or "max" in md:
            help_ += f" [{md.get('min', '')}..{md.get('max', '')}]"
        line = f"  {f.name} = {getattr(params, f.name)!r}"
        lines.append(line + (f"  # {help_.strip()}" if help_.strip() else ""))
    if isinstance(params, Params) and params.PRESETS:
        lines.append(f"presets (--param {PRESET_KEY}=NAME):")
        for name, preset in params.PRESETS.items():
            values = ", ".join(f"{k}={v!r}" for k, v in preset.values.items())
            lines.append(f"  {name}: {preset.help} ({values})")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from engine.sources import open_source
    from engine.trackers import default_tracker_name, get_spec
    from engine.tracking_run import apply_param_overrides, run_tracker, summarize

    if _DISCOVERY_ERROR:
        raise TrackerError(_DISCOVERY_ERROR[0])
    if args.max_frames is not None and args.max_frames < 1:
        raise TrackerError(f"--max-frames must be >= 1, got {args.max_frames}")
    name = args.tracker or default_tracker_name()
    spec = get_spec(name)
    params = spec.params_cls()
    if spec.params_from_cli is not None:
        params = spec.params_from_cli(args, params)
    params = apply_param_overrides(params, args.param)
    if args.list_params:
        print(f"{name} ({spec.params_cls.__name__}):\n{_params_text(params)}")
        return 0
    if args.out is None:
        raise TrackerError("track needs --out FILE (the trajectory or box file to write)")
    from engine.persist import check_output_file
    from engine.sources.base import StopOnError

    out_path = check_output_file(args.out, error=TrackerError, label="--out", force=args.force)
    source = setup_source(args, open_source(args.source))
    with source:
        check_output_file(out_path, error=TrackerError, label="--out", force=args.force,
                          inputs=run_inputs(args, source))
        tracker = spec.factory(params)
        total = len(source) if args.max_frames is None else min(len(source), args.max_frames)
        log(f"tracking {getattr(source, 'name', args.source)} with {name} "
            f"({total or 'unknown number of'} frames)")
        every = max(1, (total or 100) // 10)

        def progress(rec: FrameRecord) -> None:
            if (rec.seq + 1) % every == 0:
                log(f"  frame {rec.seq + 1}/{total or '?'}  {rec.result.state.value}"
                    f"  {rec.process_ms:.1f} ms")

        guarded = StopOnError(source)  # a read error mid-run keeps the frames before it
        # --freed / --opentrackio: pose-output sink; Ctrl-C / SIGTERM: stop after this frame
        with StopSignals("tracking") as stop, sending(args) as send:
            tr_run = run_tracker(guarded, tracker, output=spec.output,
                                 max_frames=args.max_frames, on_record=progress,
                                 sinks=send.sinks, should_stop=stop,
                                 timecode=timecode_clock(args, source))
        notes = list(source.end_notes())
    if len(tr_run) == 0:
        if guarded.error is not None:
            raise guarded.error
        if stop():
            raise KeyboardInterrupt
        raise TrackerError(f"{args.source}: the source yielded no frames")
    _write_output(out_path, tr_run)
    partial = stop() or guarded.error is not None
    reason = stop.reason or (f"source error after {len(tr_run)} frames: {guarded.error}"
                             if guarded.error is not None else "")
    log(f"wrote {out_path}" + (f" (partial: {len(tr_run)} frames, {reason})" if partial else ""))
    summary = summarize(tr_run)
    summary["source"] = args.source
    summary["out"] = str(out_path)
    summary["partial"] = partial
    summary["stop_reason"] = reason
    summary["skipped_frames"] = guarded.frames_skipped
    if send.summary is not None:
        summary["outputs"] = send.summary
    input_stats = _input_stats(guarded)
    if input_stats:
        summary["input"] = input_stats
    summary["warnings"] = notes
    for note in summary.get("notes", []):
        log(f"note: {note}")
    for note in notes:
        warn(note)
    if args.json:
        emit_json(summary)
    else:
        print(json.dumps(summary, indent=2))
    if guarded.error is not None:
        raise type(guarded.error)(f"{guarded.error} (the {len(tr_run)} frames before it were "
                                  f"written to {out_path}, flagged partial)")
    if send.summary is not None and send.summary.get("nothing_sent"):
        raise TrackerError(f"outputs: nothing could be sent ({send.summary['problem']}); the "
                           f"trajectory was written to {out_path}")
    if stop() and not source.live:
        return stop.exit_code
    return 0


def _input_stats(source: StopOnError) -> dict[str, object] | None:
    """Counters of skipped input (beacon logs, live UDP readings) as of the last frame."""
    last = source.last_frame
    for payload in () if last is None else last.payloads:
        stats = getattr(payload, "input_stats", None)
        if stats:
            return dict(stats)
    return None


def _write_output(path: Path, tr_run: TrackingRun) -> None:
    from engine.evaluation.boxes import write_boxes
    from engine.evaluation.trajectory import write_tum

    if tr_run.output == "box":
        write_boxes(path, tr_run.boxes_xywh)
    else:
        write_tum(path, tr_run.estimated_trajectory())


COMMANDS = (
    CommandSpec(
        name="track",
        help="track a source and write the trajectory (TUM) or boxes (x,y,w,h)",
        description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
        raw_description=True,
        add_arguments=add_arguments,
        run=run,
    ),
)
