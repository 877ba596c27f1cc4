"""Ray-casting renderer of the virtual studio (numba, parallel over image rows).

One ray per pixel through the pixel's *undistorted* normalised coordinates (precomputed once
per camera with :func:`engine.camera.pixels_to_normalized`, so lens distortion is exact:
the image is what a distorting lens would record). The nearest hit among the room box
(seen from inside, always hit) and the primitives gives

- depth: z along the optical axis (float32 metres), exact up to float rounding;
- colour: baked static textures (bilinear) or, for flat materials (presenter, ball),
  Lambertian shading with one directional light at render time;
- a label map (:data:`engine.studio.scene.LABEL_NAMES`).

Primitives are culled per image row and per pixel by their screen-space rectangles in
normalised coordinates, computed per frame from their world bounding boxes.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numba
import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from engine.camera import Intrinsics, pixels_to_normalized
from engine.studio.scene import StudioScene

F64 = NDArray[np.float64]
I32 = NDArray[np.int32]
I64 = NDArray[np.int64]

_EPS = 1e-6
_INF = 1e30

# Flat materials: ambient + diffuse * max(0, n . L), L towards a key light front-left above.
_DYN_LIGHT = np.array([-0.35, -1.0, 0.9]) / np.linalg.norm([-0.35, -1.0, 0.9])
_DYN_AMBIENT = 0.42
_DYN_DIFFUSE = 0.7



def numba_max_threads() -> int:
    """Size of numba's thread pool (``numba.config.NUMBA_NUM_THREADS``: set when numba
    starts, which its type information does not show)."""
    return int(vars(numba.config)["NUMBA_NUM_THREADS"])


# the omp/workqueue layers do not like concurrent parallel launches from several threads
_KERNEL_LOCK = threading.Lock()


@njit(cache=True, fastmath=True, nogil=True)
def _hit_box(ox: float, oy: float, oz: float, dx: float, dy: float, dz: float,
             g: F64) -> tuple[float, int]:
    """Entry distance and face of a yawed box (the ray starts outside), or (-1, -1)."""
    c, s = g[6], g[7]
    rx, ry, rz = ox - g[0], oy - g[1], oz - g[2]
    lx = c * rx + s * ry
    ly = -s * rx + c * ry
    lz = rz
    ex = c * dx + s * dy
    ey = -s * dx + c * dy
    ez = dz
    tn = -_INF
    tf = _INF
    face = -1
    # x slab
    if abs(ex) < 1e-12:
        if lx < -g[3] or lx > g[3]:
            return -1.0, -1
    else:
        t1 = (-g[3] - lx) / ex
        t2 = (g[3] - lx) / ex
        f1 = 0
        if t1 > t2:
            t1, t2 = t2, t1
            f1 = 1
        if t1 > tn:
            tn = t1
            face = f1
        tf = min(tf, t2)
    if abs(ey) < 1e-12:
        if ly < -g[4] or ly > g[4]:
            return -1.0, -1
    else:
        t1 = (-g[4] - ly) / ey
        t2 = (g[4] - ly) / ey
        f1 = 2
        if t1 > t2:
            t1, t2 = t2, t1
            f1 = 3
        if t1 > tn:
            tn = t1
            face = f1
        tf = min(tf, t2)
    if abs(ez) < 1e-12:
        if lz < -g[5] or lz > g[5]:
            return -1.0, -1
    else:
        t1 = (-g[5] - lz) / ez
        t2 = (g[5] - lz) / ez
        f1 = 4
        if t1 > t2:
            t1, t2 = t2, t1
            f1 = 5
        if t1 > tn:
            tn = t1
            face = f1
        tf = min(tf, t2)
    if tn > tf or tn <= _EPS:
        return -1.0, -1
    return tn, face


@njit(cache=True, fastmath=True, nogil=True)
def _hit_cyl(ox: float, oy: float, oz: float, dx: float, dy: float, dz: float,
             g: F64) -> tuple[float, int]:
    cx, cy, r, z0, z1 = g[0], g[1], g[2], g[3], g[4]
    px = ox - cx
    py = oy - cy
    a = dx * dx + dy * dy
    best = -1.0
    face = -1
    if a > 1e-12:
        b = px * dx + py * dy
        cc = px * px + py * py - r * r
        h = b * b - a * cc
        if h >= 0.0:
            t = (-b - math.sqrt(h)) / a
            if t > _EPS:
                z = oz + t * dz
                if z0 <= z <= z1:
                    best = t
                    face = 0
    if abs(dz) > 1e-12 and oz > z1:
        t = (z1 - oz) / dz
        if t > _EPS and (best < 0.0 or t < best):
            qx = px + t * dx
            qy = py + t * dy
            if qx * qx + qy * qy <= r * r:
                best = t
                face = 1
    return best, face


@njit(cache=True, fastmath=True, nogil=True)
def _hit_sph(ox: float, oy: float, oz: float, dx: float, dy: float, dz: float,
             g: F64) -> tuple[float, int]:
    px = ox - g[0]
    py = oy - g[1]
    pz = oz - g[2]
    b = px * dx + py * dy + pz * dz
    c = px * px + py * py + pz * pz - g[3] * g[3]
    h = b * b - c
    if h < 0.0:
        return -1.0, -1
    t = -b - math.sqrt(h)
    if t <= _EPS:
        return -1.0, -1
    return t, 0


@njit(cache=True, fastmath=True, nogil=True)
def _hit_cap(ox: float, oy: float, oz: float, dx: float, dy: float, dz: float,
             g: F64) -> tuple[float, int]:
    """Ray-capsule intersection (segment a-b, radius r; unit ray direction)."""
    bax, bay, baz = g[3] - g[0], g[4] - g[1], g[5] - g[2]
    oax, oay, oaz = ox - g[0], oy - g[1], oz - g[2]
    r = g[6]
    baba = bax * bax + bay * bay + baz * baz
    bard = bax * dx + bay * dy + baz * dz
    baoa = bax * oax + bay * oay + baz * oaz
    rdoa = dx * oax + dy * oay + dz * oaz
    oaoa = oax * oax + oay * oay + oaz * oaz
    a = baba - bard * bard
    b = baba * rdoa - baoa * bard
    c = baba * oaoa - baoa * baoa - r * r * baba
    h = b * b - a * c
    if h < 0.0:
        return -1.0, -1
    if a > 1e-12:
        t = (-b - math.sqrt(h)) / a
        y = baoa + t * bard
        if 0.0 < y < baba and t > _EPS:
            return t, 0
    else:
        y = -1.0
    # spherical caps
    if y <= 0.0:
        cx, cy, cz = oax, oay, oaz
    else:
        cx, cy, cz = ox - g[3], oy - g[4], oz - g[5]
    b2 = dx * cx + dy * cy + dz * cz
    c2 = cx * cx + cy * cy + cz * cz - r * r
    h2 = b2 * b2 - c2
    if h2 > 0.0:
        t = -b2 - math.sqrt(h2)
        if t > _EPS:
            return t, 0
    return -1.0, -1


@njit(cache=True, fastmath=True, nogil=True)
def _fetch(mat_i: I64, mat_f: F64, atlas: NDArray[np.uint32], m: int, u: float, v: float,
           out: F64) -> bool:
    """Bilinear texture fetch (or flat albedo) into out[0:3] as floats in [0, 255]; returns
    False for a flat material. ``atlas`` holds texels packed as b | g << 8 | r << 16."""
    tw = mat_i[m, 2]
    if tw == 0:
        out[0] = mat_f[m, 2]
        out[1] = mat_f[m, 3]
        out[2] = mat_f[m, 4]
        return False
    off = mat_i[m, 0]
    th = mat_i[m, 1]
    inv_texel = mat_f[m, 0]
    col = u * inv_texel
    row = (mat_f[m, 1] - v) * inv_texel
    c0f = math.floor(col)
    r0f = math.floor(row)
    fc = col - c0f
    fr = row - r0f
    c0 = int(c0f)
    r0 = int(r0f)
    if mat_i[m, 3] != 0:
        while c0 < 0:
            c0 += tw
        while c0 >= tw:
            c0 -= tw
        c1 = c0 + 1
        if c1 == tw:
            c1 = 0
    else:
        c0 = min(max(c0, 0), tw - 1)
        c1 = min(c0 + 1, tw - 1)
    r0 = min(max(r0, 0), th - 1)
    r1 = min(r0 + 1, th - 1)
    a00 = atlas[off + r0 * tw + c0]
    a01 = atlas[off + r0 * tw + c1]
    a10 = atlas[off + r1 * tw + c0]
    a11 = atlas[off + r1 * tw + c1]
    w00 = (1.0 - fc) * (1.0 - fr)
    w01 = fc * (1.0 - fr)
    w10 = (1.0 - fc) * fr
    w11 = fc * fr
    for k in range(3):
        sh = 8 * k
        out[k] = (
            w00 * ((a00 >> sh) & 255)
            + w01 * ((a01 >> sh) & 255)
            + w10 * ((a10 >> sh) & 255)
            + w11 * ((a11 >> sh) & 255)
        )
    return True


@njit(cache=True, fastmath=True, nogil=True)
def _box_uv(lx: float, ly: float, lz: float, g: F64, face: int) -> tuple[float, float]:
    a = face // 2
    if a == 0:
        return ly + g[4], lz + g[5]
    if a == 1:
        return lx + g[3], lz + g[5]
    return lx + g[3], ly + g[4]


@njit(parallel=True, cache=True, fastmath=True, nogil=True)
def _render_kernel(
    xn: F64,
    yn: F64,
    inv_norm: F64,
    row_ymin: F64,
    row_ymax: F64,
    R: F64,
    o: F64,
    room: F64,
    room_mat: I32,
    ptype: I32,
    pgeom: F64,
    pmat: I32,
    plabel: NDArray[np.uint8],
    prect: F64,
    pdmin: F64,
    mat_i: I64,
    mat_f: F64,
    atlas: NDArray[np.uint32],
    dyn: F64,
    out_bgr: NDArray[np.uint8],
    out_depth: NDArray[np.float32],
    out_label: NDArray[np.uint8],
) -> None:
    H, W = xn.shape
    N = ptype.shape[0]
    ox, oy, oz = o[0], o[1], o[2]
    # rows interleaved over chunks: every chunk gets top (cheap) and bottom (busy) rows
    n_chunks = min(H, 64)
    for chunk in prange(n_chunks):
        cand = np.empty(N, np.int64)
        col = np.empty(3, np.float64)
        for v in range(chunk, H, n_chunks):
            nc = 0
            for k in range(N):
                if prect[k, 2] <= row_ymax[v] and prect[k, 3] >= row_ymin[v]:
                    cand[nc] = k
                    nc += 1
            for u in range(W):
                x = xn[v, u]
                y = yn[v, u]
                s = inv_norm[v, u]
                dx = (R[0, 0] * x + R[0, 1] * y + R[0, 2]) * s
                dy = (R[1, 0] * x + R[1, 1] * y + R[1, 2]) * s
                dz = (R[2, 0] * x + R[2, 1] * y + R[2, 2]) * s
                # room (from inside): exit distance
                t = _INF
                face = -1
                if dx > 1e-12:
                    tt = (room[0] + room[3] - ox) / dx
                    if tt < t:
                        t, face = tt, 1
                elif dx < -1e-12:
                    tt = (room[0] - room[3] - ox) / dx
                    if tt < t:
                        t, face = tt, 0
                if dy > 1e-12:
                    tt = (room[1] + room[4] - oy) / dy
                    if tt < t:
                        t, face = tt, 3
                elif dy < -1e-12:
                    tt = (room[1] - room[4] - oy) / dy
                    if tt < t:
                        t, face = tt, 2
                if dz > 1e-12:
                    tt = (room[2] + room[5] - oz) / dz
                    if tt < t:
                        t, face = tt, 5
                elif dz < -1e-12:
                    tt = (room[2] - room[5] - oz) / dz
                    if tt < t:
                        t, face = tt, 4
                best = -1
                for ci in range(nc):
                    k = cand[ci]
                    if pdmin[k] >= t:
                        break  # sorted by distance: nothing further can be nearer
                    if x < prect[k, 0] or x > prect[k, 1] or y < prect[k, 2] or y > prect[k, 3]:
                        continue
                    typ = ptype[k]
                    if typ == 0:
                        tk, fk = _hit_box(ox, oy, oz, dx, dy, dz, pgeom[k])
                    elif typ == 1:
                        tk, fk = _hit_cyl(ox, oy, oz, dx, dy, dz, pgeom[k])
                    elif typ == 2:
                        tk, fk = _hit_sph(ox, oy, oz, dx, dy, dz, pgeom[k])
                    else:
                        tk, fk = _hit_cap(ox, oy, oz, dx, dy, dz, pgeom[k])
                    if tk > 0.0 and tk < t:
                        t = tk
                        best = k
                        face = fk
                px = ox + t * dx
                py = oy + t * dy
                pz = oz + t * dz
                nx = 0.0
                ny = 0.0
                nz = 1.0
                if best < 0:
                    m = room_mat[face]
                    uu, vv = _box_uv(px - room[0], py - room[1], pz - room[2], room, face)
                    label = 0
                else:
                    g = pgeom[best]
                    typ = ptype[best]
                    m = pmat[best, face]
                    label = plabel[best]
                    if typ == 0:
                        c, sn = g[6], g[7]
                        rx, ry = px - g[0], py - g[1]
                        uu, vv = _box_uv(c * rx + sn * ry, -sn * rx + c * ry, pz - g[2], g, face)
                        a = face // 2
                        sg = 1.0 if face % 2 == 1 else -1.0
                        if a == 0:
                            nx, ny, nz = c * sg, sn * sg, 0.0
                        elif a == 1:
                            nx, ny, nz = -sn * sg, c * sg, 0.0
                        else:
                            nx, ny, nz = 0.0, 0.0, sg
                    elif typ == 1:
                        rx, ry = px - g[0], py - g[1]
                        if face == 0:
                            uu = (math.atan2(ry, rx) + math.pi) * g[2]
                            vv = pz - g[3]
                            nx, ny, nz = rx / g[2], ry / g[2], 0.0
                        else:
                            uu = rx + g[2]
                            vv = ry + g[2]
                    elif typ == 2:
                        rx, ry, rz = px - g[0], py - g[1], pz - g[2]
                        uu = (math.atan2(ry, rx) + math.pi) * g[3]
                        vv = rz + g[3]
                        nx, ny, nz = rx / g[3], ry / g[3], rz / g[3]
                    else:
                        bax, bay, baz = g[3] - g[0], g[4] - g[1], g[5] - g[2]
                        hh = ((px - g[0]) * bax + (py - g[1]) * bay + (pz - g[2]) * baz) / (
                            bax * bax + bay * bay + baz * baz
                        )
                        hh = min(max(hh, 0.0), 1.0)
                        nx = (px - g[0] - bax * hh) / g[6]
                        ny = (py - g[1] - bay * hh) / g[6]
                        nz = (pz - g[2] - baz * hh) / g[6]
                        uu = 0.0
                        vv = 0.0
                textured = _fetch(mat_i, mat_f, atlas, m, uu, vv, col)
                if not textured:
                    lam = nx * dyn[0] + ny * dyn[1] + nz * dyn[2]
                    sh = dyn[3] + dyn[4] * max(lam, 0.0)
                    col[0] *= sh
                    col[1] *= sh
                    col[2] *= sh
                for k in range(3):
                    out_bgr[v, u, k] = np.uint8(min(max(col[k] + 0.5, 0.0), 255.0))
                out_depth[v, u] = np.float32(t * s)
                out_label[v, u] = label


@njit(cache=True, nogil=True)
def label_boxes(labels: NDArray[np.uint8], n_labels: int) -> I64:
    """Per label: (xmin, ymin, xmax, ymax, pixel count) over the label map (count 0: absent)."""
    out = np.zeros((n_labels, 5), np.int64)
    for i in range(n_labels):
        out[i, 0] = 1 << 30
        out[i, 1] = 1 << 30
        out[i, 2] = -1
        out[i, 3] = -1
    H, W = labels.shape
    for v in range(H):
        for u in range(W):
            k = labels[v, u]
            if k == 0 or k >= n_labels:
                continue
            if u < out[k, 0]:
                out[k, 0] = u
            if u > out[k, 2]:
                out[k, 2] = u
            if v < out[k, 1]:
                out[k, 1] = v
            if v > out[k, 3]:
                out[k, 3] = v
            out[k, 4] += 1
    return out


@dataclass(frozen=True, slots=True)
class Prims:
    """Extra (dynamic) primitives for one frame, encoded as in :mod:`engine.studio.scene`."""

    ptype: NDArray[np.int32]
    geom: F64
    mat: NDArray[np.int32]
    label: NDArray[np.uint8]
    corners: F64

    @staticmethod
    def empty() -> Prims:
        return Prims(
            np.zeros(0, np.int32),
            np.zeros((0, 9)),
            np.zeros((0, 6), np.int32),
            np.zeros(0, np.uint8),
            np.zeros((0, 8, 3)),
        )


@dataclass(frozen=True, slots=True)
class RenderOutput:
    color_bgr: NDArray[np.uint8]
    depth_m: NDArray[np.float32]
    labels: NDArray[np.uint8]


class Renderer:
    """Renders a :class:`StudioScene` for one camera (intrinsics and distortion fixed).

    ``threads``: numba threads for one frame (1 by default: on a loaded 2-core machine one
    thread gives the best and steadiest frame rate, and leaves a core to the tracker; 0 means
    numba's default, all cores). The kernel releases the GIL while it runs.
    """

    def __init__(self, scene: StudioScene, intrinsics: Intrinsics, threads: int = 1,
                 dynamic_light: F64 | None = None) -> None:
        self.scene = scene
        self.intrinsics = intrinsics
        self.threads = int(threads)
        w, h = intrinsics.width, intrinsics.height
        u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        xy = pixels_to_normalized(intrinsics, np.stack([u.ravel(), v.ravel()], axis=1))
        self.xn = np.ascontiguousarray(xy[:, 0].reshape(h, w))
        self.yn = np.ascontiguousarray(xy[:, 1].reshape(h, w))
        self.inv_norm = 1.0 / np.sqrt(self.xn**2 + self.yn**2 + 1.0)
        self.row_ymin = self.yn.min(axis=1)
        self.row_ymax = self.yn.max(axis=1)
        # (direction, ambient, diffuse) of the flat materials' light (engine.studio.lighting)
        self._dyn = (np.array([*_DYN_LIGHT, _DYN_AMBIENT, _DYN_DIFFUSE]) if dynamic_light is None
                     else np.ascontiguousarray(dynamic_light, dtype=np.float64))
        self._mat_i, self._mat_f, self._atlas = _pack_materials(scene)

    def render(
        self,
        T_world_cam: F64,
        extra: Prims | None = None,
        out: RenderOutput | None = None,
    ) -> RenderOutput:
        """Colour, depth and labels seen from ``T_world_cam`` with ``extra`` primitives."""
        sc = self.scene
        extra = extra if extra is not None else Prims.empty()
        ptype = np.concatenate([sc.prim_type, extra.ptype])
        geom = np.ascontiguousarray(np.concatenate([sc.prim_geom, extra.geom]))
        mat = np.ascontiguousarray(np.concatenate([sc.prim_mat, extra.mat]))
        label = np.concatenate([sc.prim_label, extra.label])
        corners = np.concatenate([sc.prim_corners, extra.corners])
        R = np.ascontiguousarray(T_world_cam[:3, :3], dtype=np.float64)
        o = np.ascontiguousarray(T_world_cam[:3, 3], dtype=np.float64)
        rect = _screen_rects(corners, R, o)
        # nearest possible distance of each primitive (bounding sphere of its box corners);
        # sorted ascending so that the kernel stops at the first one beyond its nearest hit
        centre = corners.mean(axis=1)
        radius = np.max(np.linalg.norm(corners - centre[:, None, :], axis=2), axis=1)
        dmin = np.maximum(np.linalg.norm(centre - o, axis=1) - radius, 0.0)
        order = np.argsort(dmin, kind="stable")
        ptype, geom, mat, label, rect, dmin = (
            np.ascontiguousarray(a[order]) for a in (ptype, geom, mat, label, rect, dmin)
        )
        h, w = self.xn.shape
        if out is None:
            out = RenderOutput(
                np.empty((h, w, 3), np.uint8),
                np.empty((h, w), np.float32),
                np.empty((h, w), np.uint8),
            )
        prev_threads = numba.get_num_threads()
        all_threads = numba_max_threads()
        want = all_threads if self.threads <= 0 else self.threads
        with _KERNEL_LOCK:
            # thread-local in numba: restored so that other kernels on this thread keep theirs
            numba.set_num_threads(max(1, min(want, all_threads)))
            try:
                _render_kernel(
                    self.xn,
                    self.yn,
                    self.inv_norm,
                    self.row_ymin,
                    self.row_ymax,
                    R,
                    o,
                    sc.room_geom,
                    sc.room_mat,
                    ptype,
                    geom,
                    mat,
                    label,
                    rect,
                    dmin,
                    self._mat_i,
                    self._mat_f,
                    self._atlas,
                    self._dyn,
                    out.color_bgr,
                    out.depth_m,
                    out.labels,
                )
            finally:
                numba.set_num_threads(prev_threads)
        return out


def _screen_rects(corners_world: F64, R_world_cam: F64, o_world: F64) -> F64:
    """(N, 4) rectangles (xmin, xmax, ymin, ymax) in normalised image coordinates; an object
    with a corner near or behind the camera plane gets an unbounded rectangle."""
    n = corners_world.shape[0]
    if n == 0:
        return np.zeros((0, 4))
    p_cam = (corners_world.reshape(-1, 3) - o_world) @ R_world_cam
    p_cam = p_cam.reshape(n, 8, 3)
    z = p_cam[..., 2]
    ok = np.all(z > 1e-3, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        xs = p_cam[..., 0] / z
        ys = p_cam[..., 1] / z
    rect = np.empty((n, 4))
    rect[:, 0] = xs.min(axis=1)
    rect[:, 1] = xs.max(axis=1)
    rect[:, 2] = ys.min(axis=1)
    rect[:, 3] = ys.max(axis=1)
    rect[~ok] = (-_INF, _INF, -_INF, _INF)
    behind = np.all(z <= 1e-3, axis=1)
    rect[behind] = (_INF, -_INF, _INF, -_INF)  # entirely behind: never hit
    return rect


def _pack_materials(scene: StudioScene) -> tuple[NDArray[np.int64], F64, NDArray[np.uint32]]:
    """Kernel-friendly material tables: ints (offset, rows, cols, wrap), floats
    (1/texel, v_top, b, g, r in 0..255) and the atlas packed one uint32 per texel."""
    m = scene.materials
    mat_i = np.ascontiguousarray(np.round(m[:, [0, 1, 2, 4]]).astype(np.int64))
    mat_f = np.ascontiguousarray(
        np.stack([1.0 / m[:, 3], m[:, 5], m[:, 6] * 255, m[:, 7] * 255, m[:, 8] * 255], axis=1)
    )
    a = scene.atlas_bgr.astype(np.uint32)
    atlas = np.ascontiguousarray(a[:, 0] | (a[:, 1] << 8) | (a[:, 2] << 16))
    return mat_i, mat_f, atlas


def core_boxes_from_labels(labels: NDArray[np.integer], codes: dict[str, int],
                           lo_pct: float = 15.0, hi_pct: float = 85.0,
                           min_pixels: int = 20, min_side_px: float = 2.0
                           ) -> dict[str, tuple[float, float, float, float]]:
    """Per-part patches the way an operator drags them: over the part's core, not its extent.

    The box spans the ``lo_pct``..``hi_pct`` percentiles of the part's pixel columns and rows,
    so swinging arms or a stride do not pull background into the patch.
    """
    out: dict[str, tuple[float, float, float, float]] = {}
    for name, code in codes.items():
        ys, xs = np.nonzero(labels == code)
        if len(xs) < min_pixels:
            continue
        x0, x1 = np.percentile(xs, [lo_pct, hi_pct])
        y0, y1 = np.percentile(ys, [lo_pct, hi_pct])
        if x1 - x0 >= min_side_px and y1 - y0 >= min_side_px:
            out[name] = (float(x0), float(y0), float(x1 - x0 + 1), float(y1 - y0 + 1))
    return out
