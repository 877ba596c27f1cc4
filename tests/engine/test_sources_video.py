"""VideoSource on the shared clips, on a video written here, and on broken files."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from engine.camera import Intrinsics
from engine.errors import SourceError
from engine.sources import open_source
from engine.sources.video import VideoSource
from tests.conftest import shared_path

W, H, N, FPS = 64, 48, 12, 10.0


def write_avi(path: Path, n: int = N) -> list[int]:
    """An MJPG .avi whose frame i is a flat grey of level 20*i (JPEG keeps flat levels)."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), FPS, (W, H))
    assert writer.isOpened()
    levels = [20 * i for i in range(n)]
    for level in levels:
        writer.write(np.full((H, W, 3), level, np.uint8))
    writer.release()
    return levels


def test_written_avi_frames_timestamps_and_len(tmp_path: Path) -> None:
    path = tmp_path / "clip.avi"
    levels = write_avi(path)
    src = open_source(str(path))
    assert isinstance(src, VideoSource)
    assert len(src) == N
    assert src.nominal_fps == pytest.approx(FPS)
    assert src.intrinsics is None
    assert src.live is False
    frames = list(src.frames())
    assert [f.index for f in frames] == list(range(N))
    np.testing.assert_allclose([f.timestamp_s for f in frames], np.arange(N) / FPS, atol=1e-6)
    for frame, level in zip(frames, levels, strict=True):
        assert frame.color_bgr is not None
        assert frame.color_bgr.shape == (H, W, 3)
        assert frame.color_bgr.dtype == np.uint8
        assert abs(float(frame.color_bgr.mean()) - level) < 3.0
        assert not frame.color_bgr.flags.writeable
    assert len(list(src.frames())) == N  # each call starts again from the first frame


def test_given_intrinsics_are_attached_and_size_checked(tmp_path: Path) -> None:
    path = tmp_path / "clip.avi"
    write_avi(path, 3)
    cam = Intrinsics(fx=50.0, fy=50.0, cx=31.5, cy=23.5, width=W, height=H)
    frames = list(VideoSource(path, intrinsics=cam).frames())
    assert all(f.intrinsics == cam for f in frames)
    with pytest.raises(SourceError, match=rf"frames are {W}x{H} but the intrinsics say 128x96"):
        VideoSource(path, intrinsics=cam.scaled(2.0))


def test_carphone_mp4() -> None:
    path = shared_path("carphone", "carphone_pristine.mp4")
    src = VideoSource(path)
    assert len(src) == 120
    assert src.nominal_fps == pytest.approx(30000 / 1001, rel=1e-6)
    frames = list(src.frames())
    assert len(frames) == 120
    assert frames[0].color_bgr is not None
    assert frames[0].color_bgr.shape == (144, 176, 3)
    t = np.array([f.timestamp_s for f in frames])
    np.testing.assert_allclose(np.diff(t), 1001 / 30000, rtol=1e-3)
    # a moving scene: consecutive frames differ
    assert np.abs(frames[60].color_bgr.astype(int) - frames[0].color_bgr).mean() > 1.0  # type: ignore[operator]


def test_opencv_sample_avi_with_dropped_frames_uses_container_times() -> None:
    # tree.avi announces 444 frames at 15 fps but holds 68 real ones spread over 29.5 s
    path = shared_path("opencv_samples", "video", "tree.avi")
    src = VideoSource(path)
    assert len(src) == 444  # the container's (upper) estimate, documented
    frames = list(src.frames())
    assert 0 < len(frames) <= len(src)
    assert frames[0].color_bgr is not None
    assert frames[0].color_bgr.shape == (240, 320, 3)
    t = np.array([f.timestamp_s for f in frames])
    assert np.all(np.diff(t) > 0)
    assert t[-1] > 20.0  # presentation times, not index / fps (which would end at ~4.5 s)


def test_missing_empty_and_corrupt_files(tmp_path: Path) -> None:
    with pytest.raises(SourceError, match="no such video file"):
        VideoSource(tmp_path / "nope.mp4")
    (tmp_path / "empty.mp4").write_bytes(b"")
    with pytest.raises(SourceError, match=r"empty.mp4: video file is empty"):
        VideoSource(tmp_path / "empty.mp4")
    garbage = tmp_path / "garbage.mp4"
    garbage.write_bytes(np.random.default_rng(0).integers(0, 256, 4096, np.uint8).tobytes())
    with pytest.raises(SourceError) as exc:
        open_source(str(garbage))
    assert str(garbage) in str(exc.value)
    assert "cannot open video" in str(exc.value)
    assert "\n" not in str(exc.value)


def test_truncated_avi(tmp_path: Path) -> None:
    path = tmp_path / "clip.avi"
    write_avi(path)
    data = path.read_bytes()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(SourceError, match=r"cut.avi: cannot open video"):
        VideoSource(cut)


def test_unsupported_suffix_is_refused_by_open_source(tmp_path: Path) -> None:
    path = tmp_path / "notes.txt"
    path.write_text("hello")
    with pytest.raises(SourceError, match="unsupported source"):
        open_source(str(path))
