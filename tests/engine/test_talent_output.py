"""Talent tracking output: the presenter's floor position and head height as their own
OpenTrackIO transform / FreeD camera id through the pose-output sink (loopback only)."""

from __future__ import annotations

import socket

import pytest

from engine.loop import run_tracking
from engine.outputs import freed as fd
from engine.outputs import opentrackio as otio
from engine.outputs.sender import OutputConfig, TargetSpec
from engine.outputs.talent import TalentPosition, TalentSettings
from engine.sinks.pose_output import PoseOutputSink
from engine.sources import open_source
from engine.trackers import create_tracker


def _drain(sock: socket.socket) -> list[bytes]:
    out = []
    sock.settimeout(0.5)
    while True:
        try:
            out.append(sock.recvfrom(65536)[0])
        except TimeoutError:
            return out


def test_presenter_position_goes_out_as_the_talent_subject() -> None:
    rx_fd = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx_ot = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        rx_fd.bind(("127.0.0.1", 0))
        rx_ot.bind(("127.0.0.1", 0))
        cfg = OutputConfig(targets=(TargetSpec("freed", "127.0.0.1", rx_fd.getsockname()[1]),
                                    TargetSpec("opentrackio", "127.0.0.1",
                                               rx_ot.getsockname()[1])),
                           talent=TalentSettings(freed_camera_id=7, transform_id="Talent"))
        sink = PoseOutputSink(cfg, clocked=False)
        src = open_source("synthetic:frames=8,width=320,height=240,presenter=1,path=static,"
                          "views=2")
        recs = list(run_tracking(src, create_tracker("presenter"), sinks=(sink,)))
        talent = [r.result.commands_of(TalentPosition) for r in recs]
        assert all(len(t) == 1 for t in talent)
        last = talent[-1][0]
        packets = [fd.decode_d1(p) for p in _drain(rx_fd)]
        assert len(packets) == len(recs)
        assert {p.camera_id for p in packets} == {7}
        assert packets[-1].x_mm == pytest.approx(1000 * last.floor_xy_m[0], abs=1.0)
        assert packets[-1].y_mm == pytest.approx(1000 * last.floor_xy_m[1], abs=1.0)
        assert packets[-1].z_mm == pytest.approx(1000 * last.head_height_m, abs=1.0)
        samples = otio.decode_datagrams(_drain(rx_ot))
        assert [t["id"] for t in samples[-1]["transforms"]] == ["Talent"]
        assert samples[-1]["transforms"][0]["translation"]["z"] == pytest.approx(
            last.head_height_m, abs=1e-6)
    finally:
        rx_fd.close()
        rx_ot.close()


def test_talent_settings_are_validated() -> None:
    from engine.outputs import OutputError

    with pytest.raises(OutputError, match="transform_id"):
        TalentSettings(transform_id=" ")
    with pytest.raises(OutputError):
        TalentSettings(freed_camera_id=300)
