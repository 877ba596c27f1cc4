"""Command-line options for pose outputs, shared by ``track``, ``record`` and benches.

``add_output_arguments(parser)`` adds ``--freed HOST:PORT``, ``--opentrackio HOST:PORT[,cbor]``
and their settings; ``config_from_args(args)`` the :class:`engine.outputs.sender.OutputConfig`
(None when no output was asked for; a host that does not resolve is refused in one line),
``output_sink(args)`` the :class:`engine.sinks.pose_output.PoseOutputSink` a pipeline feeds
(one packet per record for headless runs; ``--output-rate HZ`` clocks them at that rate).

``add_setup_arguments(parser)`` adds the studio set-up: ``--project DIR`` (lens file, studio
frame, nodal offset, pan-tilt calibration), ``--lens FILE``, typed ``--lens-zoom/--lens-focus``
encoders, ``--timecode-start/--timecode-rate``, and a real head (``--head visca:HOST``,
``--head-position freed:PORT|visca``); ``setup_source(args, source)`` wraps the source
(lens file, head readings and commands), ``timecode_clock(args, source)`` gives the
records' timecode.
"""

from __future__ import annotations

import argparse
import contextlib
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from app.commands._common import log, number_arg
from engine.outputs import OutputError


def parse_target(text: str, protocol: str, bind: str | None) -> Any:
    """``HOST:PORT[,json|cbor]``; for OpenTrackIO also ``multicast[:PORT][,cbor]``."""
    from engine.outputs import opentrackio as ot
    from engine.outputs.sender import TargetSpec

    addr, _, enc = text.partition(",")
    enc = enc.strip().lower() or "json"
    if protocol == "freed" and enc != "json":
        raise OutputError(f"--freed {text!r}: FreeD takes HOST:PORT only")
    host, sep, port_s = addr.strip().rpartition(":")
    if not sep:
        host, port_s = addr.strip(), ""
    if protocol == "opentrackio" and host in ("multicast", "mc", ""):
        host = "multicast"
    if not port_s:
        if protocol == "opentrackio":
            port_s = str(ot.DEFAULT_PORT)
        else:
            raise OutputError(f"--freed {text!r}: expected HOST:PORT")
    try:
        port = int(port_s)
    except ValueError:
        raise OutputError(f"{protocol} target {text!r}: port {port_s!r} is not a number") from None
    return TargetSpec(protocol, host, port, enc, bind)


def add_output_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("pose outputs (UDP; bind to 127.0.0.1 unless --output-bind)")
    g.add_argument("--freed", action="append", default=[], metavar="HOST:PORT",
                   help="send FreeD D1 packets to HOST:PORT (repeatable; broadcast allowed)")
    g.add_argument("--freed-camera-id", type=number_arg(integer=True, lo=0, hi=255), default=1,
                   metavar="N",
                   help="FreeD camera id 0-255 (default 1)")
    g.add_argument("--freed-lens", choices=("raw", "mm100", "mm64"), default="mm100",
                   help="FreeD zoom/focus fields: raw values, or focal length/focus distance "
                   "in mm x100 or x64 (default mm100)")
    g.add_argument("--opentrackio", action="append", default=[], metavar="HOST:PORT[,cbor]",
                   help="send OpenTrackIO samples (JSON, or CBOR with ',cbor'); "
                   "'multicast' means 239.135.1.<source number>:55555")
    g.add_argument("--opentrackio-source", type=number_arg(integer=True, lo=1, hi=200),
                   default=1, metavar="N",
                   help="OpenTrackIO sourceNumber 1-200 (default 1)")
    g.add_argument("--output-bind", default=None, metavar="ADDR",
                   help="local address the output sockets bind to (default 127.0.0.1 for "
                   "loopback targets, 0.0.0.0 otherwise)")
    g.add_argument("--output-delay-ms", default=None, metavar="MS|AXIS=MS,...",
                   help="delay applied to the outputs: one value for all axes, or per axis, "
                   "e.g. 'x=40,y=40,z=40,pan=33,tilt=33,roll=33' (negative = predict ahead)")
    g.add_argument("--sensor-width-mm", type=number_arg(gt=0, hi=1000), default=9.59,
                   help="sensor width used to express focal length in mm (default 9.59, 2/3\")")
    g.add_argument("--studio-frame", type=Path, default=None, metavar="FILE.json",
                   help="studio frame JSON ({\"T_world_studio\": 4x4}); default identity")
    g.add_argument("--output-rate", default=None, metavar="HZ",
                   help="send at this video rate (23.976, 24, 25, 29.97, 30, 50, 59.94, 60) "
                   "from the output clock instead of one packet per tracked frame")


def add_setup_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("studio set-up (lens, offsets, timecode, head)")
    g.add_argument("--project", type=Path, default=None, metavar="DIR",
                   help="studio project: its lens file, studio frame, nodal offset and "
                   "pan-tilt calibration are used (the ptz tracker uses the calibration)")
    g.add_argument("--lens", type=Path, default=None, metavar="FILE.json",
                   help="lens file (zoom/focus table); overrides the project's")
    g.add_argument("--lens-zoom", type=int, default=None, metavar="RAW",
                   help="zoom encoder value for frames that carry none (typed)")
    g.add_argument("--lens-focus", type=int, default=0, metavar="RAW",
                   help="focus encoder value for frames that carry none (typed)")
    g.add_argument("--timecode-start", default=None, metavar="HH:MM:SS:FF",
                   help="first generated timecode (default 00:00:00:00; a source with its "
                   "own timecode keeps it)")
    g.add_argument("--timecode-rate", default=None, metavar="RATE",
                   help="timecode rate: 23.976, 24, 25, 29.97 (drop frame), 30, 50, 59.94 "
                   "(drop frame), 60 (default: --output-rate, else nearest the source's)")
    g.add_argument("--head", default=None, metavar="visca:HOST[:PORT]",
                   help="drive a VISCA-over-IP PTZ camera with the tracker's pan-tilt commands")
    g.add_argument("--head-position", default=None, metavar="freed:PORT|visca",
                   help="where the head's angles come from: its FreeD output on PORT, or "
                   "the VISCA position inquiry (default: none)")


def load_project(args: argparse.Namespace) -> Any:
    """The ``--project`` (None without one); a bad project is one line."""
    folder = getattr(args, "project", None)
    if folder is None:
        return None
    from engine.project import open_project

    return open_project(folder)


def setup_source(args: argparse.Namespace, source: Any) -> Any:
    """``source`` with the head (``--head``/``--head-position``) and the lens file
    (``--lens`` or the project's) applied; on a bad option ``source`` is closed."""
    try:
        return _setup_source(args, source)
    except BaseException:
        source.close()
        raise


def _setup_source(args: argparse.Namespace, source: Any) -> Any:
    head_spec = getattr(args, "head", None)
    pos_spec = getattr(args, "head_position", None)
    if head_spec or pos_spec:
        from engine.ptz.head_io import HeadedSource
        from engine.ptz.visca import ViscaError
        from engine.ptz.visca_head import parse_head_spec

        driver = parse_head_spec(head_spec) if head_spec else None
        position: Any = None
        if pos_spec == "visca":
            if driver is None:
                raise ViscaError("--head-position visca needs --head visca:HOST")
            position = driver
        elif pos_spec:
            kind, _, port = pos_spec.partition(":")
            if kind != "freed" or not port.strip().isdigit():
                raise ViscaError(f"--head-position {pos_spec!r}: expected freed:PORT or visca")
            from engine.outputs.freed_input import FreeDListener

            position = FreeDListener(int(port))
        source = HeadedSource(source, driver, position)
    lens = None
    lens_path = getattr(args, "lens", None)
    if lens_path is not None:
        from engine.lens import LensFile

        lens = LensFile.load(lens_path)
    else:
        proj = load_project(args)
        if proj is not None and proj.lens is not None:
            lens = proj.lens
            lens.check_complete(f"{args.project}: lens file")
    if lens is not None:
        from engine.sources.lensed import LensedSource

        zoom = getattr(args, "lens_zoom", None)
        typed = None if zoom is None else (int(zoom), int(getattr(args, "lens_focus", 0)))
        log(f"lens file {lens.name!r}: {len(lens.samples)} sample(s)")
        source = LensedSource(source, lens, typed)
    return source


def timecode_clock(args: argparse.Namespace, source: Any) -> Any:
    """The records' timecode clock from ``--timecode-start/--timecode-rate``."""
    from engine.timecode import TimecodeClock, nearest_rate, parse_rate, parse_timecode

    rate_text = getattr(args, "timecode_rate", None) or getattr(args, "output_rate", None)
    rate = (parse_rate(rate_text, "--timecode-rate") if rate_text
            else nearest_rate(float(getattr(source, "nominal_fps", 30.0) or 30.0)))
    start = getattr(args, "timecode_start", None)
    if start is None:
        return TimecodeClock(rate=rate)
    return TimecodeClock(parse_timecode(start, rate, where="--timecode-start"), rate)


def _delays(text: str | None) -> Any:
    from engine.outputs.timing import AXES, DelayParams

    if not text:
        return DelayParams()
    try:
        if "=" not in text:
            return DelayParams.uniform(float(text))
        kw: dict[str, float] = {}
        for item in text.split(","):
            k, _, v = item.partition("=")
            k = k.strip()
            if k not in AXES:
                raise OutputError(f"--output-delay-ms: unknown axis {k!r} (axes: {AXES})")
            kw[f"{k}_ms"] = float(v)
        return DelayParams(**kw)
    except ValueError as exc:
        raise OutputError(f"--output-delay-ms {text!r}: {exc}") from None


def config_from_args(args: argparse.Namespace) -> Any:
    """The :class:`OutputConfig` the options describe, or None when no target is given."""
    from dataclasses import replace

    from engine.outputs import opentrackio as ot
    from engine.outputs.clock import parse_rate
    from engine.outputs.freed import ZoomFocusMapping
    from engine.outputs.sender import FreeDSettings, OutputConfig, check_targets
    from engine.outputs.studio_frame import StudioFrame

    freed = list(getattr(args, "freed", None) or [])
    otio = list(getattr(args, "opentrackio", None) or [])
    if not freed and not otio:
        return None
    bind = getattr(args, "output_bind", None)
    src = int(getattr(args, "opentrackio_source", 1))
    targets = [parse_target(t, "freed", bind) for t in freed]
    for text in otio:
        t = parse_target(text, "opentrackio", bind)
        if t.host == "multicast":
            t = replace(t, host=ot.default_multicast_group(src))
        targets.append(t)
    studio = StudioFrame()
    sf_path = getattr(args, "studio_frame", None)
    if sf_path is not None:
        try:
            studio = StudioFrame.from_json_dict(json.loads(Path(sf_path).read_text()))
        except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise OutputError(f"{sf_path}: cannot read studio frame ({exc})") from None
    rate = getattr(args, "output_rate", None)
    cfg = OutputConfig(
        targets=tuple(targets),
        freed=FreeDSettings(
            camera_id=int(getattr(args, "freed_camera_id", 1)),
            lens_mapping=ZoomFocusMapping(getattr(args, "freed_lens", "mm100")),
        ),
        opentrackio_source_number=src,
        lens=ot.LensInfo(sensor_width_mm=float(getattr(args, "sensor_width_mm", 9.59))),
        delays=_delays(getattr(args, "output_delay_ms", None)),
        studio=studio,
        rate_hz=None if rate is None else parse_rate(rate),
    )
    proj = load_project(args)
    if proj is not None:
        if sf_path is not None:  # an explicit --studio-frame wins over the project's
            cfg = replace(proj.output_config(cfg), studio=studio)
        else:
            cfg = proj.output_config(cfg)
    check_targets(cfg)
    return cfg


def output_sink(args: argparse.Namespace) -> Any:
    """The pose-output sink for the options, or None when no output was asked for.

    Headless runs send one packet per tracked frame unless ``--output-rate`` clocks them.
    """
    from engine.sinks.pose_output import PoseOutputSink

    cfg = config_from_args(args)
    if cfg is None:
        return None
    return PoseOutputSink(cfg, clocked=cfg.rate_hz is not None)


def describe(sink: Any) -> str:
    """One line per target for the log: where it sends and what it is bound to."""
    return "; ".join(f"{t.name} (bind {t.effective_bind})" for t in sink.config.targets)


def outputs_summary(stats: Any) -> dict[str, Any]:
    """The sender's counters for ``--json`` plus the totals and the verdict: ``errors`` counts
    send and encode errors (a pose FreeD cannot carry is an encode error), ``nothing_sent``
    is true when samples were due but no target sent a single packet."""
    d = dict(stats.to_json_dict())
    send_errors = sum(t.errors for t in stats.targets)
    d["packets_sent"] = stats.packets_sent
    d["send_errors"] = send_errors
    d["errors"] = send_errors + stats.encode_errors
    due = stats.processed - stats.skipped_no_pose
    d["nothing_sent"] = bool(stats.packets_sent == 0 and due > 0 and d["errors"] > 0)
    last = stats.last_encode_error or next(
        (t.last_error for t in stats.targets if t.last_error), "")
    d["problem"] = (f"{d['errors']} error(s) for {due} sample(s); last: {last}"
                    if d["errors"] else "")
    return d


def report(sink: Any) -> dict[str, Any] | None:
    """Log the per-target counts after a run; the sender statistics (for ``--json``)."""
    st = sink.stats()
    if st is None:
        return None
    line = "outputs sent: " + "; ".join(
        f"{t.name} {t.packets_sent} packets, {t.errors} send errors"
        + (f" (last: {t.last_error})" if t.last_error else "") for t in st.targets)
    line += f"; dropped {st.dropped}; encode errors {st.encode_errors}"
    if st.encode_errors:
        line += f" (last: {st.last_encode_error})"
    if st.skipped_no_pose:
        line += f"; {st.skipped_no_pose} sample(s) without a pose to send"
    log(line)
    return outputs_summary(st)


class Sending:
    """What ``with sending(args) as send`` gives: ``send.sinks`` for the pipeline and, after
    the block, ``send.summary`` (the counters for ``--json``; None without outputs)."""

    def __init__(self, sinks: list[Any]) -> None:
        self.sinks = sinks
        self.summary: dict[str, Any] | None = None


@contextlib.contextmanager
def sending(args: argparse.Namespace) -> Iterator[Sending]:
    """``with sending(args) as send: run_tracker(..., sinks=send.sinks)`` - no sinks when no
    output was asked; logs where the outputs send and, at the end, what they sent (packets,
    send and encode errors) and keeps the counters in ``send.summary``."""
    sink = output_sink(args)
    send = Sending([] if sink is None else [sink])
    if sink is None:
        yield send
        return
    log(f"outputs: {describe(sink)}")
    try:
        yield send
    finally:
        send.summary = report(sink)
