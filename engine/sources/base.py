"""The frame-source interface."""

from __future__ import annotations

import abc
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from engine.camera import Intrinsics
from engine.errors import SourceError
from engine.frames import Frame


class Source(abc.ABC):
    """A finite or live sequence of frames.

    Subclasses validate what they can at construction (so that a bad folder fails before
    tracking starts) and raise :class:`engine.errors.SourceError` with one line naming the
    file and the problem for what can only be found while reading.

    The iterator ``frames()`` returns may define ``consumer_idle()``: a real-time pipeline
    calls it once each frame's record went out, so a source that makes frames ahead (the
    built-in studio, :mod:`engine.sources.ahead`) makes the next one in the engine's idle
    time rather than beside its tracking.
    """

    #: short human-readable description, e.g. "TUM folder rgbd_dataset_freiburg1_xyz"
    name: str = "source"
    #: nominal frame rate, used for live pacing and RPE deltas when timestamps are synthetic
    nominal_fps: float = 30.0
    #: True for live inputs (webcam, network) that have no length and cannot be rewound
    live: bool = False

    @property
    @abc.abstractmethod
    def intrinsics(self) -> Intrinsics | None:
        """Calibration of the colour camera, if known."""

    @abc.abstractmethod
    def __len__(self) -> int:
        """Number of frames (0 if unknown/live)."""

    @abc.abstractmethod
    def frames(self) -> Iterator[Frame]:
        """Yield frames in order, starting from the first one each call."""

    def sinks(self) -> Sequence[Any]:
        """Sinks (:class:`engine.pipeline.Sink`) a pipeline running this source must add to
        close the source's own loop (e.g. the simulated pan-tilt head obeying the tracker)."""
        return ()

    def input_paths(self) -> tuple[Path, ...]:
        """Files this source reads (a folder: everything in it); outputs must not be one.

        The default names the conventional attributes (``path``, ``groundtruth_path``);
        folder sources add their lists and image folders.
        """
        found = (getattr(self, a, None) for a in ("path", "groundtruth_path"))
        return tuple(Path(p) for p in found if isinstance(p, str | Path) and str(p))

    def end_notes(self) -> tuple[str, ...]:
        """Warnings about how the last :meth:`frames` pass ended or what it skipped (a
        truncated video: which frame was the last good one; skipped readings), for the
        caller to show and put in its JSON. Empty when the source ended normally."""
        return ()

    def __iter__(self) -> Iterator[Frame]:
        return self.frames()

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release devices/files."""

    def __enter__(self) -> Source:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True, slots=True)
class SourceSpec:
    """How :func:`engine.sources.open_source` recognises and opens one kind of source.

    A *scheme* source (``detect`` None) answers the spec strings ``name`` and ``name:REST``;
    ``opener(REST)`` opens it (``REST`` is ``""`` for a bare ``name``). A *path* source answers
    an existing file or folder for which ``detect(path)`` is true; ``opener(str(path))`` opens
    it. ``description`` is one short phrase shown in error messages and help ("a TUM RGB-D
    folder (rgb.txt)"); ``example`` a spec string that works.
    """

    name: str
    description: str
    opener: Callable[[str], Source]
    detect: Callable[[Path], bool] | None = None
    example: str = ""

    @property
    def is_path(self) -> bool:
        return self.detect is not None


def parse_options(text: str) -> dict[str, str]:
    """``"a=1,b=x"`` -> ``{"a": "1", "b": "x"}``; a malformed item raises SourceError."""
    out: dict[str, str] = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise SourceError(f"source option {item!r} is not key=value")
        out[key.strip()] = value.strip()
    return out


class StopOnError(Source):
    """Wraps a source so that an error while reading (a truncated file at frame 500, a
    device gone) ends the frames instead of the run: the frames read before it are kept
    and the error is stored in :attr:`error`, for the caller to save the partial result
    first and report the error after."""

    def __init__(self, inner: Source) -> None:
        self.inner = inner
        self.name = inner.name
        self.nominal_fps = inner.nominal_fps
        self.live = inner.live
        self.error: Exception | None = None
        self.frames_read = 0
        #: frames the source dropped before the ones read (``Frame.skipped_before``, e.g. a
        #: live camera's frames the engine was too busy for) plus those it never pairs (TUM
        #: colour images without depth)
        self.frames_skipped = int(getattr(inner, "dropped_rgb", 0) or 0)
        self.last_frame: Frame | None = None

    @property
    def intrinsics(self) -> Intrinsics | None:
        return self.inner.intrinsics

    def __len__(self) -> int:
        return len(self.inner)

    def __getattr__(self, name: str) -> object:  # groundtruth_path, end_notes, ...
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    def input_paths(self) -> tuple[Path, ...]:
        return self.inner.input_paths()

    def end_notes(self) -> tuple[str, ...]:
        return self.inner.end_notes()

    def sinks(self) -> Sequence[Any]:
        return self.inner.sinks()

    def frames(self) -> Iterator[Frame]:
        from engine.errors import StudioTrackError

        it = self.inner.frames()
        while True:
            try:
                frame = next(it)
            except StopIteration:
                return
            except (StudioTrackError, OSError) as exc:
                self.error = exc
                return
            self.frames_read += 1
            self.frames_skipped += int(getattr(frame, "skipped_before", 0) or 0)
            self.last_frame = frame
            yield frame

    def close(self) -> None:
        self.inner.close()
