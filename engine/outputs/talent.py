"""Talent tracking output: the presenter's place in the studio as its own pose stream.

Studio talent trackers send the presenter's floor position (and head height) to the render
engine as a subject of its own, beside the camera: virtual shadows, occlusion and
"walk-behind" graphics need it. A tracker that knows where the presenter stands returns a
:class:`TalentPosition` command each frame; the pose-output sink carries it out
(:meth:`engine.outputs.sender.OutputSet.submit_record`): the talent pose is

- translation: the floor position (x, y) and the head height z (0 when unknown) in the
  tracker's world (for the presenter tracker the floor calibration's frame), through the
  operator's studio frame like every pose;
- rotation: none (pan = tilt = roll = 0: a position, not an orientation);
- OpenTrackIO: one transform with id ``TalentSettings.transform_id`` ("Talent") in the
  sample; FreeD D1: camera id ``TalentSettings.freed_camera_id`` (2 by default: the camera
  keeps 1), zoom and focus 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.outputs import OutputError
from engine.params import Params, param
from engine.results import TrackerCommand


@dataclass(frozen=True, slots=True)
class TalentPosition(TrackerCommand):
    """Where the presenter is: floor (x, y) and head height z, metres, tracker world."""

    floor_xy_m: tuple[float, float]
    head_height_m: float | None = None

    def T_world_talent(self) -> NDArray[np.float64]:
        """The talent 'pose': the position with the zero orientation of the studio frame
        (pan = tilt = roll = 0 looks along +Y, camera axes as in ``studio_frame``)."""
        from engine.geometry import R_from_pan_tilt_roll_deg, make_T

        x, y = self.floor_xy_m
        z = self.head_height_m if self.head_height_m is not None else 0.0
        return make_T(R_from_pan_tilt_roll_deg(0.0, 0.0, 0.0), (x, y, z))


@dataclass(frozen=True, slots=True)
class TalentSettings(Params):
    """How the talent stream is labelled on the wire."""

    ERROR = OutputError

    freed_camera_id: int = param(2, lo=0, hi=255, step=1,
                                 help="FreeD camera id of the talent stream (the camera's is "
                                 "the FreeD settings' id)")
    transform_id: str = param("Talent", help="OpenTrackIO transform id of the talent")

    def validate(self) -> None:
        if not self.transform_id.strip():
            raise OutputError("TalentSettings.transform_id must not be empty")
