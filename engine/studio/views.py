"""The built-in studio's second camera (``synthetic:views=2``) and its floor calibration.

The VR-TV paper's set-up (Fig. 2) has an overhead camera beside the robot's frontal one, for
the presenter's distance d from the robot. The studio's is a wide lens high up under the
lighting grid at the front of the set, looking steeply down on the presenter's area, fixed
(its own pose and intrinsics). Its floor calibration is what an operator would enter: four
floor marks (the corners of a 2 m x 2 m square on the set floor) and where they appear in its
image - here projected exactly. The robot's floor position is the camera rail's centre (the
robot base, ``ROBOT_FLOOR_XY_M``).

With ``synthetic:views=2,over_zoom=...`` the second camera has the studio's zoom lens
(:func:`engine.studio.zoom.studio_zoom_lens`, a known lens file): it renders through the lens
at the frame's encoders, its projection centre moving forward with the entrance pupil, and
its floor calibration is the marks clicked at the wide end (encoder 0) with the lens file - a
camera model (:mod:`engine.floor`); ``over_zoom=sweep`` zooms in to ``OVER_ZOOM_SWEEP_MAX_RAW``
(about 1.3x, the presenter's walk stays in view) and back over the shot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics, project
from engine.floor import FloorCalibration, calibrate_floor
from engine.geometry import R_from_pan_tilt_roll_deg, invert, make_T

F64 = NDArray[np.float64]

#: the robot base on the floor (world x, y): a large arm standing 2.6 m behind the camera rail's
#: centre, reaching forward (the paper's Fig. 2); the presenter walks about 5 m from it
ROBOT_FLOOR_XY_M = (0.0, -2.6)
#: the floor marks the operator measures (world x, y, metres)
FLOOR_MARKS_M = ((-1.0, 2.0), (1.0, 2.0), (1.0, 4.0), (-1.0, 4.0))
#: the zoom encoder at the tele end of the second camera's sweep (``over_zoom=sweep``)
OVER_ZOOM_SWEEP_MAX_RAW = 16384


@dataclass(frozen=True, slots=True)
class SecondCamera:
    """A fixed camera: position (m), pan/tilt (deg, the paths' convention), lens."""

    name: str = "overhead"
    position_m: tuple[float, float, float] = (0.0, 0.3, 3.45)
    pan_deg: float = 0.0
    tilt_deg: float = -45.0
    f_px_at_640: float = 330.0  # a wide lens: about 88 x 72 degrees

    def T_world_cam(self) -> F64:
        return make_T(R_from_pan_tilt_roll_deg(self.pan_deg, self.tilt_deg, 0.0),
                      self.position_m)

    def intrinsics(self, width: int, height: int) -> Intrinsics:
        f = self.f_px_at_640 * width / 640.0
        return Intrinsics(fx=f, fy=f, cx=(width - 1) / 2.0, cy=(height - 1) / 2.0,
                          width=width, height=height)

    def floor_calibration(self, width: int, height: int, zoom: bool = False
                          ) -> FloorCalibration:
        """The exact calibration from ``FLOOR_MARKS_M`` projected into this camera (``zoom``:
        through the zoom lens at its wide end, with the lens file: a camera model)."""
        marks = np.array([[x, y, 0.0, 1.0] for x, y in FLOOR_MARKS_M])
        if not zoom:
            p_cam = (invert(self.T_world_cam()) @ marks.T).T[:, :3]
            uv = project(self.intrinsics(width, height), p_cam)
            return calibrate_floor(uv, FLOOR_MARKS_M, ROBOT_FLOOR_XY_M, (width, height),
                                   self.f_px_at_640 * width / 640.0)
        from engine.studio.zoom import FOCUS_RAW, studio_zoom_lens

        lens = studio_zoom_lens(width, height)
        cam, T = self.zoom_camera(width, height, 0, FOCUS_RAW)
        uv = project(cam, (invert(T) @ marks.T).T[:, :3])
        return calibrate_floor(uv, FLOOR_MARKS_M, ROBOT_FLOOR_XY_M, (width, height),
                               cam.fx, lens=lens, encoders_raw=(0, FOCUS_RAW))

    def zoom_camera(self, width: int, height: int, zoom_raw: int, focus_raw: int
                    ) -> tuple[Intrinsics, F64]:
        """Intrinsics and pose ``T_world_cam`` through the zoom lens at the encoders: the
        projection centre (the entrance pupil) moves along the optical axis from where it is
        at the wide end (``position_m``)."""
        from engine.studio.zoom import studio_zoom_lens

        lens = studio_zoom_lens(width, height)
        shift = (lens.values_at(zoom_raw, focus_raw)["entrance_pupil_m"]
                 - lens.values_at(0, focus_raw)["entrance_pupil_m"])
        T = self.T_world_cam()
        T[:3, 3] += shift * T[:3, 2]
        return lens.intrinsics_at(zoom_raw, focus_raw), T


OVERHEAD = SecondCamera()
