"""``studiotrack calibrate``: chessboard (OpenCV), DLT from points (Gaspar 2009 sec. 3.1) and
line-based lens distortion (sec. 3.3)."""

from __future__ import annotations

import argparse
from pathlib import Path

from app.commands import CommandSpec
from app.commands._common import emit_json, log, number_arg, warn


def add_arguments(p: argparse.ArgumentParser) -> None:
    csub = p.add_subparsers(dest="calib_kind", metavar="KIND", required=True)

    cb = csub.add_parser("chessboard", help="OpenCV chessboard calibration of IMAGES")
    cb.add_argument("images", nargs="+", type=Path)
    cb.add_argument("--pattern", default="9x6", help="inner corners COLSxROWS (default 9x6)")
    cb.add_argument("--square", type=number_arg(gt=0, hi=100), default=0.025,
                    help="square size (m)")
    cb.add_argument("--fix-aspect", action="store_true", help="CALIB_FIX_ASPECT_RATIO")
    cb.add_argument("--out", type=Path, default=None, help="write camera.json here")
    cb.add_argument("--json", action="store_true", help="end with one JSON line")
    cb.set_defaults(func=_chessboard)

    dl = csub.add_parser("dlt", help="DLT from a CSV of x,y,z,u,v correspondences (>= 6)")
    dl.add_argument("points", type=Path)
    dl.add_argument("--outlier-px", type=number_arg(gt=0), default=3.0,
                    help="outlier residual (px)")
    dl.add_argument("--json", action="store_true", help="end with one JSON line")
    dl.set_defaults(func=_dlt)

    ln = csub.add_parser("lines", help="line-based radial distortion from a chessboard image")
    ln.add_argument("images", nargs="+", type=Path)
    ln.add_argument("--pattern", default="9x6", help="inner corners COLSxROWS; 'edges' = LSD")
    ln.add_argument("--terms", type=number_arg(integer=True, lo=1, hi=4), default=2,
                    help="number of k terms (k3, k5, ...)")
    ln.add_argument("--json", action="store_true", help="end with one JSON line")
    ln.set_defaults(func=_lines)


def _chessboard(args: argparse.Namespace) -> int:
    from engine.camera import save_camera_json
    from engine.ptz.chessboard import calibrate_chessboard, parse_pattern

    res = calibrate_chessboard(args.images, parse_pattern(args.pattern), args.square,
                               fix_aspect_ratio=args.fix_aspect)
    c = res.intrinsics
    for path, why in zip(res.skipped_images, res.skipped_reasons, strict=True):
        warn(f"{path}: skipped ({why})")
    log(f"{len(res.used_images)} of {len(args.images)} images used; rms {res.rms_px:.3f} px")
    log(f"fx {c.fx:.2f} fy {c.fy:.2f} cx {c.cx:.2f} cy {c.cy:.2f} dist {c.dist_k1k2p1p2k3}")
    if args.out:
        save_camera_json(c, args.out)
        log(f"wrote {args.out}")
    if args.json:
        emit_json(res.to_json_dict())
    return 0


def _dlt(args: argparse.Namespace) -> int:
    from engine.ptz.dlt import calibrate_dlt, load_points_csv, outlier_mask

    X, uv = load_points_csv(args.points)
    res = calibrate_dlt(X, uv)
    d = res.decomposition
    out = outlier_mask(res.residuals_px, args.outlier_px)
    for i, (r, o) in enumerate(zip(res.residuals_px, out, strict=True)):
        log(f"point {i:3d}: residual {r:7.3f} px{'  OUTLIER' if o else ''}")
    log(f"alpha_u {d.alpha_u:.2f} alpha_v {d.alpha_v:.2f} u0 {d.u0:.2f} v0 {d.v0:.2f} "
        f"rmse {res.rmse_px:.3f} px")
    if args.json:
        emit_json({
            "P": res.P.tolist(), "alpha_u": d.alpha_u, "alpha_v": d.alpha_v, "u0": d.u0,
            "v0": d.v0, "R_cam_world": d.R_cam_world.tolist(),
            "t_cam_world": d.t_cam_world.tolist(),
            "camera_centre_world": d.camera_centre_world.tolist(), "skew_deg": d.skew_deg,
            "reproj_rmse_px": res.rmse_px, "residuals_px": res.residuals_px.tolist(),
            "outliers": [int(i) for i in out.nonzero()[0]],
        })
    return 0


def _lines(args: argparse.Namespace) -> int:
    from engine.errors import CalibrationError
    from engine.ptz.chessboard import parse_pattern, read_calibration_image
    from engine.ptz.distortion import (
        estimate_radial_from_lines,
        propose_lines_chessboard,
        propose_lines_edges,
    )

    pattern = None if args.pattern == "edges" else parse_pattern(args.pattern)
    lines = []
    size = None
    for path in args.images:
        g = read_calibration_image(path)  # missing, truncated, undecodable: one-line error
        wh = (g.shape[1], g.shape[0])
        if size is not None and wh != size:
            raise CalibrationError(f"{path}: size {wh[0]}x{wh[1]} differs from the first "
                                   f"image's {size[0]}x{size[1]}; give photos of one camera mode")
        size = wh
        found = propose_lines_edges(g) if pattern is None else propose_lines_chessboard(g, pattern)
        log(f"{path}: {len(found)} line(s)")
        lines += found
    if not lines or size is None:
        raise CalibrationError("no lines found in the images")
    fit = estimate_radial_from_lines(lines, size, n_terms=args.terms)
    log(f"k {fit.model.k}, centre {fit.model.centre_px}, straightness "
        f"{fit.rms_before_px:.3f} -> {fit.rms_after_px:.3f} px")
    if args.json:
        emit_json({**fit.model.to_json_dict(), "lines": len(lines),
                   "rms_before_px": fit.rms_before_px, "rms_after_px": fit.rms_after_px})
    return 0


COMMANDS = (
    CommandSpec(
        name="calibrate",
        help="camera calibration: chessboard, dlt, lines",
        add_arguments=add_arguments,
    ),
)
