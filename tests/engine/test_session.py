"""Recording, deterministic replay, export, and a write error mid-recording."""

from __future__ import annotations

import errno
import json
from collections.abc import Iterator

import numpy as np
import pytest

from engine.camera import Intrinsics
from engine.frames import Frame
from engine.geometry import R_from_pan_tilt_roll_deg, make_T
from engine.session import RecordingStopped, SessionError
from engine.session import recorder as recmod
from engine.session.export import export_trajectory
from engine.session.reader import SessionSource, read_index, read_records
from engine.session.recorder import SessionRecorder, record_session
from engine.session.replay import replay_session
from engine.sources.base import Source
from engine.trackers import create_tracker
from engine.trackers.base import TrackResult, TrackState

INTR = Intrinsics(40.0, 40.0, 15.5, 11.5, 32, 24)


class TinySource(Source):
    """Seeded random colour + float depth + ground truth, 32x24."""

    name = "tiny"
    nominal_fps = 25.0

    def __init__(self, n: int = 12, seed: int = 0) -> None:
        self.n = n
        self.seed = seed

    @property
    def intrinsics(self) -> Intrinsics:
        return INTR

    def __len__(self) -> int:
        return self.n

    def frames(self) -> Iterator[Frame]:
        rng = np.random.default_rng(self.seed)
        for i in range(self.n):
            color = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
            depth = rng.uniform(0.5, 4.0, (24, 32)).astype(np.float32)
            depth[0, :4] = 0.0
            gt = make_T(R_from_pan_tilt_roll_deg(3.0 * i, -5.0, 0.5), [0.1 * i, -2.0, 1.6])
            yield Frame(i, i / 25.0, color, INTR, depth, gt)


class ContentTracker:
    """Pose computed from image and depth content in float arithmetic (order sensitive)."""

    name = "content"

    def __init__(self) -> None:
        self.acc = np.zeros(3)

    params = None

    def set_params(self, p: object) -> None: ...

    def reset(self) -> None:
        self.acc = np.zeros(3)

    def track(self, frame: Frame) -> TrackResult:
        d = frame.depth_m.astype(np.float64)
        c = frame.color_bgr.astype(np.float64)
        self.acc = self.acc * 0.9 + np.array([d.mean(), (d * c[..., 0]).sum() / 1e6,
                                              np.sqrt((d**2).mean())])
        T = make_T(R_from_pan_tilt_roll_deg(self.acc[1] * 10, 0.0, 0.0), self.acc)
        state = TrackState.TRACKING if frame.index % 5 else TrackState.DEGRADED
        return TrackResult(state=state, T_world_cam=T, residual=float(d.std()))


def _record(tmp_path, tracker, n=12, name="s"):
    src = TinySource(n)
    rec = SessionRecorder(tmp_path / name, source=src, source_spec="tiny:test",
                          tracker_name="ground-truth", tracker_params=None)
    out = list(record_session(src, tracker, rec))
    return tmp_path / name, out


def test_record_then_replay_is_bit_identical(tmp_path):
    sdir, live = _record(tmp_path, ContentTracker())
    idx = read_index(sdir)
    assert idx.status == "complete"
    assert idx.frames_recorded == 12
    assert idx.has_depth
    recs = read_records(sdir)
    assert len(recs) == 12
    for r, lv in zip(recs, live, strict=True):
        assert np.array_equal(np.reshape(r["T_world_cam"], (4, 4)), lv.result.T_world_cam)
    res = replay_session(sdir, ContentTracker())
    assert res.frames == 12
    assert res.identical
    assert res.mismatches == 0
    # Colour is lossless; depth is what the tracker saw (16-bit quantised).
    src_frames = list(TinySource(12).frames())
    rep_frames = list(SessionSource(sdir).frames())
    assert np.array_equal(src_frames[3].color_bgr, rep_frames[3].color_bgr)
    assert np.abs(src_frames[3].depth_m - rep_frames[3].depth_m).max() <= 0.5 / 5000 + 1e-7
    assert np.array_equal(rep_frames[3].gt_T_world_cam, src_frames[3].gt_T_world_cam)


def test_replay_detects_a_different_engine(tmp_path):
    sdir, _ = _record(tmp_path, ContentTracker())
    res = replay_session(sdir, create_tracker("ground-truth"))
    assert not res.identical
    assert res.mismatches == 12


def test_replay_with_recorded_tracker_from_registry(tmp_path):
    sdir, _ = _record(tmp_path, create_tracker("ground-truth"))
    res = replay_session(sdir)  # tracker name + params from index.json
    assert res.identical
    assert res.params_restored


def test_export_formats(tmp_path):
    sdir, _ = _record(tmp_path, create_tracker("ground-truth"), n=5)
    recs = read_records(sdir)
    assert export_trajectory(recs, tmp_path / "t.txt") == "tum"
    lines = [ln for ln in (tmp_path / "t.txt").read_text().splitlines() if not ln.startswith("#")]
    assert len(lines) == 5
    assert len(lines[2].split()) == 8
    assert float(lines[2].split()[1]) == pytest.approx(0.2)
    export_trajectory(recs, tmp_path / "t.csv")
    csv_lines = (tmp_path / "t.csv").read_text().splitlines()
    assert csv_lines[0].startswith("seq,index,timestamp_s,state,tx")
    assert len(csv_lines) == 6
    export_trajectory(recs, tmp_path / "t.json")
    js = json.loads((tmp_path / "t.json").read_text())
    assert len(js["poses"]) == 5
    assert np.asarray(js["poses"][1]["T_world_cam"]).shape == (4, 4)


def test_disk_full_stops_recording_and_keeps_frames_readable(tmp_path, monkeypatch):
    calls = {"n": 0}
    real = recmod._write_file

    def flaky(path, data):
        calls["n"] += 1
        if calls["n"] > 7:  # 2 files per frame: frame 3's colour write fails
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        real(path, data)

    monkeypatch.setattr(recmod, "_write_file", flaky)
    src = TinySource(10)
    rec = SessionRecorder(tmp_path / "full", source=src, source_spec="tiny",
                          tracker_name="ground-truth")
    with pytest.raises(RecordingStopped, match="No space left on device") as info:
        list(record_session(src, create_tracker("ground-truth"), rec))
    assert "after 3 frame(s)" in str(info.value)
    idx = read_index(tmp_path / "full")
    assert idx.status == "stopped"
    assert "No space left" in idx.stop_reason
    assert len(read_records(tmp_path / "full")) == 3
    assert len(list(SessionSource(tmp_path / "full").frames())) == 3


def test_truncated_last_record_line_is_ignored(tmp_path):
    sdir, _ = _record(tmp_path, create_tracker("ground-truth"), n=4)
    p = sdir / "records.jsonl"
    p.write_bytes(p.read_bytes() + b'{"seq": 4, "T_world')
    assert len(read_records(sdir)) == 4


def test_refuses_to_overwrite_a_non_session_folder(tmp_path):
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "keep.txt").write_text("mine")
    with pytest.raises(SessionError, match="not empty"):
        SessionRecorder(tmp_path / "x", source=TinySource(), source_spec="t", tracker_name="g")
    with pytest.raises(SessionError, match="not a session"):
        SessionRecorder(tmp_path / "x", source=TinySource(), source_spec="t", tracker_name="g",
                        overwrite=True)


class ImageTracker(ContentTracker):
    def track(self, frame: Frame) -> TrackResult:
        c = frame.color_bgr.astype(np.float64)
        self.acc = self.acc * 0.5 + np.array([c.mean(), c[..., 1].std(), c[::7, ::5].sum()])
        return TrackResult(state=TrackState.TRACKING, T_world_cam=make_T(np.eye(3), self.acc))


def test_video_source_is_recorded_as_is_and_replays_identically(tmp_path):
    from engine.sources import open_source
    from tests.conftest import shared_path

    video = shared_path("carphone", "carphone_pristine.mp4")
    src = open_source(str(video))
    rec = SessionRecorder(tmp_path / "v", source=src, source_spec=str(video),
                          tracker_name="ground-truth")
    live = list(record_session(src, ImageTracker(), rec, max_frames=8))
    assert (tmp_path / "v" / "input.mp4").read_bytes() == video.read_bytes()
    assert not (tmp_path / "v" / "frames").exists()
    assert read_index(tmp_path / "v").source_kind == "video"
    res = replay_session(tmp_path / "v", ImageTracker())
    assert res.frames == len(live) == 8
    assert res.identical
