"""``studiotrack listen --freed PORT --opentrackio PORT``: decode pose outputs on this machine.

A check for the operator (and for render-engine set-up): binds UDP ports (127.0.0.1 unless
``--bind``), decodes FreeD D1 and OpenTrackIO datagrams with the same decoders the tests use,
prints one line per sample and ends with a JSON summary.
"""

from __future__ import annotations

import argparse
import select
import socket
import time

from app.commands import CommandSpec
from app.commands._common import emit_json, log, number_arg, port_arg


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--freed", type=port_arg(), default=None, metavar="PORT",
                   help="FreeD UDP port")
    p.add_argument("--opentrackio", type=port_arg(), default=None, metavar="PORT",
                   help="OpenTrackIO UDP port")
    p.add_argument("--group", default=None, metavar="ADDR",
                   help="join this multicast group for OpenTrackIO (e.g. 239.135.1.1)")
    p.add_argument("--bind", default="127.0.0.1", help="local address (default 127.0.0.1)")
    p.add_argument("--seconds", type=number_arg(gt=0, hi=1e7), default=5.0,
                   help="listen this long (default 5)")
    p.add_argument("--count", type=number_arg(integer=True, lo=1), default=None,
                   help="stop after N samples")
    p.add_argument("--quiet", action="store_true", help="only the summary")
    p.add_argument("--json", action="store_true", help="end with one JSON line of results")


def _sock(bind: str, port: int, group: str | None = None) -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    s.bind((group or bind, port))
    if group:
        s.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP,
                     socket.inet_aton(group) + socket.inet_aton(bind))
    return s


def _run(args: argparse.Namespace) -> int:
    from engine.errors import StudioTrackError
    from engine.outputs import OutputError
    from engine.outputs import freed as fd
    from engine.outputs import opentrackio as ot

    if args.freed is None and args.opentrackio is None:
        raise OutputError("listen: give --freed PORT and/or --opentrackio PORT")
    socks: dict[socket.socket, str] = {}
    try:
        if args.freed is not None:
            socks[_sock(args.bind, args.freed)] = "freed"
        if args.opentrackio is not None:
            socks[_sock(args.bind, args.opentrackio, args.group)] = "opentrackio"
    except OSError as exc:
        for s in socks:
            s.close()
        raise OutputError(f"listen: cannot bind {args.bind} ({exc.strerror or exc})") from None
    log(f"listening on {args.bind} for {args.seconds:g} s: "
        + ", ".join(f"{k} port {s.getsockname()[1]}" for s, k in socks.items()))
    counts = {"freed": 0, "opentrackio": 0, "errors": 0}
    last_error = ""
    reasm = ot.Reassembler()
    deadline = time.monotonic() + args.seconds
    try:
        while time.monotonic() < deadline:
            if args.count is not None and counts["freed"] + counts["opentrackio"] >= args.count:
                break
            ready, _, _ = select.select(list(socks), [], [], 0.1)
            for s in ready:
                data = s.recv(65536)
                try:
                    if socks[s] == "freed":
                        p = fd.decode_d1(data)
                        counts["freed"] += 1
                        line = (f"FreeD cam {p.camera_id}: pan {p.pan_deg:.3f} tilt "
                                f"{p.tilt_deg:.3f} roll {p.roll_deg:.3f} deg, X {p.x_mm:.1f} "
                                f"Y {p.y_mm:.1f} Z {p.z_mm:.1f} mm, zoom {p.zoom} focus "
                                f"{p.focus}")
                    else:
                        sample = reasm.feed(data)
                        if sample is None:
                            continue
                        pose = ot.sample_pose(sample)
                        counts["opentrackio"] += 1
                        line = (f"OpenTrackIO #{pose.sequence_number} {pose.status}: "
                                f"x {pose.x_m:.3f} y {pose.y_m:.3f} z {pose.z_m:.3f} m, "
                                f"pan {pose.pan_deg:.2f} tilt {pose.tilt_deg:.2f} "
                                f"roll {pose.roll_deg:.2f} deg")
                except StudioTrackError as exc:
                    counts["errors"] += 1
                    last_error = str(exc)
                    line = f"bad {socks[s]} packet: {exc}"
                if not args.quiet:
                    print(line, flush=True)
    finally:
        for s in socks:
            s.close()
    result = {**counts, "last_error": last_error, "bind": args.bind,
              "opentrackio_dropped_samples": reasm.dropped}
    if args.json:
        emit_json(result)
    else:
        log(str(result))
    return 0


COMMANDS = (
    CommandSpec(
        name="listen",
        help="receive and decode FreeD / OpenTrackIO packets (check)",
        add_arguments=add_arguments,
        run=_run,
    ),
)
