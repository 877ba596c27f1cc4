"""The walking presenter: a script (where and how the presenter moves) and the body.

The body is a few capsules and spheres with distinct flat colours: skin head (with dark
hair), blue shirt (torso and arms), dark trousers (legs) and black shoes; labels split it into
head / torso / legs for per-part ground-truth boxes. The presenter walks parallel to the back
wall at ``y_m`` (2.4 m from the rail), swinging legs and arms.

Modes:
- ``walk``: back and forth between ``x_min_m`` and ``x_max_m`` at ``speed_mps``; with
  ``enter_from_m`` the presenter first walks in from there (off the set).
- ``still``: standing exactly still at ``x_still_m`` facing the camera.
- ``leave``: standing at ``x_still_m`` facing the camera; at ``leave_frame`` walks out to the
  right to ``x_out_m`` (outside the camera's view), waits, and at ``return_frame`` walks
  back to ``x_still_m`` and stands there facing the camera.

Before ``start_frame`` the presenter is not in the studio.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.studio.render import Prims
from engine.studio.scene import CAP, LABEL_HEAD, LABEL_LEGS, LABEL_TORSO, SPH, StudioScene

F64 = NDArray[np.float64]

MODES = ("walk", "still", "leave")
STRIDE_M = 1.4  # distance of one full gait cycle (two steps)
X_OUT_M = 4.6  # where the presenter waits in ``leave`` mode (outside every path's view)


@dataclass(frozen=True, slots=True)
class PresenterState:
    """Where the presenter is: floor position, heading (rad, 0 = +x) and gait phase (rad)."""

    x_m: float
    y_m: float
    heading_rad: float
    phase_rad: float
    walking: bool


@dataclass(frozen=True, slots=True)
class PresenterScript:
    mode: str = "walk"
    fps: float = 30.0
    start_frame: int = 0
    speed_mps: float = 0.9
    x_min_m: float = -2.6
    x_max_m: float = 2.6
    x_still_m: float = 0.0
    y_m: float = 2.4
    leave_frame: int = 100
    return_frame: int = 200
    x_out_m: float = X_OUT_M
    enter_from_m: float | None = None  # walk mode: walk in from this x before the range

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"presenter mode {self.mode!r} is not one of {MODES}")
        if not self.x_max_m > self.x_min_m:
            raise ValueError(f"presenter x range [{self.x_min_m}, {self.x_max_m}] is empty")
        if not self.speed_mps > 0:
            raise ValueError(f"presenter speed must be positive, got {self.speed_mps}")
        if self.mode == "leave" and not self.return_frame > self.leave_frame:
            raise ValueError(
                f"presenter return frame {self.return_frame} must follow leave frame "
                f"{self.leave_frame}"
            )

    def state(self, index: int) -> PresenterState | None:
        """State at frame ``index``; None before ``start_frame``."""
        if index < self.start_frame:
            return None
        facing_camera = -0.5 * math.pi
        if self.mode == "still":
            return PresenterState(self.x_still_m, self.y_m, facing_camera, 0.0, False)
        if self.mode == "walk":
            s = self.speed_mps * (index - self.start_frame) / self.fps
            if self.enter_from_m is not None and self.enter_from_m < self.x_min_m:
                # entering the set mid-sequence: walk in from off-set first
                x = self.enter_from_m + s
                if x < self.x_min_m:
                    return PresenterState(x, self.y_m, 0.0, 2.0 * math.pi * s / STRIDE_M, True)
                s -= self.x_min_m - self.enter_from_m
            span = self.x_max_m - self.x_min_m
            pos = s % (2.0 * span)
            if pos < span:
                x, heading = self.x_min_m + pos, 0.0
            else:
                x, heading = self.x_max_m - (pos - span), math.pi
            return PresenterState(x, self.y_m, heading, 2.0 * math.pi * s / STRIDE_M, True)
        # leave: stand, walk out to the right (to x_out_m), wait, walk back, stand
        v = self.speed_mps / self.fps  # metres per frame
        if index < self.leave_frame:
            return PresenterState(self.x_still_m, self.y_m, facing_camera, 0.0, False)
        if index < self.return_frame:
            s = v * (index - self.leave_frame)
            x = min(self.x_still_m + s, self.x_out_m)
            walking = x < self.x_out_m
            return PresenterState(x, self.y_m, 0.0, 2.0 * math.pi * s / STRIDE_M, walking)
        x_r = min(self.x_still_m + v * (self.return_frame - self.leave_frame), self.x_out_m)
        s = v * (index - self.return_frame)
        x = max(x_r - s, self.x_still_m)
        if x > self.x_still_m:
            return PresenterState(x, self.y_m, math.pi, 2.0 * math.pi * s / STRIDE_M, True)
        return PresenterState(self.x_still_m, self.y_m, facing_camera, 0.0, False)


def body_prims(state: PresenterState, scene: StudioScene) -> tuple[Prims, dict[str, F64]]:
    """Primitives of the body and its 3D key points (``feet``, ``head``, ``pelvis``)."""
    h = state.heading_rad
    f = np.array([math.cos(h), math.sin(h), 0.0])  # forward
    lft = np.array([-math.sin(h), math.cos(h), 0.0])  # left
    up = np.array([0.0, 0.0, 1.0])
    base = np.array([state.x_m, state.y_m, 0.0])
    swing = math.radians(26.0) * math.sin(state.phase_rad) if state.walking else 0.0
    bob = 0.012 * math.cos(2.0 * state.phase_rad) if state.walking else 0.0
    m = scene.flat_mat
    caps: list[tuple[F64, F64, float, int, int]] = []
    sphs: list[tuple[F64, float, int, int]] = []
    hip_z = 0.92 + bob
    leg_len = 0.84
    for side, sgn in ((1.0, 1.0), (-1.0, -1.0)):
        a = sgn * swing
        hip = base + side * 0.095 * lft + hip_z * up
        ankle = hip + leg_len * (math.sin(a) * f - math.cos(a) * up)
        caps.append((hip, ankle, 0.075, m["trousers"], LABEL_LEGS))
        caps.append((ankle, ankle + 0.14 * f, 0.05, m["shoes"], LABEL_LEGS))
    torso_lo = base + (1.06 + bob) * up
    torso_hi = base + (1.38 + bob) * up
    caps.append((torso_lo, torso_hi, 0.165, m["shirt"], LABEL_TORSO))
    for side, sgn in ((1.0, -1.0), (-1.0, 1.0)):
        b = sgn * 0.8 * swing
        shoulder = base + side * 0.225 * lft + (1.44 + bob) * up
        hand = shoulder + 0.6 * (math.sin(b) * f - math.cos(b) * up) + side * 0.03 * lft
        caps.append((shoulder, hand, 0.05, m["shirt"], LABEL_TORSO))
    neck_lo = base + (1.5 + bob) * up
    head_c = base + (1.68 + bob) * up
    caps.append((neck_lo, neck_lo + 0.1 * up, 0.045, m["skin"], LABEL_HEAD))
    sphs.append((head_c, 0.105, m["skin"], LABEL_HEAD))
    sphs.append((head_c - 0.03 * f + 0.025 * up, 0.104, m["hair"], LABEL_HEAD))

    n = len(caps) + len(sphs)
    ptype = np.empty(n, np.int32)
    geom = np.zeros((n, 9))
    mat = np.zeros((n, 6), np.int32)
    label = np.empty(n, np.uint8)
    corners = np.empty((n, 8, 3))
    for i, (a_, b_, r, mi, lab) in enumerate(caps):
        ptype[i] = CAP
        geom[i, :7] = (*a_, *b_, r)
        mat[i, 0] = mi
        label[i] = lab
        corners[i] = _aabb(np.minimum(a_, b_) - r, np.maximum(a_, b_) + r)
    for j, (c, r, mi, lab) in enumerate(sphs, start=len(caps)):
        ptype[j] = SPH
        geom[j, :4] = (*c, r)
        mat[j, 0] = mi
        label[j] = lab
        corners[j] = _aabb(c - r, c + r)
    keypoints = {"feet": base, "head": head_c, "pelvis": base + hip_z * up}
    return Prims(ptype, geom, mat, label, corners), keypoints


def _aabb(lo: F64, hi: F64) -> F64:
    return np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )


def concat_prims(*parts: Prims) -> Prims:
    if not parts:
        return Prims.empty()
    return Prims(
        np.concatenate([p.ptype for p in parts]),
        np.concatenate([p.geom for p in parts]),
        np.concatenate([p.mat for p in parts]),
        np.concatenate([p.label for p in parts]),
        np.concatenate([p.corners for p in parts]),
    )
