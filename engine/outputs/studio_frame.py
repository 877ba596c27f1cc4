"""The studio coordinate frame and the conversion of poses to each protocol's conventions.

The tracker reports ``T_world_cam`` (OpenCV camera axes: x right, y down, z forward) in its
own world. The operator defines the *studio* frame: an origin on the floor and axes, either
identity (the tracker world is already z-up with the floor at z = 0) or from three floor
points (origin, a point along +X, a point on the +Y side). Then

    T_studio_cam = inv(T_world_studio) @ T_world_cam

and the pose is expressed as a :class:`StudioPose` in the OpenTrackIO convention, from which
the FreeD fields follow:

=============  ====================================  ====================================
quantity       OpenTrackIO 1.0 (transforms[-1])      FreeD D1 (Vinten App. B)
=============  ====================================  ====================================
axes           right-handed, Z up, pan=tilt=0 looks  right-handed, Z up, pan=tilt=0 looks
               along +Y, X = camera right            along +Y
translation    x, y, z in metres                     X, Y, Z in mm (x1000), 1/64 mm units
pan            about +Z, positive = LEFT (CCW seen   positive = RIGHT (clockwise seen
               from above), degrees                  from above): ``pan_freed = -pan``
tilt           about camera X, positive = up         positive = up (same)
roll           about the optical axis, positive =    positive = clockwise seen from
               clockwise seen from behind            behind (same)
order          intrinsic Z-X-Y: R = Rz(pan) Rx(tilt) Ry(roll) applied to the zero-pose camera
=============  ====================================  ====================================

``R_studio_cam = Rz(pan) @ Rx(tilt) @ Ry(roll) @ R_base`` with ``R_base`` mapping OpenCV
camera axes to (right, forward, up); this is exactly :func:`engine.geometry.pan_tilt_roll_deg`.
Near tilt = +-90 degrees pan and roll are not separable (gimbal lock); outputs then carry the
decomposition geometry returns (roll absorbs the remainder).

Where the studio origin comes from (all give ``T_world_studio``, saved in the project):

=========================  ====================================================================
three floor points         origin, a point on +X, a point on the +Y side (:meth:`StudioFrame.
                           from_floor_points`); Z is the floor normal, up
the DLT calibration        the calibration points' own frame becomes the studio frame
                           (:meth:`StudioFrame.from_dlt`): the points were measured in studio
                           coordinates (x right, y away from the camera, z up, metres)
a clicked 3D-view point    the origin moves to the point, the axes stay
                           (:meth:`StudioFrame.with_origin_at`)
=========================  ====================================================================

The *nodal offset* (:class:`CameraOffset`) is the rigid transform from the tracked point to
the camera's nodal point (entrance pupil at the calibration zoom), ``T_tracked_nodal``, in the
tracked camera's OpenCV axes (x right, y down, z forward, metres; rotation as pan/tilt/roll
degrees about those axes). It is applied before every output, before the studio frame::

    T_world_nodal = T_world_tracked @ T_tracked_nodal
    T_studio_nodal = inv(T_world_studio) @ T_world_nodal

A zoom-dependent entrance pupil (lens file) is *not* added to the pose: OpenTrackIO carries it
as ``lens.entrancePupilOffset`` for the render engine to apply; FreeD has no field for it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.geometry import R_from_pan_tilt_roll_deg, invert, make_T, pan_tilt_roll_deg
from engine.outputs import OutputError

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class StudioPose:
    """Camera pose in the studio frame, OpenTrackIO conventions (metres, degrees)."""

    x_m: float
    y_m: float
    z_m: float
    pan_deg: float
    tilt_deg: float
    roll_deg: float

    def as_array(self) -> F64:
        return np.array(
            [self.x_m, self.y_m, self.z_m, self.pan_deg, self.tilt_deg, self.roll_deg]
        )

    @staticmethod
    def from_array(v: Sequence[float] | F64) -> StudioPose:
        return StudioPose(*(float(x) for x in v[:6]))

    @property
    def freed_pan_deg(self) -> float:
        """FreeD pan: positive to the right, wrapped to [-180, 180)."""
        return wrap_deg(-self.pan_deg)

    def T_studio_cam(self) -> F64:
        R = R_from_pan_tilt_roll_deg(self.pan_deg, self.tilt_deg, self.roll_deg)
        return make_T(R, np.array([self.x_m, self.y_m, self.z_m]))


def wrap_deg(a: float) -> float:
    """Angle wrapped to [-180, 180)."""
    return (a + 180.0) % 360.0 - 180.0


@dataclass(frozen=True, slots=True)
class StudioFrame:
    """Origin and axes of the studio in the tracker's world: ``T_world_studio``."""

    T_world_studio: tuple[tuple[float, ...], ...] = field(
        default=((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0),
                 (0.0, 0.0, 0.0, 1.0))
    )

    def __post_init__(self) -> None:
        T = np.asarray(self.T_world_studio, dtype=np.float64)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise OutputError(f"studio frame must be a finite 4x4 transform, got {T.shape}")
        R = T[:3, :3]
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
            raise OutputError("studio frame rotation is not a proper rotation matrix")

    @staticmethod
    def identity() -> StudioFrame:
        return StudioFrame()

    @staticmethod
    def from_matrix(T_world_studio: F64) -> StudioFrame:
        T = np.asarray(T_world_studio, dtype=np.float64)
        return StudioFrame(tuple(tuple(float(v) for v in row) for row in T))

    @staticmethod
    def from_floor_points(p_origin: F64, p_on_x: F64, p_on_y_side: F64) -> StudioFrame:
        """Studio frame from three floor points (world coordinates, metres).

        X points from ``p_origin`` to ``p_on_x``; Z is the floor normal on the side that makes
        ``p_on_y_side`` have positive Y (right-handed); Y = Z x X.
        """
        o, a, b = (np.asarray(p, dtype=np.float64).reshape(3) for p in
                   (p_origin, p_on_x, p_on_y_side))
        ex = a - o
        nx = float(np.linalg.norm(ex))
        if not math.isfinite(nx) or nx < 1e-6:
            raise OutputError("studio frame: origin and X point coincide")
        ex /= nx
        ez = np.cross(ex, b - o)
        nz = float(np.linalg.norm(ez))
        if not math.isfinite(nz) or nz < 1e-6:
            raise OutputError("studio frame: the three floor points are collinear")
        ez /= nz
        ey = np.cross(ez, ex)
        return StudioFrame.from_matrix(make_T(np.stack([ex, ey, ez], axis=1), o))

    @property
    def matrix(self) -> F64:
        return np.asarray(self.T_world_studio, dtype=np.float64)

    def T_studio_cam(self, T_world_cam: F64) -> F64:
        return invert(self.matrix) @ np.asarray(T_world_cam, dtype=np.float64)

    def studio_pose(self, T_world_cam: F64) -> StudioPose:
        """Pose in OpenTrackIO conventions (see the module table)."""
        T = self.T_studio_cam(T_world_cam)
        pan, tilt, roll = pan_tilt_roll_deg(T[:3, :3])
        return StudioPose(float(T[0, 3]), float(T[1, 3]), float(T[2, 3]), pan, tilt, roll)

    @staticmethod
    def from_dlt(T_world_cam: F64, R_cam_dlt: F64, t_cam_dlt: F64) -> StudioFrame:
        """The DLT's world (its calibration points' frame) as the studio frame.

        ``R_cam_dlt``, ``t_cam_dlt`` map DLT-world points into the camera
        (:class:`engine.ptz.dlt.DltDecomposition`); ``T_world_cam`` is the tracker's pose of
        that camera when the DLT image was taken (identity when the tracker's world is the
        DLT's, as for the pan-tilt tracker)."""
        R = np.asarray(R_cam_dlt, dtype=np.float64)
        t = np.asarray(t_cam_dlt, dtype=np.float64).reshape(3)
        if R.shape != (3, 3) or not np.all(np.isfinite(R)) or not np.all(np.isfinite(t)):
            raise OutputError("studio frame from DLT: rotation must be a finite 3x3 matrix")
        U, _, Vt = np.linalg.svd(R)
        R = U @ Vt
        if np.linalg.det(R) < 0:
            raise OutputError("studio frame from DLT: the rotation is a reflection")
        T_cam_dlt = make_T(R, t)
        return StudioFrame.from_matrix(np.asarray(T_world_cam, dtype=np.float64) @ T_cam_dlt)

    def with_origin_at(self, p_world: F64) -> StudioFrame:
        """The same axes with the origin moved to a world point (a clicked 3D-view point)."""
        p = np.asarray(p_world, dtype=np.float64).reshape(-1)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise OutputError(f"studio origin {p_world!r} is not a finite 3D point")
        T = self.matrix.copy()
        T[:3, 3] = p
        return StudioFrame.from_matrix(T)

    def to_json_dict(self) -> dict[str, Any]:
        return {"T_world_studio": [list(r) for r in self.T_world_studio]}

    @staticmethod
    def from_json_dict(d: dict[str, Any]) -> StudioFrame:
        try:
            return StudioFrame.from_matrix(np.asarray(d["T_world_studio"], dtype=np.float64))
        except (KeyError, TypeError, ValueError) as exc:
            raise OutputError(f"studio frame JSON is malformed ({exc})") from None


@dataclass(frozen=True, slots=True)
class CameraOffset:
    """Tracked point -> camera nodal point, ``T_tracked_nodal`` (see the module docstring).

    Translation in metres along the tracked camera's axes (x right, y down, z forward);
    rotation in degrees with the output convention (pan positive left, tilt positive up,
    roll positive clockwise seen from behind) relative to the tracked camera's own axes.
    """

    x_m: float = 0.0
    y_m: float = 0.0
    z_m: float = 0.0
    pan_deg: float = 0.0
    tilt_deg: float = 0.0
    roll_deg: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "z_m", "pan_deg", "tilt_deg", "roll_deg"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise OutputError(f"nodal offset {name}: {v!r} is not a finite number")
        if max(abs(self.x_m), abs(self.y_m), abs(self.z_m)) > 10.0:
            raise OutputError("nodal offset: a translation over 10 m is not a camera offset")

    @property
    def is_identity(self) -> bool:
        return not any((self.x_m, self.y_m, self.z_m, self.pan_deg, self.tilt_deg,
                        self.roll_deg))

    @property
    def T_tracked_nodal(self) -> F64:
        """4x4 in the tracked camera's OpenCV axes."""
        # pan/tilt/roll as in the studio convention, expressed in camera axes: R_base maps
        # OpenCV axes to (right, forward, up); the offset's rotation is R_base^T R R_base
        base = R_from_pan_tilt_roll_deg(0.0, 0.0, 0.0)
        R = base.T @ R_from_pan_tilt_roll_deg(self.pan_deg, self.tilt_deg, self.roll_deg)
        return make_T(R, np.array([self.x_m, self.y_m, self.z_m]))

    def apply(self, T_world_tracked: F64) -> F64:
        if self.is_identity:
            return np.asarray(T_world_tracked, dtype=np.float64)
        return np.asarray(T_world_tracked, dtype=np.float64) @ self.T_tracked_nodal

    def to_json_dict(self) -> dict[str, Any]:
        return {"x_m": self.x_m, "y_m": self.y_m, "z_m": self.z_m, "pan_deg": self.pan_deg,
                "tilt_deg": self.tilt_deg, "roll_deg": self.roll_deg}

    @staticmethod
    def from_json_dict(d: Any, where: str = "nodal offset") -> CameraOffset:
        if not isinstance(d, dict):
            raise OutputError(f"{where}: expected an object, got {type(d).__name__}")
        known = ("x_m", "y_m", "z_m", "pan_deg", "tilt_deg", "roll_deg")
        unknown = sorted(set(d) - set(known))
        if unknown:
            raise OutputError(f"{where}: unknown field {unknown[0]!r} (fields: "
                              f"{', '.join(known)})")
        kw = {}
        for k in known:
            v = d.get(k, 0.0)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise OutputError(f"{where}.{k}: {v!r} is not a finite number")
            kw[k] = float(v)
        try:
            return CameraOffset(**kw)
        except OutputError as exc:
            raise OutputError(f"{where}: {str(exc).removeprefix('nodal offset').strip(': ')}"
                              ) from None
