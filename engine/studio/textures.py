"""Procedural textures of the virtual studio (deterministic by seed).

Every generator returns an RGB float32 albedo image in [0, 1] "as the viewer sees it"
(row 0 at the top, column 0 at the left) sampled every ``texel_m`` metres, so that a
surface ``w_m`` x ``h_m`` gets ``ceil(h_m/texel_m)+1`` rows and ``ceil(w_m/texel_m)+1``
columns (texel centres on both borders). Content is band-limited (blurred noise, anti-aliased
drawing) so that photometric trackers see smooth gradients rather than texel aliasing.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.arrays import f32

F32 = NDArray[np.float32]
RGB = tuple[float, float, float]


def texture_shape(w_m: float, h_m: float, texel_m: float) -> tuple[int, int]:
    """(rows, cols) of a texture covering ``w_m`` x ``h_m`` at ``texel_m`` (borders included)."""
    return math.ceil(h_m / texel_m - 1e-9) + 1, math.ceil(w_m / texel_m - 1e-9) + 1


def noise(rng: np.random.Generator, shape: tuple[int, int], cell_px: float) -> F32:
    """Smooth value noise in [0, 1]: a random grid every ``cell_px`` texels, cubic upsampling."""
    h, w = shape
    gh = max(2, math.ceil(h / cell_px) + 2)
    gw = max(2, math.ceil(w / cell_px) + 2)
    grid = rng.random((gh, gw), dtype=np.float32)
    big = cv2.resize(
        grid, (round(gw * cell_px), round(gh * cell_px)), interpolation=cv2.INTER_CUBIC
    )
    return np.clip(big[:h, :w], 0.0, 1.0)


def fbm(rng: np.random.Generator, shape: tuple[int, int], cell_px: float, octaves: int = 4) -> F32:
    """Fractal sum of value noise (octaves halving the cell size), normalised to [0, 1]."""
    acc = np.zeros(shape, np.float32)
    amp, total = 1.0, 0.0
    for _ in range(octaves):
        acc += amp * noise(rng, shape, max(cell_px, 1.5))
        total += amp
        amp *= 0.5
        cell_px *= 0.5
    return acc / total


def solid(shape: tuple[int, int], rgb: RGB) -> F32:
    img = np.empty((*shape, 3), np.float32)
    img[:] = rgb
    return img


def modulate(img: F32, field: F32, amount: float) -> F32:
    """Multiply by ``1 + amount * (field - 0.5) * 2`` (brightness variation)."""
    gain = field * np.float32(2.0 * amount) + np.float32(1.0 - amount)
    return img * gain[..., None]


def px(metres: float, texel_m: float) -> int:
    return round(metres / texel_m)


def rect(img: F32, x0: float, y0: float, x1: float, y1: float, rgb: RGB, texel_m: float) -> None:
    """Filled rectangle, corners in metres from the top-left."""
    cv2.rectangle(
        img, (px(x0, texel_m), px(y0, texel_m)), (px(x1, texel_m), px(y1, texel_m)), rgb, -1
    )


def put_text(
    img: F32,
    s: str,
    org: tuple[int, int],
    font: int,
    scale: float,
    rgb: RGB,
    thickness: int,
    line_type: int = cv2.LINE_AA,
) -> None:
    """cv2.putText for float images (OpenCV 5 draws text on 8-bit images only)."""
    mask = np.zeros(img.shape[:2], np.uint8)
    cv2.putText(mask, s, org, font, scale, 255, thickness, line_type)
    a = (mask.astype(np.float32) / 255.0)[..., None]
    img *= 1.0 - a
    img += a * np.asarray(rgb, np.float32)


def text(
    img: F32, s: str, x: float, y: float, height_m: float, rgb: RGB, texel_m: float, bold: int = 2
) -> None:
    """Anti-aliased text with its baseline-left corner at (x, y) metres."""
    scale = px(height_m, texel_m) / 22.0
    put_text(
        img,
        s,
        (px(x, texel_m), px(y, texel_m)),
        cv2.FONT_HERSHEY_DUPLEX,
        scale,
        rgb,
        max(1, round(bold * scale)),
        cv2.LINE_AA,
    )


def blur(img: F32, sigma_px: float) -> F32:
    if sigma_px <= 0:
        return img
    return f32(cv2.GaussianBlur(img, (0, 0), sigma_px))


# ----------------------------------------------------------------------------- materials


def plaster(rng: np.random.Generator, shape: tuple[int, int], rgb: RGB, texel_m: float) -> F32:
    img = solid(shape, rgb)
    img = modulate(img, fbm(rng, shape, 0.6 / texel_m, 5), 0.18)
    return modulate(img, noise(rng, shape, 0.02 / texel_m), 0.06)


def wood_planks(
    rng: np.random.Generator,
    shape: tuple[int, int],
    texel_m: float,
    plank_m: float = 0.18,
    base: RGB = (0.56, 0.38, 0.22),
    vertical_boards: bool = False,
) -> F32:
    """Planks with per-plank tone, staggered joints and grain along the plank."""
    h, w = shape
    if vertical_boards:
        return np.ascontiguousarray(
            wood_planks(rng, (w, h), texel_m, plank_m, base).transpose(1, 0, 2)
        )
    img = solid(shape, base)
    rows = np.arange(h)
    plank_px = max(3, px(plank_m, texel_m))
    plank_id = rows // plank_px
    n_planks = int(plank_id.max()) + 1
    tone = rng.uniform(0.78, 1.2, size=n_planks).astype(np.float32)
    hue = rng.uniform(-0.05, 0.05, size=(n_planks, 3)).astype(np.float32)
    img *= tone[plank_id][:, None, None]
    img += hue[plank_id][:, None, :]
    # grain: noise stretched along the plank (x), fine across it
    g = f32(cv2.resize(
        rng.random((h, max(2, w // 40)), dtype=np.float32), (w, h), interpolation=cv2.INTER_CUBIC
    ))
    img = modulate(img, blur(g, 0.7), 0.22)
    # joints: dark lines between planks and staggered butt joints
    joint = (rows % plank_px) < max(1, plank_px // 30)
    img[joint] *= 0.45
    plank_len = max(8, px(1.2, texel_m))
    for i in range(n_planks):
        off = int(rng.integers(0, plank_len))
        r0, r1 = i * plank_px, min(h, (i + 1) * plank_px)
        for c in range(off, w, plank_len):
            img[r0:r1, c : c + max(1, plank_px // 30)] *= 0.5
    return blur(img, 0.6)


def bricks(rng: np.random.Generator, shape: tuple[int, int], texel_m: float) -> F32:
    h, w = shape
    img = solid(shape, (0.78, 0.76, 0.72))  # mortar
    bh, bw = px(0.075, texel_m), px(0.24, texel_m)
    mortar = max(1, px(0.012, texel_m))
    for r, y in enumerate(range(0, h, bh)):
        off = (bw // 2) * (r % 2)
        for x in range(-off, w, bw):
            tone = rng.uniform(0.75, 1.15)
            col = (0.62 * tone, 0.30 * tone * rng.uniform(0.85, 1.1), 0.22 * tone)
            cv2.rectangle(img, (x + mortar, y + mortar), (x + bw - 1, y + bh - 1), col, -1)
    img = modulate(img, fbm(rng, shape, 0.05 / texel_m, 3), 0.25)
    return blur(img, 0.7)


def acoustic_foam(rng: np.random.Generator, shape: tuple[int, int], texel_m: float) -> F32:
    """Grey foam tiles in alternating orientation (pyramids shaded)."""
    h, w = shape
    img = solid(shape, (0.26, 0.27, 0.30))
    t = px(0.3, texel_m)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    fx = (xx % t) / t - 0.5
    fy = (yy % t) / t - 0.5
    checker = ((xx // t + yy // t) % 2).astype(bool)
    ridge = np.where(checker, np.abs(np.sin(fx * 18.0)), np.abs(np.sin(fy * 18.0)))
    img = img * (0.75 + 0.5 * ridge[..., None])
    img = modulate(img, noise(rng, shape, 0.03 / texel_m), 0.15)
    return blur(img, 0.8)


def chroma_green(rng: np.random.Generator, shape: tuple[int, int], texel_m: float) -> F32:
    """Chroma-key paint: nearly uniform, a faint very-low-frequency variation only."""
    img = solid(shape, (0.12, 0.62, 0.24))
    return modulate(img, noise(rng, shape, 1.5 / texel_m), 0.03)


def curtain(rng: np.random.Generator, shape: tuple[int, int], texel_m: float, rgb: RGB) -> F32:
    _h, w = shape
    xx = np.arange(w, dtype=np.float32) * texel_m
    folds = 0.7 + 0.3 * np.sin(xx * 2 * np.pi / 0.22 + 2.0 * np.sin(xx * 1.3))
    img = solid(shape, rgb) * folds[None, :, None]
    return modulate(img, noise(rng, shape, 0.5 / texel_m), 0.1)


def cardboard(rng: np.random.Generator, shape: tuple[int, int], texel_m: float) -> F32:
    h, w = shape
    img = solid(shape, (0.66, 0.5, 0.32))
    img = modulate(img, fbm(rng, shape, 0.08 / texel_m, 4), 0.25)
    tape = px(0.05, texel_m)
    img[:, w // 2 - tape // 2 : w // 2 + tape // 2] *= np.float32(1.12)
    put_text(
        img,
        "FRAGILE",
        (w // 10, h // 3),
        cv2.FONT_HERSHEY_SIMPLEX,
        max(0.3, w / 160),
        (0.15, 0.12, 0.1),
        max(1, w // 80),
        cv2.LINE_AA,
    )
    cv2.arrowedLine(
        img, (w // 4, int(h * 0.85)), (w // 4, int(h * 0.5)), (0.15, 0.12, 0.1), max(1, w // 60)
    )
    return blur(img, 0.6)


def flight_case(rng: np.random.Generator, shape: tuple[int, int], texel_m: float) -> F32:
    h, w = shape
    img = solid(shape, (0.09, 0.09, 0.1))
    img = modulate(img, noise(rng, shape, 0.01 / texel_m), 0.3)
    e = max(2, px(0.04, texel_m))
    for sl in (np.s_[:e, :], np.s_[-e:, :], np.s_[:, :e], np.s_[:, -e:]):
        img[sl] = (0.7, 0.7, 0.72)
    c = max(3, px(0.07, texel_m))
    for y, x in ((0, 0), (0, w - c), (h - c, 0), (h - c, w - c)):
        img[y : y + c, x : x + c] = (0.82, 0.8, 0.75)
    cv2.circle(img, (w // 2, h // 2), max(2, px(0.05, texel_m)), (0.75, 0.75, 0.75), -1)
    return blur(img, 0.6)


def foliage(rng: np.random.Generator, shape: tuple[int, int], texel_m: float) -> F32:
    h, w = shape
    img = solid(shape, (0.12, 0.36, 0.1))
    for _ in range(int(h * w / 120)):
        y, x = int(rng.integers(0, h)), int(rng.integers(0, w))
        ax = (max(1, int(rng.integers(2, 6))), max(1, int(rng.integers(1, 3))))
        ang = float(rng.uniform(0, 180))
        tone = rng.uniform(0.5, 1.4)
        col = (0.12 * tone, 0.42 * tone, 0.1 * tone * rng.uniform(0.8, 1.3))
        cv2.ellipse(img, (x, y), ax, ang, 0, 360, col, -1, cv2.LINE_AA)
    return blur(img, 0.5)


def terracotta(rng: np.random.Generator, shape: tuple[int, int], texel_m: float) -> F32:
    h, _w = shape
    img = solid(shape, (0.64, 0.33, 0.2))
    img = modulate(img, fbm(rng, shape, 0.05 / texel_m, 3), 0.2)
    img[: max(1, h // 6)] *= 0.8
    return blur(img, 0.6)


def metal(rng: np.random.Generator, shape: tuple[int, int], texel_m: float, rgb: RGB) -> F32:
    img = solid(shape, rgb)
    return blur(modulate(img, noise(rng, shape, 0.02 / texel_m), 0.15), 0.6)


def poster(rng: np.random.Generator, shape: tuple[int, int], title: str) -> F32:
    """A colourful poster: gradient, circles, bars and a title (drawn in texels)."""
    h, w = shape
    c0 = rng.uniform(0.1, 0.9, 3)
    c1 = rng.uniform(0.1, 0.9, 3)
    t = np.linspace(0, 1, h, dtype=np.float32)[:, None, None]
    img = ((1 - t) * c0 + t * c1).astype(np.float32) * np.ones((1, w, 1), np.float32)
    for _ in range(6):
        col = tuple(float(v) for v in rng.uniform(0.05, 1.0, 3))
        cx, cy = int(rng.integers(0, w)), int(rng.integers(0, h))
        r = int(rng.integers(max(2, min(h, w) // 12), max(3, min(h, w) // 3)))
        cv2.circle(img, (cx, cy), r, col, -1, cv2.LINE_AA)
    for i in range(5):
        y = int(h * (0.62 + 0.06 * i))
        cv2.rectangle(
            img,
            (w // 10, y),
            (int(w * rng.uniform(0.4, 0.9)), y + max(1, h // 60)),
            (0.95, 0.95, 0.95),
            -1,
        )
    scale = w / (22.0 * max(4, len(title))) * 1.6
    put_text(
        img,
        title,
        (w // 12, int(h * 0.2)),
        cv2.FONT_HERSHEY_DUPLEX,
        scale,
        (0.98, 0.98, 0.95),
        max(1, round(scale * 2)),
        cv2.LINE_AA,
    )
    return blur(img, 0.6)


def video_wall(rng: np.random.Generator, shape: tuple[int, int]) -> F32:
    """A big screen showing a blue news graphic with a globe, tickers and headline text."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    img = np.empty((h, w, 3), np.float32)
    img[..., 0] = 0.05 + 0.15 * xx / w
    img[..., 1] = 0.15 + 0.25 * yy / h
    img[..., 2] = 0.45 + 0.4 * (1 - yy / h)
    cx, cy, r = int(w * 0.72), int(h * 0.42), int(h * 0.3)
    cv2.circle(img, (cx, cy), r, (0.2, 0.55, 0.85), -1, cv2.LINE_AA)
    for k in range(-3, 4):
        cv2.ellipse(
            img, (cx, cy), (abs(k) * r // 4, r), 0, 0, 360, (0.7, 0.9, 1.0), 2, cv2.LINE_AA
        )
        cv2.line(img, (cx - r, cy + k * r // 4), (cx + r, cy + k * r // 4), (0.7, 0.9, 1.0), 2)
    cv2.rectangle(img, (0, int(h * 0.78)), (w, int(h * 0.92)), (0.85, 0.1, 0.1), -1)
    put_text(
        img,
        "BREAKING NEWS",
        (w // 30, int(h * 0.89)),
        cv2.FONT_HERSHEY_DUPLEX,
        h / 220,
        (1.0, 1.0, 1.0),
        max(1, h // 90),
        cv2.LINE_AA,
    )
    put_text(
        img,
        "STUDIO 3",
        (w // 20, int(h * 0.3)),
        cv2.FONT_HERSHEY_DUPLEX,
        h / 130,
        (1.0, 0.95, 0.6),
        max(1, h // 60),
        cv2.LINE_AA,
    )
    for i in range(3):
        y = int(h * (0.42 + 0.09 * i))
        x1 = int(w * rng.uniform(0.25, 0.45))
        cv2.rectangle(img, (w // 20, y), (x1, y + max(2, h // 30)), (0.9, 0.9, 0.95), -1)
    return blur(img, 0.7)


def ceiling(rng: np.random.Generator, shape: tuple[int, int], texel_m: float) -> F32:
    h, w = shape
    img = solid(shape, (0.12, 0.12, 0.13))
    img = modulate(img, noise(rng, shape, 0.3 / texel_m), 0.3)
    step = px(1.0, texel_m)
    bar = max(1, px(0.06, texel_m))
    for x in range(step // 2, w, step):
        img[:, x : x + bar] = (0.45, 0.45, 0.47)
    for y in range(step // 2, h, step):
        img[y : y + bar, :] = (0.45, 0.45, 0.47)
    return blur(img, 0.6)


def desk_front(rng: np.random.Generator, shape: tuple[int, int], texel_m: float) -> F32:
    """News desk front: glossy blue panel with white stripes and the programme's name."""
    h, w = shape
    img = solid(shape, (0.08, 0.2, 0.5))
    img = modulate(img, noise(rng, shape, 0.4 / texel_m), 0.15)
    for i, frac in enumerate((0.18, 0.24, 0.78)):
        y = int(h * frac)
        cv2.rectangle(img, (0, y), (w, y + max(1, h // (40 + 20 * i))), (0.9, 0.92, 0.95), -1)
    text(img, "NEWS 24", 0.55 * texel_m * w / 2.2, h * texel_m * 0.62, 0.2, (1, 1, 1), texel_m, 3)
    cv2.circle(img, (int(w * 0.14), int(h * 0.5)), max(2, h // 6), (0.95, 0.75, 0.1), -1)
    cv2.circle(img, (int(w * 0.14), int(h * 0.5)), max(1, h // 10), (0.08, 0.2, 0.5), -1)
    return blur(img, 0.6)
