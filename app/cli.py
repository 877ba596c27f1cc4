"""``studiotrack`` command line. Subcommands live in ``app.commands`` (one module each).

:func:`main` is the one error boundary of the command line; whatever a command raises ends
as exactly one line on stderr, never a raw traceback:

- a module's own error (:class:`engine.errors.StudioTrackError`), a bad command-line value,
  or the system refusing a file (``OSError``): ``studiotrack: error: ...``, exit 2;
- an interruption (Ctrl-C) a command did not handle itself: ``studiotrack: interrupted``,
  exit 130;
- anything else is an internal error: ``studiotrack: internal error: ... (please report ...)``
  with the traceback written to a log file (:func:`crash_log_dir`), exit 1.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import sys
import tempfile
import traceback
from pathlib import Path
from typing import Any, NoReturn

from app import __version__
from app.commands import add_command_parser, available_commands
from engine.errors import StudioTrackError

PROG = "studiotrack"
EXIT_ERROR = 2
EXIT_INTERNAL = 1
EXIT_INTERRUPTED = 130


class CliParser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line on stderr (exit 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_ERROR, f"{self.prog}: error: {one_line(message)} "
                              f"(see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = CliParser(
        prog=PROG,
        description="Live camera and presenter tracking for TV virtual studios. "
        "With no command, opens the operator window on the built-in studio and starts tracking.",
    )
    parser.add_argument("--version", action="version", version=f"studiotrack {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for spec in available_commands().values():
        add_command_parser(sub, spec)
    validate_numeric_options(parser)
    return parser


def iter_parsers(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()) -> Any:
    """``(command path, parser)`` for the parser and every nested subcommand parser."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from iter_parsers(sub, (*path, name))


def validate_numeric_options(parser: argparse.ArgumentParser) -> None:
    """Every plain ``type=int`` / ``type=float`` option of every command parses through the
    validated number path (finite, integral where needed, no overflow); commands that need a
    range declare it with :func:`app.commands._common.number_arg`."""
    from app.commands._common import number_arg

    for _path, p in iter_parsers(parser):
        for action in p._actions:
            if action.type is float:
                action.type = number_arg()
            elif action.type is int:
                action.type = number_arg(integer=True)


def one_line(text: object) -> str:
    """A message as one line (OpenCV and others put newlines in theirs)."""
    return " ".join(str(text).split())


def crash_log_dir() -> Path:
    """Where internal-error tracebacks go: ``$STUDIOTRACK_LOG_DIR``, else
    ``$XDG_STATE_HOME/studiotrack/logs`` (default ``~/.local/state/studiotrack/logs``)."""
    env = os.environ.get("STUDIOTRACK_LOG_DIR")
    if env:
        return Path(env).expanduser()
    state = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(state) / "studiotrack" / "logs"


def write_crash_log(exc: BaseException, argv: list[str]) -> Path | None:
    """Write the traceback of an internal error; the path, or None if nothing could be
    written anywhere (the log folder, then the temp folder)."""
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    text = (f"studiotrack {__version__} internal error {stamp}\nargv: {argv!r}\n"
            f"python: {sys.version.split()[0]}\n\n"
            + "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)))
    for folder in (crash_log_dir(), Path(tempfile.gettempdir())):
        try:
            folder.mkdir(parents=True, exist_ok=True)
            path = folder / f"studiotrack-crash-{stamp}-{os.getpid()}.log"
            path.write_text(text, encoding="utf-8")
            return path
        except OSError:
            continue
    return None


def _os_error_line(exc: OSError) -> str:
    where = exc.filename if exc.filename is not None else ""
    what = exc.strerror or one_line(exc)
    return f"{where}: {what}" if where else what


def _error(msg: str) -> None:
    print(f"{PROG}: error: {one_line(msg)}", file=sys.stderr, flush=True)


def main(argv: list[str] | None = None) -> int:
    """Run one command; returns the exit code (0, 1 internal error, 2 error, 130 interrupted)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if not argv or (argv[0].startswith("-")
                        and argv[0] not in ("-h", "--help", "--version")):
            argv = ["gui", *argv]  # `studiotrack [--source ...]` opens the window
        parser = build_parser()
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # --help/--version (0) or a bad option (2, one line printed)
            return exc.code if isinstance(exc.code, int) else EXIT_ERROR
        if getattr(args, "func", None) is None:
            parser.print_help(sys.stderr)
            return EXIT_ERROR
        return int(args.func(args) or 0)
    except StudioTrackError as exc:
        _error(str(exc))
        return EXIT_ERROR
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr, flush=True)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # e.g. `studiotrack ... | head`: the reader went away
        _silence_stdout()
        return 0
    except MemoryError as exc:
        _error(f"out of memory ({one_line(exc) or 'allocation failed'}); "
               "try a smaller input or fewer frames")
        return EXIT_ERROR
    except OSError as exc:  # the system refused a file or socket the command was given
        _error(_os_error_line(exc))
        return EXIT_ERROR
    except Exception as exc:
        log_path = write_crash_log(exc, argv)
        where = f"the traceback is in {log_path}" if log_path else "no log could be written"
        print(f"{PROG}: internal error: {type(exc).__name__}: {one_line(exc)[:300]} "
              f"(please report this; {where})", file=sys.stderr, flush=True)
        return EXIT_INTERNAL


def _silence_stdout() -> None:
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


if __name__ == "__main__":
    sys.exit(main())
