"""Frames made ahead on a worker thread (engine.sources.ahead) and the studio's use of it."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from engine.errors import SourceError
from engine.frames import Frame
from engine.sources import open_source
from engine.sources.ahead import read_ahead


def _frame(i: int) -> Frame:
    return Frame(index=i, timestamp_s=i / 30, color_bgr=np.zeros((2, 2, 3), np.uint8))


def _workers() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "test-ahead"]


def test_every_frame_in_order_made_on_another_thread_one_ahead() -> None:
    made: list[tuple[int, str]] = []

    def make(i: int) -> Frame:
        made.append((i, threading.current_thread().name))
        return _frame(i)

    it = read_ahead(make, 5, depth=1, name="test-ahead")
    first = next(it)
    deadline = time.monotonic() + 5.0
    while len(made) < 2 and time.monotonic() < deadline:
        time.sleep(0.005)
    assert first.index == 0
    assert [i for i, _ in made][:2] == [0, 1]  # the next one is ready meanwhile ...
    time.sleep(0.05)
    assert len(made) <= 3  # ... but no further than the depth (+1 being put)
    rest = [f.index for f in it]
    assert rest == [1, 2, 3, 4]
    assert all(name == "test-ahead" for _, name in made)
    assert not _workers()


def test_capture_time_is_when_the_frame_is_handed_out() -> None:
    it = read_ahead(_frame, 3, depth=1, name="test-ahead")
    next(it)
    time.sleep(0.1)  # frame 1 was made long before it is taken
    before = time.monotonic()
    f = next(it)
    assert f.capture_mono_s >= before
    it.close()


def test_closing_early_stops_the_worker_and_errors_reach_the_consumer() -> None:
    it = read_ahead(_frame, 1000, depth=2, name="test-ahead")
    next(it)
    it.close()
    assert not _workers()

    def bad(i: int) -> Frame:
        if i == 2:
            raise SourceError("frame 2 is broken")
        return _frame(i)

    got = []
    with pytest.raises(SourceError, match="frame 2 is broken"):
        got.extend(f.index for f in read_ahead(bad, 5, name="test-ahead"))
    assert got == [0, 1]
    assert not _workers()


def test_a_consumer_that_says_it_is_idle_gets_the_next_frame_made_only_then() -> None:
    made: list[int] = []

    def make(i: int) -> Frame:
        made.append(i)
        return _frame(i)

    def settle() -> None:
        time.sleep(0.15)

    it = read_ahead(make, 10, depth=1, name="test-ahead")
    assert next(it).index == 0
    it.consumer_idle()  # gated from here on (frames 1 and 2 were made free-running)
    settle()
    assert next(it).index == 1
    it.consumer_idle()
    assert next(it).index == 2
    settle()
    n = len(made)  # frame 3 waits for the consumer to finish frame 2
    assert made[-1] == 2
    it.consumer_idle()
    settle()
    assert made[-1] == 3
    assert len(made) == n + 1
    assert next(it).index == 3
    settle()
    assert made[-1] == 3  # still busy with frame 3: nothing made beside it
    assert next(it).index == 4  # asked before it was made: made at once
    assert [f.index for f in it] == [5, 6, 7, 8, 9]  # no idle calls: made when asked
    assert not _workers()


def test_depth_zero_makes_frames_on_the_callers_thread() -> None:
    names: list[str] = []

    def make(i: int) -> Frame:
        names.append(threading.current_thread().name)
        return _frame(i)

    assert [f.index for f in read_ahead(make, 3, depth=0)] == [0, 1, 2]
    assert set(names) == {threading.current_thread().name}


def test_studio_frames_ahead_are_the_same_frames() -> None:
    spec = "synthetic:frames=4,width=64,height=48,presenter=1"
    with open_source(spec + ",ahead=0") as a, open_source(spec) as b:
        assert getattr(b, "ahead", None) == 1  # the default: rendered ahead like a camera
        for fa, fb in zip(a.frames(), b.frames(), strict=True):
            assert fa.index == fb.index
            np.testing.assert_array_equal(fa.color_bgr, fb.color_bgr)
            np.testing.assert_array_equal(fa.depth_m, fb.depth_m)
    with pytest.raises(SourceError, match="ahead"):
        open_source("synthetic:ahead=9")
