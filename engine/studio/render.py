"""Ray-casting renderer of the virtual studio (numba, parallel over image rows).

One ray per pixel through the pixel's *undistorted* normalised coordinates (precomputed once
per camera with :func:`engine.camera.pixels_to_normalized`, so lens distortion is exact:
the image is what a distorting lens would record). The nearest hit among the room box
(seen from inside, always hit) and the primitives gives

- depth: z along the optical axis (float32 metres), exact up to float rounding;
- colour: baked static textures (bilinear) or, for flat materials (presenter, ball),
  Lambertian shading with one directional light at render time;
- a label map (:data:`engine.studio.scene.LABEL_NAMES`).

Primitives are culled per image tile (8 x 16 pixels) and per pixel by their screen-space
rectangles in normalised coordinates, computed per frame from their world bounding boxes.
"""

from __future__ import annotations

import math
import threading
import weakref
from dataclasses import dataclass

import cv2
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
#: "every tile" for the kernel's tile mask
_NO_MASK = np.zeros((1, 1), np.uint8)
#: culling tiles (pixels): the kernel tests a primitive's screen rectangle once per tile
_TILE_H = 8
_TILE_W = 16

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


#: pixels of one cv2.remap call: OpenCV splits a call into total / 2**16 stripes (rounded)
_REMAP_BAND_PX = 1 << 16
#: sub-pixel steps of OpenCV's fixed-point remap maps (``cv2.INTER_BITS`` = 5)
_REMAP_BITS = 5
_REMAP_TAB = 1 << _REMAP_BITS


@njit(cache=True, fastmath=True, nogil=True)
def _atlas_map(mat_i: I64, mat_f: F64, mat_xy: I64, m: int, u: float, v: float,
               out_xy: NDArray[np.int16], out_frac: NDArray[np.uint16], row: int,
               col: int) -> None:
    """Texture coordinates (u, v) of material ``m`` as one fixed-point ``cv2.remap`` entry
    into the 2D atlas (:func:`_atlas_2d`): the same texel grid and the same wrapping as
    :func:`_fetch`, coordinates clamped to the texture (the atlas pads each wrapping texture
    with a copy of its first column)."""
    tw = mat_i[m, 2]
    th = mat_i[m, 1]
    inv_texel = mat_f[m, 0]
    c = u * inv_texel
    r = (mat_f[m, 1] - v) * inv_texel
    if mat_i[m, 3] != 0:
        if c < 0.0 or c >= tw:
            c = c - math.floor(c / tw) * tw
        c = min(max(c, 0.0), float(tw))
    else:
        c = min(max(c, 0.0), tw - 1.0)
    r = min(max(r, 0.0), th - 1.0)
    # cv2.convertMaps: rounded to 1/32 pixel, integer part and (row, col) fraction index
    # (the coordinates are >= 0: truncation rounds down)
    ix = int((mat_xy[m, 0] + c) * _REMAP_TAB + 0.5)
    iy = int((mat_xy[m, 1] + r) * _REMAP_TAB + 0.5)
    out_xy[row, col, 0] = np.int16(ix >> _REMAP_BITS)
    out_xy[row, col, 1] = np.int16(iy >> _REMAP_BITS)
    out_frac[row, col] = np.uint16(((iy & (_REMAP_TAB - 1)) << _REMAP_BITS)
                                   | (ix & (_REMAP_TAB - 1)))


@njit(cache=True, fastmath=True, nogil=True)
def _box_uv(lx: float, ly: float, lz: float, g: F64, face: int) -> tuple[float, float]:
    a = face // 2
    if a == 0:
        return ly + g[4], lz + g[5]
    if a == 1:
        return lx + g[3], lz + g[5]
    return lx + g[3], ly + g[4]


@njit(inline="always", fastmath=True, nogil=True)
def _pick(face: int, p0: float, p1: float, p2: float, p3: float, p4: float,
          p5: float) -> float:
    """p[face] as selects (an array lookup here would stop the loop vectorising)."""
    return p0 if face == 0 else (p1 if face == 1 else (p2 if face == 2 else (
        p3 if face == 3 else (p4 if face == 4 else p5))))


@njit(parallel=True, cache=True, fastmath=True, nogil=True)
def _room_map_kernel(
    xn: F64,
    yn: F64,
    inv_norm: F64,
    R: F64,
    o: F64,
    room: F64,
    ft: F64,
    out_depth: NDArray[np.float32],
    out_label: NDArray[np.uint8],
    out_map_xy: NDArray[np.int32],
    out_map_frac: NDArray[np.uint16],
) -> None:
    """The room alone (every pixel): depth, label 0 and the remap entry of its exit face.

    The same rays, exit distances and texel grid as :func:`_render_kernel` (the same depth and
    maps, bit for bit), written without branches or table lookups so that the compiler
    vectorises the loop. ``ft`` per room face: (1/texel, v_top, atlas x, atlas y, last
    column, last row); ``out_map_xy``: the (x, y) int16 pairs as one little-endian int32.
    """
    H, W = xn.shape
    ox, oy, oz = o[0], o[1], o[2]
    r00, r01, r02 = R[0, 0], R[0, 1], R[0, 2]
    r10, r11, r12 = R[1, 0], R[1, 1], R[1, 2]
    r20, r21, r22 = R[2, 0], R[2, 1], R[2, 2]
    # exit planes: the far side along each axis (+ when the ray goes +)
    xp, xm = room[0] + room[3] - ox, room[0] - room[3] - ox
    yp, ym = room[1] + room[4] - oy, room[1] - room[4] - oy
    zp, zm = room[2] + room[5] - oz, room[2] - room[5] - oz
    it0, it1, it2, it3, it4, it5 = ft[0, 0], ft[1, 0], ft[2, 0], ft[3, 0], ft[4, 0], ft[5, 0]
    vt0, vt1, vt2, vt3, vt4, vt5 = ft[0, 1], ft[1, 1], ft[2, 1], ft[3, 1], ft[4, 1], ft[5, 1]
    ax0, ax1, ax2, ax3, ax4, ax5 = ft[0, 2], ft[1, 2], ft[2, 2], ft[3, 2], ft[4, 2], ft[5, 2]
    ay0, ay1, ay2, ay3, ay4, ay5 = ft[0, 3], ft[1, 3], ft[2, 3], ft[3, 3], ft[4, 3], ft[5, 3]
    cm0, cm1, cm2, cm3, cm4, cm5 = ft[0, 4], ft[1, 4], ft[2, 4], ft[3, 4], ft[4, 4], ft[5, 4]
    rm0, rm1, rm2, rm3, rm4, rm5 = ft[0, 5], ft[1, 5], ft[2, 5], ft[3, 5], ft[4, 5], ft[5, 5]
    for v in prange(H):
        xr, yr, sr = xn[v], yn[v], inv_norm[v]
        dr, lr, mr, fr = out_depth[v], out_label[v], out_map_xy[v], out_map_frac[v]
        for u in range(W):
            x = xr[u]
            y = yr[u]
            s = sr[u]
            dx = (r00 * x + r01 * y + r02) * s
            dy = (r10 * x + r11 * y + r12) * s
            dz = (r20 * x + r21 * y + r22) * s
            okx = abs(dx) > 1e-12
            oky = abs(dy) > 1e-12
            okz = abs(dz) > 1e-12
            tx = (xp if dx > 0.0 else xm) / (dx if okx else 1.0)
            tx = tx if okx else _INF
            ty = (yp if dy > 0.0 else ym) / (dy if oky else 1.0)
            ty = ty if oky else _INF
            tz = (zp if dz > 0.0 else zm) / (dz if okz else 1.0)
            tz = tz if okz else _INF
            # the first exit, x before y before z on ties (as _render_kernel)
            t = tx
            face = 1 if dx > 0.0 else 0
            sel = ty < t
            t = ty if sel else t
            face = (3 if dy > 0.0 else 2) if sel else face
            sel = tz < t
            t = tz if sel else t
            face = (5 if dz > 0.0 else 4) if sel else face
            # face texture coordinates (_box_uv of the room box), texel grid (_atlas_map)
            lx = ox + t * dx - room[0] + room[3]
            ly = oy + t * dy - room[1] + room[4]
            lz = oz + t * dz - room[2] + room[5]
            uu = ly if face < 2 else lx
            vv = ly if face >= 4 else lz
            inv_texel = _pick(face, it0, it1, it2, it3, it4, it5)
            c = min(max(uu * inv_texel, 0.0), _pick(face, cm0, cm1, cm2, cm3, cm4, cm5))
            r = min(max((_pick(face, vt0, vt1, vt2, vt3, vt4, vt5) - vv) * inv_texel, 0.0),
                    _pick(face, rm0, rm1, rm2, rm3, rm4, rm5))
            ix = np.int32((_pick(face, ax0, ax1, ax2, ax3, ax4, ax5) + c) * _REMAP_TAB + 0.5)
            iy = np.int32((_pick(face, ay0, ay1, ay2, ay3, ay4, ay5) + r) * _REMAP_TAB + 0.5)
            mr[u] = (ix >> _REMAP_BITS) | ((iy >> _REMAP_BITS) << 16)
            fr[u] = np.uint16(((iy & (_REMAP_TAB - 1)) << _REMAP_BITS) | (ix & (_REMAP_TAB - 1)))
            dr[u] = np.float32(t * s)
            lr[u] = 0


@njit(parallel=True, cache=True, fastmath=True, nogil=True)
def _render_kernel(
    xn: F64,
    yn: F64,
    inv_norm: F64,
    tile_bounds: F64,
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
    to_maps: bool,
    room_done: bool,
    tile_mask: NDArray[np.uint8],
    pextra: NDArray[np.uint8],
    mat_xy: I64,
    out_bgr: NDArray[np.uint8],
    out_depth: NDArray[np.float32],
    out_label: NDArray[np.uint8],
    out_map_xy: NDArray[np.int16],
    out_map_frac: NDArray[np.uint16],
) -> None:
    H, W = xn.shape
    N = ptype.shape[0]
    ox, oy, oz = o[0], o[1], o[2]
    TH, TW = tile_bounds.shape[0], tile_bounds.shape[1]
    masked = tile_mask.shape[0] == TH and tile_mask.shape[1] == TW
    # tiles interleaved over chunks: every chunk gets cheap (top) and busy (bottom) tiles
    n_chunks = min(TH * TW, 64)
    for chunk in prange(n_chunks):
        cand = np.empty(N, np.int64)
        col = np.empty(3, np.float64)
        for ti in range(chunk, TH * TW, n_chunks):
            ty = ti // TW
            tx = ti - ty * TW
            if masked and tile_mask[ty, tx] == 0:
                continue  # the static camera's cached frame stands here
            # the primitives whose screen rectangle meets the tile's, nearest first
            tb = tile_bounds[ty, tx]
            nc = 0
            for k in range(N):
                if (prect[k, 0] <= tb[1] and prect[k, 1] >= tb[0]
                        and prect[k, 2] <= tb[3] and prect[k, 3] >= tb[2]):
                    cand[nc] = k
                    nc += 1
            if nc == 0 and room_done:
                continue  # the room alone: _room_map_kernel did these pixels
            v0 = ty * _TILE_H
            v1 = min(v0 + _TILE_H, H)
            u0 = tx * _TILE_W
            u1 = min(u0 + _TILE_W, W)
            for v in range(v0, v1):
                for u in range(u0, u1):
                    x = xn[v, u]
                    y = yn[v, u]
                    if room_done:
                        # (on a kept frame only the extra primitives change a pixel)
                        inside = False
                        for ci in range(nc):
                            k = cand[ci]
                            if masked and pextra[k] == 0:
                                continue
                            if (prect[k, 0] <= x <= prect[k, 1]
                                    and prect[k, 2] <= y <= prect[k, 3]):
                                inside = True
                                break
                        if not inside:
                            continue  # no primitive here: the room pass's pixel stands
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
                        if (x < prect[k, 0] or x > prect[k, 1]
                                or y < prect[k, 2] or y > prect[k, 3]):
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
                            uu, vv = _box_uv(c * rx + sn * ry, -sn * rx + c * ry, pz - g[2], g,
                                             face)
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
                    out_depth[v, u] = np.float32(t * s)
                    out_label[v, u] = label
                    if to_maps:
                        if mat_i[m, 2] != 0:
                            # textured: where cv2.remap is to sample the 2D atlas
                            _atlas_map(mat_i, mat_f, mat_xy, m, uu, vv, out_map_xy, out_map_frac,
                                       v, u)
                            continue
                        # flat: shaded here; outside the atlas, so that remap leaves it
                        out_map_xy[v, u, 0] = -8
                        out_map_xy[v, u, 1] = -8
                        out_map_frac[v, u] = 0
                    textured = _fetch(mat_i, mat_f, atlas, m, uu, vv, col)
                    if not textured:
                        lam = nx * dyn[0] + ny * dyn[1] + nz * dyn[2]
                        sh = dyn[3] + dyn[4] * max(lam, 0.0)
                        col[0] *= sh
                        col[1] *= sh
                        col[2] *= sh
                    for k in range(3):
                        out_bgr[v, u, k] = np.uint8(min(max(col[k] + 0.5, 0.0), 255.0))


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


#: how :class:`Renderer` colours textured surfaces: ``remap`` (the kernel traces the rays and
#: writes, per pixel, where in the texture atlas to sample; ``cv2.remap`` samples, bilinear in
#: fixed point, outside the GIL) or ``raycast`` (the kernel samples the texture itself, in
#: floating point). Depth and labels are the same; colours differ by rounding (a grey level,
#: rarely two or three on the sharpest texture edges; ``tests/engine/test_studio.py``).
RENDER_METHODS = ("remap", "raycast")


class Renderer:
    """Renders a :class:`StudioScene` for one camera (intrinsics and distortion fixed).

    ``threads``: numba threads for one frame (1 by default: on a loaded 2-core machine one
    thread gives the best and steadiest frame rate, and leaves a core to the tracker; 0 means
    numba's default, all cores). The kernel releases the GIL while it runs, and so does
    ``cv2.remap`` (``method``: :data:`RENDER_METHODS`).
    """

    def __init__(self, scene: StudioScene, intrinsics: Intrinsics, threads: int = 1,
                 dynamic_light: F64 | None = None, method: str = "remap") -> None:
        if method not in RENDER_METHODS:
            raise ValueError(f"render method {method!r} is not one of "
                             f"{', '.join(RENDER_METHODS)}")
        self.scene = scene
        self.intrinsics = intrinsics
        self.threads = int(threads)
        self.method = method
        w, h = intrinsics.width, intrinsics.height
        u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        xy = pixels_to_normalized(intrinsics, np.stack([u.ravel(), v.ravel()], axis=1))
        self.xn = np.ascontiguousarray(xy[:, 0].reshape(h, w))
        self.yn = np.ascontiguousarray(xy[:, 1].reshape(h, w))
        self.inv_norm = 1.0 / np.sqrt(self.xn**2 + self.yn**2 + 1.0)
        self.tile_bounds = _tile_bounds(self.xn, self.yn)
        # (direction, ambient, diffuse) of the flat materials' light (engine.studio.lighting)
        self._dyn = (np.array([*_DYN_LIGHT, _DYN_AMBIENT, _DYN_DIFFUSE]) if dynamic_light is None
                     else np.ascontiguousarray(dynamic_light, dtype=np.float64))
        self._mat_i, self._mat_f = _material_tables(scene)
        self._last_T: F64 | None = None
        #: a still camera's frame of the set alone: (pose, colour, depth, labels, maps)
        self._still: tuple[F64, NDArray[np.uint8], NDArray[np.float32], NDArray[np.uint8],
                           NDArray[np.int16], NDArray[np.uint16]] | None = None
        if method == "remap":
            self._atlas = np.zeros(1, np.uint32)  # the kernel samples no texture itself
            self._atlas_2d, self._mat_xy = _atlas_2d(scene)
            # the room pass needs textured, non-wrapping room faces (the built-in set's)
            rm = np.asarray(scene.room_mat)
            self._room_tex: F64 | None = None
            if np.all(self._mat_i[rm, 2] > 0) and not np.any(self._mat_i[rm, 3]):
                self._room_tex = np.ascontiguousarray(np.stack([
                    self._mat_f[rm, 0], self._mat_f[rm, 1],
                    self._mat_xy[rm, 0].astype(np.float64), self._mat_xy[rm, 1].astype(np.float64),
                    self._mat_i[rm, 2] - 1.0, self._mat_i[rm, 1] - 1.0,
                ], axis=1))
            self._map_xy = np.empty((h, w, 2), np.int16)
            self._map_frac = np.empty((h, w), np.uint16)
        else:
            self._atlas = _packed_atlas(scene)
            self._room_tex = None
            self._mat_xy = np.zeros((1, 2), np.int64)
            self._map_xy = np.zeros((1, 1, 2), np.int16)
            self._map_frac = np.zeros((1, 1), np.uint16)

    def render(
        self,
        T_world_cam: F64,
        extra: Prims | None = None,
        out: RenderOutput | None = None,
    ) -> RenderOutput:
        """Colour, depth and labels seen from ``T_world_cam`` with ``extra`` primitives.

        A camera that stands still (``remap``: the same pose twice running) gets the set
        rendered once without ``extra`` and kept: each frame then starts from that and
        traces only the tiles the extra primitives' screen rectangles reach (the same images,
        bit for bit)."""
        h, w = self.xn.shape
        if out is None:
            out = RenderOutput(
                np.empty((h, w, 3), np.uint8),
                np.empty((h, w), np.float32),
                np.empty((h, w), np.uint8),
            )
        T = np.asarray(T_world_cam, dtype=np.float64)
        with _KERNEL_LOCK:
            if self.method == "remap" and self._room_tex is not None:
                still = self._last_T is not None and np.array_equal(T, self._last_T)
                self._last_T = T.copy()
                if still:
                    if self._still is None or not np.array_equal(T, self._still[0]):
                        # the set alone from here, kept with its maps
                        self._trace(T, Prims.empty(), out, None)
                        self._still = (T.copy(), out.color_bgr.copy(), out.depth_m.copy(),
                                       out.labels.copy(), self._map_xy.copy(),
                                       self._map_frac.copy())
                    self._trace_on_still(T, extra, out)
                    return out
                self._still = None
            self._trace(T, extra if extra is not None else Prims.empty(), out, None)
        return out

    def _trace_on_still(self, T: F64, extra: Prims | None, out: RenderOutput) -> None:
        """The kept frame of the set, with the tiles that ``extra`` reaches traced again."""
        assert self._still is not None
        _, bgr, depth, labels, map_xy, map_frac = self._still
        np.copyto(out.color_bgr, bgr)
        np.copyto(out.depth_m, depth)
        np.copyto(out.labels, labels)
        np.copyto(self._map_xy, map_xy)
        np.copyto(self._map_frac, map_frac)
        if extra is None or len(extra.ptype) == 0:
            return
        rect = _screen_rects(extra.corners, np.ascontiguousarray(T[:3, :3]),
                             np.ascontiguousarray(T[:3, 3]))
        tb = self.tile_bounds[..., None, :]
        reach = np.any((rect[:, 0] <= tb[..., 1]) & (rect[:, 1] >= tb[..., 0])
                       & (rect[:, 2] <= tb[..., 3]) & (rect[:, 3] >= tb[..., 2]), axis=-1)
        rows = np.flatnonzero(reach.any(axis=1))
        if rows.size == 0:
            return
        h = out.depth_m.shape[0]
        self._trace(T, extra, out, np.ascontiguousarray(reach, dtype=np.uint8),
                    rows=(int(rows[0]) * _TILE_H, min(h, (int(rows[-1]) + 1) * _TILE_H)))

    def _trace(self, T_world_cam: F64, extra: Prims, out: RenderOutput,
               tile_mask: NDArray[np.uint8] | None,
               rows: tuple[int, int] | None = None) -> None:
        """The kernels (under the kernel lock): with ``tile_mask``, only the marked tiles on
        top of what ``out`` and the maps hold, and colour sampled in ``rows`` only."""
        sc = self.scene
        ptype = np.concatenate([sc.prim_type, extra.ptype])
        geom = np.ascontiguousarray(np.concatenate([sc.prim_geom, extra.geom]))
        mat = np.ascontiguousarray(np.concatenate([sc.prim_mat, extra.mat]))
        label = np.concatenate([sc.prim_label, extra.label])
        corners = np.concatenate([sc.prim_corners, extra.corners])
        is_extra = np.concatenate([np.zeros(len(sc.prim_type), np.uint8),
                                   np.ones(len(extra.ptype), np.uint8)])
        R = np.ascontiguousarray(T_world_cam[:3, :3], dtype=np.float64)
        o = np.ascontiguousarray(T_world_cam[:3, 3], dtype=np.float64)
        rect = _screen_rects(corners, R, o)
        # nearest possible distance of each primitive (bounding sphere of its box corners);
        # sorted ascending so that the kernel stops at the first one beyond its nearest hit
        centre = corners.mean(axis=1)
        radius = np.max(np.linalg.norm(corners - centre[:, None, :], axis=2), axis=1)
        dmin = np.maximum(np.linalg.norm(centre - o, axis=1) - radius, 0.0)
        order = np.argsort(dmin, kind="stable")
        ptype, geom, mat, label, rect, dmin, is_extra = (
            np.ascontiguousarray(a[order])
            for a in (ptype, geom, mat, label, rect, dmin, is_extra)
        )
        remap = self.method == "remap"
        room_pass = remap and self._room_tex is not None
        prev_threads = numba.get_num_threads()
        all_threads = numba_max_threads()
        want = all_threads if self.threads <= 0 else self.threads
        # thread-local in numba: restored so that other kernels on this thread keep theirs
        numba.set_num_threads(max(1, min(want, all_threads)))
        try:
            if room_pass and tile_mask is None:
                assert self._room_tex is not None
                _room_map_kernel(self.xn, self.yn, self.inv_norm, R, o, sc.room_geom,
                                 self._room_tex, out.depth_m, out.labels,
                                 self._map_xy.view(np.int32)[..., 0], self._map_frac)
            _render_kernel(
                self.xn,
                self.yn,
                self.inv_norm,
                self.tile_bounds,
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
                remap,
                room_pass,
                _NO_MASK if tile_mask is None else tile_mask,
                is_extra,
                self._mat_xy,
                out.color_bgr,
                out.depth_m,
                out.labels,
                self._map_xy,
                self._map_frac,
            )
            if remap:
                self._sample(out.color_bgr, rows)
        finally:
            numba.set_num_threads(prev_threads)

    def _sample(self, out_bgr: NDArray[np.uint8], rows: tuple[int, int] | None = None) -> None:
        """``cv2.remap`` of the atlas by this frame's maps into ``out_bgr`` (called under the
        kernel lock: the maps are this renderer's, reused by its next frame). Pixels of flat
        materials point outside the atlas and keep their shading (BORDER_TRANSPARENT).

        In bands of fewer than 2**16 pixels: OpenCV runs such a call on the calling thread
        (one stripe), so the sampling costs this thread's time at this thread's priority,
        not OpenCV's worker pool's (which would compete with the tracker at its priority).
        """
        h, w = out_bgr.shape[:2]
        band = max(1, _REMAP_BAND_PX // w)
        lo, hi = (0, h) if rows is None else rows
        for r0 in range(lo, hi, band):
            r1 = min(hi, r0 + band)
            cv2.remap(self._atlas_2d, self._map_xy[r0:r1], self._map_frac[r0:r1],
                      cv2.INTER_LINEAR, dst=out_bgr[r0:r1], borderMode=cv2.BORDER_TRANSPARENT)


def _tile_bounds(xn: F64, yn: F64) -> F64:
    """(rows, cols, 4) bounds (xmin, xmax, ymin, ymax) of the normalised coordinates of each
    :data:`_TILE_H` x :data:`_TILE_W` pixel tile (the kernel's culling cells)."""
    h, w = xn.shape
    th, tw = -(-h // _TILE_H), -(-w // _TILE_W)
    out = np.empty((th, tw, 4))
    for ty in range(th):
        for tx in range(tw):
            sl = (slice(ty * _TILE_H, (ty + 1) * _TILE_H), slice(tx * _TILE_W, (tx + 1) * _TILE_W))
            out[ty, tx] = (xn[sl].min(), xn[sl].max(), yn[sl].min(), yn[sl].max())
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


def _material_tables(scene: StudioScene) -> tuple[NDArray[np.int64], F64]:
    """Kernel-friendly material tables: ints (offset, rows, cols, wrap) and floats
    (1/texel, v_top, b, g, r in 0..255)."""
    m = scene.materials
    mat_i = np.ascontiguousarray(np.round(m[:, [0, 1, 2, 4]]).astype(np.int64))
    mat_f = np.ascontiguousarray(
        np.stack([1.0 / m[:, 3], m[:, 5], m[:, 6] * 255, m[:, 7] * 255, m[:, 8] * 255], axis=1)
    )
    return mat_i, mat_f


def _packed_atlas(scene: StudioScene) -> NDArray[np.uint32]:
    """The atlas packed one uint32 per texel (b | g << 8 | r << 16): the ray caster's."""
    a = scene.atlas_bgr.astype(np.uint32)
    return np.ascontiguousarray(a[:, 0] | (a[:, 1] << 8) | (a[:, 2] << 16))


#: width of the 2D atlas (OpenCV's fixed-point maps address at most 32767 pixels)
_ATLAS_2D_WIDTH = 4096
_ATLAS_2D_CACHE: dict[int, tuple[weakref.ref[StudioScene], NDArray[np.uint8], I64]] = {}
_ATLAS_2D_LOCK = threading.Lock()


def _atlas_2d(scene: StudioScene) -> tuple[NDArray[np.uint8], I64]:
    """The scene's textures as one BGR image for ``cv2.remap`` and each material's (x, y)
    offset in it (flat materials: (0, 0)); one per scene, shared by its renderers.

    Shelf packing, tallest first. Each texture gets a margin column and row (remap reads the
    right and lower neighbours even at weight 0) and a wrapping one a copy of its first column
    on the right, so that bilinear sampling wraps the way :func:`_fetch` does.
    """
    with _ATLAS_2D_LOCK:
        hit = _ATLAS_2D_CACHE.get(id(scene))
        if hit is not None and hit[0]() is scene:
            return hit[1], hit[2]
        mat_i, _ = _material_tables(scene)
        xy = np.zeros((len(mat_i), 2), np.int64)
        textured = [k for k in range(len(mat_i)) if mat_i[k, 2] > 0]
        textured.sort(key=lambda k: (-int(mat_i[k, 1]), k))
        x = y = shelf_h = 0
        for k in textured:
            slot_w, slot_h = int(mat_i[k, 2]) + 2, int(mat_i[k, 1]) + 1
            if x + slot_w > _ATLAS_2D_WIDTH:
                x, y, shelf_h = 0, y + shelf_h, 0
            xy[k] = (x, y)
            x += slot_w
            shelf_h = max(shelf_h, slot_h)
        height = y + shelf_h
        if height > 32767:
            raise ValueError(f"texture atlas of {height} rows: more than remap addresses")
        img = np.zeros((max(height, 2), _ATLAS_2D_WIDTH, 3), np.uint8)
        for k in textured:
            off, th, tw, wrap = (int(v) for v in mat_i[k])
            tex = scene.atlas_bgr[off:off + th * tw].reshape(th, tw, 3)
            x0, y0 = int(xy[k, 0]), int(xy[k, 1])
            img[y0:y0 + th, x0:x0 + tw] = tex
            if wrap:
                img[y0:y0 + th, x0 + tw] = tex[:, 0]
        img.flags.writeable = False
        xy.flags.writeable = False
        for key in [k for k, v in _ATLAS_2D_CACHE.items() if v[0]() is None]:
            del _ATLAS_2D_CACHE[key]
        _ATLAS_2D_CACHE[id(scene)] = (weakref.ref(scene), img, xy)
        return img, xy


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
