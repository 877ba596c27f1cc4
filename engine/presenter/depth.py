"""Depth agreement of the presenter hypotheses (beyond the VR-TV paper; RGB-D sources only).

The paper's likelihood, eq. (5), is colour and motion: a second person in the same clothes
is as likely as the presenter, and a look-alike walking *behind* the presenter takes the
track as they pass (built-in studio, 0.5 m behind: 50-112 frames stolen over filter seeds).
A studio camera that also gives depth (the dense tracker's RGB-D input) separates them: the
presenter's body stays at a depth that changes by a few centimetres a frame, the other
person's is half a metre or more away.

Each hypothesis (x, y, h) is given the median depth of a 3 x 3 grid of pixels over the
body's middle (:data:`TORSO_GRID`: the box's central fifth in width, from a quarter of its
height above the centre down to the centre: chest and belly of a full-body box, the chest
of an upper-body one), and its weight is multiplied by::

    L_depth = f + (1 - f) exp(-0.5 ((z - z_ref) / sigma_z)^2),   f = FLOOR = 0.1

with ``z_ref`` the depth at the estimate of the last confident frames
(:class:`DepthReference`, an exponential average). The reference is learned only from an
estimate whose samples agree (:data:`MIXED_SPREAD`: a box over two people half a metre apart
has a median that is neither's) and moves no faster than a person walks
(:data:`MAX_SPEED_M_S`): without these two the box slid onto a look-alike passing behind
over a few frames, each frame's depth inside the gate, and the reference went with it
(built-in studio, behind, same clothes: 75 and 74 frames stolen for two of five filter
seeds; 0 with them). A hypothesis without enough valid depth there (holes, beyond the range,
off the image) is left as it is (L = 1), and so is every hypothesis while the reference is
unknown. After a loss the reference is kept for :data:`RESEED_FRAMES` frames (a presenter
covered by someone crossing in front is re-acquired at its own depth, not at the other
person's), and re-acquisition locks only on a state at the kept depth
(:meth:`DepthReference.agrees`: without it the search, after the box had slid onto the set
behind, locked on a look-alike walking 0.5 m behind the presenter and held it until the
reference restarted there, 65 frames stolen for three of five filter seeds at 320 x 240);
then forgotten, so that a presenter who comes back later at another depth is found by colour
as before.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

#: sample offsets over the body's middle: (fraction of the box width, fraction of its height)
#: from the box centre (x, y)
TORSO_GRID: tuple[tuple[float, float], ...] = tuple(
    (dx, dy) for dy in (-0.25, -0.15, -0.05) for dx in (-0.1, 0.0, 0.1))
#: fewest valid samples for a hypothesis' depth (else NaN: no opinion)
MIN_VALID = 3
#: a confident frame's depth further than this many std from the reference is not learned
GATE = 2.5
#: ... unless it stays so this many frames in a row (1 s at 30 Hz): the reference restarts
RESEED_FRAMES = 30
#: the fastest the presenter's depth is learned to change (m/s): a person walks at 1-1.5 m/s;
#: the reference follows no faster, so a box that slides onto someone behind the presenter
#: over a few frames (each frame's depth inside the gate) does not carry the reference with it
MAX_SPEED_M_S = 1.5
#: the estimate's samples must agree to be learned: their spread between the quartiles (m)
#: above this many std means the box straddles two depths (two people overlapping,
#: a shoulder against the set) and its median is neither's
MIXED_SPREAD = 1.0
#: the likelihood's floor: depth alone never vetoes a hypothesis whose colour is far better
#: (a lock taken on the wrong depth, e.g. re-acquired on the set, is not entrenched by it)
FLOOR = 0.1


def torso_depths(depth_m: NDArray[np.float32], xyh: F64, aspect: float) -> F64:
    """Median valid depth (m) over :data:`TORSO_GRID` of each hypothesis ``xyh`` (N, 3) ->
    (N,), NaN where fewer than :data:`MIN_VALID` samples are valid (0, negative, not finite
    or off the image)."""
    z = _samples(depth_m, xyh, aspect)
    n_valid = np.sum(np.isfinite(z), axis=1)
    out = np.full(len(z), np.nan)
    ok = n_valid >= MIN_VALID
    if np.any(ok):
        out[ok] = np.nanmedian(z[ok], axis=1)
    return out


def _samples(depth_m: NDArray[np.float32], xyh: F64, aspect: float) -> F64:
    """Depth (m) at the :data:`TORSO_GRID` points of each state (N, 3) -> (N, K), NaN where
    invalid or off the image."""
    H, W = depth_m.shape[:2]
    pts = np.asarray(xyh, dtype=np.float64).reshape(-1, 3)
    off = np.asarray(TORSO_GRID, dtype=np.float64)  # (K, 2)
    h = pts[:, 2:3]
    u = np.rint(pts[:, 0:1] + off[None, :, 0] * aspect * h)
    v = np.rint(pts[:, 1:2] + off[None, :, 1] * h)
    inside = (u >= 0) & (u < W) & (v >= 0) & (v < H) & np.isfinite(u) & np.isfinite(v)
    ui = np.where(inside, u, 0).astype(np.intp)
    vi = np.where(inside, v, 0).astype(np.intp)
    z = np.asarray(depth_m[vi, ui], dtype=np.float64)
    z[~inside | ~np.isfinite(z) | (z <= 0.0)] = np.nan
    return z


def estimate_depth(depth_m: NDArray[np.float32], xyh: F64, aspect: float
                   ) -> tuple[float, float]:
    """One state ``xyh`` (3,): its depth (m; as :func:`torso_depths`) and the spread (m)
    between the quartiles of its valid :data:`TORSO_GRID` samples, from one sampling; both NaN
    with fewer than :data:`MIN_VALID` valid samples."""
    z = _samples(depth_m, np.asarray(xyh, dtype=np.float64).reshape(1, 3), aspect)[0]
    z = np.sort(z[np.isfinite(z)])
    n = len(z)
    if n < MIN_VALID:
        return math.nan, math.nan
    spread = float(z[(3 * (n - 1)) // 4] - z[(n - 1) // 4])  # nearest-rank quartiles
    return float(np.median(z)), spread


def depth_likelihood(z: F64, z_ref: float, sigma_m: float) -> F64:
    """``FLOOR + (1 - FLOOR) exp(-0.5 ((z - z_ref) / sigma)^2)`` per hypothesis; 1 where
    ``z`` is NaN or the reference unknown or ``sigma`` <= 0 (off)."""
    z = np.asarray(z, dtype=np.float64)
    if not (sigma_m > 0.0 and math.isfinite(z_ref)):
        return np.ones(len(z))
    r = (z - z_ref) / sigma_m
    out = FLOOR + (1.0 - FLOOR) * np.exp(-0.5 * r * r)
    out[~np.isfinite(z)] = 1.0
    return out


class DepthReference:
    """The presenter's depth at the last confident estimates (exponential average).

    A depth that jumps by more than :data:`GATE` std from the reference is not learned: the
    estimate's body is covered (a person crossing in front, the desk) and the presenter is
    still behind it at the old depth; after :data:`RESEED_FRAMES` such frames in a row the
    reference starts again from the estimate (the presenter did move)."""

    def __init__(self, rate: float = 0.5) -> None:
        self.rate = float(rate)
        self.z_m = math.nan
        self.rejected = 0  # consecutive confident frames whose depth jumped

    def update(self, z: float, sigma_m: float, spread_m: float = 0.0,
               frame_rate_hz: float = 30.0) -> bool:
        """A confident frame's depth at the estimate ``z`` (NaN: no change) and the spread of
        its samples (:func:`estimate_depth`); False when not learned (gated or mixed). A learned
        step is at most :data:`MAX_SPEED_M_S` / ``frame_rate_hz``."""
        if not math.isfinite(z):
            return False
        if math.isfinite(self.z_m) and abs(z - self.z_m) > GATE * sigma_m:
            self.rejected += 1
            if self.rejected < RESEED_FRAMES:
                return False
            self.z_m = math.nan
        self.rejected = 0
        if not math.isfinite(self.z_m):
            self.z_m = z
            return True
        if spread_m > MIXED_SPREAD * sigma_m:
            return False
        max_step = MAX_SPEED_M_S / max(float(frame_rate_hz), 1.0)
        self.z_m += float(np.clip(self.rate * (z - self.z_m), -max_step, max_step))
        return True

    def agrees(self, z: float, sigma_m: float) -> bool:
        """``z`` lies within :data:`GATE` std of the reference (True without an opinion: ``z``
        NaN, the reference unknown or ``sigma_m`` <= 0). Re-acquisition asks it of the
        state it would lock on: a look-alike behind the presenter, or the set where the box
        slid, is not taken while the presenter's depth is still known."""
        if not (sigma_m > 0.0 and math.isfinite(z) and math.isfinite(self.z_m)):
            return True
        return abs(z - self.z_m) <= GATE * sigma_m

    def reset(self) -> None:
        """Forget it (a loss): no depth opinion until the next confident frame."""
        self.z_m = math.nan
        self.rejected = 0
