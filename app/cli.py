"""``studiotrack`` command line. Subcommands live in ``app.commands`` (one module each)."""

from __future__ import annotations

import argparse
import sys

from app import __version__
from app.commands import add_command_parser, available_commands
from engine.errors import StudioTrackError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="studiotrack",
        description="Live camera and presenter tracking for TV virtual studios. "
        "With no command, opens the operator window on the built-in studio and starts tracking.",
    )
    parser.add_argument("--version", action="version", version=f"studiotrack {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for spec in available_commands().values():
        add_command_parser(sub, spec)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or (argv[0].startswith("-") and argv[0] not in ("-h", "--help", "--version")):
        argv = ["gui", *argv]  # `studiotrack [--source ...]` opens the window
    args = parser.parse_args(argv)
    try:
        rc = args.func(args)
    except StudioTrackError as exc:
        print(f"studiotrack: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("studiotrack: interrupted", file=sys.stderr)
        return 130
    return int(rc or 0)


if __name__ == "__main__":
    sys.exit(main())
