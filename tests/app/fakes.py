"""Tiny fake source and trackers for run-owner and window tests (error injection)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from engine.camera import Intrinsics
from engine.errors import ParamsError, SourceError
from engine.frames import Frame
from engine.sources.base import Source
from engine.trackers.base import Overlay, TrackerSpec, TrackResult, TrackState


class FakeSource(Source):
    """``n`` small noisy frames with a ground-truth pose moving along x."""

    name = "fake"

    def __init__(self, n: int = 50, size_wh: tuple[int, int] = (64, 48)) -> None:
        self.n = n
        self.w, self.h = size_wh
        self._intr = Intrinsics(
            fx=50, fy=50, cx=self.w / 2, cy=self.h / 2, width=self.w, height=self.h
        )

    @property
    def intrinsics(self) -> Intrinsics:
        return self._intr

    def __len__(self) -> int:
        return self.n

    def frames(self) -> Iterator[Frame]:
        rng = np.random.default_rng(0)
        for i in range(self.n):
            T = np.eye(4)
            T[0, 3] = 0.01 * i
            img = rng.integers(0, 255, (self.h, self.w, 3), dtype=np.uint8)
            yield Frame(i, i / 30.0, img, self._intr, None, T)


def open_fake(spec: str) -> Source:
    """``fake:N`` opens a FakeSource of N frames; anything else fails like a bad path."""
    kind, _, rest = spec.partition(":")
    if kind != "fake":
        raise SourceError(f"{spec}: no such file or folder")
    return FakeSource(int(rest or 50))


@dataclass(frozen=True, slots=True)
class FakeParams:
    gain: float = field(default=1.0, metadata={"help": "gain", "min": 0.0, "max": 10.0})
    fail_at_frame: int = field(default=-1, metadata={"help": "raise on this frame (-1: never)"})
    lost_frames: tuple[int, ...] = field(default=(), metadata={"help": "frames reported LOST"})

    def __post_init__(self) -> None:
        if self.gain < 0:
            raise ParamsError(f"gain must be >= 0, got {self.gain}")


class FakeTracker:
    name = "fake"

    def __init__(self, params: FakeParams) -> None:
        self._params = params
        self.n = 0

    @property
    def params(self) -> FakeParams:
        return self._params

    def set_params(self, params: FakeParams) -> None:
        self._params = params

    def reset(self) -> None:
        self.n = 0

    def track(self, frame: Frame) -> TrackResult:
        if frame.index == self._params.fail_at_frame:
            raise RuntimeError(f"injected failure at frame {frame.index}")
        self.n += 1
        T = np.array(frame.gt_T_world_cam) if frame.gt_T_world_cam is not None else np.eye(4)
        T[1, 3] += 0.001 * self._params.gain * frame.index
        pts = np.array([[10, 10], [20, 20], [30, 30]], np.float32)
        if frame.index in self._params.lost_frames:
            state = TrackState.LOST
        else:
            state = TrackState.TRACKING if frame.index % 10 else TrackState.DEGRADED
        return TrackResult(
            state,
            T,
            residual=1.0 / (1 + frame.index),
            inlier_fraction=0.9,
            timings_ms={"total": 0.1},
            overlay=Overlay(points_uv=pts, point_weights=np.array([1.0, 0.5, 0.0], np.float32)),
        )


def create_fake(name: str, params: object | None) -> FakeTracker:
    p = params if isinstance(params, FakeParams) else FakeParams()
    if name == "explode":
        p = dataclasses.replace(p, fail_at_frame=5)
    elif name != "fake":
        raise ValueError(f"unknown tracker {name!r}")
    return FakeTracker(p)


FAKE_SPEC = TrackerSpec("fake", "test tracker", FakeParams, lambda p: FakeTracker(p))
EXPLODE_SPEC = TrackerSpec(
    "explode",
    "test tracker that raises on frame 5",
    FakeParams,
    lambda p: FakeTracker(dataclasses.replace(p, fail_at_frame=5)),
)
