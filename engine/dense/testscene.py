"""A tiny analytic RGB-D scene (textured box room + optional occluding quads) for tests and
as a fallback scene of the dense benchmark. Ray-cast per pixel with the camera's distortion,
so rendered images follow eq. (2)-(4) exactly. World axes: x right, y down, z forward.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics, pixels_to_normalized
from engine.frames import Frame

F64 = NDArray[np.float64]

# (normal, offset): points X with n.X = d; the room is the inside of these planes.
_PLANES: tuple[tuple[tuple[float, float, float], float], ...] = (
    ((0.0, 0.0, 1.0), 3.5),  # back wall
    ((0.0, 1.0, 0.0), 1.3),  # floor
    ((0.0, -1.0, 0.0), 1.6),  # ceiling
    ((1.0, 0.0, 0.0), 2.4),  # right wall
    ((-1.0, 0.0, 0.0), 2.4),  # left wall
    ((0.0, 0.0, -1.0), 2.0),  # wall behind
)


@dataclass(frozen=True)
class Quad:
    """An axis-aligned rectangle facing the camera (z = const) drawn in front of the room."""

    x0: float
    x1: float
    y0: float
    y1: float
    z: float
    shade: float = 40.0


def _noise_grid(seed: int) -> F64:
    return np.random.default_rng(seed).uniform(0.0, 1.0, (64, 64))


def _value_noise(grid: F64, a: F64, b: F64) -> F64:
    n = grid.shape[0]
    a0 = np.floor(a)
    b0 = np.floor(b)
    fa = a - a0
    fb = b - b0
    # smoothstep keeps the texture C1 so that image gradients are well defined
    fa = fa * fa * (3 - 2 * fa)
    fb = fb * fb * (3 - 2 * fb)
    i0 = a0.astype(np.int64) % n
    j0 = b0.astype(np.int64) % n
    i1 = (i0 + 1) % n
    j1 = (j0 + 1) % n
    v: F64 = (1 - fb) * ((1 - fa) * grid[j0, i0] + fa * grid[j0, i1]) + fb * (
        (1 - fa) * grid[j1, i0] + fa * grid[j1, i1]
    )
    return v


class PlaneScene:
    """Renders grey + depth frames of the textured room from any camera pose."""

    def __init__(self, intrinsics: Intrinsics, seed: int = 0, room_scale: float = 1.0) -> None:
        self.intrinsics = intrinsics
        self.room_scale = room_scale
        self._g1 = _noise_grid(seed)
        self._g2 = _noise_grid(seed + 1)
        h, w = intrinsics.height, intrinsics.width
        u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        xy = pixels_to_normalized(intrinsics, np.stack([u.ravel(), v.ravel()], axis=1))
        self._rays = np.stack([xy[:, 0], xy[:, 1], np.ones(xy.shape[0])], axis=1)

    def _texture(self, a: F64, b: F64) -> F64:
        return 30.0 + 160.0 * _value_noise(self._g1, a * 5.0, b * 5.0) + 60.0 * _value_noise(
            self._g2, a * 17.0, b * 17.0
        )

    def render(
        self, T_world_cam: F64, quads: tuple[Quad, ...] = ()
    ) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
        """(grey uint8 (H, W), depth float32 metres along the optical axis)."""
        R = T_world_cam[:3, :3]
        o = T_world_cam[:3, 3]
        d = self._rays @ R.T  # world directions with camera z = 1
        best = np.full(d.shape[0], np.inf)
        inten = np.zeros(d.shape[0])
        for k, (nrm, off_unit) in enumerate(_PLANES):
            nv = np.asarray(nrm)
            off = off_unit * self.room_scale
            den = d @ nv
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (off - o @ nv) / den
            hit = (t > 1e-6) & (t < best)
            if not np.any(hit):
                continue
            X = o + d[hit] * t[hit, None]
            # in-plane coordinates: the two axes not along the normal
            axes = [i for i in range(3) if abs(nv[i]) < 0.5]
            inten[hit] = self._texture(X[:, axes[0]] + 7.0 * k, X[:, axes[1]])
            best[hit] = t[hit]
        for q in quads:
            # the quad plane z = q.z
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (q.z - o[2]) / d[:, 2]
            X = o + d * t[:, None]
            hit = (t > 1e-6) & (t < best) & (X[:, 0] > q.x0) & (X[:, 0] < q.x1)
            hit &= (X[:, 1] > q.y0) & (X[:, 1] < q.y1)
            inten[hit] = q.shade + 0.5 * self._texture(X[hit, 0] * 2.0, X[hit, 1] * 2.0)
            best[hit] = t[hit]
        h, w = self.intrinsics.height, self.intrinsics.width
        depth = np.where(np.isfinite(best), best, 0.0).reshape(h, w).astype(np.float32)
        gray = np.clip(inten, 0, 255).reshape(h, w).round().astype(np.uint8)
        return gray, depth

    def frame(
        self, index: int, T_world_cam: F64, quads: tuple[Quad, ...] = (), fps: float = 30.0
    ) -> Frame:
        gray, depth = self.render(T_world_cam, quads)
        bgr = np.repeat(gray[:, :, None], 3, axis=2)
        return Frame(
            index=index,
            timestamp_s=index / fps,
            color_bgr=bgr,
            intrinsics=self.intrinsics,
            depth_m=depth,
            gt_T_world_cam=np.array(T_world_cam, dtype=np.float64),
        )


def small_intrinsics(distorted: bool = True) -> Intrinsics:
    """320x240 camera with mild Caltech distortion for fast unit tests."""
    dist = (0.05, -0.08, 0.001, -0.001, 0.02) if distorted else (0.0,) * 5
    return Intrinsics(260.0, 260.0, 159.5, 119.5, 320, 240, dist, 5000.0)
