"""``freed-relay``: poses from a FreeD input (``freed:PORT``) re-sent with the studio set-up.

A FreeD-emitting camera or tracker reports its pose; this pass-through turns each packet
into ``T_world_cam`` (the FreeD frame is the tracker world: X, Y horizontal, Z up; FreeD pan
positive to the right, :mod:`engine.outputs.studio_frame`) so that the outputs re-send it with
what the project adds: the lens file at the packet's zoom/focus encoders, the nodal offset,
the studio frame, SMPTE timecode, OpenTrackIO. Frames without a reading are LOST (holding
the last pose).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from engine.frames import Frame
from engine.outputs.freed_input import FreeDReading
from engine.outputs.studio_frame import StudioPose
from engine.params import Params
from engine.trackers.base import TrackerSpec, TrackResult, TrackState


@dataclass(frozen=True, slots=True)
class FreeDRelayParams(Params):
    """No parameters: the pose is the FreeD packet's."""


def T_world_cam_of(reading: FreeDReading) -> np.ndarray:
    """The FreeD pose as ``T_world_cam`` (OpenCV camera axes) in the FreeD frame."""
    p = reading.pose
    return StudioPose(p.x_mm / 1000.0, p.y_mm / 1000.0, p.z_mm / 1000.0, -p.pan_deg,
                      p.tilt_deg, p.roll_deg).T_studio_cam()


class FreeDRelay:
    name = "freed-relay"

    def __init__(self, params: FreeDRelayParams) -> None:
        self._params = params
        self._last: np.ndarray | None = None

    @property
    def params(self) -> FreeDRelayParams:
        return self._params

    def set_params(self, params: FreeDRelayParams) -> None:
        self._params = params

    def reset(self) -> None:
        self._last = None

    def track(self, frame: Frame) -> TrackResult:
        t0 = time.perf_counter()
        r = frame.payload(FreeDReading)
        if r is None:
            return TrackResult(state=TrackState.LOST if self._last is not None
                               else TrackState.INITIALIZING,
                               T_world_cam=None if self._last is None else self._last.copy(),
                               message="no FreeD reading")
        self._last = T_world_cam_of(r)
        return TrackResult(state=TrackState.TRACKING, T_world_cam=self._last.copy(),
                           timings_ms={"total": (time.perf_counter() - t0) * 1000.0})


TRACKERS = (
    TrackerSpec(
        name="freed-relay",
        description="poses of a FreeD input (freed:PORT) re-sent with the project's lens "
        "file, nodal offset, studio frame and timecode",
        params_cls=FreeDRelayParams,
        factory=FreeDRelay,
        needs_image=False,
    ),
)
