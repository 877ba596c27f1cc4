"""A loopback VISCA-over-IP PTZ camera: the real byte protocol, finite speed, FreeD out.

:class:`ViscaCameraSim` listens on 127.0.0.1 (port 0 = any free port) and answers what a
Sony camera answers (:mod:`engine.ptz.visca`): ACK then completion for an absolute
pan-tilt or zoom command, the position for inquiries, a syntax error for what it does not
understand, a control reply to RESET. Its head *moves*: :meth:`advance` steps the motors
towards the commanded position at the commanded speed (Sony EVI-D30 table: pan 3.33 deg/s
per speed step up to 0x18 = 80 deg/s, tilt 2.5 deg/s per step up to 0x14 = 50 deg/s; zoom
full range in 2 s) in the caller's time (the ptz-sim frame clock, so runs are repeatable and
real time when the frames are paced) and then emits one FreeD D1 packet of its position to
``freed_to`` (a PTZ camera's genlocked FreeD output).

Faults for tests and demonstrations (:meth:`set_fault`): ``"silent"`` (answers nothing),
``"garbage"`` (answers random bytes), ``"slow"`` (answers 0.5 s late); ``None`` heals it.
"""

from __future__ import annotations

import contextlib
import math
import socket
import threading
import time

import numpy as np

from engine.outputs.freed import FreeDPose, encode_d1, wrap_deg
from engine.ptz import visca as vc

FAULTS = ("silent", "garbage", "slow")


class ViscaCameraSim:
    """See the module docstring. ``pan_deg``/``tilt_deg`` are motor angles (pan left +)."""

    def __init__(self, *, host: str = "127.0.0.1", port: int = 0,
                 units: vc.ViscaUnits | None = None,
                 freed_to: tuple[str, int] | None = None, camera_id: int = 1,
                 position_m: tuple[float, float, float] = (0.0, 0.0, 1.5),
                 pan_deg: float = 0.0, tilt_deg: float = 0.0,
                 pan_range_deg: tuple[float, float] = (-170.0, 170.0),
                 tilt_range_deg: tuple[float, float] = (-30.0, 90.0),
                 speed_scale: float = 1.0) -> None:
        self.units = units or vc.ViscaUnits()
        self.freed_to = freed_to
        self.camera_id = camera_id
        self.position_m = position_m
        self.pan_range_deg = pan_range_deg
        self.tilt_range_deg = tilt_range_deg
        self.speed_scale = float(speed_scale)
        self._lock = threading.Lock()
        self.pan_deg = float(pan_deg)
        self.tilt_deg = float(tilt_deg)
        self.zoom_raw = 0
        self._target = (self.pan_deg, self.tilt_deg)
        self._speed_dps = (80.0, 50.0)
        self._zoom_target = 0
        self._pending: list[tuple[tuple[str, int], int, str]] = []  # completion owed
        self._t: float | None = None
        self._fault: str | None = None
        self.commands = 0
        self.inquiries = 0
        self.errors_sent = 0
        self.freed_sent = 0
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.bind((host, int(port)))
        self._sock.settimeout(0.05)
        self.host = host
        self.port = int(self._sock.getsockname()[1])
        self._out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._out.bind((host, 0))
        self._rng = np.random.default_rng(17)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name=f"visca-sim:{self.port}",
                                        daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------- control
    def set_fault(self, fault: str | None) -> None:
        if fault is not None and fault not in FAULTS:
            raise ValueError(f"fault {fault!r}: expected one of {', '.join(FAULTS)} or None")
        self._fault = fault

    def angles(self) -> tuple[float, float]:
        with self._lock:
            return self.pan_deg, self.tilt_deg

    def advance(self, t_s: float) -> tuple[float, float]:
        """Move the motors to time ``t_s`` (seconds, the caller's clock), send completions
        of finished moves and one FreeD packet; returns the motor (pan, tilt)."""
        with self._lock:
            dt = 0.0 if self._t is None else max(0.0, t_s - self._t)
            self._t = t_s
            tp, tt = self._target
            sp, st = self._speed_dps
            self.pan_deg = _step(self.pan_deg, tp, sp * self.speed_scale * dt)
            self.tilt_deg = _step(self.tilt_deg, tt, st * self.speed_scale * dt)
            self.zoom_raw = int(_step(self.zoom_raw, self._zoom_target,
                                      32768.0 * self.speed_scale * dt))
            done: list[tuple[tuple[str, int], int, str]] = []
            keep: list[tuple[tuple[str, int], int, str]] = []
            for addr, seq, kind in self._pending:
                reached = ((kind == "pt" and self.pan_deg == tp and self.tilt_deg == tt)
                           or (kind == "zoom" and self.zoom_raw == self._zoom_target))
                (done if reached else keep).append((addr, seq, kind))
            self._pending = keep
            pan, tilt, zoom = self.pan_deg, self.tilt_deg, self.zoom_raw
        for addr, seq, _ in done:
            self._reply(addr, vc.ViscaMessage(vc.REPLY, seq, vc.COMPLETION))
        if self.freed_to is not None:
            x, y, z = self.position_m
            pkt = encode_d1(FreeDPose(
                camera_id=self.camera_id, pan_deg=wrap_deg(-pan), tilt_deg=tilt, roll_deg=0.0,
                x_mm=x * 1000.0, y_mm=y * 1000.0, z_mm=z * 1000.0,
                zoom=min(max(zoom, 0), 0xFFFFFF), focus=0))
            with contextlib.suppress(OSError):
                self._out.sendto(pkt, self.freed_to)
                self.freed_sent += 1
        return pan, tilt

    def close(self) -> None:
        self._stop.set()
        self._thread.join(1.0)
        self._sock.close()
        self._out.close()

    def __enter__(self) -> ViscaCameraSim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -------------------------------------------------------------------- server
    def _reply(self, addr: tuple[str, int], msg: vc.ViscaMessage) -> None:
        if self._fault == "silent":
            return
        data = vc.encode_message(msg)
        if self._fault == "garbage":
            data = bytes(self._rng.integers(0, 256, int(self._rng.integers(1, 24)),
                                            dtype=np.uint8))
        if self._fault == "slow":
            threading.Timer(0.5, self._send_raw, (addr, data)).start()
            return
        self._send_raw(addr, data)

    def _send_raw(self, addr: tuple[str, int], data: bytes) -> None:
        with contextlib.suppress(OSError):
            self._sock.sendto(data, addr)

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                data, addr = self._sock.recvfrom(2048)
            except TimeoutError:
                continue
            except OSError:
                return
            try:
                msg = vc.decode_message(data)
            except vc.ViscaError:
                # a datagram this camera cannot even frame: Sony answers a control error
                self._reply(addr, vc.ViscaMessage(vc.CONTROL_REPLY, 0, b"\x0f\x02"))
                continue
            self._handle(addr, msg)

    def _handle(self, addr: tuple[str, int], msg: vc.ViscaMessage) -> None:
        if msg.payload_type == vc.CONTROL:
            if msg.payload == vc.CONTROL_RESET:
                self._reply(addr, vc.ViscaMessage(vc.CONTROL_REPLY, msg.sequence, b"\x01"))
            else:
                self._reply(addr, vc.ViscaMessage(vc.CONTROL_REPLY, msg.sequence, b"\x0f\x02"))
            return
        if msg.payload_type not in (vc.COMMAND, vc.INQUIRY):
            self._reply(addr, vc.ViscaMessage(vc.CONTROL_REPLY, msg.sequence, b"\x0f\x02"))
            return
        try:
            what = vc.parse_command(msg.payload)
        except vc.ViscaError:
            self.errors_sent += 1
            self._reply(addr, vc.ViscaMessage(vc.REPLY, msg.sequence, vc.error_reply(0x02)))
            return
        if isinstance(what, str):
            self.inquiries += 1
            with self._lock:
                pan, tilt, zoom = self.pan_deg, self.tilt_deg, self.zoom_raw
            if what == "pan_tilt_pos":
                body = vc.pan_tilt_position_reply(self.units.pan_counts(pan),
                                                  self.units.tilt_counts(tilt))
            elif what == "zoom_pos":
                body = vc.value_reply(zoom)
            elif what == "focus_pos":
                body = vc.value_reply(0)
            else:  # IF_Clear
                body = vc.COMPLETION
            self._reply(addr, vc.ViscaMessage(vc.REPLY, msg.sequence, body))
            return
        self.commands += 1
        if isinstance(what, vc.PanTiltAbsolute):
            pan = self.units.pan_deg(what.pan_counts)
            tilt = self.units.tilt_deg(what.tilt_counts)
            if not (self.pan_range_deg[0] <= pan <= self.pan_range_deg[1]
                    and self.tilt_range_deg[0] <= tilt <= self.tilt_range_deg[1]):
                self._reply(addr, vc.ViscaMessage(vc.REPLY, msg.sequence,
                                                  vc.error_reply(0x41, 1)))
                return
            with self._lock:
                self._target = (pan, tilt)
                self._speed_dps = (3.33 * what.pan_speed, 2.5 * what.tilt_speed)
                # a new move cancels the completion owed for the previous one
                self._pending = [p for p in self._pending if p[2] != "pt"]
                self._pending.append((addr, msg.sequence, "pt"))
        else:
            with self._lock:
                self._zoom_target = min(max(what.zoom_raw, 0), 0x4000 * 4 - 1)
                self._pending = [p for p in self._pending if p[2] != "zoom"]
                self._pending.append((addr, msg.sequence, "zoom"))
        self._reply(addr, vc.ViscaMessage(vc.REPLY, msg.sequence, vc.ACK))


def _step(x: float, target: float, max_step: float) -> float:
    d = target - x
    if abs(d) <= max_step or not math.isfinite(max_step):
        return float(target)
    return float(x + math.copysign(max_step, d))


def wall_clock_driver(cam: ViscaCameraSim, rate_hz: float, stop: threading.Event) -> None:
    """Advance ``cam`` on the wall clock at ``rate_hz`` until ``stop`` (a free-running camera
    for demonstrations outside a ptz-sim run)."""
    t0 = time.monotonic()
    while not stop.wait(1.0 / rate_hz):
        cam.advance(time.monotonic() - t0)
