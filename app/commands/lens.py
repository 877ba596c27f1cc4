"""``studiotrack lens``: the studio project's lens file (zoom/focus table).

    studiotrack lens show --project DIR [--json]
    studiotrack lens add-sample IMAGES... --project DIR --zoom RAW [--focus RAW]
                                [--pattern 9x6] [--square 0.025] [--entrance-pupil-m M]
    studiotrack lens delete-sample --project DIR --zoom RAW [--focus RAW]
    studiotrack lens fixed --project DIR --camera camera.json     (a one-sample fixed lens)
    studiotrack lens import FILE.json --project DIR [--force]
    studiotrack lens export FILE.json --project DIR

Every change saves a new project revision (the previous one stays as the backup). A lens
file that is malformed stops with one line naming the file and field.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from app.commands import CommandSpec
from app.commands._common import emit_json, log
from engine.lens import LensError


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="lens_cmd", metavar="ACTION", required=True)

    def project(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--project", type=Path, required=True, metavar="DIR",
                        help="studio project folder (created when absent)")

    sh = sub.add_parser("show", help="list the lens file's samples")
    project(sh)
    sh.add_argument("--json", action="store_true")
    sh.set_defaults(func=_show)

    ad = sub.add_parser("add-sample", help="calibrate one zoom/focus sample from chessboard "
                        "images taken at those encoder values")
    ad.add_argument("images", nargs="+", type=Path)
    project(ad)
    ad.add_argument("--zoom", type=int, required=True, metavar="RAW")
    ad.add_argument("--focus", type=int, default=0, metavar="RAW")
    ad.add_argument("--pattern", default="9x6", help="inner corners COLSxROWS")
    ad.add_argument("--square", type=float, default=0.025, help="square size (m)")
    ad.add_argument("--entrance-pupil-m", type=float, default=0.0,
                    help="entrance-pupil offset along the optical axis (m, + towards the scene)")
    ad.add_argument("--sensor-width-mm", type=float, default=None,
                    help="sensor width for mm focal lengths (a new lens file: default 9.59)")
    ad.add_argument("--json", action="store_true")
    ad.set_defaults(func=_add)

    de = sub.add_parser("delete-sample", help="remove one sample")
    project(de)
    de.add_argument("--zoom", type=int, required=True, metavar="RAW")
    de.add_argument("--focus", type=int, default=0, metavar="RAW")
    de.set_defaults(func=_delete)

    fx = sub.add_parser("fixed", help="a fixed lens (one sample) from camera.json")
    project(fx)
    fx.add_argument("--camera", type=Path, required=True, metavar="camera.json")
    fx.add_argument("--sensor-width-mm", type=float, default=9.59)
    fx.add_argument("--force", action="store_true", help="replace an existing lens file")
    fx.set_defaults(func=_fixed)

    im = sub.add_parser("import", help="read a lens file into the project")
    im.add_argument("file", type=Path)
    project(im)
    im.add_argument("--force", action="store_true", help="replace an existing lens file")
    im.set_defaults(func=_import)

    ex = sub.add_parser("export", help="write the project's lens file")
    ex.add_argument("file", type=Path)
    project(ex)
    ex.set_defaults(func=_export)


def _open(folder: Path) -> Any:
    from engine.project import INDEX_NAME, new_project, open_project

    if (folder / INDEX_NAME).exists():
        return open_project(folder)
    proj = new_project(folder.name)
    proj.folder = folder
    return proj


def _save(proj: Any, what: str) -> None:
    proj.save()
    log(f"{proj.folder}: {what}; saved revision {proj.revision}")


def _show(args: argparse.Namespace) -> int:
    from engine.lens import samples_table

    proj = _open(args.project)
    lens = proj.lens
    if lens is None:
        log(f"{args.project}: no lens file")
        if args.json:
            emit_json({"lens": None})
        return 0
    for z, f, mm, k1, rms in samples_table(lens):
        log(f"zoom {z:8d} focus {f:8d}  f {mm:7.3f} mm  k1 {k1:+.4f}  "
            f"rms {'-' if rms is None else f'{rms:.3f} px'}")
    missing = lens.missing_corners()
    if missing:
        log(f"incomplete grid: {len(missing)} corner(s) missing, e.g. zoom {missing[0][0]}, "
            f"focus {missing[0][1]}")
    if args.json:
        emit_json({"lens": lens.to_json(), "complete": lens.complete})
    return 0


def _add(args: argparse.Namespace) -> int:
    import cv2

    from engine.errors import CalibrationError
    from engine.lens import LensFile
    from engine.ptz.chessboard import lens_sample_from_chessboard, parse_pattern

    grays = []
    for path in args.images:
        g = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if g is None:
            raise CalibrationError(f"{path}: cannot read image")
        grays.append(g)
    sample, res = lens_sample_from_chessboard(
        grays, args.zoom, args.focus, parse_pattern(args.pattern), args.square,
        entrance_pupil_m=args.entrance_pupil_m, names=[str(p) for p in args.images])
    proj = _open(args.project)
    lens = proj.lens
    w, h = res.intrinsics.width, res.intrinsics.height
    if lens is None:
        lens = LensFile(w, h, (), sensor_width_mm=args.sensor_width_mm or 9.59,
                        name=f"{proj.name} lens")
    elif (lens.width, lens.height) != (w, h):
        raise LensError(f"{args.images[0]}: images are {w}x{h}, the lens file is "
                        f"{lens.width}x{lens.height}")
    proj.lens = lens.with_sample(sample)
    proj.mark_dirty()
    _save(proj, f"lens sample zoom {args.zoom} focus {args.focus} "
          f"(f {sample.fx_px:.1f} px, k1 {sample.k1:+.4f}, rms {res.rms_px:.3f} px)")
    if args.json:
        emit_json({"sample": sample.to_json(), "samples": len(proj.lens.samples),
                   "complete": proj.lens.complete})
    return 0


def _delete(args: argparse.Namespace) -> int:
    proj = _open(args.project)
    if proj.lens is None or not any((s.zoom_raw, s.focus_raw) == (args.zoom, args.focus)
                                    for s in proj.lens.samples):
        raise LensError(f"{args.project}: no lens sample at zoom {args.zoom}, "
                        f"focus {args.focus}")
    proj.lens = proj.lens.without_sample(args.zoom, args.focus)
    proj.mark_dirty()
    _save(proj, f"deleted lens sample zoom {args.zoom} focus {args.focus}")
    return 0


def _fixed(args: argparse.Namespace) -> int:
    from engine.camera import load_camera_json
    from engine.lens import LensFile

    cam = load_camera_json(args.camera)
    proj = _open(args.project)
    if proj.lens is not None and not args.force:
        raise LensError(f"{args.project}: already has a lens file of "
                        f"{len(proj.lens.samples)} sample(s); --force replaces it")
    proj.lens = LensFile.fixed(cam, args.sensor_width_mm, note=str(args.camera))
    proj.mark_dirty()
    _save(proj, f"fixed lens from {args.camera}")
    return 0


def _import(args: argparse.Namespace) -> int:
    from engine.lens import LensFile

    lens = LensFile.load(args.file, require_complete=False)
    proj = _open(args.project)
    if proj.lens is not None and not args.force:
        raise LensError(f"{args.project}: already has a lens file; --force replaces it")
    proj.lens = lens
    proj.mark_dirty()
    _save(proj, f"imported {args.file} ({len(lens.samples)} samples)")
    return 0


def _export(args: argparse.Namespace) -> int:
    proj = _open(args.project)
    if proj.lens is None:
        raise LensError(f"{args.project}: has no lens file to export")
    proj.lens.save(args.file)
    log(f"wrote {args.file}")
    return 0


COMMANDS = (
    CommandSpec(name="lens", help="the project's lens file: show, add-sample, delete-sample, "
                "fixed, import, export", add_arguments=add_arguments,
                description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
                raw_description=True),
)
