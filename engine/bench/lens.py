"""``studiotrack bench lens``: the lens chain from calibration to the packets on the wire.

1. Calibrate a lens file the way an operator does, one zoom sample at a time: at each of
   ``--samples`` zoom encoder values the built-in studio's zoom lens (a known lens file,
   :mod:`engine.studio.zoom`) renders ``--views`` chessboard views
   (:mod:`engine.studio.chessboard_view`), OpenCV calibrates them (k1, k2; k3 and tangential
   fixed) and the result becomes a :class:`engine.lens.LensSample`.
2. Run ``synthetic:zoom=sweep`` (wide -> tele -> wide) through
   :class:`engine.sources.lensed.LensedSource` with that lens file, the ``ground-truth``
   tracker and the pose outputs - OpenTrackIO (JSON) and FreeD (raw zoom/focus) to loopback
   listeners - with timecode generated from ``--timecode-start`` at ``--rate``.
3. Decode every packet and compare with the truth at the encoder values the packet itself
   reports: ``focal_length_err_mm`` (OpenTrackIO ``pinholeFocalLength`` vs the known lens),
   ``k1_err``; FreeD zoom/focus fields vs the frames' encoders (``freed_encoders_ok``);
   ``timecode_ok``: every OpenTrackIO sample has ``timing.timecode`` and they count up by
   one frame from the start value. ``interp_only`` repeats step 3's errors for a lens file
   sampled from the truth at the same zoom values (no calibration error): what bilinear
   interpolation between that many samples costs.

Seeds: the chessboard poses use seed ``--seed`` (default 7); the view count, fill and model
(k3 and tangential fixed) were chosen on seeds 0, 32768 and 65535 (see the tests).
"""

from __future__ import annotations

import argparse
import json
import socket
import threading
from typing import Any

import numpy as np

from engine.bench import BenchSpec
from engine.progress import log

HELP = "lens files: zoom-sweep calibration -> OpenTrackIO/FreeD lens vs ground truth, timecode"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--samples", type=int, default=7, help="zoom samples calibrated (default 7)")
    p.add_argument("--views", type=int, default=15, help="chessboard views per sample")
    p.add_argument("--frames", type=int, default=150, help="frames of the zoom sweep")
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=480)
    p.add_argument("--rate", default="25", help="timecode / frame rate (default 25)")
    p.add_argument("--timecode-start", default="01:00:00:00", help="first timecode")
    p.add_argument("--seed", type=int, default=7, help="chessboard pose seed")


class _Listener:
    """A loopback UDP socket collecting datagrams on a thread."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = int(self.sock.getsockname()[1])
        self.packets: list[bytes] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="bench-lens-listen", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self.packets.append(self.sock.recv(65535))
            except TimeoutError:
                continue
            except OSError:
                return

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.sock.close()


def calibrate_lens_file(width: int, height: int, n_samples: int, n_views: int, seed: int,
                        ) -> tuple[Any, list[dict[str, Any]]]:
    """A lens file calibrated from chessboard views at ``n_samples`` zoom values."""
    from engine.lens import LensFile
    from engine.ptz.chessboard import lens_sample_from_chessboard
    from engine.studio.chessboard_view import calibration_views, render_chessboard
    from engine.studio.zoom import FOCUS_RAW, ZOOM_MAX_RAW, studio_zoom_lens

    truth = studio_zoom_lens(width, height)
    lens = LensFile(width, height, (), sensor_width_mm=truth.sensor_width_mm,
                    zoom_range_raw=truth.zoom_range_raw, focus_range_raw=truth.focus_range_raw,
                    name="calibrated (bench lens)")
    report = []
    for i, z in enumerate(np.round(np.linspace(0, ZOOM_MAX_RAW, n_samples)).astype(int)):
        cam = truth.intrinsics_at(int(z), FOCUS_RAW)
        poses = calibration_views(cam, n_views, (9, 6), 0.05, fill=0.7, seed=seed + 1000 * i)
        views = [render_chessboard(cam, T, (9, 6), 0.05) for T in poses]
        sample, res = lens_sample_from_chessboard(views, int(z), 0, (9, 6), 0.05)
        lens = lens.with_sample(sample)
        report.append({"zoom_raw": int(z), "views": len(res.used_images), "rms_px": res.rms_px,
                       "fx_err_px": sample.fx_px - cam.fx, "k1_err": sample.k1 - cam.dist[0]})
        log(f"  zoom {int(z):5d}: f {sample.fx_px:7.1f} px (truth {cam.fx:7.1f}), k1 "
            f"{sample.k1:+.4f} (truth {cam.dist[0]:+.4f}), rms {res.rms_px:.3f} px")
    return lens, report


def run_chain(lens: Any, frames: int, width: int, height: int, rate: str, start: str
              ) -> dict[str, Any]:
    """Zoom sweep -> lensed source -> outputs -> loopback listeners -> errors vs truth."""
    from engine.loop import run_tracking
    from engine.outputs.freed import ZoomFocusMapping, decode_d1
    from engine.outputs.opentrackio import decode_datagrams
    from engine.outputs.sender import FreeDSettings, OutputConfig, TargetSpec
    from engine.sinks.pose_output import PoseOutputSink
    from engine.sources.lensed import LensedSource
    from engine.sources.synthetic import SyntheticSource, config_from_options
    from engine.studio.zoom import studio_zoom_lens
    from engine.timecode import RATE_RATIONALS, TimecodeClock, parse_timecode
    from engine.trackers.ground_truth import GroundTruthParams, GroundTruthTracker

    truth = studio_zoom_lens(width, height)
    n, d = RATE_RATIONALS[parse_timecode(start, rate).rate]
    src = SyntheticSource(config_from_options({
        "zoom": "sweep", "frames": str(frames), "width": str(width), "height": str(height),
        "fps": repr(n / d)}))
    otio_l, freed_l = _Listener(), _Listener()
    try:
        cfg = OutputConfig(
            targets=(TargetSpec("opentrackio", "127.0.0.1", otio_l.port, "json"),
                     TargetSpec("freed", "127.0.0.1", freed_l.port)),
            freed=FreeDSettings(lens_mapping=ZoomFocusMapping.RAW))
        sink = PoseOutputSink(cfg, clocked=False)
        encoders: list[tuple[int, int]] = []
        from engine.lens import LensEncoders

        clock = TimecodeClock(parse_timecode(start, rate))
        for rec in run_tracking(LensedSource(src, lens), GroundTruthTracker(GroundTruthParams()),
                                sinks=[sink], timecode=clock):
            enc = rec.frame.payload(LensEncoders)
            assert enc is not None
            encoders.append((enc.zoom_raw, enc.focus_raw))
        import time

        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and (len(otio_l.packets) < len(encoders)
                                               or len(freed_l.packets) < len(encoders)):
            time.sleep(0.02)
    finally:
        otio_l.close()
        freed_l.close()
    samples = decode_datagrams(otio_l.packets)
    f_err, k1_err, tcs = [], [], []
    for smp in samples:
        ln = smp.get("lens", {})
        raw = ln.get("rawEncoders", {})
        cam = truth.intrinsics_at(int(raw.get("zoom", -1)), int(raw.get("focus", 0)))
        f_true = truth.focal_length_mm(cam.fx)
        f_err.append(abs(float(ln["pinholeFocalLength"]) - f_true))
        k1_err.append(abs(float(ln["distortion"][0]["radial"][0]) - float(cam.dist[0])))
        tc = smp.get("timing", {}).get("timecode")
        tcs.append(tc)
    start_tc = parse_timecode(start, rate)
    tc_ok = bool(samples) and len(samples) == len(encoders) and all(
        tc is not None and (tc["hours"], tc["minutes"], tc["seconds"], tc["frames"])
        == _hmsf(start_tc.plus(i)) and tc["frameRate"] == {"num": n, "denom": d}
        for i, tc in enumerate(tcs))
    freed = [decode_d1(p) for p in freed_l.packets]
    freed_ok = len(freed) == len(encoders) and all(
        (p.zoom, p.focus) == (min(z, 0xFFFFFF), min(f, 0xFFFFFF))
        for p, (z, f) in zip(freed, encoders, strict=True))
    return {
        "focal_length_err_mm": _stats(f_err),
        "k1_err": _stats(k1_err),
        "timecode_ok": tc_ok,
        "freed_encoders_ok": freed_ok,
        "packets": {"opentrackio": len(otio_l.packets), "freed": len(freed_l.packets),
                    "frames": len(encoders)},
        "first_timecode": None if not tcs or tcs[0] is None else json.dumps(tcs[0]),
    }


def _hmsf(tc: Any) -> tuple[int, int, int, int]:
    return (tc.hours, tc.minutes, tc.seconds, tc.frames)


def _stats(v: list[float]) -> dict[str, float | None]:
    if not v:
        return {"median": None, "max": None}
    a = np.asarray(v)
    return {"median": float(np.median(a)), "max": float(a.max())}


def run(args: argparse.Namespace) -> dict[str, Any]:
    from engine.lens import LensFile
    from engine.studio.zoom import FOCUS_RAW, ZOOM_MAX_RAW, studio_zoom_lens

    log(f"calibrating {args.samples} zoom samples x {args.views} chessboard views "
        f"({args.width}x{args.height})")
    lens, report = calibrate_lens_file(args.width, args.height, args.samples, args.views,
                                       args.seed)
    log(f"zoom sweep: {args.frames} frames, timecode from {args.timecode_start} at "
        f"{args.rate}")
    out = run_chain(lens, args.frames, args.width, args.height, args.rate,
                    args.timecode_start)
    log(f"  focal length err median {out['focal_length_err_mm']['median']:.4f} mm, max "
        f"{out['focal_length_err_mm']['max']:.4f} mm; k1 err median "
        f"{out['k1_err']['median']:.4f}; timecode ok {out['timecode_ok']}; FreeD encoders ok "
        f"{out['freed_encoders_ok']}")
    truth = studio_zoom_lens(args.width, args.height)
    zs = np.round(np.linspace(0, ZOOM_MAX_RAW, args.samples)).astype(int)
    sampled = LensFile(args.width, args.height,
                       tuple(_sample_of(truth.evaluate(int(z), FOCUS_RAW), int(z)) for z in zs),
                       sensor_width_mm=truth.sensor_width_mm, name="truth sampled")
    log("same chain with the truth sampled at those zoom values (interpolation only)")
    interp = run_chain(sampled, args.frames, args.width, args.height, args.rate,
                       args.timecode_start)
    out["interp_only"] = {"focal_length_err_mm": interp["focal_length_err_mm"],
                          "k1_err": interp["k1_err"]}
    out["calibration"] = report
    out["samples"] = args.samples
    out["views_per_sample"] = args.views
    return out


def _sample_of(state: Any, zoom_raw: int) -> Any:
    from engine.lens import LensSample

    return LensSample.from_intrinsics(state.intrinsics, zoom_raw, 0, state.entrance_pupil_m,
                                      note="truth")


BENCHES = (BenchSpec(name="lens", help=HELP, add_arguments=add_arguments, run=run),)
