"""``studiotrack bench NAME [--json]``: benchmarks discovered from ``engine.bench`` and, for
those that need the operator window, ``app.benches``."""

from __future__ import annotations

import argparse
import json

from app.commands import CommandSpec
from app.commands._common import emit_json
from engine.bench import available_benches


def add_arguments(p: argparse.ArgumentParser) -> None:
    bsub = p.add_subparsers(dest="bench_name", metavar="NAME", required=True)
    from app.benches import available_app_benches

    for name, spec in {**available_benches(), **available_app_benches()}.items():
        bp = bsub.add_parser(name, help=spec.help)
        bp.add_argument("--json", action="store_true", help="end with one JSON line of results")
        spec.add_arguments(bp)
        bp.set_defaults(func=_run, bench=spec)


def _run(args: argparse.Namespace) -> int:
    results = args.bench.run(args)
    if args.json:
        emit_json(results)
    else:
        print(json.dumps(results, indent=2, default=float))
    return 0


COMMANDS = (
    CommandSpec(
        name="bench",
        help="run a benchmark (medians, peers side by side)",
        add_arguments=add_arguments,
    ),
)
