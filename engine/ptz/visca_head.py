"""The VISCA-over-IP head driver behind the head port (:class:`engine.ptz.head.HeadPort`).

:class:`ViscaHead` is what the pipeline's head sink commands (like ptz-sim's simulated
port): :meth:`ViscaHead.command` only stores the newest target and returns; the driver's own
thread sends it (absolute pan-tilt at the configured speed), polls the position
(PanTiltPosInq, ZoomPosInq) at ``poll_hz``, and keeps the newest :class:`HeadPosition`.
Tracking therefore never waits for the camera.

A camera that does not answer, answers garbage, or answers too late: each request waits at
most ``timeout_s``; after ``offline_after_s`` without a valid reply the head is OFFLINE
(health ALARM "head OFFLINE: ..."), targets keep being stored (the newest is sent when the
camera is back) and the driver reconnects every ``reconnect_s``: a fresh socket, a control
RESET of the sequence numbers, then the pending target. Garbage is counted and dropped.
Sockets bind to 127.0.0.1 for loopback cameras, else to ``bind_host`` or 0.0.0.0.
"""

from __future__ import annotations

import contextlib
import ipaddress
import math
import socket
import threading
import time
from dataclasses import dataclass

from engine.pipeline import SinkHealth, SinkLevel
from engine.ptz import visca as vc


@dataclass(frozen=True, slots=True)
class HeadPosition:
    """The head's reported motor angles (degrees, pan left +), zoom and when (monotonic)."""

    pan_deg: float
    tilt_deg: float
    zoom_raw: int | None
    mono_s: float


class ViscaHead:
    """A VISCA-over-IP PTZ camera as a head port and a position source."""

    def __init__(self, host: str = "127.0.0.1", port: int = vc.VISCA_PORT, *,
                 units: vc.ViscaUnits | None = None, bind_host: str | None = None,
                 pan_speed: int = 0x18, tilt_speed: int = 0x14, timeout_s: float = 0.2,
                 poll_hz: float = 20.0, offline_after_s: float = 1.0,
                 reconnect_s: float = 1.0, start: bool = True) -> None:
        if not 1 <= int(port) <= 65535:
            raise vc.ViscaError(f"VISCA port {port} is outside 1..65535")
        self.host = host
        self.port = int(port)
        self.units = units or vc.ViscaUnits()
        self.bind_host = bind_host or ("127.0.0.1" if _is_loopback(host) else "0.0.0.0")
        self.pan_speed = int(pan_speed)
        self.tilt_speed = int(tilt_speed)
        self.timeout_s = float(timeout_s)
        self.poll_s = 1.0 / max(0.1, float(poll_hz))
        self.offline_after_s = float(offline_after_s)
        self.reconnect_s = float(reconnect_s)
        self.name = f"VISCA head {host}:{port}"
        self._cond = threading.Condition()
        self._target: tuple[float, float] | None = None
        self._zoom_target: int | None = None
        self._position: HeadPosition | None = None
        self._sock: socket.socket | None = None
        self._seq = 0
        self._stop = False
        self._last_ok = time.monotonic()  # grace period from start
        self._ever_ok = False
        self.sent = 0
        self.acks = 0
        self.timeouts = 0
        self.garbage = 0
        self.refusals = 0
        self.reconnects = 0
        self.last_error = ""
        self._thread: threading.Thread | None = None
        if start:
            self.start()

    # ----------------------------------------------------------------- head port
    def command(self, pan_deg: float, tilt_deg: float) -> None:
        """Go to motor angles (degrees); never blocks (the newest target wins)."""
        with self._cond:
            self._target = (float(pan_deg), float(tilt_deg))
            self._cond.notify()

    def zoom(self, zoom_raw: int) -> None:
        with self._cond:
            self._zoom_target = int(zoom_raw)
            self._cond.notify()

    def position(self) -> HeadPosition | None:
        with self._cond:
            return self._position

    @property
    def online(self) -> bool:
        return self._ever_ok and time.monotonic() - self._last_ok < self.offline_after_s

    def health(self) -> SinkHealth:
        age = time.monotonic() - self._last_ok
        counters = {"sent": self.sent, "acks": self.acks, "timeouts": self.timeouts,
                    "garbage": self.garbage, "refusals": self.refusals,
                    "reconnects": self.reconnects}
        if self.online:
            pos = self._position
            msg = ("" if pos is None else
                   f"at {pos.pan_deg:.1f}° / {pos.tilt_deg:.1f}°")
            return SinkHealth(self.name, SinkLevel.OK, msg, counters=counters)
        if not self._ever_ok and self.timeouts == 0 and self.garbage == 0:
            return SinkHealth(self.name, SinkLevel.WAITING, "connecting", counters=counters)
        why = self.last_error or "no answer"
        return SinkHealth(self.name, SinkLevel.ALARM,
                          f"head OFFLINE: {why} ({self.host}:{self.port}, "
                          f"{age:.1f} s without a valid reply); reconnecting",
                          counters=counters)

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=f"visca:{self.port}",
                                            daemon=True)
            self._thread.start()

    def close(self) -> None:
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(2.0)
            self._thread = None
        self._close_sock()

    def __enter__(self) -> ViscaHead:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------- driver
    def _open(self) -> socket.socket:
        if self._sock is None:
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                s.bind((self.bind_host, 0))
            except OSError:
                s.close()
                raise
            s.settimeout(self.timeout_s)
            self._sock = s
        return self._sock

    def _close_sock(self) -> None:
        if self._sock is not None:
            with contextlib.suppress(OSError):
                self._sock.close()
            self._sock = None

    def _request(self, ptype: int, payload: bytes) -> vc.ViscaMessage | None:
        """Send one message, return the reply with its sequence number (None: none came
        within ``timeout_s``; garbage and stale replies are skipped and counted)."""
        sock = self._open()
        self._seq = (self._seq + 1) & vc.SEQ_MAX
        seq = self._seq
        try:
            sock.sendto(vc.encode_message(vc.ViscaMessage(ptype, seq, payload)),
                        (self.host, self.port))
            self.sent += 1
        except OSError as exc:
            self.last_error = f"send failed ({exc.strerror or exc})"
            self._close_sock()
            return None
        deadline = time.monotonic() + self.timeout_s
        bad = ""
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                self.timeouts += 1
                self.last_error = bad or "no answer"
                return None
            sock.settimeout(left)
            try:
                data = sock.recv(2048)
            except TimeoutError:
                continue
            except OSError as exc:
                self.last_error = f"receive failed ({exc.strerror or exc})"
                self._close_sock()
                return None
            try:
                msg = vc.decode_message(data)
            except vc.ViscaError as exc:
                self.garbage += 1
                bad = f"garbage reply ({exc})"
                continue
            if msg.sequence != seq:
                continue  # a completion or a late reply of an earlier request
            if ptype == vc.CONTROL:
                if msg.payload_type == vc.CONTROL_REPLY and msg.payload == b"\x01":
                    return msg
                self.garbage += 1
                bad = f"control reply {msg.payload.hex(' ')}"
                continue
            if msg.payload_type != vc.REPLY:
                self.garbage += 1
                bad = f"reply of type 0x{msg.payload_type:04X}"
                continue
            return msg

    def _ok(self) -> None:
        self._last_ok = time.monotonic()
        self._ever_ok = True
        self.last_error = ""

    def _reset(self) -> bool:
        """Reconnect: fresh socket, sequence RESET. True when the camera acknowledged."""
        self._close_sock()
        self._seq = 0
        reply = self._request(vc.CONTROL, vc.CONTROL_RESET)
        if reply is None:
            return False
        self._seq = 0
        self._ok()
        return True

    def _send_target(self, target: tuple[float, float]) -> bool:
        payload = vc.pan_tilt_absolute(self.units.pan_counts(target[0]),
                                       self.units.tilt_counts(target[1]), self.pan_speed,
                                       self.tilt_speed)
        return self._command(payload)

    def _command(self, payload: bytes) -> bool:
        reply = self._request(vc.COMMAND, payload)
        if reply is None:
            return False
        try:
            r = vc.parse_reply(reply.payload)
        except vc.ViscaError as exc:
            self.garbage += 1
            self.last_error = f"garbage reply ({exc})"
            return False
        self._ok()
        if r.kind == "error":
            self.refusals += 1
            self.last_error = f"camera refused: {r.error_name}"
            return True  # the camera answered; do not resend a refused target
        self.acks += 1
        return True

    def _poll(self) -> None:
        reply = self._request(vc.INQUIRY, vc.PAN_TILT_POS_INQ)
        if reply is None:
            return
        try:
            r = vc.parse_reply(reply.payload)
            pan_c, tilt_c = vc.parse_pan_tilt(r.data) if r.kind == "data" else (None, None)
        except vc.ViscaError as exc:
            self.garbage += 1
            self.last_error = f"garbage reply ({exc})"
            return
        if pan_c is None or tilt_c is None:
            self.garbage += 1
            self.last_error = f"unexpected {r.kind} to a position inquiry"
            return
        self._ok()
        zoom = None
        zr = self._request(vc.INQUIRY, vc.ZOOM_POS_INQ)
        if zr is not None:
            with contextlib.suppress(vc.ViscaError):
                rz = vc.parse_reply(zr.payload)
                if rz.kind == "data" and len(rz.data) == 4:
                    zoom = vc.from_nibbles(rz.data, signed=False)
        with self._cond:
            self._position = HeadPosition(self.units.pan_deg(pan_c),
                                          self.units.tilt_deg(tilt_c), zoom, time.monotonic())

    def _put_back(self, target: tuple[float, float] | None, zoom: int | None) -> None:
        """Keep what could not be sent for the next try (a newer command wins)."""
        with self._cond:
            if self._target is None:
                self._target = target
            if self._zoom_target is None:
                self._zoom_target = zoom

    def _run(self) -> None:
        next_poll = 0.0
        next_reconnect = 0.0
        connected = False
        while True:
            with self._cond:
                if self._stop:
                    return
                now = time.monotonic()
                wake = next_poll if connected else next_reconnect
                if self._target is None and self._zoom_target is None and now < wake:
                    self._cond.wait(min(wake - now, 0.1))
                    continue
                target, self._target = self._target, None
                zoom, self._zoom_target = self._zoom_target, None
            now = time.monotonic()
            if not connected:
                if now < next_reconnect:
                    self._put_back(target, zoom)
                    with self._cond:
                        if not self._stop:
                            self._cond.wait(min(next_reconnect - now, 0.1))
                    continue
                next_reconnect = now + self.reconnect_s
                if self._ever_ok:
                    self.reconnects += 1  # an attempt after the head was lost
                if not self._reset():
                    self._put_back(target, zoom)
                    continue
                connected = True
            if target is not None and not self._send_target(target):
                self._put_back(target, None)
            if zoom is not None and not self._command(vc.zoom_direct(zoom)):
                self._put_back(None, zoom)
            if time.monotonic() >= next_poll:
                self._poll()
                next_poll = time.monotonic() + self.poll_s
            if time.monotonic() - self._last_ok >= self.offline_after_s:
                connected = False  # OFFLINE: reconnect (fresh socket, RESET) from now on


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def parse_head_spec(text: str) -> ViscaHead:
    """``visca:HOST[:PORT][,pan_speed=24,tilt_speed=20,counts_per_deg=14.4,bind=ADDR]``."""
    kind, _, rest = text.partition(":")
    if kind != "visca" or not rest:
        raise vc.ViscaError(f"head {text!r}: expected visca:HOST[:PORT][,options]")
    addr, _, opts_s = rest.partition(",")
    host, sep, port_s = addr.rpartition(":")
    if not sep:
        host, port_s = addr, str(vc.VISCA_PORT)
    try:
        port = int(port_s)
    except ValueError:
        raise vc.ViscaError(f"head {text!r}: port {port_s!r} is not a number") from None
    opts: dict[str, str] = {}
    for item in filter(None, (s.strip() for s in opts_s.split(","))):
        k, eq, v = item.partition("=")
        if not eq:
            raise vc.ViscaError(f"head {text!r}: option {item!r} is not key=value")
        opts[k.strip()] = v.strip()
    unknown = sorted(set(opts) - {"pan_speed", "tilt_speed", "counts_per_deg", "bind"})
    if unknown:
        raise vc.ViscaError(f"head {text!r}: unknown option {unknown[0]!r} (pan_speed, "
                            "tilt_speed, counts_per_deg, bind)")
    try:
        cpd = float(opts.get("counts_per_deg", 14.4))
        ps, ts = int(opts.get("pan_speed", 0x18)), int(opts.get("tilt_speed", 0x14))
    except ValueError:
        raise vc.ViscaError(f"head {text!r}: speeds and counts_per_deg must be numbers") \
            from None
    if not (1 <= ps <= vc.PAN_SPEED_MAX and 1 <= ts <= vc.TILT_SPEED_MAX) \
            or not 0 < cpd < math.inf:
        raise vc.ViscaError(f"head {text!r}: pan_speed 1..24, tilt_speed 1..20, "
                            "counts_per_deg > 0 and finite")
    if not 1 <= port <= 65535:
        raise vc.ViscaError(f"VISCA port {port} is outside 1..65535")
    try:
        socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
    except (OSError, UnicodeError) as exc:
        raise vc.ViscaError(f"head {text!r}: host {host!r} does not resolve "
                            f"({getattr(exc, 'strerror', None) or exc})") from None
    return ViscaHead(host, port, units=vc.ViscaUnits(cpd, cpd), bind_host=opts.get("bind"),
                     pan_speed=ps, tilt_speed=ts)
