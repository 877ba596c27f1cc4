"""The frame-source interface."""

from __future__ import annotations

import abc
from collections.abc import Iterator

from engine.camera import Intrinsics
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

    def __iter__(self) -> Iterator[Frame]:
        return self.frames()

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release devices/files."""

    def __enter__(self) -> Source:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
