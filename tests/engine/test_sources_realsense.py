"""RealSense: bags written in the SDK's layout, played back by the real SDK (pyrealsense2).

The SDK is a locked dependency; the tests that need it skip with a clear reason only where it
cannot be installed (no wheel for the platform). Live-camera behaviour that needs a device
(disconnect, reconnect, a source faster than the tracker) runs on a fake device behind the
same stream interface, and on the SDK's own real-time playback.
"""

from __future__ import annotations

import itertools
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from engine.errors import SourceError
from engine.frames import Frame
from engine.sources import open_source
from engine.sources.realsense import (
    DISCONNECTED,
    DeviceLost,
    RawFrame,
    RealSenseOptions,
    RealSenseSource,
    parse_realsense_options,
)
from engine.sources.realsense_bag import write_realsense_bag
from engine.sources.synthetic import SyntheticSource

W, H, N = 160, 120, 20


def _sdk():  # type: ignore[no-untyped-def]
    return pytest.importorskip(
        "pyrealsense2", reason="the RealSense SDK (pyrealsense2) has no wheel for this platform"
    )


def _studio(**extra: str) -> SyntheticSource:
    opts = {"frames": str(N), "width": str(W), "height": str(H), "path": "rail"}
    opts.update(extra)
    return SyntheticSource.from_options(opts)


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("rs") / "studio.bag"
    src = _studio()
    write_realsense_bag(src.frames(), path, src.intrinsics, fps=src.nominal_fps)
    return path


def test_sdk_accepts_the_written_layout(bag: Path) -> None:
    rs = _sdk()
    dev = rs.context().load_device(str(bag))
    names = sorted(s.get_info(rs.camera_info.name) for s in dev.query_sensors())
    assert names == ["RGB Camera", "Stereo Module"]
    assert dev.first_depth_sensor().get_depth_scale() == pytest.approx(0.001)
    profiles = [p for s in dev.query_sensors() for p in s.get_stream_profiles()]
    kinds = sorted((str(p.stream_type()), str(p.format())) for p in profiles)
    assert kinds == [("stream.color", "format.rgb8"), ("stream.depth", "format.z16")]
    assert all(p.fps() == 30 for p in profiles)


def test_bag_plays_every_frame_exactly_through_the_sdk(bag: Path) -> None:
    _sdk()
    truth = list(_studio().frames())
    with open_source(str(bag)) as src:
        assert not src.live
        assert len(src) == N
        assert src.intrinsics.size_wh == (W, H)
        assert src.intrinsics.fx == pytest.approx(truth[0].intrinsics.fx)
        got = list(src.frames())
        again = sum(1 for _ in src.frames())  # a second pass rewinds the recording
    assert again == N
    assert [f.index for f in got] == list(range(N))
    for f, t in zip(got, truth, strict=True):
        assert f.timestamp_s == pytest.approx(t.timestamp_s, abs=1e-9)
        np.testing.assert_array_equal(f.color_bgr, t.color_bgr)
        # Z16 in 1 mm units: the SDK's depth is the truth rounded to the millimetre
        assert np.max(np.abs(f.depth_m - t.depth_m)) <= 0.0005 + 1e-6
        np.testing.assert_allclose(f.gt_T_world_cam, t.gt_T_world_cam, atol=1e-9)
        assert f.skipped_before == 0


def test_capture_round_trips_to_a_tum_folder(bag: Path, tmp_path: Path) -> None:
    _sdk()
    from engine.capture import capture_to_tum
    from engine.sources.tum import TumSource

    with open_source(str(bag)) as src:
        summary = capture_to_tum(src, tmp_path / "tum", max_frames=15)
        ref = list(src.frames())[:15]
    assert summary["frames"] == 15
    assert summary["groundtruth"] is True
    tum = TumSource(tmp_path / "tum")
    assert len(tum) == 15
    assert tum.intrinsics.depth_scale == 1000.0
    for a, b in zip(tum.frames(), ref, strict=True):
        np.testing.assert_array_equal(a.color_bgr, b.color_bgr)
        np.testing.assert_allclose(a.depth_m, b.depth_m, atol=1e-6)  # lossless 1 mm PNGs
        np.testing.assert_allclose(a.gt_T_world_cam, b.gt_T_world_cam, atol=1e-8)


def test_sdk_alignment_can_be_forced(bag: Path) -> None:
    _sdk()
    src = RealSenseSource(parse_realsense_options({"align": "sdk"}, bag))
    with src:
        f = next(iter(src.frames()))
    truth = next(iter(_studio().frames()))
    valid = f.depth_m > 0
    # the SDK's rs.align re-samples even identical geometry: most pixels equal, a few holes
    assert valid.mean() > 0.9
    assert np.median(np.abs(f.depth_m[valid] - truth.depth_m[valid])) < 1e-3


# -- bad input: one line each ----------------------------------------------------------------
def test_missing_device_is_one_line() -> None:
    rs = _sdk()
    if len(rs.context().query_devices()):
        pytest.skip("a RealSense camera is connected to this machine")
    with pytest.raises(SourceError, match="no RealSense camera connected") as exc:
        open_source("realsense")
    assert "\n" not in str(exc.value)
    with pytest.raises(SourceError, match="no RealSense camera connected"):
        open_source("realsense:serial=123456789")


def test_bag_without_depth_stream(tmp_path: Path) -> None:
    _sdk()
    path = tmp_path / "colour_only.bag"
    src = _studio(frames="3")
    write_realsense_bag(src.frames(), path, src.intrinsics, with_depth=False)
    with pytest.raises(SourceError, match=r"colour_only\.bag: no depth stream"):
        open_source(str(path))


def test_unsupported_resolution(bag: Path) -> None:
    _sdk()
    with pytest.raises(SourceError, match=r"1280x720@30 is not supported .*160x120@30"):
        open_source(f"realsense:file={bag},width=1280,height=720")
    with pytest.raises(SourceError, match="both width= and height="):
        open_source(f"realsense:file={bag},width=1280")


@pytest.mark.parametrize("model", ["Kannala Brandt4", "Ftheta"])
def test_unsupported_distortion_model(tmp_path: Path, model: str) -> None:
    _sdk()
    path = tmp_path / "fisheye.bag"
    src = _studio(frames="2", distortion="1")
    write_realsense_bag(src.frames(), path, src.intrinsics, distortion_model=model)
    with pytest.raises(SourceError, match=f"distortion model '{model}' is not supported"):
        open_source(str(path))


def test_distorted_bag_keeps_its_brown_conrady_coefficients(tmp_path: Path) -> None:
    _sdk()
    path = tmp_path / "kinect.bag"
    src = _studio(frames="2", distortion="1")
    write_realsense_bag(src.frames(), path, src.intrinsics)
    with open_source(str(path)) as rs_src:
        np.testing.assert_allclose(rs_src.intrinsics.dist, src.intrinsics.dist, atol=1e-7)


def test_bad_files_and_options(tmp_path: Path, bag: Path) -> None:
    _sdk()
    junk = tmp_path / "junk.bag"
    junk.write_text("not a bag\n")
    with pytest.raises(SourceError, match=r"junk\.bag: not a RealSense recording"):
        open_source(str(junk))
    with pytest.raises(SourceError, match="no such file"):
        open_source(f"realsense:file={tmp_path / 'missing.bag'}")
    with pytest.raises(SourceError, match="'colour' is unknown"):
        open_source(f"realsense:file={bag},colour=1")
    with pytest.raises(SourceError, match="align='depth'"):
        open_source(f"realsense:file={bag},align=depth")


def test_write_refuses_to_overwrite(bag: Path) -> None:
    src = _studio(frames="1")
    with pytest.raises(SourceError, match="exists"):
        write_realsense_bag(src.frames(), bag, src.intrinsics)


# -- the newest-frame policy on the SDK's real-time playback ---------------------------------
def test_realtime_playback_skips_what_a_slow_tracker_cannot_take(bag: Path) -> None:
    _sdk()
    src = RealSenseSource(parse_realsense_options({"realtime": "1"}, bag))
    with src:
        assert src.live
        frames = []
        for f in src.frames():
            frames.append(f)
            time.sleep(0.1)  # a tracker at 10 Hz on a 30 Hz recording
    taken = len(frames)
    skipped = sum(f.skipped_before for f in frames)
    assert taken < N
    assert skipped > 0
    # each recorded frame is taken or counted as skipped (from the SDK's frame numbers, the
    # recording's first one included) exactly once
    assert taken + skipped == N


# -- a fake device: faster than the tracker, unplugged mid-run, plugged back ----------------
class Bench:
    """The camera side of the fake-device tests: the test decides when each frame exists.

    Every opened :class:`FakeDevice` delivers the frames released to it (one at open, then
    :meth:`release`), one per ``read()``. :meth:`wait_stored` returns once the source's
    grabber has stored the ``n``-th frame delivered so far (it reads again only after
    storing one), so the tests count frames, not milliseconds. The device fails as told:
    the first one stops delivering after ``lost_after`` frames (silently, or with a USB
    error), and the first ``fail_reopens`` attempts to open it again find no camera.
    """

    def __init__(self, *, lost_after: int | None = None, raise_on_loss: bool = False,
                 fail_reopens: int = 0) -> None:
        self.cond = threading.Condition()
        self.devices: list[FakeDevice] = []
        self.delivered = 0  # frames delivered by all devices
        self.asked_after = 0  # frames delivered before the latest read()
        self.lost_after = lost_after
        self.raise_on_loss = raise_on_loss
        self.fail_reopens = fail_reopens
        self.reopen_attempts = 0

    def opener(self, opts: RealSenseOptions) -> FakeDevice:
        with self.cond:
            if self.devices:
                self.reopen_attempts += 1
                if self.reopen_attempts <= self.fail_reopens:
                    raise SourceError("realsense: no RealSense camera connected")
            dev = FakeDevice(self)
            self.devices.append(dev)
            return dev

    def release(self, n: int = 1) -> None:
        with self.cond:
            self.devices[-1].credit += n
            self.cond.notify_all()

    def wait_stored(self, n: int) -> None:
        with self.cond:
            assert self.cond.wait_for(lambda: self.asked_after >= n, timeout=10.0)


def frame_no(frame: Frame) -> int:
    """The global number a :class:`FakeDevice` wrote into the frame's first pixel."""
    assert frame.color_bgr is not None
    return int(frame.color_bgr[0, 0, 0]) + 256 * int(frame.color_bgr[0, 0, 1])


class FakeDevice:
    """Stands in for the SDK pipeline (same ``RgbdStream`` interface)."""

    fps = 200.0
    name = "fake RealSense"

    def __init__(self, bench: Bench) -> None:
        from engine.camera import Intrinsics

        self.bench = bench
        self.intrinsics = Intrinsics(100.0, 100.0, 15.5, 11.5, 32, 24, depth_scale=1000.0)
        self.credit = 1  # a camera has a frame at once
        self.n = 0  # frames this device delivered (its clock restarts at every open)

    def read(self, timeout_s: float) -> RawFrame | None:
        b = self.bench
        with b.cond:
            b.asked_after = b.delivered
            b.cond.notify_all()
            lost = b.devices[0] is self and b.lost_after is not None and self.n >= b.lost_after
            if not lost:
                if not b.cond.wait_for(lambda: self.credit > 0, timeout=timeout_s):
                    return None
                self.credit -= 1
                fn = b.delivered
                b.delivered += 1
                self.n += 1
        if lost:
            if b.raise_on_loss:
                raise DeviceLost("USB error")
            time.sleep(timeout_s)
            return None
        color = np.zeros((24, 32, 3), np.uint8)
        color[0, 0, :2] = (fn % 256, fn // 256)
        return RawFrame(color_bgr=color, depth_m=np.ones((24, 32), np.float32),
                        timestamp_s=(self.n - 1) / self.fps, frame_number=None)

    def close(self) -> None:
        pass


def _fake_source(bench: Bench) -> RealSenseSource:
    # timeouts far above any scheduling delay: only the scripted loss is a lost camera
    opts = RealSenseOptions(timeout_s=1.0, reconnect_s=0.05)
    return RealSenseSource(opts, opener=bench.opener)


def test_source_faster_than_the_tracker_gives_the_newest_frame_and_counts_skips() -> None:
    from engine.pipeline import Pipeline
    from engine.trackers.base import TrackResult, TrackState

    period = 0.05  # a 20 Hz tracker (on the pipeline's clock, advanced by the tracker)
    per_track = 10  # frames the camera delivers while the tracker works on one
    now = [0.0]
    lags: list[int] = []

    class SlowTracker:
        name = "slow"
        params = None

        def set_params(self, params: object) -> None:
            pass

        def reset(self) -> None:
            pass

        def track(self, frame: Frame) -> TrackResult:
            # how many frames the camera had delivered beyond the one handed to the tracker
            lags.append(bench.delivered - 1 - frame_no(frame))
            # capture time = when the grabber got the frame, before the tracker took it
            assert frame.capture_mono_s <= time.monotonic()
            target = bench.delivered + per_track
            bench.release(per_track)
            bench.wait_stored(target)
            now[0] += period
            return TrackResult(state=TrackState.TRACKING, T_world_cam=np.eye(4))

    bench = Bench()
    src = _fake_source(bench)
    pipe = Pipeline(src, SlowTracker(), max_frames=30, clock=lambda: now[0])
    records = list(pipe.records())
    src.close()
    skipped = [r.frame.skipped_before for r in records]
    assert skipped == [0] + [per_track - 1] * 29  # 9 of every 10 camera frames skipped
    assert lags == [0] * 30  # the frame taken is the newest: no stale backlog
    assert src.total_skipped == sum(skipped)
    # "skipping N frames/s": 9 skipped per tracked frame at 20 Hz
    assert records[-1].skipped_per_s == pytest.approx((per_track - 1) / period, rel=0.1)


@pytest.mark.parametrize("raise_error", [False, True])
def test_unplugged_mid_run_reports_lost_then_reconnects(raise_error: bool) -> None:
    from engine.loop import run_tracking
    from engine.trackers.base import TrackResult, TrackState

    class LockstepTracker:
        """The camera's next frame comes once this one is tracked: none is ever skipped."""

        name = "lockstep"
        params = None

        def set_params(self, params: object) -> None:
            pass

        def reset(self) -> None:
            pass

        def track(self, frame: object) -> TrackResult:
            bench.release()
            return TrackResult(state=TrackState.TRACKING, T_world_cam=np.eye(4))

    bench = Bench(lost_after=5, raise_on_loss=raise_error, fail_reopens=2)
    src = _fake_source(bench)
    records = list(run_tracking(src, LockstepTracker(), max_frames=14))
    src.close()
    states = [r.result.state for r in records]
    assert states[:5] == [TrackState.TRACKING] * 5
    lost = [r for r in records if r.result.state is TrackState.LOST]
    assert len(lost) == 3  # two failed reopen attempts, then the camera is back
    assert bench.reopen_attempts == 3
    assert all(r.result.message == DISCONNECTED for r in lost)
    assert all(r.frame.color_bgr is None and r.frame.link_lost_reason == DISCONNECTED
               for r in lost)
    np.testing.assert_array_equal(lost[0].result.T_world_cam, np.eye(4))  # pose held
    assert states[8:] == [TrackState.TRACKING] * 6
    assert [frame_no(r.frame) for r in records if r.frame.color_bgr is not None] == list(
        range(11))
    assert src.reconnects == 1
    assert src.total_skipped == 0
    ts = [r.frame.timestamp_s for r in records]
    assert all(b > a for a, b in itertools.pairwise(ts))  # increasing across the gap


def test_sdk_missing_gives_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    import builtins

    real_import = builtins.__import__

    def fake_import(name: str, *args: object, **kwargs: object) -> object:
        if name == "pyrealsense2":
            raise ImportError("No module named 'pyrealsense2'")
        return real_import(name, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(builtins, "__import__", fake_import)
    with pytest.raises(SourceError, match=r"pyrealsense2\) is not installed"):
        open_source("realsense")
    from engine.sources.realsense import list_devices

    assert list_devices() == []


def test_a_first_frame_dropped_by_the_sdk_restarts_the_playback(bag: Path) -> None:
    _sdk()
    from engine.sources.realsense import SdkStream

    armed = [False]  # drop frame 0 of the next playback that delivers it
    injected = [0]
    bad_starts = [0]  # playbacks whose first frame handed to the source was not frame 0

    class DropsFirstOnce(SdkStream):
        """The real SDK stream, losing frame 0 once when armed (as the SDK sometimes does).

        The real SDK may drop a first frame by itself too (a few starts in a hundred on a
        loaded machine): every start whose first frame is not frame 0 is counted, so the
        restarts are checked exactly whoever dropped the frame.
        """

        def __init__(self, opts: RealSenseOptions) -> None:
            super().__init__(opts)
            self._first = True

        def read(self, timeout_s: float) -> RawFrame | None:
            raw = super().read(timeout_s)
            if armed[0] and self._first and raw is not None and raw.frame_number == 0:
                armed[0] = False
                injected[0] += 1
                raw = super().read(timeout_s)
            if self._first and raw is not None:
                self._first = False
                bad_starts[0] += raw.frame_number != 0
            return raw

    src = RealSenseSource(parse_realsense_options({}, bag), opener=DropsFirstOnce)
    with src:
        first = list(src.frames())  # first pass: nothing injected
        first_restarts = src.playback_restarts
        armed[0] = True
        second = list(src.frames())  # reopened: frame 0 dropped, restarted, then all played
    assert injected[0] == 1
    assert len(first) == N
    assert len(second) == N
    assert src.playback_restarts == bad_starts[0] >= first_restarts + 1
    assert [f.skipped_before for f in second] == [0] * N
    assert [f.timestamp_s for f in second] == [f.timestamp_s for f in first]  # from frame 0


def test_a_frame_dropped_mid_recording_is_counted(bag: Path) -> None:
    _sdk()
    from engine.sources.realsense import SdkStream

    class DropsFive(SdkStream):
        def read(self, timeout_s: float) -> RawFrame | None:
            raw = super().read(timeout_s)
            if raw is not None and raw.frame_number == 5:
                return super().read(timeout_s)
            return raw

    src = RealSenseSource(parse_realsense_options({}, bag), opener=DropsFive)
    with src:
        frames = list(src.frames())
    assert len(frames) == N - 1
    assert [f.skipped_before for f in frames].count(1) == 1
    assert frames[5].skipped_before == 1
    assert src.total_skipped == 1
