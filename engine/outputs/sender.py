"""The output sender: a thread that turns tracked poses into FreeD / OpenTrackIO datagrams.

Tracking never waits for the network. :meth:`OutputSet.submit` appends to a bounded queue and
returns at once; when the queue is full the *oldest* sample is dropped and counted (a render
engine wants the newest pose, not a backlog). Packets leave per record (headless runs) or at
the output rate (:class:`engine.outputs.clock.OutputClock`, on-air runs). A socket error
(unreachable host, no route, interface down) is counted on its target with the message kept
as ``last_error`` and its time, so a target is reported failing while its latest send failed;
it never raises into the tracking loop. Host names are resolved when a configuration is
checked (:func:`check_targets`, one-line refusal) and when a socket opens, never per packet.

Sockets bind to 127.0.0.1 unless the operator chooses another address (``bind_host``), or the
target itself is not on the loopback network, in which case the socket binds to 0.0.0.0 so
the kernel can route it; the bind address is part of each target's statistics.
"""

from __future__ import annotations

import bisect
import collections
import contextlib
import ipaddress
import math
import socket
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from engine.camera import Intrinsics
from engine.lens import LensState
from engine.outputs import OutputError
from engine.outputs import freed as fd
from engine.outputs import opentrackio as otio
from engine.outputs.studio_frame import CameraOffset, StudioFrame, StudioPose
from engine.outputs.talent import TalentPosition, TalentSettings
from engine.outputs.timing import DelayCompensator, DelayParams
from engine.params import Params, param
from engine.realtime import PriorityGrant, raise_priority, run_queue_s
from engine.timecode import Timecode

PROTOCOLS = ("freed", "opentrackio")

#: the clocked sender thread asks for this real-time priority (SCHED_FIFO; it only wakes
#: once a slot, ~1 ms of work) and falls back to :data:`SENDER_NICE`; refused without the
#: right to (an ordinary account, CI): it then runs at the process's priority, reported
SENDER_FIFO = 10
SENDER_NICE = -10


@dataclass(frozen=True, slots=True)
class TargetSpec:
    """One destination: protocol, host, port; ``encoding`` is 'json'/'cbor' (OpenTrackIO)."""

    protocol: str
    host: str = "127.0.0.1"
    port: int = 40000
    encoding: str = "json"
    bind_host: str | None = None  # None: 127.0.0.1 for loopback targets, else 0.0.0.0

    def __post_init__(self) -> None:
        if self.protocol not in PROTOCOLS:
            raise OutputError(f"output protocol {self.protocol!r} is not one of {PROTOCOLS}")
        if not 1 <= int(self.port) <= 65535:
            raise OutputError(f"output port {self.port} is outside 1..65535")
        if not self.host:
            raise OutputError("output host is empty")
        if self.protocol == "opentrackio":
            otio.encoding_byte(self.encoding)

    @property
    def name(self) -> str:
        suffix = f",{self.encoding}" if self.protocol == "opentrackio" else ""
        return f"{self.protocol}:{self.host}:{self.port}{suffix}"

    @property
    def effective_bind(self) -> str:
        if self.bind_host:
            return self.bind_host
        return "127.0.0.1" if _is_loopback(self.host) else "0.0.0.0"


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _is_multicast(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_multicast
    except ValueError:
        return False


@dataclass(frozen=True, slots=True)
class FreeDSettings(Params):
    """FreeD camera id and how the zoom/focus fields are filled."""

    ERROR = OutputError

    camera_id: int = param(1, lo=0, hi=255, step=1, help="FreeD camera id (0-255)")
    lens_mapping: fd.ZoomFocusMapping = param(
        fd.ZoomFocusMapping.MM_X100, help="how the zoom and focus fields are filled: raw "
        "lens encoder counts (the frame's, else the values below), or focal length and "
        "focus distance in mm x 100 / mm x 64")
    zoom_raw: int = param(0, lo=0, hi=0xFFFFFF, help="zoom field when mapping is raw and "
                          "the frame has no lens encoders")
    focus_raw: int = param(0, lo=0, hi=0xFFFFFF, help="focus field when mapping is raw and "
                           "the frame has no lens encoders")


@dataclass(frozen=True, slots=True)
class OutputConfig:
    """Everything the sender needs; swap a new one in with :meth:`OutputSet.set_config`."""

    targets: tuple[TargetSpec, ...] = ()
    freed: FreeDSettings = field(default_factory=FreeDSettings)
    opentrackio_source_number: int = 1
    lens: otio.LensInfo = field(default_factory=otio.LensInfo)
    delays: DelayParams = field(default_factory=DelayParams)
    studio: StudioFrame = field(default_factory=StudioFrame)
    talent: TalentSettings = field(default_factory=TalentSettings)
    #: tracked point -> camera nodal point, applied before the studio frame
    offset: CameraOffset = field(default_factory=CameraOffset)
    queue_size: int = 64
    rate_hz: float | None = None  # on-air output rate; None: the source's frame rate

    def __post_init__(self) -> None:
        if self.rate_hz is not None and not (math.isfinite(self.rate_hz)
                                             and 1.0 <= self.rate_hz <= 240.0):
            raise OutputError(f"output rate {self.rate_hz} Hz is outside 1..240")
        if not 1 <= self.opentrackio_source_number <= 200:
            raise OutputError(
                f"OpenTrackIO source number {self.opentrackio_source_number} is outside 1..200"
            )
        if self.queue_size < 1:
            raise OutputError(f"queue size {self.queue_size} must be >= 1")


@dataclass(frozen=True, slots=True)
class OutputSample:
    """What the tracking loop hands to the sender for one frame.

    ``capture_mono_s`` and ``done_mono_s`` (``time.monotonic()``: frame captured, tracker
    done) give the end-to-end latency to the packet on the wire; 0 when unknown.
    """

    seq: int
    timestamp_s: float
    state: str
    T_world_cam: np.ndarray | None
    intrinsics: Intrinsics | None = None
    wall_time_s: float = 0.0
    submit_mono_s: float = 0.0  # set by OutputSet.submit (queue latency statistics)
    capture_mono_s: float = 0.0
    done_mono_s: float = 0.0
    #: "camera" or "talent" (the presenter's position: engine.outputs.talent)
    subject: str = "camera"
    lens: LensState | None = None  # lens file at the frame's encoders
    timecode: Timecode | None = None  # the record's SMPTE timecode

    def __post_init__(self) -> None:
        if self.T_world_cam is not None and self.T_world_cam.flags.writeable:
            self.T_world_cam.flags.writeable = False


@dataclass(frozen=True, slots=True)
class TargetStats:
    name: str
    protocol: str
    address: str
    bind: str
    packets_sent: int
    samples_sent: int
    bytes_sent: int
    errors: int
    last_error: str
    rate_hz: float
    last_ok_age_s: float = math.inf  # seconds since the last datagram left without error
    last_error_age_s: float = math.inf  # seconds since the last failed send

    @property
    def failing(self) -> bool:
        """The latest send attempt failed (an alarm: nothing reaches this target now)."""
        return self.last_error_age_s < self.last_ok_age_s


@dataclass(frozen=True, slots=True)
class SenderStats:
    submitted: int
    dropped: int
    processed: int
    skipped_no_pose: int
    encode_errors: int
    last_encode_error: str
    targets: tuple[TargetStats, ...]
    latency_p50_ms: float = float("nan")  # submit -> last datagram sent, last 600 samples
    latency_p95_ms: float = float("nan")
    clocked: bool = False  # packets at the output rate (else one per record)
    rate_hz: float = float("nan")  # the output rate in force
    ticks: int = 0  # samples sent (clocked: output slots fired)
    held_ticks: int = 0  # clocked: slots sent without a new pose (tracker late)
    lost_ticks: int = 0  # slots/samples sent flagged LOST because the engine stalled/failed
    missed_ticks: int = 0  # clocked: slots the sender thread could not keep (skipped)
    capture_to_send_ms: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    done_to_send_ms: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    send_gap_ms: tuple[float, float, float] = (math.nan, math.nan, math.nan)  # p50 p99 max

    @property
    def packets_sent(self) -> int:
        return sum(t.packets_sent for t in self.targets)

    @property
    def samples_sent(self) -> int:
        return min((t.samples_sent for t in self.targets), default=0)

    def to_json_dict(self) -> dict[str, Any]:
        def trio(v: tuple[float, float, float], keys: tuple[str, str, str]) -> dict[str, Any]:
            return {k: (x if math.isfinite(x) else None) for k, x in zip(keys, v, strict=True)}

        return {
            "submitted": self.submitted,
            "dropped": self.dropped,
            "processed": self.processed,
            "skipped_no_pose": self.skipped_no_pose,
            "encode_errors": self.encode_errors,
            "last_encode_error": self.last_encode_error,
            "latency_p50_ms": self.latency_p50_ms,
            "latency_p95_ms": self.latency_p95_ms,
            "clocked": self.clocked,
            "rate_hz": self.rate_hz if math.isfinite(self.rate_hz) else None,
            "ticks": self.ticks,
            "held_ticks": self.held_ticks,
            "lost_ticks": self.lost_ticks,
            "missed_ticks": self.missed_ticks,
            "capture_to_send_ms": trio(self.capture_to_send_ms, ("p50", "p95", "max")),
            "done_to_send_ms": trio(self.done_to_send_ms, ("p50", "p95", "max")),
            "send_gap_ms": trio(self.send_gap_ms, ("p50", "p99", "max")),
            "targets": [
                {k: getattr(t, k) for k in TargetStats.__slots__
                 if k not in ("last_ok_age_s", "last_error_age_s")}
                for t in self.targets
            ],
        }


@dataclass(frozen=True, slots=True)
class SlotTiming:
    """When one clocked output slot was due, and where the time to its send went
    (``time.monotonic()`` seconds; NaN where it does not apply).

    ``by_timer``: the sender woke for the slot's due time (held pose, or a fresh one that
    arrived before the slot's window); else a fresh pose arriving inside the window woke it.
    ``deadline_s``/``woke_s``: the wake-up it asked for and the moment it ran again, so
    ``woke_s - deadline_s`` is the sleep overshoot; ``run_queue_ms``: of the wait, the time
    it was runnable but had no CPU (the OS; :func:`engine.realtime.run_queue_s`) - the rest
    of an overshoot is waiting for the interpreter lock (another thread held the GIL).
    ``arrival_s``: the newest pose's submit time; ``capture_s``/``done_s``: its frame's
    capture and tracker-done times (fresh slots only).
    """

    due_s: float
    sent_s: float
    by_timer: bool
    fresh: bool
    deadline_s: float
    woke_s: float
    run_queue_ms: float
    arrival_s: float
    capture_s: float
    done_s: float

    @property
    def late_ms(self) -> float:
        """Sent after the slot's due time (ms; negative: early, inside the window)."""
        return (self.sent_s - self.due_s) * 1000.0

    @property
    def overshoot_ms(self) -> float:
        """Woke after the deadline it slept for (ms; NaN when woken by a fresh pose)."""
        return (self.woke_s - self.deadline_s) * 1000.0


@dataclass(frozen=True, slots=True)
class _Planned:
    """What one clocked slot sends."""

    pose: StudioPose
    state: str
    carry: OutputSample  # the sample sent (latency fields cleared for a held slot)
    stale: bool
    timecode: Timecode | None


@dataclass(frozen=True, slots=True)
class _Prepared:
    """A held slot encoded ahead of its due time, and what it assumed."""

    due: float
    newest: OutputSample
    cfg: OutputConfig
    out_seq: int
    targets: tuple[_Target, ...]
    plan: _Planned
    encoded: list[_Encoded]


def resolve_target(spec: TargetSpec) -> str:
    """The target's IPv4 address; a host that does not resolve raises one line.

    Called when a configuration is applied (so a bad name is refused there) and when the
    socket opens (so sending never waits for name resolution).
    """
    try:
        return str(ipaddress.IPv4Address(spec.host))
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(spec.host, spec.port, socket.AF_INET, socket.SOCK_DGRAM)
    except (OSError, UnicodeError) as exc:
        why = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        raise OutputError(f"{spec.protocol} target {spec.host!r}: cannot resolve "
                          f"the host name ({why})") from None
    if not infos:
        raise OutputError(f"{spec.protocol} target {spec.host!r}: no IPv4 address")
    return str(infos[0][4][0])


def check_targets(config: OutputConfig) -> None:
    """Refuse a configuration whose targets cannot be reached at all (one line).

    Host names must resolve; a loopback bind address cannot reach another machine.
    """
    for t in config.targets:
        addr = resolve_target(t)
        bind = t.effective_bind
        if bind.startswith("127.") and not ipaddress.ip_address(addr).is_loopback:
            raise OutputError(f"{t.name}: a socket bound to {bind} cannot reach {t.host} "
                              "(choose a network bind address)")


class _Target:
    def __init__(self, spec: TargetSpec) -> None:
        self.spec = spec
        self.sock: socket.socket | None = None
        self.addr: tuple[str, int] | None = None
        self.packets = 0
        self.samples = 0
        self.bytes = 0
        self.errors = 0
        self.last_error = ""
        self.last_ok_mono = -math.inf
        self.last_error_mono = -math.inf
        self.otio_seq = 0
        self.send_times: collections.deque[float] = collections.deque(maxlen=2048)

    def open(self) -> socket.socket:
        if self.sock is None:
            self.addr = (resolve_target(self.spec), int(self.spec.port))
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                s.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
                bind = self.spec.effective_bind
                s.bind((bind, 0))
                if _is_multicast(self.spec.host):
                    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
                    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
                    if bind != "0.0.0.0":
                        s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF,
                                     socket.inet_aton(bind))
                s.setblocking(False)  # a full send buffer is an error, never a wait
            except OSError:
                s.close()
                raise
            self.sock = s
        return self.sock

    def send(self, packets: Sequence[bytes]) -> None:
        try:
            sock = self.open()
            assert self.addr is not None
            for p in packets:
                sock.sendto(p, self.addr)
                self.packets += 1
                self.bytes += len(p)
            self.samples += 1
            now = time.monotonic()
            self.send_times.append(now)
            self.last_ok_mono = now
        except (OSError, OutputError) as exc:
            self.errors += 1
            why = getattr(exc, "strerror", None) or str(exc)
            self.last_error = why if isinstance(exc, OutputError) else f"{self.spec.name}: {why}"
            self.last_error_mono = time.monotonic()
            # A fresh socket next time (e.g. after an interface came back).
            self.close()

    def close(self) -> None:
        if self.sock is not None:
            with contextlib.suppress(OSError):
                self.sock.close()
            self.sock = None

    def stats(self, now: float) -> TargetStats:
        times = list(self.send_times)  # a copy (the sender thread appends)
        recent = times[bisect.bisect_right(times, now - 1.0):]
        if len(recent) >= 2:
            rate = (len(recent) - 1) / max(recent[-1] - recent[0], 1e-9)
        else:
            rate = float(len(recent))
        return TargetStats(
            name=self.spec.name,
            protocol=self.spec.protocol,
            address=f"{self.spec.host}:{self.spec.port}",
            bind=self.spec.effective_bind,
            packets_sent=self.packets,
            samples_sent=self.samples,
            bytes_sent=self.bytes,
            errors=self.errors,
            last_error=self.last_error,
            rate_hz=rate,
            last_ok_age_s=now - self.last_ok_mono,
            last_error_age_s=now - self.last_error_mono,
        )


#: one target's datagrams for a slot, or why they could not be encoded
_Encoded = tuple["_Target", "list[bytes] | OutputError"]


def freed_packet(pose: StudioPose, settings: FreeDSettings, intr: Intrinsics | None,
                 lens: otio.LensInfo, state: LensState | None = None) -> bytes:
    """D1 packet of a studio pose (conventions in :mod:`engine.outputs.studio_frame`).

    With a lens ``state`` (the lens file at the frame's encoders) the raw mapping sends the
    same encoder counts the lens file was evaluated at, and the mm mappings its focal
    length."""
    if state is not None:
        focal_mm: float | None = state.focal_length_mm
        zoom_raw, focus_raw = state.zoom_raw, state.focus_raw
    else:
        focal_mm = intr.fx * lens.sensor_width_mm / intr.width if intr is not None else None
        zoom_raw, focus_raw = settings.zoom_raw, settings.focus_raw
    focus_mm = lens.focus_distance_m * 1000.0 if lens.focus_distance_m else None
    return fd.encode_d1(
        fd.FreeDPose(
            camera_id=settings.camera_id,
            pan_deg=pose.freed_pan_deg,
            tilt_deg=pose.tilt_deg,
            roll_deg=pose.roll_deg,
            x_mm=pose.x_m * 1000.0,
            y_mm=pose.y_m * 1000.0,
            z_mm=pose.z_m * 1000.0,
            zoom=fd.lens_field(settings.lens_mapping, zoom_raw, focal_mm),
            focus=fd.lens_field(settings.lens_mapping, focus_raw, focus_mm),
        )
    )


def _trio(values: Sequence[float], q: tuple[float, float]) -> tuple[float, float, float]:
    a = np.asarray(values, dtype=np.float64)
    if a.size == 0:
        return (math.nan, math.nan, math.nan)
    lo, hi = np.percentile(a, q)
    return (float(lo), float(hi), float(a.max()))


class OutputSet:
    """Sender thread + targets. Use as a context manager or call :meth:`close`.

    Two cadences:

    - per record (default, ``rate_hz=None``): every submitted sample becomes one packet per
      target, as fast as they come (headless ``track``/``record``/``soak``);
    - clocked (``rate_hz`` given): packets leave at the output rate
      (:class:`engine.outputs.clock.OutputClock`) with the newest delayed/interpolated pose;
      slots without a new pose repeat the held one, and when no record came for
      ``stale_after_s`` or :meth:`mark_lost` was called (engine failure) they carry the last
      good pose flagged LOST until :meth:`close`.
    """

    def __init__(self, config: OutputConfig, *, start: bool = True,
                 rate_hz: float | None = None, stale_after_s: float | None = None) -> None:
        from engine.outputs.clock import OutputClock

        self._config = config
        self._targets = [_Target(t) for t in config.targets]
        self._queue: collections.deque[OutputSample] = collections.deque()
        self._cond = threading.Condition()
        self._stop = False
        self._busy = False
        self.submitted = 0
        self.dropped = 0
        self.processed = 0
        self.skipped_no_pose = 0
        self.encode_errors = 0
        self.last_encode_error = ""
        self._comp = DelayCompensator(config.delays)
        self._builder = otio.SampleBuilder(
            source_number=config.opentrackio_source_number, lens=config.lens
        )
        self._last_t: float | None = None
        self._rate_hz = 30.0 if rate_hz is None else float(rate_hz)
        self._rate_measured = rate_hz is not None
        self._thread: threading.Thread | None = None
        self._last_sample: OutputSample | None = None
        self._latency_ms: collections.deque[float] = collections.deque(maxlen=600)
        self._cap_send_ms: collections.deque[float] = collections.deque(maxlen=600)
        self._done_send_ms: collections.deque[float] = collections.deque(maxlen=600)
        self._gaps_ms: collections.deque[float] = collections.deque(maxlen=3000)
        self._last_emit_mono: float | None = None
        self.clock = OutputClock(rate_hz) if rate_hz is not None else None
        self.stale_after_s = (stale_after_s if stale_after_s is not None
                              else max(0.25, 4.0 / self._rate_hz))
        self._newest: OutputSample | None = None  # clocked: latest ingested sample
        self._newest_arrival = 0.0
        self._fresh = False
        self._faulted = False
        self._out_seq = 0
        self.ticks = 0
        self.held_ticks = 0
        self.lost_ticks = 0
        self._last_tc: Timecode | None = None
        self._prepared: _Prepared | None = None
        #: clocked: the OS priority the sender thread got (None before it started)
        self.priority: PriorityGrant | None = None
        self._prio_set = threading.Event()
        self.prepared_used = 0  # clocked slots sent from datagrams encoded ahead
        #: clocked: the timing of the last slots (:class:`SlotTiming`)
        self.slot_timings: collections.deque[SlotTiming] = collections.deque(maxlen=4096)
        if start:
            self.start()

    # -- control -------------------------------------------------------------------------

    @property
    def config(self) -> OutputConfig:
        return self._config

    @property
    def clocked(self) -> bool:
        return self.clock is not None

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="output-sender", daemon=True)
            self._thread.start()
            if self.clock is not None:
                self._prio_set.wait(1.0)  # the grant is known when start() returns

    def set_config(self, config: OutputConfig) -> None:
        """Swap in new settings (targets are re-opened if they changed)."""
        with self._cond:
            if config.targets != self._config.targets:
                for t in self._targets:
                    t.close()
                self._targets = [_Target(t) for t in config.targets]
            self._comp.set_params(config.delays)
            if (config.opentrackio_source_number != self._config.opentrackio_source_number
                    or config.lens != self._config.lens):
                self._builder = replace(self._builder,
                                        source_number=config.opentrackio_source_number,
                                        lens=config.lens)
            self._config = config

    def close(self, timeout_s: float = 2.0) -> None:
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout_s)
            self._thread = None
        for t in self._targets:
            t.close()

    def __enter__(self) -> OutputSet:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- producer side (tracking thread) ----------------------------------------------------

    def submit(self, sample: OutputSample) -> None:
        """Queue one sample; never blocks; drops (and counts) the oldest when full."""
        with self._cond:
            if len(self._queue) >= self._config.queue_size:
                self._queue.popleft()
                self.dropped += 1
            if not sample.submit_mono_s:
                sample = replace(sample, submit_mono_s=time.monotonic())
            self._queue.append(sample)
            self.submitted += 1
            self._last_sample = sample
            self._faulted = False
            self._cond.notify()

    def mark_lost(self) -> None:
        """The engine failed or stopped mid-show: send the last pose flagged LOST.

        Per record: one more packet now. Clocked: every slot from now on until a new sample
        arrives or :meth:`close`.
        """
        if self.clock is not None:
            with self._cond:
                self._faulted = True
                self._cond.notify()
            return
        last = self._last_sample
        if last is None:
            return
        period = 1.0 / self._rate_hz if self._rate_hz > 0 else 1.0 / 30.0
        self.submit(replace(last, seq=last.seq + 1, timestamp_s=last.timestamp_s + period,
                            state="LOST", wall_time_s=time.time(), submit_mono_s=0.0,
                            capture_mono_s=0.0, done_mono_s=0.0,
                            timecode=None if last.timecode is None else last.timecode.plus(1)))

    def submit_record(self, record: Any) -> None:
        """Queue an :class:`engine.loop.FrameRecord`: the camera pose of pose trackers, or
        the talent position a tracker returned (:class:`TalentPosition`)."""
        res = record.result
        T = res.T_world_cam
        subject = "camera"
        if T is None:
            talent = res.commands_of(TalentPosition)
            if talent:
                T, subject = talent[-1].T_world_talent(), "talent"
            elif self._last_sample is not None and self._last_sample.subject == "talent":
                # the presenter not located this frame: the last position, flagged
                T, subject = self._last_sample.T_world_cam, "talent"
        self.submit(
            OutputSample(
                seq=int(record.seq),
                timestamp_s=float(record.frame.timestamp_s),
                state=res.state.value,
                T_world_cam=None if T is None else np.array(T, dtype=np.float64),
                intrinsics=record.frame.intrinsics,
                wall_time_s=time.time(),
                capture_mono_s=float(getattr(record, "capture_mono_s", 0.0) or 0.0),
                done_mono_s=float(getattr(record, "done_mono_s", 0.0) or 0.0),
                subject=subject,
                lens=record.frame.payload(LensState) if subject == "camera" else None,
                timecode=getattr(record, "timecode", None),
            )
        )

    def flush(self, timeout_s: float = 5.0) -> bool:
        """Wait until every queued sample has been processed (tests, end of a run)."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while self._queue or self._busy:
                left = deadline - time.monotonic()
                if left <= 0 or self._thread is None:
                    return False
                self._cond.wait(min(left, 0.05))
        return True

    def stats(self) -> SenderStats:
        """A snapshot (any thread). The sender's lock is held only to copy the counters and
        histories: the percentiles are computed after, so a window asking for statistics
        never delays a send."""
        now = time.monotonic()
        with self._cond:
            clk = self.clock
            counters = (self.submitted, self.dropped, self.processed, self.skipped_no_pose,
                        self.encode_errors, self.last_encode_error, self._rate_hz, self.ticks,
                        self.held_ticks, self.lost_ticks, 0 if clk is None else clk.missed)
            targets = list(self._targets)
            lat_ms = list(self._latency_ms)
            cap, done = list(self._cap_send_ms), list(self._done_send_ms)
            gaps = list(self._gaps_ms)
        (submitted, dropped, processed, skipped, enc_errors, last_enc, rate, ticks, held,
         lost, missed) = counters
        lat = np.asarray(lat_ms, dtype=np.float64)
        p50, p95 = np.percentile(lat, [50, 95]) if lat.size else (np.nan, np.nan)
        return SenderStats(
            latency_p50_ms=float(p50),
            latency_p95_ms=float(p95),
            submitted=submitted,
            dropped=dropped,
            processed=processed,
            skipped_no_pose=skipped,
            encode_errors=enc_errors,
            last_encode_error=last_enc,
            targets=tuple(t.stats(now) for t in targets),
            clocked=clk is not None,
            rate_hz=rate,
            ticks=ticks,
            held_ticks=held,
            lost_ticks=lost,
            missed_ticks=missed,
            capture_to_send_ms=_trio(cap, (50, 95)),
            done_to_send_ms=_trio(done, (50, 95)),
            send_gap_ms=_trio(gaps, (50, 99)),
        )

    # -- consumer side (sender thread) -----------------------------------------------------

    def _run(self) -> None:
        if self.clock is not None:
            self.priority = raise_priority("output sender", fifo=SENDER_FIFO, nice=SENDER_NICE)
            self._prio_set.set()
            self._run_clocked()
            return
        while True:
            with self._cond:
                while not self._queue and not self._stop:
                    self._cond.wait()
                if self._stop and not self._queue:
                    return
                sample = self._queue.popleft()
                self._busy = True
                cfg = self._config
                targets = list(self._targets)
            try:
                self.process(sample, cfg, targets)
            except Exception as exc:  # never let one bad sample kill the sender
                self.encode_errors += 1
                self.last_encode_error = f"{type(exc).__name__}: {exc}"
            finally:
                with self._cond:
                    self.processed += 1
                    self._busy = False
                    self._cond.notify_all()

    def _ingest(self, sample: OutputSample, cfg: OutputConfig) -> bool:
        """Put a sample's pose into the delay history; False if nothing can be sent yet."""
        T = sample.T_world_cam
        if T is not None and sample.subject == "camera":
            T = cfg.offset.apply(T)  # tracked point -> nodal point, before the studio frame
        good = sample.state in ("TRACKING", "DEGRADED") and T is not None
        pose = cfg.studio.studio_pose(T) if good and T is not None else None
        if T is not None and not good and not self._comp.has_pose:
            # Not good before any good frame (initialising): hold the tracker's own pose.
            self._comp.add(sample.timestamp_s, cfg.studio.studio_pose(T), True)
        self._comp.add(sample.timestamp_s, pose, good)
        if self._last_t is not None and sample.timestamp_s > self._last_t \
                and self.clock is None:
            inst = 1.0 / (sample.timestamp_s - self._last_t)
            if math.isfinite(inst):
                self._rate_hz = inst if not self._rate_measured else (
                    0.9 * self._rate_hz + 0.1 * inst
                )
                self._rate_measured = True
        self._last_t = sample.timestamp_s
        return self._comp.has_pose

    def process(self, sample: OutputSample, cfg: OutputConfig,
                targets: Sequence[_Target]) -> None:
        """Per record: the sample's pose (delayed) to every target."""
        T = sample.T_world_cam
        good = sample.state in ("TRACKING", "DEGRADED") and T is not None
        if not self._ingest(sample, cfg):
            self.skipped_no_pose += 1
            return
        timed = self._comp.value(sample.timestamp_s) if good else self._comp.held()
        assert timed is not None
        if sample.state == "LOST" and not sample.capture_mono_s:
            self.lost_ticks += 1
        self._emit(timed.pose, sample.state, sample, cfg, targets)
        if sample.submit_mono_s:
            self._latency_ms.append((time.monotonic() - sample.submit_mono_s) * 1000.0)

    def _emit(self, pose: StudioPose, state: str, sample: OutputSample, cfg: OutputConfig,
              targets: Sequence[_Target]) -> None:
        """Encode once per protocol/encoding and send to every target."""
        seq = sample.seq if self.clock is None else self._out_seq
        wall = (sample.wall_time_s if self.clock is None else 0.0) or time.time()
        self._send(self._encode(pose, state, sample, cfg, targets, seq, wall), sample)

    def _encode(self, pose: StudioPose, state: str, sample: OutputSample, cfg: OutputConfig,
                targets: Sequence[_Target], seq: int, wall_s: float) -> list[_Encoded]:
        """Every target's datagrams for one pose (or the encode error), sending nothing: the
        OpenTrackIO packet sequence numbers are the targets' next ones."""
        freed_bytes: bytes | None = None
        otio_payloads: dict[str, bytes] = {}
        out: list[_Encoded] = []
        for t in targets:
            try:
                if t.spec.protocol == "freed":
                    if freed_bytes is None:
                        if sample.subject == "talent":
                            freed_bytes = freed_packet(
                                pose, FreeDSettings(camera_id=cfg.talent.freed_camera_id,
                                                    lens_mapping=fd.ZoomFocusMapping.RAW),
                                None, cfg.lens)
                        else:
                            freed_bytes = freed_packet(pose, cfg.freed, sample.intrinsics,
                                                       cfg.lens, sample.lens)
                    out.append((t, [freed_bytes]))
                else:
                    enc = t.spec.encoding
                    if enc not in otio_payloads:
                        sample_dict = self._builder.build(
                            otio.SampleInputs(
                                pose=pose,
                                status=state,
                                timestamp_s=wall_s,
                                sequence_number=seq,
                                sample_rate_hz=self._rate_hz,
                                intrinsics=(sample.intrinsics if sample.subject == "camera"
                                            else None),
                                transform_id=("Camera" if sample.subject == "camera"
                                              else cfg.talent.transform_id),
                                lens=sample.lens if sample.subject == "camera" else None,
                                timecode=sample.timecode,
                            )
                        )
                        otio_payloads[enc] = otio.encode_payload(sample_dict, enc)
                    out.append((t, otio.build_packets(otio_payloads[enc], t.otio_seq, enc)))
            except OutputError as exc:
                out.append((t, exc))
        return out

    def _send(self, encoded: Sequence[_Encoded], sample: OutputSample) -> None:
        """Put encoded datagrams on the wire (errors counted per target) and count the send."""
        for t, packets in encoded:
            if isinstance(packets, OutputError):
                self.encode_errors += 1
                self.last_encode_error = str(packets)
                t.errors += 1
                t.last_error = f"{t.spec.name}: {packets}"
                t.last_error_mono = time.monotonic()
                continue
            t.send(packets)
            if t.spec.protocol == "opentrackio":
                t.otio_seq = (t.otio_seq + 1) & 0xFFFF
        self._out_seq += 1
        now = time.monotonic()
        self.ticks += 1
        if self._last_emit_mono is not None:
            self._gaps_ms.append((now - self._last_emit_mono) * 1000.0)
        self._last_emit_mono = now
        if sample.capture_mono_s:
            self._cap_send_ms.append((now - sample.capture_mono_s) * 1000.0)
        if sample.done_mono_s:
            self._done_send_ms.append((now - sample.done_mono_s) * 1000.0)

    def _run_clocked(self) -> None:
        clock = self.clock
        assert clock is not None
        nan = math.nan
        while True:
            deadline = woke = rq = nan
            with self._cond:
                while True:
                    if self._stop:
                        return
                    if self._queue:
                        break
                    now = time.monotonic()
                    wake = clock.wake_at()
                    if wake is not None and now >= wake:
                        break
                    rq0 = run_queue_s()
                    self._cond.wait(None if wake is None else max(0.0, wake - now))
                    woke = time.monotonic()
                    rq = (run_queue_s() - rq0) * 1000.0
                    deadline = nan if wake is None or self._queue else wake
                samples = list(self._queue)
                self._queue.clear()
                self._busy = True
                cfg = self._config
                targets = list(self._targets)
                faulted = self._faulted
            firing = False
            try:
                now = time.monotonic()
                arrived = False
                for s in samples:
                    if self._ingest(s, cfg):
                        self._newest = s
                        self._newest_arrival = s.submit_mono_s or now
                        self._fresh = arrived = True
                        clock.on_arrival(now)
                    else:
                        self.skipped_no_pose += 1
                    self.processed += 1
                if self._newest is not None and clock.should_fire(now, arrived):
                    due = clock.due
                    fresh = self._fresh
                    newest = self._newest
                    firing = True
                    self._tick(now, cfg, targets, faulted)
                    firing = False
                    clock.fired(now)
                    self._prepare(cfg, targets, faulted)
                    self.slot_timings.append(SlotTiming(
                        due_s=nan if due is None else due,
                        sent_s=self._last_emit_mono or now, by_timer=not arrived,
                        fresh=fresh, deadline_s=deadline, woke_s=woke, run_queue_ms=rq,
                        arrival_s=self._newest_arrival,
                        capture_s=newest.capture_mono_s if fresh else nan,
                        done_s=newest.done_mono_s if fresh else nan))
            except Exception as exc:  # never let one bad sample kill the sender
                self.encode_errors += 1
                self.last_encode_error = f"{type(exc).__name__}: {exc}"
                if firing:  # the slot is spent: retrying it at once would spin a core
                    clock.fired(time.monotonic())
            finally:
                with self._cond:
                    self._busy = False
                    self._cond.notify_all()

    def _plan(self, now: float, faulted: bool) -> _Planned:
        """What the slot firing at ``now`` sends: the newest pose, held when not fresh,
        LOST when stale or faulted (nothing is changed)."""
        newest = self._newest
        assert newest is not None
        stale = faulted or now - self._newest_arrival > self.stale_after_s
        good = newest.state in ("TRACKING", "DEGRADED") and newest.T_world_cam is not None
        if stale or not good:
            timed = self._comp.held()
            state = "LOST" if stale else newest.state
        else:
            lead = max(0.0, now - self._newest_arrival)
            timed = self._comp.value(newest.timestamp_s, min(lead, self.clock_period))
            state = newest.state
        assert timed is not None
        # latency is counted once, for the slot that carried the fresh pose; a held slot is the
        # next video frame: its timecode counts on from the last one sent
        tc = newest.timecode
        if not self._fresh and self._last_tc is not None:
            tc = self._last_tc.plus(1)
        carry = newest if self._fresh else replace(newest, capture_mono_s=0.0, done_mono_s=0.0)
        if tc is not carry.timecode:
            carry = replace(carry, timecode=tc)
        return _Planned(timed.pose, state, carry, stale, tc)

    def _tick(self, now: float, cfg: OutputConfig, targets: Sequence[_Target],
              faulted: bool) -> None:
        """One clocked slot: the prepared datagrams when the slot is the held one they were
        made for, else planned and encoded now."""
        ready = self._prepared
        self._prepared = None
        stale = faulted or now - self._newest_arrival > self.stale_after_s
        if (ready is not None and not self._fresh and ready.newest is self._newest
                and ready.cfg is cfg and ready.out_seq == self._out_seq
                and ready.plan.stale == stale and ready.targets == tuple(targets)
                and ready.due == (self.clock.due if self.clock is not None else None)):
            plan, encoded = ready.plan, ready.encoded
            self.prepared_used += 1
        else:
            plan = self._plan(now, faulted)
            encoded = self._encode(plan.pose, plan.state, plan.carry, cfg, targets,
                                   self._out_seq, time.time())
        if not self._fresh:
            self.held_ticks += 1
        if plan.stale:
            self.lost_ticks += 1
        self._last_tc = plan.timecode
        self._send(encoded, plan.carry)
        self._fresh = False

    def _prepare(self, cfg: OutputConfig, targets: Sequence[_Target], faulted: bool) -> None:
        """Encode the next slot as a held one ahead of time (it fires by the timer when no
        fresh pose comes): at its due time the sender then only puts bytes on the wire,
        so a late wake-up (another thread holding the interpreter) costs the send nothing
        more. A fresh pose, a new configuration or a fault discards it."""
        clock = self.clock
        if clock is None or clock.due is None or self._newest is None or self._fresh:
            return
        due = clock.due
        plan = self._plan(due, faulted)
        wall = time.time() + (due - time.monotonic())  # the slot's own time
        encoded = self._encode(plan.pose, plan.state, plan.carry, cfg, targets,
                               self._out_seq, wall)
        self._prepared = _Prepared(due, self._newest, cfg, self._out_seq, tuple(targets),
                                   plan, encoded)

    @property
    def clock_period(self) -> float:
        return self.clock.period_s if self.clock is not None else 1.0 / 30.0
