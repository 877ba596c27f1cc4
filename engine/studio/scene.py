"""Layout of the virtual studio set and its baked texture atlas.

World frame: z up, metres, floor at z = 0. The camera rail runs along x at y = 0 looking
towards +y; the back wall is at y = 4.6. The set, left to right as the camera sees it:
a brick wall with a poster, wooden slats with a video wall above the news desk, a chroma-key
green area (wall and floor, little texture), acoustic foam; props (desk, monitor, crates,
flight case, lectern, plants, stool, light stand) stand on a wooden floor.

Static surfaces are Lambertian, so their shading does not depend on the viewpoint: the
lighting (a few point/spot lights with distance falloff) is baked into each face's own
texture once per scene. Rendering then needs only a bilinear texture fetch per pixel, and
the images obey brightness constancy exactly (what photometric trackers assume).

Primitive encoding shared with :mod:`engine.studio.render` (``prim_geom`` rows):

- ``BOX``  (cx, cy, cz, hx, hy, hz, cos_yaw, sin_yaw, 0): faces 0..5 = -x, +x, -y, +y, -z, +z
  in the box frame; face texture coordinates (u, v) in metres from the face's min corner:
  x faces (u=y, v=z), y faces (u=x, v=z), z faces (u=x, v=y).
- ``CYL`` vertical cylinder (cx, cy, r, z0, z1): face 0 side (u = (atan2+pi) r, v = z - z0),
  face 1 top (u = x - cx + r, v = y - cy + r).
- ``SPH`` sphere (cx, cy, cz, r): face 0 (u = (atan2+pi) r, v = z - cz + r).
- ``CAP`` capsule (ax, ay, az, bx, by, bz, r): flat colour only.

Materials rows: (atlas_offset, rows, cols, texel_m, wrap_u, v_top_m, b, g, r); ``cols == 0``
means a flat albedo (b, g, r) shaded at render time (presenter, ball).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8
from engine.studio import textures as tx

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
#: a texture generator: ``gen(rng, (rows, cols), texel_m)`` -> RGB image in [0, 1]
TextureGen = Callable[[np.random.Generator, tuple[int, int], float], F32]
#: world points and normals of a face at texel coordinates: ``p_fn(rows, cols)``
SurfaceFn = Callable[[F64, F64], tuple[F64, F64]]

BOX, CYL, SPH, CAP = 0, 1, 2, 3

#: label map codes (``StudioLabels.labels`` of :mod:`engine.studio.sim`)
LABEL_SET, LABEL_HEAD, LABEL_TORSO, LABEL_LEGS, LABEL_BALL, LABEL_OCCLUDER = 0, 1, 2, 3, 4, 5
#: a second person in the studio (all body parts)
LABEL_PERSON2 = 6
LABEL_NAMES = {
    LABEL_SET: "set",
    LABEL_HEAD: "head",
    LABEL_TORSO: "torso",
    LABEL_LEGS: "legs",
    LABEL_BALL: "ball",
    LABEL_OCCLUDER: "occluder",
    LABEL_PERSON2: "person2",
}

ROOM_MIN = (-5.0, -3.0, 0.0)
ROOM_MAX = (5.0, 4.6, 3.6)
CHROMA_X = (0.9, 3.4)  # chroma-key area on the back wall and floor (x range)
CHROMA_FLOOR_Y = 3.0  # the green floor starts here (towards the back wall)

#: flat albedos (RGB) of dynamic objects, shaded at render time
FLAT_COLOURS: dict[str, tuple[float, float, float]] = {
    "skin": (0.87, 0.64, 0.5),
    "hair": (0.22, 0.13, 0.07),
    "shirt": (0.14, 0.3, 0.78),
    "trousers": (0.13, 0.13, 0.17),
    "shoes": (0.05, 0.05, 0.05),
    "ball": (0.88, 0.06, 0.05),
    "occluder": (0.55, 0.56, 0.6),
    # further looks of the presenter and of a second person (``engine.studio.presenter.LOOKS``)
    "skin_dark": (0.45, 0.3, 0.22),
    "skin_olive": (0.72, 0.52, 0.38),
    "hair_black": (0.05, 0.04, 0.04),
    "hair_blond": (0.78, 0.62, 0.35),
    "hair_grey": (0.55, 0.54, 0.52),
    "shirt_red": (0.72, 0.1, 0.12),
    "shirt_green": (0.15, 0.5, 0.25),
    "shirt_yellow": (0.85, 0.7, 0.15),
    "shirt_white": (0.86, 0.86, 0.84),
    "shirt_purple": (0.42, 0.16, 0.5),
    "jacket_grey": (0.35, 0.36, 0.38),
    "trousers_beige": (0.66, 0.56, 0.4),
    "trousers_jeans": (0.16, 0.24, 0.45),
    "trousers_black": (0.05, 0.05, 0.06),
    "shoes_brown": (0.25, 0.14, 0.07),
}


@dataclass(frozen=True, slots=True)
class Light:
    """Point light, optionally a spot (aim direction and cone half-angle)."""

    pos: tuple[float, float, float]
    intensity: float
    aim: tuple[float, float, float] | None = None
    cone_deg: float = 180.0


LIGHTS = (
    Light((-2.2, -0.5, 3.3), 1.5),  # key, front left
    Light((2.6, -0.5, 3.2), 1.1),  # fill, front right
    Light((-1.3, 2.6, 3.5), 1.0, (0.0, 0.4, -1.0), 50.0),  # desk spot
    Light((2.3, 2.6, 3.5), 0.5, (0.0, 0.3, -1.0), 60.0),  # chroma wash
    Light((-3.8, 3.0, 3.5), 1.0, (0.0, 0.3, -1.0), 45.0),  # crates spot
    Light((0.0, 2.0, 3.55), 0.5),  # ceiling top light
)
AMBIENT = 0.22
FALLOFF_D0_M = 3.0


def shade_static(p_world: F64, n_world: F64) -> F64:
    """Lambertian irradiance factor at points with unit normals (both (..., 3))."""
    out = np.full(p_world.shape[:-1], AMBIENT)
    for light in LIGHTS:
        d = np.asarray(light.pos) - p_world
        dist = np.linalg.norm(d, axis=-1)
        l_dir = d / np.maximum(dist, 1e-9)[..., None]
        lam = np.clip(np.sum(l_dir * n_world, axis=-1), 0.0, None)
        fall = 1.0 / (1.0 + (dist / FALLOFF_D0_M) ** 2)
        spot = 1.0
        if light.aim is not None:
            aim = np.asarray(light.aim) / np.linalg.norm(light.aim)
            cos_a = np.sum(-l_dir * aim, axis=-1)
            cos_c = math.cos(math.radians(light.cone_deg))
            spot = np.clip((cos_a - cos_c) / (1.0 - cos_c) * 2.0, 0.0, 1.0)
        out = out + light.intensity * lam * fall * spot
    return out


@dataclass(frozen=True)
class StudioScene:
    """Static set: room, primitives, materials and the baked atlas (read-only arrays)."""

    seed: int
    room_geom: F64  # (cx, cy, cz, hx, hy, hz) of the room box (seen from inside)
    room_mat: NDArray[np.int32]  # (6,)
    prim_type: NDArray[np.int32]  # (N,)
    prim_geom: F64  # (N, 9)
    prim_mat: NDArray[np.int32]  # (N, 6)
    prim_label: NDArray[np.uint8]  # (N,)
    prim_corners: F64  # (N, 8, 3) world bounding-box corners (for screen-space culling)
    materials: F64  # (M, 9)
    atlas_bgr: NDArray[np.uint8]  # (T, 3)
    flat_mat: dict[str, int] = field(default_factory=dict)


# ----------------------------------------------------------------------------- builder


def _Rz(yaw: float) -> F64:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


_UV_AXES = {0: (1, 2), 1: (0, 2), 2: (0, 1)}  # face axis -> (u axis, v axis) in the box frame


class _Builder:
    def __init__(self, seed: int) -> None:
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        self.materials: list[list[float]] = []
        self.chunks: list[NDArray[np.uint8]] = []
        self.offset = 0
        self.prims: list[tuple[int, list[float], list[int], int, F64]] = []

    # materials ------------------------------------------------------------------------
    def _add_texture(self, rgb01: F32, texel_m: float, wrap: bool, v_top_m: float) -> int:
        h, w = rgb01.shape[:2]
        rgb = np.ascontiguousarray(rgb01, dtype=np.float32)
        # saturating, rounding conversion (values are >= 0, so the "abs" is a no-op)
        bgr = u8(cv2.convertScaleAbs(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), alpha=255.0))
        self.chunks.append(bgr.reshape(-1, 3))
        self.materials.append(
            [float(self.offset), float(h), float(w), texel_m, float(wrap), v_top_m, 0, 0, 0]
        )
        self.offset += h * w
        return len(self.materials) - 1

    def add_flat(self, rgb: tuple[float, float, float]) -> int:
        self.materials.append([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, rgb[2], rgb[1], rgb[0]])
        return len(self.materials) - 1

    # baking -----------------------------------------------------------------------------
    @staticmethod
    def _bake(albedo: F32, p_fn: SurfaceFn, shape: tuple[int, int], step_px: int) -> F32:
        """Multiply by the lighting evaluated on a coarse grid (``p_fn(rows, cols)`` gives
        world points and normals of texel coordinates) and upsampled (lighting is smooth)."""
        h, w = shape
        rr = np.linspace(0, h - 1, max(2, h // step_px + 2))
        cc = np.linspace(0, w - 1, max(2, w // step_px + 2))
        R, C = np.meshgrid(rr, cc, indexing="ij")
        p, n = p_fn(R, C)
        s = shade_static(p, n).astype(np.float32)
        s_full = cv2.resize(s, (w, h), interpolation=cv2.INTER_LINEAR)
        return albedo * s_full[..., None]

    def box_face_material(
        self,
        geom: list[float],
        face: int,
        texel_m: float,
        gen: TextureGen,
        inside: bool = False,
    ) -> int:
        """Texture of one box face: ``gen(rng, shape, texel_m)`` gives the viewer's image."""
        c = np.asarray(geom[:3])
        hh = np.asarray(geom[3:6])
        yaw = math.atan2(geom[7], geom[6])
        Rz = _Rz(yaw)
        a, sgn = face // 2, (1.0 if face % 2 else -1.0)
        ua, va = _UV_AXES[a]
        U, V = 2 * hh[ua], 2 * hh[va]
        shape = tx.texture_shape(U, V, texel_m)
        albedo = gen(self.rng, shape, texel_m)
        n_out = Rz[:, a] * sgn
        n_view = -n_out if inside else n_out
        if a != 2:
            right = np.cross([0.0, 0.0, 1.0], n_view)
            if float(right @ Rz[:, ua]) < 0.0:
                albedo = np.ascontiguousarray(albedo[:, ::-1])

        def p_fn(rows: F64, cols: F64) -> tuple[F64, F64]:
            loc = np.zeros((*rows.shape, 3))
            loc[..., ua] = cols * texel_m - hh[ua]
            loc[..., va] = (V - rows * texel_m) - hh[va]
            loc[..., a] = sgn * hh[a]
            return loc @ Rz.T + c, np.broadcast_to(n_view, loc.shape)

        baked = self._bake(albedo, p_fn, shape, max(2, round(0.05 / texel_m)))
        return self._add_texture(baked, texel_m, False, V)

    def cyl_materials(
        self, geom: list[float], texel_m: float, side: TextureGen, top: TextureGen
    ) -> list[int]:
        cx, cy, r, z0, z1 = geom[:5]
        n_cols = max(8, round(2 * math.pi * r / texel_m))
        t_eff = 2 * math.pi * r / n_cols
        V = z1 - z0
        shape = (tx.texture_shape(1.0, V, t_eff)[0], n_cols)
        albedo = side(self.rng, shape, t_eff)

        def p_side(rows: F64, cols: F64) -> tuple[F64, F64]:
            th = cols * t_eff / r - math.pi
            n = np.stack([np.cos(th), np.sin(th), np.zeros_like(th)], axis=-1)
            p = np.stack([cx + r * n[..., 0], cy + r * n[..., 1], z0 + V - rows * t_eff], axis=-1)
            return p, n

        m_side = self._add_texture(self._bake(albedo, p_side, shape, 4), t_eff, True, V)
        shape_t = tx.texture_shape(2 * r, 2 * r, texel_m)
        albedo_t = top(self.rng, shape_t, texel_m)

        def p_top(rows: F64, cols: F64) -> tuple[F64, F64]:
            p = np.stack(
                [cx - r + cols * texel_m, cy + r - rows * texel_m, np.full_like(rows, z1)], -1
            )
            return p, np.broadcast_to(np.array([0.0, 0.0, 1.0]), p.shape)

        m_top = self._add_texture(self._bake(albedo_t, p_top, shape_t, 4), texel_m, False, 2 * r)
        return [m_side, m_top]

    def sph_material(self, geom: list[float], texel_m: float, gen: TextureGen) -> int:
        cx, cy, cz, r = geom[:4]
        n_cols = max(8, round(2 * math.pi * r / texel_m))
        t_eff = 2 * math.pi * r / n_cols
        shape = (tx.texture_shape(1.0, 2 * r, t_eff)[0], n_cols)
        albedo = gen(self.rng, shape, t_eff)

        def p_fn(rows: F64, cols: F64) -> tuple[F64, F64]:
            z = cz + r - rows * t_eff
            rho = np.sqrt(np.clip(r * r - (z - cz) ** 2, 0.0, None))
            th = cols * t_eff / r - math.pi
            p = np.stack([cx + rho * np.cos(th), cy + rho * np.sin(th), z], axis=-1)
            return p, (p - np.array([cx, cy, cz])) / r

        return self._add_texture(self._bake(albedo, p_fn, shape, 4), t_eff, True, 2 * r)

    # primitives -------------------------------------------------------------------------
    def add_box(
        self,
        centre: tuple[float, float, float],
        half: tuple[float, float, float],
        yaw_rad: float,
        faces: Mapping[int | str, TextureGen] | TextureGen,
        texel_m: float = 0.005,
    ) -> None:
        """``faces``: one generator for all faces, or one per face number and a "default"."""
        geom = [*centre, *half, math.cos(yaw_rad), math.sin(yaw_rad), 0.0]
        gens: Mapping[int | str, TextureGen] = (
            faces if isinstance(faces, Mapping) else {"default": faces})
        mats = []
        for f in range(6):
            gen = gens[f] if f in gens else gens["default"]
            if f == 4 and centre[2] - half[2] <= 1e-6:
                mats.append(self.add_flat((0.0, 0.0, 0.0)))  # bottom face on the floor
                continue
            mats.append(self.box_face_material(geom, f, texel_m, gen))
        Rz = _Rz(yaw_rad)
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        corners = (signs * np.asarray(half)) @ Rz.T + np.asarray(centre)
        self.prims.append((BOX, geom, mats, LABEL_SET, corners))

    def add_cyl(
        self,
        cx: float,
        cy: float,
        r: float,
        z0: float,
        z1: float,
        side: TextureGen,
        top: TextureGen,
        texel_m: float = 0.005,
    ) -> None:
        geom = [cx, cy, r, z0, z1, 0.0, 0.0, 0.0, 0.0]
        mats = self.cyl_materials(geom, texel_m, side, top)
        self.prims.append(
            (
                CYL,
                geom,
                [*mats, 0, 0, 0, 0],
                LABEL_SET,
                _aabb_corners((cx - r, cy - r, z0), (cx + r, cy + r, z1)),
            )
        )

    def add_sph(self, cx: float, cy: float, cz: float, r: float, gen: TextureGen) -> None:
        geom = [cx, cy, cz, r, 0.0, 0.0, 0.0, 0.0, 0.0]
        m = self.sph_material(geom, 0.006, gen)
        self.prims.append(
            (
                SPH,
                geom,
                [m, 0, 0, 0, 0, 0],
                LABEL_SET,
                _aabb_corners((cx - r, cy - r, cz - r), (cx + r, cy + r, cz + r)),
            )
        )


def _aabb_corners(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> F64:
    return np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])],
        dtype=np.float64,
    )


# ----------------------------------------------------------------------------- set design


def _back_wall(rng: np.random.Generator, shape: tuple[int, int], t: float) -> F32:
    """Back wall as the camera sees it: x from -5 (left) to +5, z from 3.6 (top) to 0."""
    img = tx.plaster(rng, shape, (0.55, 0.52, 0.49), t)
    x0, top = ROOM_MIN[0], ROOM_MAX[2]

    def sub(xa: float, xb: float, za: float, zb: float) -> tuple[slice, slice]:
        return (
            slice(tx.px(top - zb, t), tx.px(top - za, t)),
            slice(tx.px(xa - x0, t), tx.px(xb - x0, t)),
        )

    def paste(xa: float, xb: float, za: float, zb: float,
              gen: Callable[[tuple[int, int]], F32]) -> None:
        sl = sub(xa, xb, za, zb)
        h = sl[0].stop - sl[0].start
        w = sl[1].stop - sl[1].start
        img[sl] = gen((h, w))

    paste(-5.0, -2.9, 0.0, 3.6, lambda s: tx.bricks(rng, s, t))
    paste(-2.9, 0.5, 0.0, 2.5, lambda s: tx.wood_planks(rng, s, t, 0.15, (0.5, 0.34, 0.2), True))
    paste(-2.9, 0.5, 2.5, 3.6, lambda s: tx.plaster(rng, s, (0.16, 0.16, 0.2), t))
    for i in range(7):  # light boxes above the slats
        xa = -2.75 + 0.47 * i
        paste(xa, xa + 0.3, 2.85, 3.25, lambda s: tx.plaster(rng, s, (0.95, 0.9, 0.78), t))
    paste(-2.35, -0.25, 1.05, 2.25, lambda s: tx.video_wall(rng, s))
    paste(-4.7, -3.55, 1.1, 2.6, lambda s: tx.poster(rng, s, "ON AIR"))
    paste(-4.7, -3.55, 0.3, 0.9, lambda s: tx.poster(rng, s, "TALK"))
    paste(CHROMA_X[0], CHROMA_X[1], 0.0, 3.6, lambda s: tx.chroma_green(rng, s, t))
    for cx_m, cz_m in ((1.4, 2.8), (2.2, 3.1), (3.0, 2.7), (1.6, 1.6), (2.9, 1.4)):
        sl = sub(cx_m - 0.08, cx_m + 0.08, cz_m - 0.08, cz_m + 0.08)
        cy_px = (sl[0].start + sl[0].stop) // 2
        cx_px = (sl[1].start + sl[1].stop) // 2
        arm = (sl[1].stop - sl[1].start) // 2
        for dx, dy in ((arm, 0), (0, arm)):
            cv2.line(
                img,
                (cx_px - dx, cy_px - dy),
                (cx_px + dx, cy_px + dy),
                (0.09, 0.5, 0.2),
                max(1, tx.px(0.012, t)),
                cv2.LINE_AA,
            )
    paste(CHROMA_X[1], 5.0, 0.0, 3.6, lambda s: tx.acoustic_foam(rng, s, t))
    for xa, xb in ((-5.0, CHROMA_X[0]), (CHROMA_X[1], 5.0)):
        paste(xa, xb, 0.0, 0.1, lambda s: tx.plaster(rng, s, (0.1, 0.1, 0.1), t))
    return tx.blur(img, 0.5)


def _floor(rng: np.random.Generator, shape: tuple[int, int], t: float) -> F32:
    """Floor seen from above: x from -5 (left) to 5, y from 4.6 (top row) to -3."""
    img = tx.wood_planks(rng, shape, t, 0.2, (0.5, 0.36, 0.24))
    x0, ytop = ROOM_MIN[0], ROOM_MAX[1]

    def sub(xa: float, xb: float, ya: float, yb: float) -> tuple[slice, slice]:
        return (
            slice(tx.px(ytop - yb, t), tx.px(ytop - ya, t)),
            slice(tx.px(xa - x0, t), tx.px(xb - x0, t)),
        )

    sl = sub(-2.9, 0.3, 2.6, 4.35)  # rug under the desk
    h, w = sl[0].stop - sl[0].start, sl[1].stop - sl[1].start
    rug = tx.solid((h, w), (0.45, 0.1, 0.12))
    b = tx.px(0.12, t)
    cv2.rectangle(rug, (b, b), (w - b, h - b), (0.85, 0.7, 0.3), max(2, tx.px(0.04, t)))
    for k in range(1, 6):
        cv2.circle(rug, (w // 2, h // 2), k * min(h, w) // 12, (0.75, 0.55, 0.25), 3, cv2.LINE_AA)
    img[sl] = tx.modulate(rug, tx.noise(rng, (h, w), 0.03 / t), 0.2)
    img[sub(CHROMA_X[0], CHROMA_X[1], CHROMA_FLOOR_Y, ytop)] = tx.chroma_green(
        rng, img[sub(CHROMA_X[0], CHROMA_X[1], CHROMA_FLOOR_Y, ytop)].shape[:2], t
    )
    for mx, my, col in (
        (0.0, 2.4, (0.95, 0.85, 0.1)),
        (-1.5, 2.4, (0.95, 0.95, 0.95)),
        (1.5, 2.4, (0.95, 0.4, 0.1)),
        (0.0, 1.2, (0.95, 0.85, 0.1)),
    ):
        s2 = sub(mx - 0.15, mx + 0.15, my - 0.15, my + 0.15)
        cy_px, cx_px = (s2[0].start + s2[0].stop) // 2, (s2[1].start + s2[1].stop) // 2
        a = (s2[1].stop - s2[1].start) // 2
        lw = max(2, tx.px(0.04, t))
        cv2.line(img, (cx_px - a, cy_px), (cx_px + a, cy_px), col, lw, cv2.LINE_AA)
        cv2.line(img, (cx_px, cy_px - a), (cx_px, cy_px + a), col, lw, cv2.LINE_AA)
    return tx.blur(img, 0.5)


def _left_wall(rng: np.random.Generator, shape: tuple[int, int], t: float) -> F32:
    """Left wall (x = -5) as seen from inside: y from -3 (left) to 4.6, z 3.6 to 0."""
    img = tx.acoustic_foam(rng, shape, t)
    y0, top = ROOM_MIN[1], ROOM_MAX[2]
    h, _w = shape
    sl = (
        slice(tx.px(top - 2.6, t), tx.px(top - 1.0, t)),
        slice(tx.px(2.0 - y0, t), tx.px(3.4 - y0, t)),
    )
    img[sl] = tx.poster(rng, (sl[0].stop - sl[0].start, sl[1].stop - sl[1].start), "CAMERA 2")
    sl = (slice(0, h), slice(0, tx.px(1.5 - y0, t)))
    img[sl] = tx.curtain(rng, (h, sl[1].stop), t, (0.2, 0.08, 0.1))
    return img


def _right_wall(rng: np.random.Generator, shape: tuple[int, int], t: float) -> F32:
    """Right wall (x = +5) as seen from inside: y from 4.6 (left) to -3, z 3.6 to 0."""
    h, w = shape
    img = tx.wood_planks(rng, shape, t, 0.12, (0.42, 0.3, 0.2), True)
    ytop, top = ROOM_MAX[1], ROOM_MAX[2]
    lower = slice(tx.px(top - 1.0, t), h)
    img[lower] = tx.bricks(rng, (h - lower.start, w), t)
    sl = (
        slice(tx.px(top - 2.7, t), tx.px(top - 1.3, t)),
        slice(tx.px(ytop - 3.6, t), tx.px(ytop - 1.6, t)),
    )
    img[sl] = tx.poster(rng, (sl[0].stop - sl[0].start, sl[1].stop - sl[1].start), "WEATHER")
    sl = (slice(0, h), slice(tx.px(ytop - (-1.5), t), w))
    img[sl] = tx.curtain(rng, (h, w - sl[1].start), t, (0.2, 0.08, 0.1))
    return img


def _desk_side(rng: np.random.Generator, s: tuple[int, int], t: float) -> F32:
    return tx.metal(rng, s, t, (0.12, 0.14, 0.2))


def _wood_top(rng: np.random.Generator, s: tuple[int, int], t: float) -> F32:
    return tx.wood_planks(rng, s, t, 0.3, (0.62, 0.45, 0.28))


def _monitor_screen(rng: np.random.Generator, s: tuple[int, int], t: float) -> F32:
    img = tx.poster(rng, s, "LIVE")
    b = max(1, tx.px(0.02, t))
    img[:b], img[-b:], img[:, :b], img[:, -b:] = 0.05, 0.05, 0.05, 0.05
    return img


def _build(seed: int) -> StudioScene:
    bld = _Builder(seed)
    lo, hi = np.asarray(ROOM_MIN), np.asarray(ROOM_MAX)
    room_geom = [*((lo + hi) / 2), *((hi - lo) / 2), 1.0, 0.0, 0.0]
    room_gens = {
        0: (_left_wall, 0.008),
        1: (_right_wall, 0.008),
        2: (lambda r, s, t: tx.curtain(r, s, t, (0.12, 0.1, 0.12)), 0.02),
        3: (_back_wall, 0.005),
        4: (_floor, 0.005),
        5: (tx.ceiling, 0.02),
    }
    room_mat = [
        bld.box_face_material(room_geom, f, t, g, inside=True) for f, (g, t) in room_gens.items()
    ]

    def flat(rgb: tuple[float, float, float]) -> TextureGen:
        return lambda r, s, t: tx.metal(r, s, t, rgb)

    # news desk with a monitor on it
    bld.add_box(
        (-1.3, 3.3, 0.38),
        (1.1, 0.35, 0.38),
        0.08,
        {2: tx.desk_front, 5: _wood_top, "default": _desk_side},
    )
    bld.add_box(
        (-1.7, 3.45, 0.96),
        (0.26, 0.03, 0.19),
        0.08,
        {2: _monitor_screen, "default": flat((0.05, 0.05, 0.06))},
        0.003,
    )
    bld.add_box((-1.7, 3.47, 0.77), (0.04, 0.04, 0.01), 0.08, flat((0.1, 0.1, 0.1)), 0.003)
    # crates, a flight case and a lectern
    bld.add_box((-3.7, 3.7, 0.3), (0.3, 0.3, 0.3), 0.0, tx.cardboard)
    bld.add_box((-3.65, 3.62, 0.82), (0.22, 0.22, 0.22), 0.35, tx.cardboard)
    bld.add_box((-4.3, 2.9, 0.2), (0.25, 0.35, 0.2), -0.2, tx.cardboard)
    bld.add_box((4.3, 3.0, 0.3), (0.45, 0.3, 0.3), -0.3, tx.flight_case)
    bld.add_box(
        (0.3, 3.9, 0.55),
        (0.25, 0.2, 0.55),
        0.0,
        {
            5: _wood_top,
            "default": lambda r, s, t: tx.wood_planks(r, s, t, 0.08, (0.45, 0.3, 0.18), True),
        },
    )
    # plants
    for px_, py_, pot_r, pot_h, leaves in (
        (
            -3.3,
            2.9,
            0.18,
            0.42,
            ((0.0, 0.0, 0.75, 0.3), (0.12, -0.08, 1.05, 0.22), (-0.12, 0.1, 1.0, 0.2)),
        ),
        (
            4.4,
            4.0,
            0.22,
            0.5,
            ((0.0, 0.0, 0.9, 0.34), (-0.1, 0.1, 1.25, 0.26), (0.12, 0.05, 1.3, 0.2)),
        ),
    ):
        bld.add_cyl(px_, py_, pot_r, 0.0, pot_h, tx.terracotta, flat((0.2, 0.14, 0.1)))
        for dx, dy, z, r in leaves:
            bld.add_sph(px_ + dx, py_ + dy, z, r, tx.foliage)
    # a stool in the green area and a light stand at the left
    bld.add_cyl(2.3, 3.7, 0.035, 0.0, 0.62, flat((0.6, 0.6, 0.62)), flat((0.6, 0.6, 0.62)))
    bld.add_cyl(2.3, 3.7, 0.22, 0.62, 0.68, flat((0.1, 0.1, 0.1)), flat((0.15, 0.15, 0.15)))
    bld.add_cyl(-4.3, 1.0, 0.025, 0.0, 1.9, flat((0.1, 0.1, 0.1)), flat((0.1, 0.1, 0.1)))
    bld.add_box((-4.3, 1.0, 2.02), (0.16, 0.13, 0.12), 0.4, flat((0.08, 0.08, 0.08)))

    flat_mat = {name: bld.add_flat(rgb) for name, rgb in FLAT_COLOURS.items()}
    n = len(bld.prims)
    prim_type = np.array([p[0] for p in bld.prims], np.int32).reshape(n)
    prim_geom = np.array([p[1] for p in bld.prims], np.float64).reshape(n, 9)
    prim_mat = np.array([p[2] for p in bld.prims], np.int32).reshape(n, 6)
    prim_label = np.array([p[3] for p in bld.prims], np.uint8).reshape(n)
    prim_corners = np.array([p[4] for p in bld.prims], np.float64).reshape(n, 8, 3)
    arrays = (
        np.asarray(room_geom[:6], np.float64),
        np.asarray(room_mat, np.int32),
        prim_type,
        prim_geom,
        prim_mat,
        prim_label,
        prim_corners,
        np.asarray(bld.materials, np.float64),
        np.ascontiguousarray(np.concatenate(bld.chunks, axis=0)),
    )
    for a in arrays:
        a.flags.writeable = False
    return StudioScene(seed, *arrays, flat_mat=flat_mat)


@lru_cache(maxsize=4)
def build_scene(seed: int = 0) -> StudioScene:
    """The studio set for ``seed`` (textures differ by seed, the layout does not); cached."""
    return _build(int(seed))
