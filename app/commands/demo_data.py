"""``studiotrack demo-data OUT --frames N [--seed S] [--path ...] [--presenter 0|1]``:
write the built-in studio as a TUM RGB-D folder (readable by evo and the TUM source), or with
``--format realsense`` as a RealSense SDK recording (``OUT.bag``, played by the SDK)."""

from __future__ import annotations

import argparse
from pathlib import Path

from app.commands import CommandSpec
from app.commands._common import emit_json, log, number_arg

PATHS = ("rail", "pan", "handheld", "static")
FORMATS = ("tum", "realsense")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("out", type=Path,
                   help="output folder (must not exist or be empty); with --format realsense "
                   "a new .bag file")
    p.add_argument("--format", choices=FORMATS, default="tum",
                   help="tum: a TUM RGB-D folder (default); realsense: a .bag in the RealSense "
                   "SDK's recording layout, with the ground truth on an extra topic")
    p.add_argument(
        "--frames",
        type=number_arg(integer=True, lo=1, hi=1_000_000),
        default=None,
        help="number of frames (300; with cycles= in --options: cycles x cycle_s x 30)",
    )
    p.add_argument("--seed", type=number_arg(integer=True, lo=0, hi=2**63 - 1), default=0,
                   help="random seed (0)")
    p.add_argument("--path", choices=PATHS, default="rail", help="camera path (rail)")
    p.add_argument("--presenter", type=int, choices=(0, 1), default=0, help="walking presenter")
    p.add_argument("--ball", type=int, choices=(0, 1), default=0, help="red target ball")
    p.add_argument(
        "--options",
        default="",
        help="more synthetic source options, e.g. 'cycles=2,noise=1,dropouts=1' "
        "(see engine/sources/synthetic.py)",
    )
    p.add_argument("--json", action="store_true", help="end with one JSON line of results")


def _run(args: argparse.Namespace) -> int:
    from engine.errors import SourceError
    from engine.persist import check_output_dir
    from engine.sources import parse_options
    from engine.sources.synthetic import SyntheticSource
    from engine.studio.export import write_tum_folder

    if args.frames is not None and args.frames < 1:
        raise SourceError(f"--frames must be at least 1, got {args.frames}")
    if args.format == "realsense":  # OUT is a new .bag file, not a folder
        from engine.persist import check_output_file
        from engine.sources.realsense_bag import check_bag_path

        check_bag_path(args.out)  # before rendering anything
        check_output_file(args.out, error=SourceError, label="OUT")
    else:
        check_output_dir(args.out, error=SourceError, label="OUT", kind="TUM folder")
    extra = parse_options(args.options)
    opts = {
        "seed": str(args.seed),
        "path": args.path,
        "presenter": str(args.presenter),
        "ball": str(args.ball),
    }
    if args.frames is not None:
        opts["frames"] = str(args.frames)
    elif "cycles" not in extra:
        opts["frames"] = "300"
    opts.update(extra)
    src = SyntheticSource.from_options(opts)
    log(f"demo-data: {src.name} -> {args.out}")
    step = max(1, len(src) // 10)

    def progress(n: int) -> None:
        if n % step == 0 or n == len(src):
            log(f"  {n}/{len(src)} frames")

    if args.format == "realsense":
        from engine.sources.realsense_bag import write_realsense_bag

        summary = write_realsense_bag(src.frames(), args.out, src.intrinsics,
                                      fps=src.nominal_fps, progress=progress)
    else:
        summary = write_tum_folder(src.frames(), args.out, src.intrinsics, progress)
    summary["source"] = src.name
    if args.json:
        emit_json(summary)
    return 0


COMMANDS = (
    CommandSpec(
        name="demo-data",
        help="write the built-in virtual studio as a TUM RGB-D folder or a RealSense .bag",
        description="Render the built-in studio and write rgb/, depth/, rgb.txt, depth.txt, "
        "groundtruth.txt and camera.json (plus presenter.txt with --presenter 1).",
        add_arguments=add_arguments,
        run=_run,
    ),
)
