"""Robot-camera control: the presenter tracker's corrections as UDP datagrams.

Each :class:`engine.presenter.control.RobotCameraCommand` with a ``target`` is sent as the
JSON message of :mod:`engine.presenter.control` to (host, port); the host name is resolved
once per target, so a send never waits for name resolution. A failing send is an alarm in
the sink's health (with the error), never raised into tracking.
"""

from __future__ import annotations

import socket
import time

from engine.pipeline import SinkBase, SinkHealth, SinkLevel, TargetHealth
from engine.presenter.control import RobotCameraCommand
from engine.records import FrameRecord
from engine.sinks import SinkSpec

#: a target is failing while its last error is newer than its last good send
ALARM_HOLD_S = 2.0


class RobotControlSink(SinkBase):
    """Sends robot-camera corrections to the command's UDP target."""

    name = "robot camera"

    def __init__(self) -> None:
        self._sock: socket.socket | None = None
        self._target: tuple[str, int] | None = None
        self._addr: tuple[str, int] | None = None
        self.sent = 0
        self.errors = 0
        self.last_error = ""
        self._last_ok = -1e9
        self._last_err = -1e9
        self._last_cmd_mono = -1e9

    def on_record(self, record: FrameRecord) -> None:
        for cmd in record.result.commands_of(RobotCameraCommand):
            self._last_cmd_mono = time.monotonic()
            if cmd.target is not None:
                self._send(cmd)

    def _send(self, cmd: RobotCameraCommand) -> None:
        assert cmd.target is not None
        now = time.monotonic()
        try:
            if cmd.target != self._target:
                self._target = cmd.target
                host, port = cmd.target
                info = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)
                self._addr = (str(info[0][4][0]), int(port))
            if self._sock is None:
                self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                self._sock.setblocking(False)
            assert self._addr is not None
            self._sock.sendto(cmd.message.to_json().encode("utf-8"), self._addr)
            self.sent += 1
            self._last_ok = now
        except (OSError, UnicodeError) as exc:
            self.errors += 1
            host, port = cmd.target
            self.last_error = f"{host}:{port}: {getattr(exc, 'strerror', None) or exc}"
            self._last_err = now
            if isinstance(exc, socket.gaierror):
                self._target = None  # resolve again next time

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def health(self) -> SinkHealth:
        now = time.monotonic()
        if self._target is None and not self.errors:
            level = SinkLevel.OFF
            msg = "UDP off (corrections shown only)"
        elif self._last_err > self._last_ok and now - self._last_err < ALARM_HOLD_S:
            level, msg = SinkLevel.ALARM, self.last_error
        elif self.sent and now - self._last_ok < ALARM_HOLD_S:
            level, msg = SinkLevel.OK, ""
        else:
            level, msg = SinkLevel.WAITING, "no correction sent recently"
        targets: tuple[TargetHealth, ...] = ()
        if self._target is not None:
            host, port = self._target
            targets = (TargetHealth(f"robot:{host}:{port}", level, 0.0, self.sent, self.errors,
                                    msg),)
        return SinkHealth(self.name, level, msg, targets,
                          counters={"sent": self.sent, "errors": self.errors})


SINKS = (SinkSpec("robot-camera", "sends the presenter tracker's robot-camera corrections "
                  "over UDP", RobotControlSink),)
