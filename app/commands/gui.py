"""``studiotrack gui``: the operator window (also what ``studiotrack`` alone runs)."""

from __future__ import annotations

import argparse

from app.commands import CommandSpec
from app.commands._common import number_arg


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--source",
        metavar="SRC",
        default=None,
        help="TUM/OTB folder, video file, camera:N or synthetic[:key=value,...] "
        "(default: the built-in studio, synthetic:frames=100000,presenter=1,path=rail)",
    )
    p.add_argument(
        "--tracker", metavar="NAME", default=None, help="tracker (default: the best registered)"
    )
    p.add_argument(
        "--quit-after",
        metavar="N",
        type=number_arg(integer=True, lo=1),
        default=None,
        help="quit after N processed frames (or when the run ends first)",
    )
    p.add_argument(
        "--screenshot",
        metavar="PNG",
        default=None,
        help="save a picture of the main window just before quitting",
    )
    p.add_argument("--no-start", action="store_true", help="open the window without tracking")
    pacing = p.add_mutually_exclusive_group()
    pacing.add_argument(
        "--realtime",
        dest="realtime",
        action="store_true",
        default=None,
        help="pace recorded sources to their nominal frame rate (default for the GUI)",
    )
    pacing.add_argument(
        "--flat-out",
        dest="realtime",
        action="store_false",
        help="process frames as fast as the tracker can",
    )


def _run(args: argparse.Namespace) -> int:
    from app.main import run_gui

    if args.tracker is not None:
        from engine.trackers import get_spec

        get_spec(args.tracker)  # unknown name -> "studiotrack: error: unknown tracker ..."
    return run_gui(
        source=args.source,
        tracker=args.tracker,
        quit_after=args.quit_after,
        screenshot=args.screenshot,
        start=not args.no_start,
        realtime=args.realtime,
    )


COMMANDS = (
    CommandSpec(
        name="gui",
        help="open the operator window and start tracking (default: the built-in studio)",
        description="Open the operator window on SRC (default: the built-in virtual studio) "
        "and start tracking immediately.",
        add_arguments=add_arguments,
        run=_run,
    ),
)
