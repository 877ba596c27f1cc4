"""The walking presenter: a script (where and how the presenter moves) and the body.

The body is a few capsules and spheres with distinct flat colours: skin head (with hair),
shirt (torso and arms), trousers (legs) and shoes; labels split it into head / torso / legs
for per-part ground-truth boxes. The presenter walks parallel to the back wall at ``y_m``
(2.4 m from the rail), swinging legs and arms. ``LOOKS`` are different people (colours of
skin, hair, clothes; height and build): look 0 is the default presenter (blue shirt, dark
trousers); a second person (``engine.studio.sim.StudioConfig.person2``) uses the same script
and body with another look and one label for the whole body.

Modes:
- ``walk``: back and forth between ``x_min_m`` and ``x_max_m`` at ``speed_mps`` (with ``dy_m``
  along a diagonal: ``y_m`` at ``x_min_m``, ``y_m + dy_m`` at ``x_max_m``, the apparent size
  changing); with ``enter_from_m`` the presenter first walks in from there (off the set).
- ``still``: standing exactly still at ``x_still_m`` facing the camera.
- ``leave``: standing at ``x_still_m`` facing the camera; at ``leave_frame`` walks out to
  ``x_out_m`` (outside the camera's view; to the right, or to the left when ``x_out_m`` is
  smaller than ``x_still_m``), waits, and at ``return_frame`` walks back to ``x_still_m`` and
  stands there facing the camera.

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


@dataclass(frozen=True, slots=True)
class Look:
    """One person's appearance: flat material names (``engine.studio.scene.FLAT_COLOURS``)
    and body proportions (1 = the default presenter, 1.8 m tall)."""

    name: str
    skin: str = "skin"
    hair: str = "hair"
    shirt: str = "shirt"
    trousers: str = "trousers"
    shoes: str = "shoes"
    height_scale: float = 1.0
    width_scale: float = 1.0


#: the people of the built-in studio (``presenter_look`` / ``person2_look`` options)
LOOKS: tuple[Look, ...] = (
    Look("blue shirt"),
    Look("red top, beige trousers", "skin_dark", "hair_black", "shirt_red", "trousers_beige",
         "shoes_brown", 1.06, 1.05),
    Look("green jumper, jeans", "skin", "hair_blond", "shirt_green", "trousers_jeans",
         "shoes", 0.93, 0.95),
    Look("yellow top, black trousers", "skin_olive", "hair_black", "shirt_yellow",
         "trousers_black", "shoes", 0.97, 1.12),
    Look("grey jacket, jeans", "skin", "hair_grey", "jacket_grey", "trousers_jeans",
         "shoes_brown", 1.03, 1.0),
    Look("white shirt, black trousers", "skin_olive", "hair", "shirt_white", "trousers_black",
         "shoes", 1.0, 0.92),
    Look("purple top, beige trousers", "skin_dark", "hair_black", "shirt_purple",
         "trousers_beige", "shoes_brown", 0.95, 1.0),
)
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
    look: int = 0  # index into LOOKS
    dy_m: float = 0.0  # walk mode: depth change from x_min to x_max (towards/away from camera)

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"presenter mode {self.mode!r} is not one of {MODES}")
        if not self.x_max_m > self.x_min_m:
            raise ValueError(f"presenter x range [{self.x_min_m}, {self.x_max_m}] is empty")
        if not self.speed_mps > 0:
            raise ValueError(f"presenter speed must be positive, got {self.speed_mps}")
        if not 0 <= self.look < len(LOOKS):
            raise ValueError(f"look {self.look} is not in 0..{len(LOOKS) - 1}")
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
            # along the line from (x_min, y) to (x_max, y + dy): dy 0 = parallel to the set
            span = math.hypot(self.x_max_m - self.x_min_m, self.dy_m)
            ux, uy = (self.x_max_m - self.x_min_m) / span, self.dy_m / span
            pos = s % (2.0 * span)
            if pos < span:
                a, heading = pos, math.atan2(uy, ux)
            else:
                a, heading = span - (pos - span), math.atan2(-uy, -ux)
            return PresenterState(self.x_min_m + a * ux, self.y_m + a * uy, heading,
                                  2.0 * math.pi * s / STRIDE_M, True)
        # leave: stand, walk out (to x_out_m), wait, walk back, stand
        v = self.speed_mps / self.fps  # metres per frame
        sgn = 1.0 if self.x_out_m >= self.x_still_m else -1.0
        out_dist = abs(self.x_out_m - self.x_still_m)
        away, back = (0.0, math.pi) if sgn > 0 else (math.pi, 0.0)
        if index < self.leave_frame:
            return PresenterState(self.x_still_m, self.y_m, facing_camera, 0.0, False)
        if index < self.return_frame:
            s = min(v * (index - self.leave_frame), out_dist)
            walking = s < out_dist
            return PresenterState(self.x_still_m + sgn * s, self.y_m, away,
                                  2.0 * math.pi * s / STRIDE_M, walking)
        s_r = min(v * (self.return_frame - self.leave_frame), out_dist)
        s = v * (index - self.return_frame)
        left = s_r - s  # distance still to walk back
        if left > 0:
            return PresenterState(self.x_still_m + sgn * left, self.y_m, back,
                                  2.0 * math.pi * s / STRIDE_M, True)
        return PresenterState(self.x_still_m, self.y_m, facing_camera, 0.0, False)


def body_prims(state: PresenterState, scene: StudioScene, look: Look | int = 0,
               label: int | None = None) -> tuple[Prims, dict[str, F64]]:
    """Primitives of the body and its 3D key points (``feet``, ``head``, ``pelvis``).

    ``look``: a :class:`Look` or an index into ``LOOKS``; ``label``: one label code for the
    whole body (a second person) instead of head / torso / legs.
    """
    lk = LOOKS[look] if isinstance(look, int) else look
    sh, sw = lk.height_scale, lk.width_scale
    h = state.heading_rad
    f = np.array([math.cos(h), math.sin(h), 0.0])  # forward
    lft = np.array([-math.sin(h), math.cos(h), 0.0])  # left
    up = np.array([0.0, 0.0, 1.0])
    base = np.array([state.x_m, state.y_m, 0.0])
    swing = math.radians(26.0) * math.sin(state.phase_rad) if state.walking else 0.0
    bob = 0.012 * math.cos(2.0 * state.phase_rad) if state.walking else 0.0
    m = scene.flat_mat
    lab_head, lab_torso, lab_legs = (LABEL_HEAD, LABEL_TORSO, LABEL_LEGS) if label is None \
        else (label, label, label)
    caps: list[tuple[F64, F64, float, int, int]] = []
    sphs: list[tuple[F64, float, int, int]] = []
    hip_z = (0.92 + bob) * sh
    leg_len = 0.84 * sh
    for side, sgn in ((1.0, 1.0), (-1.0, -1.0)):
        a = sgn * swing
        hip = base + side * 0.095 * sw * lft + hip_z * up
        ankle = hip + leg_len * (math.sin(a) * f - math.cos(a) * up)
        caps.append((hip, ankle, 0.075 * sw, m[lk.trousers], lab_legs))
        caps.append((ankle, ankle + 0.14 * sh * f, 0.05, m[lk.shoes], lab_legs))
    torso_lo = base + (1.06 + bob) * sh * up
    torso_hi = base + (1.38 + bob) * sh * up
    caps.append((torso_lo, torso_hi, 0.165 * sw, m[lk.shirt], lab_torso))
    for side, sgn in ((1.0, -1.0), (-1.0, 1.0)):
        b = sgn * 0.8 * swing
        shoulder = base + side * 0.225 * sw * lft + (1.44 + bob) * sh * up
        hand = shoulder + 0.6 * sh * (math.sin(b) * f - math.cos(b) * up) + side * 0.03 * lft
        caps.append((shoulder, hand, 0.05 * sw, m[lk.shirt], lab_torso))
    neck_lo = base + (1.5 + bob) * sh * up
    head_c = base + (1.68 + bob) * sh * up
    caps.append((neck_lo, neck_lo + 0.1 * sh * up, 0.045 * sw, m[lk.skin], lab_head))
    sphs.append((head_c, 0.105, m[lk.skin], lab_head))
    sphs.append((head_c - 0.03 * f + 0.025 * up, 0.104, m[lk.hair], lab_head))

    n = len(caps) + len(sphs)
    ptype = np.empty(n, np.int32)
    geom = np.zeros((n, 9))
    mat = np.zeros((n, 6), np.int32)
    labels = np.empty(n, np.uint8)
    corners = np.empty((n, 8, 3))
    for i, (a_, b_, r, mi, lab) in enumerate(caps):
        ptype[i] = CAP
        geom[i, :7] = (*a_, *b_, r)
        mat[i, 0] = mi
        labels[i] = lab
        corners[i] = _aabb(np.minimum(a_, b_) - r, np.maximum(a_, b_) + r)
    for j, (c, r, mi, lab) in enumerate(sphs, start=len(caps)):
        ptype[j] = SPH
        geom[j, :4] = (*c, r)
        mat[j, 0] = mi
        labels[j] = lab
        corners[j] = _aabb(c - r, c + r)
    keypoints = {"feet": base, "head": head_c, "pelvis": base + hip_z * up}
    return Prims(ptype, geom, mat, labels, corners), keypoints


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
