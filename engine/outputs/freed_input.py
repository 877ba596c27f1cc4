"""FreeD input: pan/tilt/roll, position, zoom and focus from a FreeD-emitting device.

PTZ cameras (Panasonic AW-UE, Sony, BirdDog) and camera trackers send FreeD D1 packets
(:mod:`engine.outputs.freed`) over UDP. :class:`FreeDListener` receives them on a thread
(bound to 127.0.0.1 unless the operator chooses an address) and keeps the newest reading;
malformed datagrams are counted, never raised.

``freed:PORT[,host=ADDR,camera=N,timeout_s=1]`` is a live source: one frame per packet (no
image), carrying :class:`FreeDReading` and the lens encoders (:class:`engine.lens.LensEncoders`:
FreeD zoom/focus as raw counts); a pan-tilt head's motor angles are
:func:`head_reading_of` (motor pan = -FreeD pan: FreeD pans positive to the right, our motor
angles to the left). When no packet came for ``timeout_s`` frames say
"no FreeD packets" (LOST) until packets return. The ``freed-relay`` tracker turns the
readings into poses (a FreeD -> OpenTrackIO bridge with the project's lens file and
timecode).
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass

from engine.camera import Intrinsics
from engine.errors import SourceError
from engine.frames import Frame, FramePayload
from engine.lens import LensEncoders
from engine.outputs.freed import FreeDError, FreeDPose, decode_d1
from engine.sources.base import Source, SourceSpec, parse_options


@dataclass(frozen=True, slots=True)
class FreeDReading(FramePayload):
    """One received D1 packet and when it arrived (``time.monotonic()``)."""

    pose: FreeDPose
    arrival_mono_s: float
    count: int  # packets received so far (this one included)


class FreeDListener:
    """Receives D1 packets on ``host:port`` (port 0: any free port) on a thread."""

    def __init__(self, port: int = 0, host: str = "127.0.0.1",
                 camera_id: int | None = None) -> None:
        if not 0 <= int(port) <= 65535:
            raise SourceError(f"FreeD input port {port} is outside 0..65535")
        self.camera_id = camera_id
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((host, int(port)))
        except OSError as exc:
            self._sock.close()
            raise SourceError(f"FreeD input {host}:{port}: cannot listen "
                              f"({exc.strerror or exc})") from None
        self._sock.settimeout(0.05)
        self.host = host
        self.port = int(self._sock.getsockname()[1])
        self._cond = threading.Condition()
        self._latest: FreeDReading | None = None
        self.count = 0
        self.errors = 0
        self.last_error = ""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"freed-in:{self.port}",
                                        daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data = self._sock.recv(2048)
            except TimeoutError:
                continue
            except OSError:
                return
            try:
                pose = decode_d1(data)
            except FreeDError as exc:
                self.errors += 1
                self.last_error = str(exc)
                continue
            if self.camera_id is not None and pose.camera_id != self.camera_id:
                continue
            with self._cond:
                self.count += 1
                self._latest = FreeDReading(pose, time.monotonic(), self.count)
                self._cond.notify_all()

    def latest(self) -> FreeDReading | None:
        with self._cond:
            return self._latest

    def wait_beyond(self, count: int, timeout_s: float) -> FreeDReading | None:
        """The newest reading once more than ``count`` packets came (None on timeout)."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while self.count <= count:
                left = deadline - time.monotonic()
                if left <= 0 or self._stop.is_set():
                    return None
                self._cond.wait(left)
            return self._latest

    def close(self) -> None:
        self._stop.set()
        self._thread.join(1.0)
        self._sock.close()


def head_reading_of(reading: FreeDReading) -> tuple[float, float]:
    """Motor (pan, tilt) of a FreeD reading (FreeD pan grows to the right, ours left)."""
    return -reading.pose.pan_deg, reading.pose.tilt_deg


class FreeDSource(Source):
    """``freed:PORT``: one image-less frame per FreeD packet (see the module docstring)."""

    live = True
    nominal_fps = 50.0

    def __init__(self, port: int, host: str = "127.0.0.1", camera_id: int | None = None,
                 timeout_s: float = 1.0) -> None:
        self.listener = FreeDListener(port, host, camera_id)
        self.timeout_s = timeout_s
        self.name = f"FreeD input {host}:{self.listener.port}"

    @property
    def intrinsics(self) -> Intrinsics | None:
        return None

    def __len__(self) -> int:
        return 0

    def frames(self) -> Iterator[Frame]:
        seen = 0
        i = 0
        t0: float | None = None
        while True:
            r = self.listener.wait_beyond(seen, self.timeout_s)
            if r is None:
                yield Frame(index=i, timestamp_s=time.monotonic() - (t0 or time.monotonic()),
                            color_bgr=None, link_lost_reason="no FreeD packets")
                i += 1
                continue
            seen = r.count
            if t0 is None:
                t0 = r.arrival_mono_s
            yield Frame(
                index=i, timestamp_s=r.arrival_mono_s - t0, color_bgr=None,
                capture_mono_s=r.arrival_mono_s,
                payloads=(r, LensEncoders(zoom_raw=r.pose.zoom, focus_raw=r.pose.focus)),
            )
            i += 1

    def close(self) -> None:
        self.listener.close()


def open_freed(rest: str) -> FreeDSource:
    """``PORT[,host=ADDR,camera=N,timeout_s=S]``."""
    port_s, _, opts_s = rest.partition(",")
    if not port_s.strip():
        raise SourceError("freed: expected freed:PORT (e.g. freed:40000)")
    try:
        port = int(port_s)
    except ValueError:
        raise SourceError(f"freed: port {port_s!r} is not a number") from None
    opts = parse_options(opts_s)
    unknown = sorted(set(opts) - {"host", "camera", "timeout_s"})
    if unknown:
        raise SourceError(f"freed: unknown option {unknown[0]!r} (host, camera, timeout_s)")
    try:
        cam = int(opts["camera"]) if "camera" in opts else None
        timeout = float(opts.get("timeout_s", 1.0))
    except ValueError:
        raise SourceError("freed: camera and timeout_s must be numbers") from None
    if not 0.05 <= timeout <= 60:
        raise SourceError(f"freed: timeout_s {timeout} is outside 0.05..60")
    return FreeDSource(port, opts.get("host", "127.0.0.1"), cam, timeout)


SOURCES = (
    SourceSpec(name="freed", description="FreeD D1 packets from a PTZ camera or tracker (UDP)",
               opener=open_freed, example="freed:40000"),
)
