"""Line-based inverse radial lens distortion (Gaspar 2009 sec. 3.3, after Thormählen 2003).

The inverse radial model maps a distorted point (x_d, y_d), relative to the distortion
centre (x0, y0), to the ideal pinhole point (sec. 3.3)::

    x = x_d + x_d (k3 r_d^2 + k5 r_d^4 + ...),   y = y_d + y_d (k3 r_d^2 + k5 r_d^4 + ...)

with r_d = sqrt(x_d^2 + y_d^2). Coordinates here are pixels divided by ``r_norm_px`` (the
image half-diagonal by default) so that k3, k5 are dimensionless and well conditioned.

Estimation uses the rationale of sec. 3.3: lines straight in the world must be straight
after correction. The paper writes each line as y = m_i x + b_i and solves the
N_r x N_p equations f_ij = (y_ij - m_i x_ij - b_i)^2 = 0 with Newton's method. Here each
line is the total-least-squares line (normal form, so vertical lines work) of its corrected
points, which eliminates (m_i, b_i) in closed form (variable projection), and the remaining
unknowns (k3, k5, ..., x0, y0) are found by Gauss-Newton / Levenberg-Marquardt on the
perpendicular distances.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8
from engine.errors import CalibrationError

F64 = NDArray[np.float64]

MIN_POINTS_PER_LINE = 3


@dataclass(frozen=True, slots=True)
class RadialModel:
    """Inverse radial model: k = (k3, k5, ...), centre (x0, y0) px, normaliser r_norm px."""

    k: tuple[float, ...]
    centre_px: tuple[float, float]
    r_norm_px: float

    def undistort_px(self, uv_d: F64) -> F64:
        """Ideal pixels of distorted pixels (N, 2): the inverse model of sec. 3.3."""
        uv = np.asarray(uv_d, dtype=np.float64).reshape(-1, 2)
        c = np.asarray(self.centre_px)
        xd = (uv - c) / self.r_norm_px
        r2 = np.sum(xd * xd, axis=1)
        f = np.zeros_like(r2)
        for i, k in enumerate(self.k):  # k3 r^2 + k5 r^4 + ...
            f += k * r2 ** (i + 1)
        out: F64 = c + self.r_norm_px * xd * (1.0 + f)[:, None]
        return out

    def distort_px(self, uv: F64, iterations: int = 30) -> F64:
        """Distorted pixels of ideal pixels: Newton on r_u = r_d (1 + sum k r_d^(2i))."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        c = np.asarray(self.centre_px)
        xu = (uv - c) / self.r_norm_px
        ru = np.linalg.norm(xu, axis=1)
        rd = ru.copy()
        for _ in range(iterations):
            g = rd.copy()
            dg = np.ones_like(rd)
            for i, k in enumerate(self.k):
                p = 2 * (i + 1)
                g += k * rd ** (p + 1)
                dg += (p + 1) * k * rd**p
            step = (g - ru) / np.where(np.abs(dg) > 1e-12, dg, 1e-12)
            rd = rd - step
            if np.max(np.abs(step), initial=0.0) < 1e-13:
                break
        scale = np.where(ru > 1e-15, rd / np.where(ru > 1e-15, ru, 1.0), 1.0)
        out: F64 = c + self.r_norm_px * xu * scale[:, None]
        return out

    def undistort_maps(self, width: int, height: int) -> tuple[NDArray[np.float32], ...]:
        """cv2.remap maps producing the ideal image (same size) from a distorted one."""
        u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
        d = self.distort_px(np.stack([u.ravel(), v.ravel()], axis=1))
        return (
            d[:, 0].reshape(height, width).astype(np.float32),
            d[:, 1].reshape(height, width).astype(np.float32),
        )

    def undistort_image(self, image: NDArray[np.uint8]) -> NDArray[np.uint8]:
        import cv2

        h, w = image.shape[:2]
        mx, my = self.undistort_maps(w, h)
        return u8(cv2.remap(image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT))

    def to_json_dict(self) -> dict[str, object]:
        return {
            "model": "inverse_radial",
            "k": list(self.k),
            "centre_px": list(self.centre_px),
            "r_norm_px": self.r_norm_px,
        }


@dataclass(frozen=True, slots=True)
class LineFitResult:
    """Estimated model and straightness before/after (RMS perpendicular distance, px)."""

    model: RadialModel
    rms_before_px: float
    rms_after_px: float
    per_line_rms_px: F64
    iterations: int


def line_distances(points: F64) -> F64:
    """Signed perpendicular distances of (N, 2) points to their total-least-squares line."""
    c: F64 = points.mean(axis=0)
    d = points - c
    # normal = eigenvector of the smallest eigenvalue of the scatter matrix
    _, vecs = np.linalg.eigh(d.T @ d)
    normal: F64 = vecs[:, 0]
    return d @ normal


def straightness_rms_px(lines: Sequence[F64]) -> float:
    res = np.concatenate([line_distances(np.asarray(ln, dtype=np.float64)) for ln in lines])
    return float(np.sqrt(np.mean(res**2)))


def _check_lines(lines: Sequence[F64]) -> list[F64]:
    out = []
    for i, ln in enumerate(lines):
        a = np.asarray(ln, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != 2:
            raise CalibrationError(f"line {i}: expected (N, 2) points, got shape {a.shape}")
        if len(a) < MIN_POINTS_PER_LINE:
            raise CalibrationError(
                f"line {i} has {len(a)} point(s); a curvature needs >= {MIN_POINTS_PER_LINE}"
            )
        out.append(a)
    return out


def estimate_radial_from_lines(
    lines: Sequence[F64],
    image_size_wh: tuple[int, int],
    n_terms: int = 2,
    estimate_centre: bool = True,
    r_norm_px: float | None = None,
) -> LineFitResult:
    """Estimate (k3, k5, ...) and (x0, y0) so that every line becomes straight (sec. 3.3).

    Parameters
    ----------
    lines : each an (N_p, 2) array of distorted pixels on one world-straight line.
    image_size_wh : the image size; the centre starts at the image centre.
    n_terms : number of k terms (2 = k3, k5 as in the paper).
    estimate_centre : also estimate (x0, y0); needs lines on both sides of the centre.
    """
    from scipy.optimize import least_squares

    lns = _check_lines(lines)
    n_pts = sum(len(ln) for ln in lns)
    n_unknowns = n_terms + (2 if estimate_centre else 0)
    if len(lns) < (3 if estimate_centre else 1) or n_pts - 2 * len(lns) < n_unknowns:
        raise CalibrationError(
            f"{len(lns)} line(s) with {n_pts} points are too few for {n_unknowns} unknowns"
        )
    w, h = image_size_wh
    r_norm = float(r_norm_px) if r_norm_px else 0.5 * float(np.hypot(w, h))
    c0 = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    all_pts = np.concatenate(lns)

    def model_of(theta: F64) -> RadialModel:
        k = tuple(float(v) for v in theta[:n_terms])
        c = (c0 + theta[n_terms:n_terms + 2] * r_norm) if estimate_centre else c0
        return RadialModel(k=k, centre_px=(float(c[0]), float(c[1])), r_norm_px=r_norm)

    def residuals(theta: F64) -> F64:
        m = model_of(theta)
        und = m.undistort_px(all_pts)
        out = []
        i = 0
        for ln in lns:
            out.append(line_distances(und[i:i + len(ln)]))
            i += len(ln)
        res = np.concatenate(out)
        if estimate_centre:  # weak prior keeps an ill-posed centre near the image centre
            res = np.concatenate([res, 1e-2 * theta[n_terms:] * r_norm])
        return res

    theta0 = np.zeros(n_unknowns)
    sol = least_squares(residuals, theta0, method="lm", x_scale=np.full(n_unknowns, 0.1),
                        max_nfev=2000)
    model = model_of(sol.x)
    und = model.undistort_px(all_pts)
    per_line = []
    i = 0
    for ln in lns:
        per_line.append(float(np.sqrt(np.mean(line_distances(und[i:i + len(ln)]) ** 2))))
        i += len(ln)
    return LineFitResult(
        model=model,
        rms_before_px=straightness_rms_px(lns),
        rms_after_px=straightness_rms_px(
            [und[s:s + len(ln)] for s, ln in zip(np.cumsum([0] + [len(x) for x in lns[:-1]]), lns,
                                                 strict=True)]
        ),
        per_line_rms_px=np.asarray(per_line),
        iterations=int(sol.nfev),
    )


# ----------------------------------------------------------------------- line proposals
def propose_lines_chessboard(
    gray: NDArray[np.uint8], pattern_cols_rows: tuple[int, int]
) -> list[F64]:
    """Rows and columns of chessboard inner corners: straight in the world. [] if not found."""
    import cv2

    if min(gray.shape[:2]) < 4 * (max(pattern_cols_rows) + 1):
        return []  # too small to hold the pattern (OpenCV's detector asserts on tiny images)
    try:
        ok, corners = cv2.findChessboardCorners(gray, pattern_cols_rows)
    except cv2.error:
        return []
    if not ok:
        return []
    corners = cv2.cornerSubPix(
        gray, corners, (5, 5), (-1, -1),
        (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 1e-3),
    )
    cols, rows = pattern_cols_rows
    g = corners.reshape(rows, cols, 2).astype(np.float64)
    return [g[r] for r in range(rows)] + [g[:, c] for c in range(cols)]


def propose_lines_edges(
    gray: NDArray[np.uint8],
    min_length_px: float = 80.0,
    max_gap_px: float = 12.0,
    max_turn_deg: float = 12.0,
    max_lines: int = 30,
    max_rms_px: float = 1.5,
) -> list[F64]:
    """Long gently curved edges the operator may accept as world-straight lines.

    Line segments from OpenCV's LSD are chained greedily end-to-start when the gap is small
    and the direction turns little (a distorted straight line is a chain of almost
    collinear segments); chains of >= 2 segments and ``min_length_px`` whose RMS distance to
    their chord line is at most ``max_rms_px`` (a gentle bow, not two different edges
    joined) are returned as points (segment end points and midpoints), longest first.
    """
    import cv2

    lsd = cv2.createLineSegmentDetector()
    segs = lsd.detect(gray)[0]
    if segs is None:
        return []
    segs = segs.reshape(-1, 4).astype(np.float64)
    lengths = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1])
    segs = segs[lengths >= 10.0]
    if len(segs) == 0:
        return []
    cos_turn = np.cos(np.radians(max_turn_deg))
    used = np.zeros(len(segs), dtype=bool)
    order = np.argsort(-np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1]))
    chains: list[F64] = []

    def direction(s: F64) -> F64:
        d = s[2:] - s[:2]
        return d / max(float(np.linalg.norm(d)), 1e-12)

    for start in order:
        if used[start]:
            continue
        used[start] = True
        chain = [segs[start].copy()]
        for forward in (True, False):
            while True:
                end_seg = chain[-1] if forward else chain[0]
                tip = end_seg[2:] if forward else end_seg[:2]
                d0 = direction(end_seg)
                best, best_gap, best_seg = -1, max_gap_px, None
                for j in np.flatnonzero(~used):
                    s = segs[j]
                    for cand in (s, np.concatenate([s[2:], s[:2]])):
                        other = cand[:2] if forward else cand[2:]
                        gap = float(np.linalg.norm(other - tip))
                        if gap < best_gap and float(direction(cand) @ d0) > cos_turn:
                            best, best_gap, best_seg = int(j), gap, cand
                if best < 0 or best_seg is None:
                    break
                used[best] = True
                if forward:
                    chain.append(best_seg)
                else:
                    chain.insert(0, best_seg)
        if len(chain) < 2:
            continue
        pts = []
        for s in chain:
            pts.extend([s[:2], 0.5 * (s[:2] + s[2:]), s[2:]])
        p = np.asarray(pts)
        if (float(np.linalg.norm(p[-1] - p[0])) >= min_length_px
                and float(np.sqrt(np.mean(line_distances(p) ** 2))) <= max_rms_px):
            chains.append(p)
    chains.sort(key=lambda p: -float(np.linalg.norm(p[-1] - p[0])))
    return chains[:max_lines]


def synthetic_distorted_grid(
    model: RadialModel,
    image_size_wh: tuple[int, int],
    n_lines: int = 8,
    points_per_line: int = 15,
    noise_px: float = 0.0,
    seed: int = 0,
) -> list[F64]:
    """Horizontal and vertical straight lines of a grid, distorted by ``model`` (+ noise)."""
    rng = np.random.default_rng(seed)
    w, h = image_size_wh
    lines: list[F64] = []
    t = np.linspace(0.05, 0.95, points_per_line)
    for f in np.linspace(0.08, 0.92, n_lines):
        lines.append(np.stack([t * (w - 1), np.full_like(t, f * (h - 1))], axis=1))
        lines.append(np.stack([np.full_like(t, f * (w - 1)), t * (h - 1)], axis=1))
    out = []
    for ln in lines:
        d = model.distort_px(ln) + rng.normal(0.0, noise_px, ln.shape)
        inside = (d[:, 0] >= 0) & (d[:, 0] < w) & (d[:, 1] >= 0) & (d[:, 1] < h)
        if inside.sum() >= MIN_POINTS_PER_LINE:
            out.append(d[inside])
    return out
