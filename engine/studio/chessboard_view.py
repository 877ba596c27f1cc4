"""Exact images of a planar chessboard through a lens (calibration views with ground truth).

Each pixel is supersampled (``ss`` x ``ss`` rays); a ray goes through the sub-pixel's
*undistorted* normalised coordinates (:func:`engine.camera.pixels_to_normalized`, so the
image is what the distorting lens records) and meets the board plane; the board has
``cols`` x ``rows`` inner corners on ``square_m`` squares, one white square of margin and a
grey surround. Used by the lens-file workflow's tests and ``bench lens`` (one zoom sample =
a handful of views at one encoder value) and by the pan-tilt calibration views.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8
from engine.camera import Intrinsics, pixels_to_normalized, project
from engine.geometry import make_T, so3_exp

F64 = NDArray[np.float64]


def board_size_m(pattern_cols_rows: tuple[int, int], square_m: float) -> tuple[float, float]:
    cols, rows = pattern_cols_rows
    return (cols + 1) * square_m, (rows + 1) * square_m


def render_chessboard(cam: Intrinsics, T_cam_board: F64, pattern_cols_rows: tuple[int, int]
                      = (9, 6), square_m: float = 0.05, ss: int = 2,
                      background: int = 110, rays: F64 | None = None) -> NDArray[np.uint8]:
    """Grey image of the board (board frame: inner corner (0, 0) at the origin, x along the
    columns, y along the rows, z into the board) seen by ``cam`` at ``T_cam_board``;
    ``rays`` (from :func:`pinhole_rays`) replaces ``cam``'s lens model (another distortion
    model, e.g. the pan-tilt camera's inverse radial one)."""
    cols, rows = pattern_cols_rows
    w, h = cam.width, cam.height
    d = _rays(cam, ss) if rays is None else rays
    T = np.asarray(T_cam_board, dtype=np.float64)
    R, t = T[:3, :3], T[:3, 3]
    n = R[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (n @ t) / (d @ n)
    p_cam = d * s[:, None]
    p_b = (p_cam - t) @ R  # R^T (p - t)
    x, y = p_b[:, 0] / square_m, p_b[:, 1] / square_m
    hit = np.isfinite(s) & (s > 0)
    in_board = hit & (x >= -1) & (x < cols) & (y >= -1) & (y < rows)
    in_margin = hit & (x >= -2) & (x < cols + 1) & (y >= -2) & (y < rows + 1)
    val = np.full(len(x), float(background))
    val[in_margin] = 235.0
    black = ((np.floor(x) + np.floor(y)) % 2 == 0) & in_board
    val[black] = 20.0
    img = val.reshape(h, ss, w, ss).mean(axis=(1, 3))
    return u8(np.clip(img + 0.5, 0, 255).astype(np.uint8))


@lru_cache(maxsize=4)
def _rays(cam: Intrinsics, ss: int) -> F64:
    """Undistorted ray directions (x, y, 1) of every sub-pixel, row-major (shared by views)."""
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    us = (np.arange(cam.width)[:, None] + sub[None, :]).ravel()
    vs = (np.arange(cam.height)[:, None] + sub[None, :]).ravel()
    U, V = np.meshgrid(us, vs)
    xy = pixels_to_normalized(cam, np.stack([U.ravel(), V.ravel()], axis=1))
    d = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)
    d.flags.writeable = False
    return d


def pinhole_rays(K: F64, width: int, height: int,
                 undistort_px: Callable[[F64], F64] | None, ss: int = 2) -> F64:
    """Ray directions of every sub-pixel through ``K`` after ``undistort_px`` (distorted
    pixels -> ideal pixels), for :func:`render_chessboard`."""
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    us = (np.arange(width)[:, None] + sub[None, :]).ravel()
    vs = (np.arange(height)[:, None] + sub[None, :]).ravel()
    U, V = np.meshgrid(us, vs)
    uv = np.stack([U.ravel(), V.ravel()], axis=1)
    if undistort_px is not None:
        uv = undistort_px(uv)
    K = np.asarray(K, dtype=np.float64)
    x = (uv[:, 0] - K[0, 2]) / K[0, 0]
    y = (uv[:, 1] - K[1, 2]) / K[1, 1]
    return np.stack([x, y, np.ones_like(x)], axis=1)


def board_corners_px(cam: Intrinsics, T_cam_board: F64, pattern_cols_rows: tuple[int, int],
                     square_m: float, margin_squares: float = 2.0) -> F64:
    """Pixels of the board's outer corners (with the white margin) - for framing checks."""
    cols, rows = pattern_cols_rows
    m = margin_squares
    pts = np.array([[-m, -m, 0], [cols + m - 1, -m, 0], [cols + m - 1, rows + m - 1, 0],
                    [-m, rows + m - 1, 0]]) * square_m
    T = np.asarray(T_cam_board, dtype=np.float64)
    p_cam = pts @ T[:3, :3].T + T[:3, 3]
    return project(cam, p_cam)


def calibration_views(cam: Intrinsics, n_views: int = 10, pattern_cols_rows: tuple[int, int]
                      = (9, 6), square_m: float = 0.05, fill: float = 0.6, seed: int = 0,
                      max_tilt_deg: float = 35.0) -> list[F64]:
    """``n_views`` board poses ``T_cam_board`` that keep the whole board in view, tilted
    up to ``max_tilt_deg`` and spanning about ``fill`` of the image width (seeded)."""
    rng = np.random.default_rng(seed)
    cols, rows = pattern_cols_rows
    bw, _ = board_size_m(pattern_cols_rows, square_m)
    dist = cam.fx * bw / (fill * cam.width)
    centre_b = np.array([(cols - 1) / 2.0, (rows - 1) / 2.0, 0.0]) * square_m
    poses: list[F64] = []
    tries = 0
    while len(poses) < n_views and tries < 200 * n_views:
        tries += 1
        ax = rng.normal(size=3)
        ax[2] *= 0.5
        ang = math.radians(rng.uniform(10.0, max_tilt_deg)) if len(poses) else 0.0
        rv = ax / max(float(np.linalg.norm(ax)), 1e-9) * ang
        R = so3_exp(rv)
        z = dist * rng.uniform(0.85, 1.15)
        half_w = 0.5 * cam.width / cam.fx * z
        half_h = 0.5 * cam.height / cam.fy * z
        c = np.array([rng.uniform(-0.5, 0.5) * half_w, rng.uniform(-0.5, 0.5) * half_h, z])
        t = c - R @ centre_b
        T = make_T(R, t)
        px = board_corners_px(cam, T, pattern_cols_rows, square_m)
        if not np.all(np.isfinite(px)):
            continue
        m = 0.03 * cam.width
        if (px[:, 0].min() < m or px[:, 0].max() > cam.width - 1 - m or px[:, 1].min() < m
                or px[:, 1].max() > cam.height - 1 - m):
            continue
        poses.append(T)
    return poses
