"""The run owner: one run per window, started/stopped from any page, engine never waits."""

from __future__ import annotations

import dataclasses
import socket
import time

import numpy as np
import pytest

from app.run_owner import RunOwner, RunRequest, running_threads
from engine.outputs import OutputError
from engine.outputs import opentrackio as ot
from engine.outputs.sender import OutputConfig, TargetSpec
from engine.pipeline import RunPhase, SinkLevel
from tests.app.fakes import FakeParams, create_fake, open_fake


@pytest.fixture
def owner(qtbot):  # type: ignore[no-untyped-def]
    o = RunOwner(open_source=open_fake, create_tracker=create_fake)
    yield o
    o.stop()


def _samples(o: RunOwner) -> list:  # type: ignore[type-arg]
    samples, _, _ = o.trace_since(0)
    return samples


def test_runs_to_the_end_history_has_every_frame(qtbot, owner: RunOwner) -> None:
    seen = []
    owner.started.connect(lambda info: seen.append(info.source_len))
    with qtbot.waitSignals([owner.started, owner.finished], timeout=10_000, order="strict"):
        owner.start("fake:30", "fake", realtime=False)
    assert seen == [30]
    assert not owner.is_running
    assert owner.frames_received == 30
    assert owner.latest() is None  # nothing stale after the run: pages clear
    assert owner.final_status is not None
    assert owner.final_status.phase is RunPhase.ENDED
    assert running_threads() == []


def test_stop_is_prompt_and_start_again_works(qtbot, owner: RunOwner) -> None:
    with qtbot.waitSignal(owner.started, timeout=10_000):
        owner.start("fake:1000000", "fake", realtime=True)
    qtbot.waitUntil(lambda: owner.frames_received > 3, timeout=10_000)
    with qtbot.waitSignal(owner.finished, timeout=5_000):
        assert owner.stop()
    assert not owner.is_running
    assert owner.stopped_by_user
    assert running_threads() == []
    with qtbot.waitSignal(owner.finished, timeout=10_000):
        owner.start(RunRequest("fake:5", "fake", realtime=False))
    assert owner.frames_received == 5


def test_bad_source_reports_one_line_through_failed(qtbot, owner: RunOwner) -> None:
    errors: list[str] = []
    owner.failed.connect(errors.append)
    with qtbot.waitSignals([owner.failed, owner.finished], timeout=10_000, order="strict"):
        owner.start("/no/such/folder", "fake")
    assert errors == ["SourceError: /no/such/folder: no such file or folder"]
    assert not owner.is_running
    assert owner.last_error == errors[0]


def test_engine_exception_holds_the_run_until_stop(qtbot, owner: RunOwner) -> None:
    errors: list[str] = []
    owner.failed.connect(errors.append)
    with qtbot.waitSignal(owner.started, timeout=10_000):
        owner.start("fake:50", "explode", realtime=False)
    qtbot.waitUntil(lambda: owner.pipeline is not None
                    and owner.pipeline.phase is RunPhase.FAULT, timeout=10_000)
    owner.poll()  # the display clock reports the fault once
    owner.poll()
    assert errors == ["RuntimeError: injected failure at frame 5"]
    assert owner.is_running  # sinks stay open (outputs hold LOST) until the operator stops
    with qtbot.waitSignal(owner.finished, timeout=5_000):
        owner.stop()
    assert owner.final_status.error == errors[0]


def test_set_params_applies_on_next_frame(qtbot, owner: RunOwner) -> None:
    with qtbot.waitSignal(owner.started, timeout=10_000):
        owner.start("fake:1000000", "fake", FakeParams(gain=0.0), realtime=True)
    qtbot.waitUntil(lambda: owner.frames_received > 2, timeout=10_000)
    with qtbot.waitSignal(owner.params_changed, timeout=1000):
        owner.set_params(dataclasses.replace(FakeParams(), gain=5.0))
    n = owner.frames_received
    qtbot.waitUntil(lambda: owner.frames_received > n + 3, timeout=10_000)
    samples = _samples(owner)
    owner.stop()
    assert samples[0].T_world_cam[1, 3] == pytest.approx(0.0)
    late = samples[-1]
    assert late.T_world_cam[1, 3] == pytest.approx(0.005 * late.index)


def test_the_engine_never_waits_for_a_stalled_gui(qtbot, owner: RunOwner) -> None:
    """The GUI thread blocks (no event loop, nobody takes records): tracking goes on."""
    with qtbot.waitSignal(owner.started, timeout=10_000):
        owner.start("fake:100000", "fake", realtime=True)  # 30 fps
    qtbot.waitUntil(lambda: owner.frames_received > 2, timeout=10_000)
    n0 = owner.frames_received
    time.sleep(0.6)  # the GUI thread is stuck
    n1 = owner.frames_received
    owner.take_latest()
    st = owner.status()
    owner.stop()
    assert n1 - n0 >= 12  # ~18 frames at 30 fps in 0.6 s: the engine did not wait
    assert st.display_dropped >= 10  # coalesced: only the latest record is kept, drops counted


def test_a_stalled_gui_gets_one_record_wake_up_not_a_queue(qtbot, owner: RunOwner) -> None:
    with qtbot.waitSignal(owner.started, timeout=10_000):
        owner.start("fake:100000", "fake", realtime=True)  # 30 fps
    qtbot.waitUntil(lambda: owner.frames_received > 2, timeout=10_000)
    woken: list[int] = []
    owner.record_ready.connect(lambda: woken.append(owner.frames_received))
    qtbot.wait(100)
    owner.take_latest()
    woken.clear()
    n0 = owner.frames_received
    time.sleep(0.5)  # the GUI thread is stuck: ~15 records, nobody takes them
    qtbot.wait(20)  # the queued wake-ups arrive
    assert owner.frames_received - n0 >= 8
    assert len(woken) == 1
    owner.take_latest()
    qtbot.waitUntil(lambda: len(woken) >= 2, timeout=2_000)  # the next record wakes it again
    owner.stop()


def test_outputs_follow_every_run_and_bad_host_is_refused(qtbot, owner: RunOwner) -> None:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(2.0)
    cfg = OutputConfig(targets=(TargetSpec("opentrackio", "127.0.0.1", rx.getsockname()[1]),))
    owner.apply_outputs(cfg)
    with pytest.raises(OutputError, match="cannot resolve"):
        owner.apply_outputs(OutputConfig(targets=(TargetSpec("freed", "no.such.host.invalid",
                                                             40000),)))
    assert owner.outputs_config == cfg  # the refused one is not in force
    owner.set_outputs_enabled(True)
    try:
        with qtbot.waitSignal(owner.started, timeout=10_000):
            owner.start("fake:100000", "fake", realtime=True, page="PTZ")
        got = ot.decode_datagrams([rx.recv(65536)])[0]
        qtbot.waitUntil(lambda: (h := owner.output_health()) is not None
                        and h.level is SinkLevel.OK, timeout=5_000)
    finally:
        owner.stop()
        rx.close()
    assert got["tracker"]["status"] in ("TRACKING", "DEGRADED")
    assert np.isfinite(got["transforms"][0]["translation"]["x"])
