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
