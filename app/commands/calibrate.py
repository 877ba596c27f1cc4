"""``studiotrack calibrate``: chessboard (OpenCV), DLT from points (Gaspar 2009 sec. 3.1),
line-based lens distortion (sec. 3.3), the pan-tilt chain on ptz-sim, and the studio set-up
of a project (``studio``: studio frame from floor points / a DLT / a moved origin, and the
tracked point -> nodal point offset; see :mod:`engine.outputs.studio_frame`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

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
    dl.add_argument("--project", type=Path, default=None, metavar="DIR",
                    help="save the head geometry (head_from_dlt) into this studio project; "
                    "its line-based distortion is applied to the pixels first")
    dl.add_argument("--pan", type=float, default=0.0, help="motor pan of the DLT image (deg)")
    dl.add_argument("--tilt", type=float, default=0.0, help="motor tilt of the DLT image (deg)")
    dl.add_argument("--offset-m", default="0,0,0", metavar="X,Y,Z",
                    help="optical-centre offset from the rotation centre, camera axes (m)")
    dl.set_defaults(func=_dlt)

    ln = csub.add_parser("lines", help="line-based radial distortion from a chessboard image")
    ln.add_argument("images", nargs="+", type=Path)
    ln.add_argument("--pattern", default="9x6", help="inner corners COLSxROWS; 'edges' = LSD")
    ln.add_argument("--terms", type=number_arg(integer=True, lo=1, hi=4), default=2,
                    help="number of k terms (k3, k5, ...)")
    ln.add_argument("--json", action="store_true", help="end with one JSON line")
    ln.add_argument("--project", type=Path, default=None, metavar="DIR",
                    help="save the distortion model into this studio project's pan-tilt "
                    "calibration")
    ln.set_defaults(func=_lines)

    ps = csub.add_parser("ptz-sim", help="run the whole pan-tilt calibration chain on ptz-sim "
                         "views (lines, marker DLTs at four poses, head) into a project")
    ps.add_argument("--project", type=Path, required=True, metavar="DIR")
    ps.add_argument("--source", default="ptz-sim:markers=1,distortion=0.12,encoder=0",
                    help="the ptz-sim spec whose camera is calibrated (needs markers=1)")
    ps.add_argument("--json", action="store_true", help="end with one JSON line")
    ps.set_defaults(func=_ptz_sim)

    st = csub.add_parser("studio", help="the studio frame and the nodal offset of a project "
                         "(applied to every output of runs with --project)")
    st.add_argument("--project", type=Path, required=True, metavar="DIR")
    st.add_argument("--floor-points", default=None, metavar="X,Y,Z;X,Y,Z;X,Y,Z",
                    help="studio frame from three floor points in the tracker's world: origin, "
                    "a point on +X, a point on the +Y side (m)")
    st.add_argument("--dlt", type=Path, default=None, metavar="POINTS.csv",
                    help="studio frame = the frame of these DLT calibration points "
                    "(x,y,z,u,v; the tracker's world is the DLT camera's, as for ptz)")
    st.add_argument("--origin", default=None, metavar="X,Y,Z",
                    help="move the studio origin to this point of the tracker's world (m), "
                    "axes kept (the 3D view's clicked point)")
    st.add_argument("--nodal", default=None, metavar="X,Y,Z[,PAN,TILT,ROLL]",
                    help="tracked point -> nodal point offset: metres in the tracked camera's "
                    "axes (x right, y down, z forward), degrees")
    st.add_argument("--reset", action="store_true",
                    help="forget the studio frame and the nodal offset first")
    st.add_argument("--json", action="store_true", help="end with one JSON line")
    st.set_defaults(func=_studio)


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
    proj: Any = _open_project(args.project) if args.project is not None else None
    if proj is not None and proj.ptz is not None and proj.ptz.radial is not None:
        uv = proj.ptz.radial.undistort_px(uv)
        log("pixels undistorted with the project's line-based model (sec. 3.3)")
    res = calibrate_dlt(X, uv)
    d = res.decomposition
    out = outlier_mask(res.residuals_px, args.outlier_px)
    for i, (r, o) in enumerate(zip(res.residuals_px, out, strict=True)):
        log(f"point {i:3d}: residual {r:7.3f} px{'  OUTLIER' if o else ''}")
    log(f"alpha_u {d.alpha_u:.2f} alpha_v {d.alpha_v:.2f} u0 {d.u0:.2f} v0 {d.v0:.2f} "
        f"rmse {res.rmse_px:.3f} px")
    if proj is not None:
        import dataclasses

        import numpy as np

        from engine.errors import CalibrationError
        from engine.ptz.calibration import DltPose, PtzCalibration
        from engine.ptz.kinematics import head_from_dlt

        try:
            off = np.array([float(v) for v in args.offset_m.split(",")])
        except ValueError:
            raise CalibrationError(f"--offset-m {args.offset_m!r}: expected X,Y,Z") from None
        if off.shape != (3,) or not np.all(np.isfinite(off)):
            raise CalibrationError(f"--offset-m {args.offset_m!r}: expected X,Y,Z")
        head = head_from_dlt(d, off, args.pan, args.tilt)
        pose = DltPose(args.pan, args.tilt, res.rmse_px, len(X))
        cal = proj.ptz or PtzCalibration(head=None)
        proj.ptz = dataclasses.replace(cal, head=head, dlt_poses=(pose,))
        proj.mark_dirty()
        proj.save()
        log(f"{proj.folder}: head geometry saved (revision {proj.revision})")
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
    if args.project is not None:
        import dataclasses

        from engine.ptz.calibration import PtzCalibration

        proj: Any = _open_project(args.project)
        cal = proj.ptz or PtzCalibration(head=None)
        proj.ptz = dataclasses.replace(cal, radial=fit.model, image_size=size)
        proj.mark_dirty()
        proj.save()
        log(f"{proj.folder}: distortion saved (revision {proj.revision})")
    if args.json:
        emit_json({**fit.model.to_json_dict(), "lines": len(lines),
                   "rms_before_px": fit.rms_before_px, "rms_after_px": fit.rms_after_px})
    return 0


def _open_project(folder: Path) -> object:
    from engine.project import INDEX_NAME, new_project, open_project

    if (folder / INDEX_NAME).exists():
        return open_project(folder)
    proj = new_project(folder.name)
    proj.folder = folder
    return proj


def _ptz_sim(args: argparse.Namespace) -> int:
    from engine.errors import CalibrationError
    from engine.ptz.sim import PtzSimSource
    from engine.ptz.sim_calibration import calibrate_sim
    from engine.sources import open_source

    src = open_source(args.source)
    if not isinstance(src, PtzSimSource):
        raise CalibrationError(f"--source {args.source!r} is not a ptz-sim source")
    cal, report = calibrate_sim(src)
    proj: Any = _open_project(args.project)
    proj.ptz = cal
    proj.mark_dirty()
    proj.save()
    log(f"{proj.folder}: pan-tilt calibration saved (revision {proj.revision}): "
        f"{report['lines']} lines, {report['dlt_views']} DLT views")
    if args.json:
        emit_json({"project": str(proj.folder), "revision": proj.revision, **report})
    return 0


def _floats(text: str, n: tuple[int, ...], what: str) -> list[float]:
    import math

    from engine.errors import CalibrationError

    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) not in n or not all(math.isfinite(v) for v in vals):
        raise CalibrationError(f"{what} {text!r}: expected {' or '.join(map(str, n))} "
                               "comma-separated numbers")
    return vals


def _studio(args: argparse.Namespace) -> int:
    import numpy as np

    from engine.errors import CalibrationError
    from engine.outputs.studio_frame import CameraOffset, StudioFrame

    proj: Any = _open_project(args.project)
    if args.reset:
        proj.studio_frame = proj.nodal_offset = None
    if args.floor_points is not None and args.dlt is not None:
        raise CalibrationError("--floor-points and --dlt both set the studio frame: give one")
    if args.floor_points is not None:
        pts = args.floor_points.split(";")
        if len(pts) != 3:
            raise CalibrationError(f"--floor-points {args.floor_points!r}: expected three "
                                   "X,Y,Z points separated by ';'")
        p = [np.array(_floats(q, (3,), "--floor-points point")) for q in pts]
        proj.studio_frame = StudioFrame.from_floor_points(*p)
    if args.dlt is not None:
        from engine.ptz.dlt import calibrate_dlt, load_points_csv

        X, uv = load_points_csv(args.dlt)
        if proj.ptz is not None and proj.ptz.radial is not None:
            uv = proj.ptz.radial.undistort_px(uv)
        res = calibrate_dlt(X, uv)
        d = res.decomposition
        proj.studio_frame = StudioFrame.from_dlt(np.eye(4), d.R_cam_world, d.t_cam_world)
        log(f"studio frame from the DLT of {args.dlt} (rmse {res.rmse_px:.3f} px)")
    if args.origin is not None:
        o = np.array(_floats(args.origin, (3,), "--origin"))
        proj.studio_frame = (proj.studio_frame or StudioFrame()).with_origin_at(o)
    if args.nodal is not None:
        v = _floats(args.nodal, (3, 6), "--nodal")
        off = CameraOffset(*v)
        proj.nodal_offset = None if off.is_identity else off
    proj.mark_dirty()
    proj.save()
    frame = proj.studio_frame
    off = proj.nodal_offset
    log(f"{proj.folder}: studio set-up saved (revision {proj.revision}): studio frame "
        f"{'identity' if frame is None else 'origin ' + str(np.round(frame.matrix[:3, 3], 4))}"
        f", nodal offset {'none' if off is None else off.to_json_dict()}")
    if args.json:
        emit_json({"project": str(proj.folder), "revision": proj.revision,
                   "T_world_studio": None if frame is None else frame.matrix.tolist(),
                   "nodal_offset": None if off is None else off.to_json_dict()})
    return 0


COMMANDS = (
    CommandSpec(
        name="calibrate",
        help="camera calibration: chessboard, dlt, lines, ptz-sim, studio (--project saves them)",
        add_arguments=add_arguments,
    ),
)
