"""``studiotrack capture SRC --out DIR [--frames N | --seconds S] [--json]``.

Writes any source (a live RealSense camera, a ``.bag`` recording, the built-in studio, a TUM
folder) as a TUM RGB-D folder: ``rgb/``, ``depth/``, ``rgb.txt``, ``depth.txt``,
``camera.json`` and ``groundtruth.txt`` where the source has ground truth. The folder is read
by ``track``, ``sweep``, evo and other TUM tools. A live source needs ``--frames`` or
``--seconds``; Ctrl-C stops early and still writes the lists of what was captured. A progress
bar goes to stderr; ``--json`` ends with one JSON line (frames, skipped_frames,
disconnected_frames, duration_s, groundtruth, out).
"""

from __future__ import annotations

import argparse
import contextlib
import signal
from collections.abc import Iterator
from pathlib import Path

from app.commands import CommandSpec
from app.commands._common import emit_json, log


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", metavar="SRC",
                   help="realsense[:serial=...], file.bag, synthetic[:...], TUM folder")
    p.add_argument("--out", required=True, type=Path, metavar="DIR",
                   help="output folder (must not exist or be empty)")
    limit = p.add_mutually_exclusive_group()
    limit.add_argument("--frames", type=int, default=None, metavar="N",
                       help="stop after N frames")
    limit.add_argument("--seconds", type=float, default=None, metavar="S",
                       help="stop after S seconds of source time")
    p.add_argument("--json", action="store_true", help="end with one JSON line of results")


@contextlib.contextmanager
def _stop_on_ctrl_c() -> Iterator[list[bool]]:
    """Ctrl-C sets a flag (the capture ends cleanly) instead of raising mid-write."""
    flag = [False]

    def handler(signum: int, frame: object) -> None:
        flag[0] = True

    try:
        old = signal.signal(signal.SIGINT, handler)
    except ValueError:  # not the main thread (tests): no handler
        yield flag
        return
    try:
        yield flag
    finally:
        signal.signal(signal.SIGINT, old)


def _run(args: argparse.Namespace) -> int:
    from app.commands._progress import ProgressBar
    from engine.capture import CaptureStats, capture_to_tum
    from engine.errors import SourceError
    from engine.sources import open_source

    if args.frames is not None and args.frames < 1:
        raise SourceError(f"--frames must be at least 1, got {args.frames}")
    if args.seconds is not None and not args.seconds > 0:
        raise SourceError(f"--seconds must be positive, got {args.seconds}")
    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise SourceError(f"--out {out}: exists and is not an empty folder")
    source = open_source(args.source)
    with source:
        total = len(source) or None
        if total is not None and args.frames is not None:
            total = min(total, args.frames)
        elif args.frames is not None:
            total = args.frames
        log(f"capture: {source.name} -> {out}")
        bar = ProgressBar(None if args.seconds is not None else total)

        def progress(n: int, stats: CaptureStats) -> None:
            extra = []
            if stats.skipped:
                extra.append(f"{stats.skipped} skipped")
            if stats.disconnected:
                extra.append(f"{stats.disconnected} disconnected")
            bar.update(n, ", ".join(extra))

        with _stop_on_ctrl_c() as stop:
            try:
                summary = capture_to_tum(source, out, max_frames=args.frames,
                                         max_seconds=args.seconds,
                                         should_stop=lambda: stop[0], progress=progress)
            finally:
                bar.close()
    log(f"wrote {summary['frames']} frames to {out}"
        + (" with ground truth" if summary.get("groundtruth") else ""))
    if args.json:
        emit_json(summary)
    return 0


COMMANDS = (
    CommandSpec(
        name="capture",
        help="write any RGB-D source (camera, .bag, built-in studio) as a TUM RGB-D folder",
        description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
        raw_description=True,
        add_arguments=add_arguments,
        run=_run,
    ),
)
