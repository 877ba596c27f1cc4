"""``studiotrack bench NAME [--json]``: benchmarks discovered from ``engine.bench``."""

from __future__ import annotations

import argparse
import json

from app.commands._common import emit_json
from engine.bench import available_benches


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("bench", help="run a benchmark (medians, peers side by side)")
    bsub = p.add_subparsers(dest="bench_name", metavar="NAME", required=True)
    for name, module in available_benches().items():
        bp = bsub.add_parser(name, help=module.HELP)
        bp.add_argument("--json", action="store_true", help="end with one JSON line of results")
        module.add_arguments(bp)
        bp.set_defaults(func=_run, bench_module=module)


def _run(args: argparse.Namespace) -> int:
    results = args.bench_module.run(args)
    if args.json:
        emit_json(results)
    else:
        print(json.dumps(results, indent=2, default=float))
    return 0
