"""Soak test: track the built-in studio for many frames with both pose outputs on.

Reports frames/s over time (one value per window), resident memory growth after warm-up
(goal < 20 MB) and the packets sent and received on loopback (goal: one FreeD packet and
one OpenTrackIO sample per tracked frame, none dropped).

The default soaks the real product path: the ``dense`` keyframe tracker on the built-in
studio at 320x240 (about 3 minutes for 20 000 frames on this 2-core machine).
``--tracker ground-truth`` (the studio's own pose passed through) isolates the engine loop,
renderer, sender thread and memory from the tracker.
"""

from __future__ import annotations

import argparse
import socket
import statistics
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

from engine.bench import BenchSpec
from engine.sources.base import Source

HELP = "track the built-in studio for N frames with FreeD + OpenTrackIO on: fps, RSS, packets"

DEFAULT_SOURCE = "synthetic:width=320,height=240"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=int, default=20000, help="frames to track (20000)")
    parser.add_argument("--tracker", default="dense",
                        help="tracker (default dense; ground-truth isolates the loop and outputs)")
    parser.add_argument("--source", default=DEFAULT_SOURCE,
                        help=f"source spec, looped to N frames (default {DEFAULT_SOURCE})")
    parser.add_argument("--window", type=int, default=500,
                        help="frames per fps/RSS sample (default 500)")
    parser.add_argument("--warmup", type=int, default=1000,
                        help="frames before the RSS baseline is taken (default 1000)")
    parser.add_argument("--encoding", choices=("json", "cbor"), default="json",
                        help="OpenTrackIO payload encoding (default json)")


class _Looped(Source):
    """Repeat a finite source's frames with increasing index and timestamps."""

    def __init__(self, inner: Any, n: int) -> None:
        self.inner = inner
        self.n = n
        self.name = f"{inner.name} (looped)"
        self.nominal_fps = inner.nominal_fps or 30.0
        self.live = False

    @property
    def intrinsics(self) -> Any:
        return self.inner.intrinsics

    def __len__(self) -> int:
        return self.n

    def frames(self) -> Iterator[Any]:
        period = 1.0 / (self.nominal_fps or 30.0)
        k = 0
        while k < self.n:
            got = False
            for f in self.inner.frames():
                if k >= self.n:
                    return
                got = True
                yield replace(f, index=k, timestamp_s=k * period)
                k += 1
            if not got:
                return

    def sinks(self) -> Any:
        return self.inner.sinks()

    def close(self) -> None:
        self.inner.close()


class _Receiver:
    """Counts datagrams on a loopback port in a background thread."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.count = 0
        self.bytes = 0
        self.last = b""
        self._stop = False
        self._t = threading.Thread(target=self._run, daemon=True, name="soak-rx")
        self._t.start()

    def _run(self) -> None:
        while not self._stop:
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            self.count += 1
            self.bytes += len(data)
            self.last = data

    def close(self) -> None:
        self._stop = True
        self._t.join(1.0)
        self.sock.close()


def _rss_mb() -> float:
    import psutil

    return float(psutil.Process().memory_info().rss) / 2**20


def run(args: argparse.Namespace) -> dict[str, Any]:
    from engine.errors import SourceError
    from engine.loop import run_tracking
    from engine.outputs import freed as fd
    from engine.outputs import opentrackio as ot
    from engine.outputs.sender import OutputConfig, TargetSpec
    from engine.sinks.pose_output import PoseOutputSink
    from engine.sources import open_source
    from engine.trackers import create_tracker

    n = int(args.frames)
    spec = args.source
    if spec.startswith("synthetic") and "frames=" not in spec:
        # The studio's camera path simply continues for N frames (no loop seam).
        spec = f"{spec}{',' if ':' in spec else ':'}frames={n}"
    try:
        inner = open_source(spec)
    except SourceError:
        if args.source != DEFAULT_SOURCE:
            raise
        inner = open_source(f"synthetic:frames={n}")
    source = _Looped(inner, n)
    tracker = create_tracker(args.tracker)
    rx_freed, rx_otio = _Receiver(), _Receiver()
    cfg = OutputConfig(
        targets=(
            TargetSpec("freed", "127.0.0.1", rx_freed.port),
            TargetSpec("opentrackio", "127.0.0.1", rx_otio.port, args.encoding),
        ),
        queue_size=256,
    )
    outputs = PoseOutputSink(cfg, clocked=False)  # one packet per frame, as fast as tracked
    window = max(1, int(args.window))
    warmup = min(int(args.warmup), max(n // 5, 1))
    fps_windows: list[float] = []
    rss_windows: list[float] = []
    rss_start = _rss_mb()
    rss_base = rss_start
    t_start = time.perf_counter()
    t_win = t_start
    frames = 0
    states: dict[str, int] = {}
    try:
        for rec in run_tracking(source, tracker, sinks=[outputs]):
            frames += 1
            states[rec.result.state.value] = states.get(rec.result.state.value, 0) + 1
            if frames == warmup:
                rss_base = _rss_mb()
            if frames % window == 0:
                now = time.perf_counter()
                fps_windows.append(window / (now - t_win))
                rss_windows.append(_rss_mb())
                t_win = now
                print(f"soak: {frames}/{n} frames, {fps_windows[-1]:.1f} fps, "
                      f"RSS {rss_windows[-1]:.1f} MB", file=sys.stderr, flush=True)
        wall = time.perf_counter() - t_start  # the pipeline flushed and closed the outputs
        deadline = time.monotonic() + 10.0
        st = outputs.stats()
        assert st is not None
        want_f = st.targets[0].packets_sent
        want_o = st.targets[1].packets_sent
        while time.monotonic() < deadline and (rx_freed.count < want_f or rx_otio.count < want_o):
            time.sleep(0.02)
    finally:
        outputs.close()  # no-op after a complete run
        source.close()
        rx_freed.close()
        rx_otio.close()
    rss_end = _rss_mb()
    last_ok = True
    try:
        fd.decode_d1(rx_freed.last)
        ot.parse_packet(rx_otio.last)
    except Exception:
        last_ok = False
    tf, to = st.targets
    if not fps_windows and frames:
        fps_windows.append(frames / wall)
    return {
        "frames": frames,
        "fps_median": statistics.median(fps_windows) if fps_windows else 0.0,
        "fps_over_time": [round(f, 1) for f in fps_windows],
        "rss_start_mb": round(rss_start, 1),
        "rss_after_warmup_mb": round(rss_base, 1),
        "rss_end_mb": round(rss_end, 1),
        "rss_growth_mb": round(max(rss_windows[-1] if rss_windows else rss_end, rss_end)
                               - rss_base, 2),
        "rss_over_time_mb": [round(r, 1) for r in rss_windows],
        "packets_sent": tf.packets_sent,
        "opentrackio_datagrams_sent": to.packets_sent,
        "freed_received": rx_freed.count,
        "opentrackio_received": rx_otio.count,
        "last_packets_decode": last_ok,
        "dropped": st.dropped,
        "output_latency_p50_ms": round(st.latency_p50_ms, 3),
        "output_latency_p95_ms": round(st.latency_p95_ms, 3),
        "send_errors": tf.errors + to.errors,
        "skipped_no_pose": st.skipped_no_pose,
        "states": states,
        "tracker": args.tracker,
        "source": inner.name,
        "wall_s": round(wall, 2),
        "warmup_frames": warmup,
    }


BENCHES = (BenchSpec(name="soak", help=HELP, add_arguments=add_arguments, run=run),)
