"""CLI subcommands: each module declares ``COMMANDS = (CommandSpec(...),)``; the CLI finds them.

``add_arguments(parser)`` fills the subcommand's parser; ``run(args) -> int`` does the work
(exit code). A command with its own sub-commands (``calibrate``, ``bench``) leaves ``run``
None and sets ``func`` on each sub-parser.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from engine.registry import Registry


@dataclass(frozen=True, slots=True)
class CommandSpec:
    """One ``studiotrack NAME`` subcommand."""

    name: str
    help: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int] | None = None
    #: the ``NAME --help`` text (argparse shows none when None)
    description: str | None = None
    #: keep the description's line breaks (``RawDescriptionHelpFormatter``)
    raw_description: bool = False


REGISTRY: Registry[CommandSpec] = Registry(
    "command", "COMMANDS", CommandSpec, places=(__name__,)
)


def available_commands() -> Mapping[str, CommandSpec]:
    """All subcommands by name, in module-name order (the order of ``studiotrack --help``)."""
    return REGISTRY.specs()


def add_command_parser(
    sub: argparse._SubParsersAction,  # type: ignore[type-arg]
    spec: CommandSpec,
) -> argparse.ArgumentParser:
    """The subcommand's parser, filled by the spec and dispatching to ``spec.run``."""
    raw = argparse.RawDescriptionHelpFormatter
    p = sub.add_parser(
        spec.name,
        help=spec.help,
        description=spec.description,
        formatter_class=raw if spec.raw_description else argparse.HelpFormatter,
    )
    spec.add_arguments(p)
    if spec.run is not None:
        p.set_defaults(func=spec.run)
    return p
