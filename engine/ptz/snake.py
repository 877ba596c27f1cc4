"""Colour segmentation, parametric active contour and (u, v, d) measurements.

Gaspar 2009 sec. 4.1-4.2. The snake minimises eq. (2),
E = int 1/2 (alpha |x'|^2 + beta |x''|^2) + E_ext ds, discretised with finite differences;
the explicit update of sec. 4.1 is

    (x_t)_i = alpha/h^2 (x_{i+1} - 2x_i + x_{i-1})
              - beta/h^4 (x_{i+2} - 4x_{i+1} + 6x_i - 4x_{i-1} + x_{i-2}) + F_ext(x_i),
    x^{n+1} = x^n + tau x_t^n,

iterated until the points stop moving. Here the internal terms are applied semi-implicitly
(Kass 1987: (I + tau A) x^{n+1} = x^n + tau F_ext), which is stable for any tau; h = 1.
The external force is the gradient of the (smoothed) edge map of the colour segmentation,
or its gradient vector flow (GVF, Xu & Prince 1998) for a larger capture range.

Measurements (sec. 4.2): centre (u, v) = mean of the contour points; the target's apparent
radius with its known size gives the distance d along the line of sight.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.arrays import f32, f64

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]


def colour_score(image_bgr: NDArray[np.uint8], target_bgr: tuple[int, int, int]) -> F32:
    """Soft membership in [0, 1] of each pixel to the target colour.

    The chromatic part of a pixel (its value minus its grey level) is projected on the
    chromatic part of the target colour: 1 for the target colour, 0 for any grey, linear in
    the mix at anti-aliased edges. Works for any saturated colour, not only red.
    """
    import cv2

    t = np.asarray(target_bgr, dtype=np.float32)
    w = t - t.mean()
    n2 = float(w @ w)
    if n2 < 1.0:
        raise ValueError(f"target colour {target_bgr} is grey: choose a saturated colour")
    # (pixel - its grey level) . w = pixel . w, as w sums to zero: one weighted channel sum
    score = f32(cv2.transform(image_bgr.astype(np.float32), (w / n2).reshape(1, 3)))
    if score.ndim == 3:
        score = score[..., 0]
    return f32(np.clip(score, 0.0, 1.0, out=score))


def find_blob(score: F32, threshold: float = 0.5, min_area_px: int = 6,
              near_uv: tuple[float, float] | None = None) -> tuple[int, int, int, int] | None:
    """Bounding box (x, y, w, h) of the connected component (largest, or nearest a point)."""
    import cv2

    mask = (score >= threshold).astype(np.uint8)
    n, _, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        return None
    cand = [i for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] >= min_area_px]
    if not cand:
        return None
    if near_uv is not None:
        i = min(cand, key=lambda j: float(np.hypot(*(cents[j] - np.asarray(near_uv)))))
    else:
        i = max(cand, key=lambda j: int(stats[j, cv2.CC_STAT_AREA]))
    x, y, w, h = (int(v) for v in stats[i, :4])
    return x, y, w, h


def gvf(fx: F32, fy: F32, mu: float = 0.2, iterations: int = 40) -> tuple[F32, F32]:
    """Gradient vector flow (Xu & Prince 1998) of an edge-map gradient (fx, fy)."""
    import cv2

    b = fx * fx + fy * fy
    u, v = fx.copy(), fy.copy()
    for _ in range(iterations):
        u = u + mu * cv2.Laplacian(u, cv2.CV_32F) - b * (u - fx)
        v = v + mu * cv2.Laplacian(v, cv2.CV_32F) - b * (v - fy)
    return u, v


def _bilinear(img: F32, xy: F64) -> F64:
    h, w = img.shape
    x = np.clip(xy[:, 0], 0, w - 1.001)
    y = np.clip(xy[:, 1], 0, h - 1.001)
    x0 = x.astype(int)
    y0 = y.astype(int)
    ax = x - x0
    ay = y - y0
    out: F64 = (
        img[y0, x0] * (1 - ax) * (1 - ay) + img[y0, x0 + 1] * ax * (1 - ay)
        + img[y0 + 1, x0] * (1 - ax) * ay + img[y0 + 1, x0 + 1] * ax * ay
    )
    return out


def _internal_matrix(n: int, alpha: float, beta: float, tau: float) -> F64:
    """(I + tau A)^-1 for the cyclic pentadiagonal A of eq. (2)'s finite differences (h=1)."""
    a = beta
    b = -(alpha + 4 * beta)
    c = 2 * alpha + 6 * beta
    A = np.zeros((n, n))
    for i in range(n):
        A[i, i] = c
        A[i, (i + 1) % n] = A[i, (i - 1) % n] = b
        A[i, (i + 2) % n] = A[i, (i - 2) % n] = a
    return f64(np.linalg.inv(np.eye(n) + tau * A))


@dataclass(frozen=True, slots=True)
class SnakeResult:
    contour_xy: F64  # (N, 2) final contour
    history: tuple[F64, ...]  # a few intermediate contours (for the display)
    iterations: int
    converged: bool


def run_snake(
    edge_map: F32,
    init_xy: F64,
    alpha: float = 0.5,
    beta: float = 0.05,
    tau: float = 1.0,
    force_gain: float = 2.0,
    external: str = "gradient",
    max_iterations: int = 200,
    tol_px: float = 0.01,
    keep_history: int = 5,
) -> SnakeResult:
    """Evolve a closed snake on an edge map (bright on edges) from ``init_xy`` (N, 2).

    The external force is ``force_gain`` x grad(edge map) (or its GVF) normalised so that
    the strongest edge gives a unit force.
    """
    import cv2

    e = edge_map.astype(np.float32)
    m = float(e.max())
    if m > 0:
        e = e / m
    fx = f32(cv2.Sobel(e, cv2.CV_32F, 1, 0, ksize=3) / 8.0)
    fy = f32(cv2.Sobel(e, cv2.CV_32F, 0, 1, ksize=3) / 8.0)
    if external == "gvf":
        fx, fy = gvf(fx, fy)
    elif external != "gradient":
        raise ValueError(f"external force {external!r}: expected 'gradient' or 'gvf'")
    g = float(np.sqrt((fx * fx + fy * fy).max()))
    if g > 0:
        fx, fy = fx / g, fy / g
    x = np.asarray(init_xy, dtype=np.float64).copy()
    inv = _internal_matrix(len(x), alpha, beta, tau)
    hist: list[F64] = [x.copy()]
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        f = np.stack([_bilinear(fx, x), _bilinear(fy, x)], axis=1) * force_gain
        x_new = inv @ (x + tau * f)
        step = float(np.max(np.abs(x_new - x)))
        x = x_new
        if keep_history and it % max(1, max_iterations // keep_history) == 0:
            hist.append(x.copy())
        if step < tol_px:
            converged = True
            break
    return SnakeResult(contour_xy=x, history=tuple(hist), iterations=it, converged=converged)


def circle_points(cx: float, cy: float, r: float, n: int) -> F64:
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.stack([cx + r * np.cos(t), cy + r * np.sin(t)], axis=1)


@dataclass(frozen=True, slots=True)
class TargetMeasurement:
    """(u, v) px and distance d (m) of the target, plus what the display needs."""

    u: float
    v: float
    radius_px: float
    d_m: float
    contour_xy: F64
    history: tuple[F64, ...]
    box_xywh: tuple[float, float, float, float]
    snake_iterations: int


def measure_target(
    image_bgr: NDArray[np.uint8],
    target_bgr: tuple[int, int, int],
    target_radius_m: float,
    focal_px: float,
    alpha: float = 0.5,
    beta: float = 0.05,
    external: str = "gradient",
    n_points: int = 32,
    near_uv: tuple[float, float] | None = None,
    centre_method: str = "moments",
) -> TargetMeasurement | None:
    """Segment, fit the snake in a region around the blob and measure (u, v, d), sec. 4.2.

    ``centre_method`` ``"contour"`` is the paper's (mean of the contour points, radius from
    the contour); ``"moments"`` refines both with the soft colour mass inside the converged
    snake (sub-pixel, no bias from the snake's tension). d is the distance to the centre of
    a sphere of radius R seen under an angular radius atan(r / f): d = R / sin(atan(r / f)).
    """
    import cv2

    score = colour_score(image_bgr, target_bgr)
    box = find_blob(score, near_uv=near_uv)
    if box is None:
        return None
    x, y, w, h = box
    pad = max(6, int(0.6 * max(w, h)))
    H, W = score.shape
    x0, y0 = max(0, x - pad), max(0, y - pad)
    x1, y1 = min(W, x + w + pad), min(H, y + h + pad)
    roi = score[y0:y1, x0:x1]
    sigma = max(0.8, 0.08 * max(w, h))
    smooth = cv2.GaussianBlur(roi, (0, 0), sigma)
    gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3)
    edge = np.sqrt(gx * gx + gy * gy)
    cx, cy = x + w / 2.0 - x0, y + h / 2.0 - y0
    r0 = 0.5 * max(w, h) + 0.5 * pad  # start outside the blob, as in the paper's Fig. 2
    snake = run_snake(edge, circle_points(cx, cy, r0, n_points), alpha=alpha, beta=beta,
                      external=external)
    c = snake.contour_xy
    u, v = float(c[:, 0].mean()), float(c[:, 1].mean())  # sec. 4.2: mean of contour points
    r = float(np.mean(np.linalg.norm(c - [u, v], axis=1)))
    if centre_method == "moments":
        poly = np.zeros(roi.shape, np.uint8)
        grown = (c - [u, v]) * (1.0 + 2.0 / max(r, 1.0)) + [u, v] + 0.0
        cv2.fillPoly(poly, [np.round(grown * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
        wts = roi * poly
        mass = float(wts.sum())
        if mass > 1.0:
            yy, xx = np.mgrid[0:roi.shape[0], 0:roi.shape[1]]
            u = float((wts * xx).sum() / mass)
            v = float((wts * yy).sum() / mass)
            # the target's own score (< 1 when its colour is not exactly target_bgr)
            inner = roi[roi > 0.5 * float(roi.max())]
            full = float(np.median(inner)) if inner.size else 1.0
            r = float(np.sqrt(mass / (np.pi * max(full, 1e-3))))
    elif centre_method != "contour":
        raise ValueError(f"centre_method {centre_method!r}: expected 'contour' or 'moments'")
    d = target_radius_m / np.sin(np.arctan(max(r, 1e-3) / focal_px))
    off = np.array([x0, y0], dtype=np.float64)
    return TargetMeasurement(
        u=u + x0, v=v + y0, radius_px=r, d_m=float(d),
        contour_xy=c + off, history=tuple(hh + off for hh in snake.history),
        box_xywh=(float(x), float(y), float(w), float(h)),
        snake_iterations=snake.iterations,
    )
