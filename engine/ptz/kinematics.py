"""Pan-tilt head geometry (Gaspar 2009 sec. 3.2).

The world-to-camera transform is the composition of five transformations,
``M_g_c = M_g_0 . 0_g_1 . 1_g_2 . 2_g_3 . 3_g_c`` (sec. 3.2): the offset from the world
origin to the head's rotation centre, pan (about world z), tilt (about the panned x axis),
roll (about the optical axis) and the offset from the rotation centre to the optical centre,
which turns with the head. The fixed mount angles (pan0, tilt0, roll) and the two offsets
are calibrated once; the motor angles (pan, tilt) change every frame and come from an
encoder or, as in the paper, from reference points of known world position
(:func:`estimate_pan_tilt`).

World frame: right-handed, z up (``engine.geometry.R_from_pan_tilt_roll_deg``); camera axes
are OpenCV's (x right, y down, z forward).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.errors import CalibrationError
from engine.geometry import R_from_pan_tilt_roll_deg, make_T, pan_tilt_roll_deg
from engine.ptz.dlt import DltDecomposition, project_P

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class PtzHead:
    """Calibrated head: intrinsics, mount angles, rotation centre and optical-centre offset."""

    K: F64
    rotation_centre_world_m: F64 = dataclasses.field(default_factory=lambda: np.zeros(3))
    optical_offset_cam_m: F64 = dataclasses.field(default_factory=lambda: np.zeros(3))
    pan0_deg: float = 0.0
    tilt0_deg: float = 0.0
    roll_deg: float = 0.0

    def R_world_cam(self, pan_deg: float, tilt_deg: float) -> F64:
        """Orientation at motor angles (pan, tilt): Rz(pan) Rx(tilt) Ry(roll) R_base."""
        return R_from_pan_tilt_roll_deg(
            self.pan0_deg + pan_deg, self.tilt0_deg + tilt_deg, self.roll_deg
        )

    def T_world_cam(self, pan_deg: float, tilt_deg: float) -> F64:
        """Camera pose: optical centre = rotation centre + R (offset in the turning head)."""
        R = self.R_world_cam(pan_deg, tilt_deg)
        c = np.asarray(self.rotation_centre_world_m) + R @ np.asarray(self.optical_offset_cam_m)
        return make_T(R, c)

    def P(self, pan_deg: float, tilt_deg: float) -> F64:
        """Projection matrix P = K [R^T | -R^T c] at motor angles (pan, tilt), eq. (1)."""
        T = self.T_world_cam(pan_deg, tilt_deg)
        R, c = T[:3, :3], T[:3, 3]
        return np.asarray(self.K) @ np.hstack([R.T, (-R.T @ c).reshape(3, 1)])

    def optical_centre_world(self, pan_deg: float, tilt_deg: float) -> F64:
        return self.T_world_cam(pan_deg, tilt_deg)[:3, 3]


def head_from_dlt(
    dec: DltDecomposition, optical_offset_cam_m: F64 | None = None,
    pan_deg: float = 0.0, tilt_deg: float = 0.0,
) -> PtzHead:
    """Head calibrated from a DLT taken at motor angles (pan, tilt) and a known offset.

    The DLT gives the optical centre and orientation at that pose; the mount angles are
    the orientation's pan/tilt/roll minus the motor angles and the rotation centre is the
    optical centre minus the turned offset.
    """
    off = np.zeros(3) if optical_offset_cam_m is None else np.asarray(optical_offset_cam_m, float)
    R_world_cam = dec.R_cam_world.T
    p, t, r = pan_tilt_roll_deg(R_world_cam)
    c = dec.camera_centre_world
    return PtzHead(
        K=dec.K,
        rotation_centre_world_m=c - R_world_cam @ off,
        optical_offset_cam_m=off,
        pan0_deg=p - pan_deg,
        tilt0_deg=t - tilt_deg,
        roll_deg=r,
    )


def estimate_pan_tilt(
    head: PtzHead,
    X_world: F64,
    uv: F64,
    init_pan_tilt_deg: tuple[float, float] = (0.0, 0.0),
    iterations: int = 20,
) -> tuple[float, float, float]:
    """Motor angles (pan, tilt) from >= 1 reference points of known world position.

    Gauss-Newton on the reprojection error with a numeric Jacobian (2 unknowns). Returns
    (pan_deg, tilt_deg, rms_px). This replaces the missing orientation sensor (sec. 3.2).
    """
    X = np.asarray(X_world, dtype=np.float64).reshape(-1, 3)
    m = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    if len(X) < 1 or len(X) != len(m):
        raise CalibrationError(f"pan/tilt estimation needs matching points, got {len(X)}/{len(m)}")
    x = np.asarray(init_pan_tilt_deg, dtype=np.float64)

    def resid(a: F64) -> F64:
        return (project_P(head.P(float(a[0]), float(a[1])), X) - m).ravel()

    eps = 1e-4
    for _ in range(iterations):
        r0 = resid(x)
        J = np.stack([(resid(x + eps * e) - r0) / eps for e in np.eye(2)], axis=1)
        step, *_ = np.linalg.lstsq(J, -r0, rcond=None)
        x = x + step
        if np.max(np.abs(step)) < 1e-7:
            break
    r = resid(x)
    return float(x[0]), float(x[1]), float(np.sqrt(np.mean(r**2)))
