"""Capture any source (live sensor, recording, built-in studio) to a TUM RGB-D folder.

The folder is what :class:`engine.sources.tum.TumSource` reads (``rgb/``, ``depth/``,
``rgb.txt``, ``depth.txt``, ``camera.json`` and ``groundtruth.txt`` when the source has
ground truth), so ``track``, ``sweep``, evo and other TUM tools take it. Depth PNGs use the
source's depth scale (1000 per metre for a RealSense = its 1 mm units, lossless; 5000 for
the built-in studio, as TUM). Frames without a picture (a camera disconnected) are not
written and are counted; a live source's skipped frames are counted too. Stopping early
(``should_stop``) still writes the lists of what was captured.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from engine.errors import SourceError
from engine.frames import Frame
from engine.sources.base import Source


@dataclass(slots=True)
class CaptureStats:
    """Counts while capturing (updated in place by :func:`capture_frames`)."""

    written: int = 0
    skipped: int = 0
    disconnected: int = 0
    first_t_s: float | None = None
    last_t_s: float | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        if self.first_t_s is None or self.last_t_s is None:
            return 0.0
        return self.last_t_s - self.first_t_s


def capture_frames(
    source: Source,
    stats: CaptureStats,
    *,
    max_frames: int | None = None,
    max_seconds: float | None = None,
    should_stop: Callable[[], bool] = lambda: False,
) -> Iterator[Frame]:
    """The source's frames that have colour and depth, up to ``max_frames`` or ``max_seconds``
    of source time (timestamps since the first frame), whichever comes first."""
    for frame in source.frames():
        if should_stop():
            stats.notes.append("stopped early")
            return
        if frame.link_lost_reason is not None:
            stats.disconnected += 1
            continue
        if frame.color_bgr is None or frame.depth_m is None:
            raise SourceError(
                f"{source.name}: frame {frame.index} has no depth; a TUM RGB-D capture needs an "
                "RGB-D source"
            )
        if stats.first_t_s is None:
            stats.first_t_s = frame.timestamp_s
        if max_seconds is not None and frame.timestamp_s - stats.first_t_s > max_seconds:
            return
        stats.skipped += frame.skipped_before
        stats.last_t_s = frame.timestamp_s
        yield frame
        stats.written += 1
        if max_frames is not None and stats.written >= max_frames:
            return


def capture_to_tum(
    source: Source,
    out_dir: Path,
    *,
    max_frames: int | None = None,
    max_seconds: float | None = None,
    should_stop: Callable[[], bool] = lambda: False,
    progress: Callable[[int, CaptureStats], None] | None = None,
) -> dict[str, object]:
    """Write the source to ``out_dir`` (new or empty) as a TUM folder; returns a summary."""
    from engine.studio.export import write_tum_folder

    if max_frames is not None and max_frames < 1:
        raise SourceError(f"--frames must be at least 1, got {max_frames}")
    if max_seconds is not None and not max_seconds > 0:
        raise SourceError(f"--seconds must be positive, got {max_seconds}")
    if source.live and max_frames is None and max_seconds is None:
        raise SourceError(f"{source.name} is live: give --frames N or --seconds S")
    cam = source.intrinsics
    if cam is None:
        raise SourceError(f"{source.name}: no intrinsics; a TUM capture needs a calibrated source")
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise SourceError(f"{out_dir}: exists and is not a folder")
    stats = CaptureStats()

    def on_frame(n: int) -> None:
        if progress is not None:
            progress(n, stats)

    frames = capture_frames(source, stats, max_frames=max_frames, max_seconds=max_seconds,
                            should_stop=should_stop)
    summary = write_tum_folder(frames, out_dir, cam, on_frame,
                               written_by=f"studiotrack capture ({source.name})")
    summary.update({
        "source": source.name,
        "skipped_frames": stats.skipped,
        "disconnected_frames": stats.disconnected,
        "duration_s": stats.duration_s,
        "depth_scale": cam.depth_scale,
    })
    if stats.notes:
        summary["notes"] = list(stats.notes)
    return summary
