"""The multi-patch presenter model of one camera view (VR-TV paper, Sec. III-B, Fig. 4).

Shape: a main region enclosing the presenter plus two or more rectangular patches inside it
(head / torso / legs, or whatever fits). Appearance: one normalised hue-saturation histogram
per patch (see ``engine.presenter.likelihood`` for the bins).

Patch geometry is stored relative to the main region (``rel_boxes``: x0, y0, x1, y1 as
fractions of the main region's width and height) so that the particle state (x, y, h) -
main-region centre and height - places every patch (the "warp" of Sec. III-C.3).

Persistence: ``<folder>/model.json`` (versioned) + ``<folder>/reference.png``; histograms are
rebuilt from the reference image on load, so nothing binary besides the PNG is stored.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8, xywh
from engine.persist import atomic_write_json, atomic_write_png, read_json_file
from engine.presenter import PresenterError
from engine.presenter.likelihood import (
    apply_gains,
    chromatic_fraction,
    direct_histogram,
    frame_grey_level,
    grey_world_gains,
)

XYWH = tuple[float, float, float, float]
F64 = NDArray[np.float64]
MODEL_VERSION = 1
MIN_SIDE_PX = 2.0
GREY_FRACTION = 0.2  # below this fraction of pixels with a hue, a patch is reported grey


@dataclass(frozen=True, slots=True)
class PatchSpec:
    """One named rectangular patch in reference-image pixel coordinates."""

    name: str
    xywh: XYWH


@dataclass(frozen=True, slots=True)
class PatchModel:
    """A validated model: main region, patches, their histograms (rows sum to 1)."""

    main_xywh: XYWH
    patches: tuple[PatchSpec, ...]
    n_bins: int
    hists: NDArray[np.float64]  # (P, N*N + N)
    rel_boxes: NDArray[np.float64]  # (P, 4) x0, y0, x1, y1 / main w, h
    warnings: tuple[str, ...] = field(default=())
    grey_world: bool = True  # histograms of grey-world balanced images (frames must match)
    #: the reference image's mean grey level (``likelihood.frame_grey_level``): the level
    #: exposure normalisation brings each frame to
    grey_level: float = math.nan

    def __post_init__(self) -> None:
        self.hists.flags.writeable = False
        self.rel_boxes.flags.writeable = False

    @property
    def aspect(self) -> float:
        """Main region width / height (the state's h sets the height)."""
        return self.main_xywh[2] / self.main_xywh[3]

    @property
    def sqrt_hists(self) -> NDArray[np.float64]:
        return np.sqrt(self.hists)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.patches)

    def state_of_main(self) -> tuple[float, float, float]:
        """The (x, y, h) state of the reference main region."""
        x, y, w, h = self.main_xywh
        return (x + w / 2.0, y + h / 2.0, h)

    def boxes_at(self, x: float, y: float, h: float) -> list[XYWH]:
        """Main region and patch boxes (xywh) at state (x, y, h)."""
        w = h * self.aspect
        left, top = x - w / 2.0, y - h / 2.0
        out: list[XYWH] = [(left, top, w, h)]
        for r in self.rel_boxes:
            out.append((left + r[0] * w, top + r[1] * h, (r[2] - r[0]) * w, (r[3] - r[1]) * h))
        return out


def _check_rect(label: str, xywh: Sequence[float]) -> XYWH:
    if len(xywh) != 4 or not all(np.isfinite(v) for v in xywh):
        raise PresenterError(f"{label}: expected 4 finite numbers x,y,w,h, got {list(xywh)}")
    x, y, w, h = (float(v) for v in xywh)
    if w < MIN_SIDE_PX or h < MIN_SIDE_PX:
        raise PresenterError(
            f"{label}: zero-area selection ({w:.0f}x{h:.0f} px); drag a rectangle of at least "
            f"{MIN_SIDE_PX:.0f}x{MIN_SIDE_PX:.0f} px"
        )
    return (x, y, w, h)


def validate_selection(image_shape: tuple[int, ...], main_xywh: Sequence[float],
                       patches: Sequence[PatchSpec]) -> None:
    """Raise PresenterError with a one-line reason for a degenerate selection."""
    H, W = int(image_shape[0]), int(image_shape[1])
    mx, my, mw, mh = _check_rect("main region", main_xywh)
    if mx >= W or my >= H or mx + mw <= 0 or my + mh <= 0:
        raise PresenterError(f"main region {mx:.0f},{my:.0f},{mw:.0f},{mh:.0f} lies outside "
                             f"the {W}x{H} image")
    if len(patches) < 2:
        raise PresenterError(f"the model needs at least two patches inside the main region, "
                             f"got {len(patches)}")
    names = [p.name for p in patches]
    if len(set(names)) != len(names) or any(not n.strip() for n in names):
        raise PresenterError(f"patch names must be unique and non-empty, got {names}")
    tol = 1.0
    for p in patches:
        x, y, w, h = _check_rect(f"patch {p.name!r}", p.xywh)
        if x < mx - tol or y < my - tol or x + w > mx + mw + tol or y + h > my + mh + tol:
            raise PresenterError(
                f"patch {p.name!r} ({x:.0f},{y:.0f},{w:.0f},{h:.0f}) is not inside the main "
                f"region ({mx:.0f},{my:.0f},{mw:.0f},{mh:.0f})"
            )


def build_model(image_bgr: NDArray[np.uint8], main_xywh: Sequence[float],
                patches: Sequence[PatchSpec], n_bins: int = 10,
                allow_grey: bool = True, grey_world: bool = True) -> PatchModel:
    """Validate a selection on a reference image and collect the patch histograms.

    A grey patch (fewer than 20 % of its pixels with a hue) is an error unless
    ``allow_grey``; with ``allow_grey`` it becomes a warning (its histogram then lives in the
    brightness bins, which still works but tells colours apart less well).
    """
    if image_bgr is None or image_bgr.ndim != 3 or image_bgr.shape[2] != 3:
        raise PresenterError("reference image must be a colour (H, W, 3) BGR image")
    validate_selection(image_bgr.shape, main_xywh, patches)
    if not 2 <= n_bins <= 32:
        raise PresenterError(f"histogram bins per axis must be in 2..32, got {n_bins}")
    balanced = apply_gains(image_bgr, grey_world_gains(image_bgr)) if grey_world else image_bgr
    hsv = u8(cv2.cvtColor(balanced, cv2.COLOR_BGR2HSV))
    mx, my, mw, mh = (float(v) for v in main_xywh)
    hists, rels, warnings = [], [], []
    for p in patches:
        x, y, w, h = (float(v) for v in p.xywh)
        ix = (round(x), round(y), max(round(w), 1), max(round(h), 1))
        counts = direct_histogram(hsv, ix, n_bins)
        if counts.sum() <= 0:
            raise PresenterError(f"patch {p.name!r} lies outside the {image_bgr.shape[1]}x"
                                 f"{image_bgr.shape[0]} image")
        frac = chromatic_fraction(hsv, ix)
        if frac < GREY_FRACTION:
            msg = (f"patch {p.name!r} is grey: only {100 * frac:.0f}% of its pixels have a hue; "
                   "its histogram uses brightness only")
            if not allow_grey:
                raise PresenterError(msg)
            warnings.append(msg)
        hists.append(counts / counts.sum())
        rels.append(((x - mx) / mw, (y - my) / mh, (x + w - mx) / mw, (y + h - my) / mh))
    return PatchModel(
        main_xywh=(mx, my, mw, mh),
        patches=tuple(PatchSpec(p.name, xywh(p.xywh)) for p in patches),
        n_bins=n_bins,
        hists=np.asarray(hists, dtype=np.float64),
        rel_boxes=np.asarray(rels, dtype=np.float64),
        warnings=tuple(warnings),
        grey_world=grey_world,
        grey_level=frame_grey_level(image_bgr),
    )


AUTO_SPLITS: dict[int, tuple[tuple[str, float, float], ...]] = {
    2: (("upper", 0.0, 0.45), ("lower", 0.45, 1.0)),
    3: (("head", 0.0, 0.25), ("torso", 0.25, 0.6), ("legs", 0.6, 1.0)),
    4: (("top", 0.0, 0.25), ("upper", 0.25, 0.5), ("lower", 0.5, 0.75), ("bottom", 0.75, 1.0)),
}


def patch_histograms(image_bgr: NDArray[np.uint8],
                     patches: Sequence[tuple[str, Sequence[float]]], n_bins: int,
                     grey_world: bool = False) -> list[tuple[str, F64]]:
    """Normalised hue-saturation (+ brightness) histograms of drawn patches, also while the
    selection is not a valid model yet (the set-up page shows them as the operator drags).

    Patches without any pixel in the image are left out.
    """
    img = apply_gains(image_bgr, grey_world_gains(image_bgr)) if grey_world else image_bgr
    hsv = u8(cv2.cvtColor(img, cv2.COLOR_BGR2HSV))
    out: list[tuple[str, F64]] = []
    for name, rect in patches:
        x, y, w, h = (round(v) for v in rect)
        c = direct_histogram(hsv, (x, y, max(w, 1), max(h, 1)), n_bins)
        if c.sum() > 0:
            out.append((name, c / c.sum()))
    return out


#: a standing person's box (at least twice as tall as wide): head, torso and legs do not fill
#: it side to side, so each band keeps its middle (head narrow, torso with the arms wider):
#: the patches an operator would drag, with little of the background around the body
FULL_BODY_ASPECT = 0.5
BODY_BAND_WIDTHS = {3: (0.5, 0.8, 0.6)}


def auto_patches(main_xywh: Sequence[float], n: int = 3) -> tuple[PatchSpec, ...]:
    """Split a main region into ``n`` horizontal bands (head / torso / legs for n = 3); for a
    full-body box (width / height <= 0.5) the three bands keep their middle only
    (``BODY_BAND_WIDTHS``)."""
    if n not in AUTO_SPLITS:
        raise PresenterError(f"automatic split supports 2, 3 or 4 patches, got {n}")
    x, y, w, h = (float(v) for v in main_xywh)
    widths = BODY_BAND_WIDTHS.get(n) if h > 0 and w / h <= FULL_BODY_ASPECT else None
    out = []
    for k, (name, a, b) in enumerate(AUTO_SPLITS[n]):
        f = 1.0 if widths is None else widths[k]
        out.append(PatchSpec(name, (x + 0.5 * (1.0 - f) * w, y + a * h, f * w, (b - a) * h)))
    return tuple(out)


def model_from_box(image_bgr: NDArray[np.uint8], box_xywh: Sequence[float], n_patches: int = 3,
                   n_bins: int = 10, grey_world: bool = True) -> PatchModel:
    """Model from a single box (e.g. the first ground-truth box), patches split automatically."""
    H, W = image_bgr.shape[:2]
    x, y, w, h = (float(v) for v in box_xywh)
    # keep the main region inside the image so every patch has pixels
    x0, y0 = max(x, 0.0), max(y, 0.0)
    x1, y1 = min(x + w, float(W)), min(y + h, float(H))
    main = (x0, y0, x1 - x0, y1 - y0)
    return build_model(image_bgr, main, auto_patches(main, n_patches), n_bins, allow_grey=True,
                       grey_world=grey_world)


def model_from_parts(image_bgr: NDArray[np.uint8], box_xywh: Sequence[float],
                     parts: Mapping[str, Sequence[float]], n_bins: int = 10,
                     grey_world: bool = True) -> PatchModel:
    """Model from a main box and named part boxes (clipped into the main region)."""
    H, W = image_bgr.shape[:2]
    x, y, w, h = (float(v) for v in box_xywh)
    x0, y0 = max(x, 0.0), max(y, 0.0)
    x1, y1 = min(x + w, float(W)), min(y + h, float(H))
    patches = []
    for name, (px, py, pw, ph) in parts.items():
        a0, b0 = max(px, x0), max(py, y0)
        a1, b1 = min(px + pw, x1), min(py + ph, y1)
        patches.append(PatchSpec(name, (a0, b0, a1 - a0, b1 - b0)))
    return build_model(image_bgr, (x0, y0, x1 - x0, y1 - y0), patches, n_bins,
                       allow_grey=True, grey_world=grey_world)


# --------------------------------------------------------------------------- persistence


def save_model(folder: Path, model: PatchModel, reference_bgr: NDArray[np.uint8],
               view: str = "frontal") -> Path:
    """Write ``model.json`` + ``reference.png`` into ``folder`` (atomically); returns the JSON."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_png(folder / "reference.png", np.ascontiguousarray(reference_bgr))
    doc = {
        "format": "studiotrack.presenter_model",
        "version": MODEL_VERSION,
        "view": view,
        "n_bins": model.n_bins,
        "grey_world": model.grey_world,
        "reference_image": "reference.png",
        "main_xywh": list(model.main_xywh),
        "patches": [{"name": p.name, "xywh": list(p.xywh)} for p in model.patches],
    }
    atomic_write_json(folder / "model.json", doc)
    return folder / "model.json"


def load_model(path: Path) -> tuple[PatchModel, NDArray[np.uint8]]:
    """Read a model folder (or its model.json); returns the model and the reference image."""
    path = Path(path)
    jpath = path / "model.json" if path.is_dir() else path
    doc = read_json_file(jpath, PresenterError, missing="no such presenter model")
    if doc.get("format") != "studiotrack.presenter_model" or doc.get("version") != MODEL_VERSION:
        raise PresenterError(f"{jpath}: not a version-{MODEL_VERSION} presenter model")
    img_path = jpath.parent / str(doc.get("reference_image", "reference.png"))
    read = cv2.imread(str(img_path), cv2.IMREAD_COLOR)
    if read is None:
        raise PresenterError(f"{img_path}: reference image missing or unreadable")
    img = u8(read)
    try:
        patches = [PatchSpec(str(p["name"]), xywh(p["xywh"]))
                   for p in doc["patches"]]
        main = [float(v) for v in doc["main_xywh"]]
        n_bins = int(doc.get("n_bins", 10))
        grey_world = bool(doc.get("grey_world", True))
    except (KeyError, TypeError, ValueError) as exc:
        raise PresenterError(f"{jpath}: malformed model ({exc})") from None
    return build_model(img, main, patches, n_bins, allow_grey=True, grey_world=grey_world), img
