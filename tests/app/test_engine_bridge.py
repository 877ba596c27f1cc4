"""The engine bridge: start/stop, records, errors, commands, no dangling threads."""

from __future__ import annotations

import dataclasses

import pytest

from app.engine_bridge import EngineBridge, running_threads
from engine.loop import FrameRecord
from tests.app.fakes import FakeParams, create_fake, open_fake


@pytest.fixture
def bridge(qtbot):  # type: ignore[no-untyped-def]
    b = EngineBridge(open_source=open_fake, create_tracker=create_fake)
    yield b
    b.stop()


def test_runs_to_the_end_and_emits_every_record(qtbot, bridge: EngineBridge) -> None:
    records: list[FrameRecord] = []
    bridge.result_ready.connect(records.append)
    with qtbot.waitSignals([bridge.started, bridge.finished], timeout=10_000, order="strict"):
        bridge.start("fake:30", "fake")
    assert [r.seq for r in records] == list(range(30))
    assert all(isinstance(r, FrameRecord) for r in records)
    assert not bridge.is_running
    assert bridge.run_info is not None
    assert bridge.run_info.source_len == 30
    assert running_threads() == []


def test_stop_is_prompt_and_start_again_works(qtbot, bridge: EngineBridge) -> None:
    with qtbot.waitSignal(bridge.result_ready, timeout=10_000):
        bridge.start("fake:1000000", "fake", realtime=True)
    assert bridge.is_running
    with qtbot.waitSignal(bridge.finished, timeout=5_000):
        assert bridge.stop()
    assert not bridge.is_running
    assert running_threads() == []
    n_before = bridge.frames_received
    assert 0 < n_before < 1000000
    # a second run starts from the first frame again
    seqs: list[int] = []
    bridge.result_ready.connect(lambda r: seqs.append(r.seq))
    with qtbot.waitSignal(bridge.finished, timeout=10_000):
        bridge.start("fake:5", "fake")
    assert seqs == [0, 1, 2, 3, 4]


def test_bad_source_reports_one_line_through_failed(qtbot, bridge: EngineBridge) -> None:
    errors: list[str] = []
    bridge.failed.connect(errors.append)
    with qtbot.waitSignals([bridge.failed, bridge.finished], timeout=10_000, order="strict"):
        bridge.start("/no/such/folder", "fake")
    [message] = errors
    assert message == "SourceError: /no/such/folder: no such file or folder"
    assert "\n" not in message
    assert not bridge.is_running
    assert running_threads() == []


def test_exception_mid_run_ends_run_and_restart_works(qtbot, bridge: EngineBridge) -> None:
    seqs: list[int] = []
    bridge.result_ready.connect(lambda r: seqs.append(r.seq))
    errors: list[str] = []
    bridge.failed.connect(errors.append)
    with qtbot.waitSignals([bridge.failed, bridge.finished], timeout=10_000, order="strict"):
        bridge.start("fake:50", "explode")
    assert errors == ["RuntimeError: injected failure at frame 5"]
    assert seqs == [0, 1, 2, 3, 4]
    assert bridge.last_error is not None
    with qtbot.waitSignal(bridge.finished, timeout=10_000):
        bridge.start("fake:3", "fake")
    assert bridge.last_error is None
    assert seqs[-3:] == [0, 1, 2]


def test_set_params_applies_on_next_frame(qtbot, bridge: EngineBridge) -> None:
    records: list[FrameRecord] = []
    bridge.result_ready.connect(records.append)
    with qtbot.waitSignal(bridge.result_ready, timeout=10_000):
        bridge.start("fake:1000000", "fake", params=FakeParams(gain=0.0), realtime=True)
    new = dataclasses.replace(FakeParams(), gain=5.0)
    with qtbot.waitSignal(bridge.params_changed, timeout=1000):
        bridge.set_params(new)
    n_sent = len(records)
    qtbot.waitUntil(lambda: len(records) > n_sent + 2, timeout=10_000)
    bridge.stop()
    # records that were processed after the command show the new gain's offset
    late = records[-1]
    assert late.result.T_world_cam is not None
    assert late.result.T_world_cam[1, 3] == pytest.approx(0.005 * late.frame.index)
    assert records[0].result.T_world_cam[1, 3] == pytest.approx(0.0)


def test_records_are_immutable(qtbot, bridge: EngineBridge) -> None:
    records: list[FrameRecord] = []
    bridge.result_ready.connect(records.append)
    with qtbot.waitSignal(bridge.finished, timeout=10_000):
        bridge.start("fake:2", "fake")
    rec = records[0]
    with pytest.raises(dataclasses.FrozenInstanceError):
        rec.seq = 5  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        rec.frame.color_bgr[0, 0, 0] = 1  # type: ignore[index]


def test_nothing_from_a_stopped_run_arrives_after_finished(qtbot, bridge: EngineBridge) -> None:
    with qtbot.waitSignal(bridge.result_ready, timeout=10_000):
        bridge.start("fake:100000000", "fake")  # flat out: records are queued when we stop
    bridge.stop()
    n = bridge.frames_received
    with qtbot.assertNotEmitted(bridge.result_ready, wait=200):
        pass
    assert bridge.frames_received == n


def test_module_threads_are_tracked_while_running(qtbot, bridge: EngineBridge) -> None:
    with qtbot.waitSignal(bridge.started, timeout=10_000):
        bridge.start("fake:100000000", "fake", realtime=True)
    alive = running_threads()
    assert len(alive) == 1
    assert alive[0].isRunning()
    bridge.stop()
    assert running_threads() == []
