"""Lens files: intrinsics over zoom and focus, as every studio tracker sends them.

A lens file is a table over the lens's zoom and focus *encoder* values (raw counts, as a lens
encoder, a PTZ camera or FreeD reports them). Each grid point is one calibrated
:class:`LensSample`: focal length (px), principal point, Brown-Conrady / Caltech distortion
k1 k2 k3 p1 p2 (:mod:`engine.camera`, eq. (3)-(4) of Tykkälä 2014, OpenCV's order), the
entrance-pupil offset along the optical axis (m, positive towards the scene) and the
calibration's reprojection error. Between samples every value is interpolated bilinearly in
(zoom, focus); outside the table the nearest edge holds. :meth:`LensFile.evaluate` gives the
:class:`LensState` of one pair of encoder values: intrinsics, focal length in mm, field of
view, normalised encoders (0 wide/infinity .. 1 tele/close, as OpenTrackIO wants them).

File (versioned JSON, one of the studio project's documents)::

    {"format": "studiotrack-lens", "version": 1, "name": "...",
     "image": {"width": 1920, "height": 1080}, "sensor_width_mm": 9.59,
     "encoder_range": {"zoom": [0, 65535], "focus": [0, 65535]},
     "zoom_raw": [0, 16384, ...], "focus_raw": [0, ...],        (strictly increasing axes)
     "samples": [{"zoom_raw": 0, "focus_raw": 0, "fx_px": ..., "fy_px": ..., "cx_px": ...,
                  "cy_px": ..., "k1": ..., "k2": ..., "k3": ..., "p1": ..., "p2": ...,
                  "entrance_pupil_m": 0.0, "rms_px": 0.2, "note": "chessboard 12 images"}]}

Every grid point (zoom x focus) needs a sample before the file can be used live (a
"missing corner" is named); a table that is being calibrated one sample at a time may be
incomplete in the project. A fixed lens is a one-sample file (:meth:`LensFile.fixed`, from
``camera.json`` or a calibration).

Frames carry the encoders as :class:`LensEncoders` (from a source, a FreeD input, or typed by
the operator) and, once a lens file is applied (:class:`engine.sources.lensed.LensedSource`),
the evaluated :class:`LensState`; the outputs send the state (OpenTrackIO ``lens``, FreeD
zoom/focus) and trackers read ``frame.intrinsics``.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from engine.camera import Intrinsics
from engine.errors import CalibrationError
from engine.frames import FramePayload

LENS_FORMAT = "studiotrack-lens"
LENS_VERSION = 1
U32_MAX = 0xFFFFFFFF
#: the values interpolated between samples, in file order
VALUE_FIELDS = ("fx_px", "fy_px", "cx_px", "cy_px", "k1", "k2", "k3", "p1", "p2",
                "entrance_pupil_m")


class LensError(CalibrationError):
    """A lens file or lens sample is malformed (one line naming the file and field)."""


@dataclass(frozen=True, slots=True)
class LensEncoders(FramePayload):
    """Raw lens encoder counts at the frame (zoom, focus; iris when known)."""

    zoom_raw: int
    focus_raw: int = 0
    iris_raw: int | None = None


@dataclass(frozen=True, slots=True)
class LensSample:
    """One calibrated (zoom, focus) point of a lens file."""

    zoom_raw: int
    focus_raw: int
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    entrance_pupil_m: float = 0.0
    rms_px: float | None = None
    note: str = ""

    def __post_init__(self) -> None:
        self.check("lens sample")

    def check(self, where: str) -> None:
        for name in ("zoom_raw", "focus_raw"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= U32_MAX:
                raise LensError(f"{where}.{name}: {v!r} is not an encoder count 0..{U32_MAX}")
        for name in VALUE_FIELDS:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise LensError(f"{where}.{name}: {v!r} is not a finite number")
        for name in ("fx_px", "fy_px"):
            if getattr(self, name) <= 0:
                raise LensError(f"{where}.{name}: focal length {getattr(self, name)!r} must "
                                "be > 0")
        if self.rms_px is not None and not (math.isfinite(self.rms_px) and self.rms_px >= 0):
            raise LensError(f"{where}.rms_px: {self.rms_px!r} is not a finite number >= 0")

    @staticmethod
    def from_intrinsics(cam: Intrinsics, zoom_raw: int = 0, focus_raw: int = 0,
                        entrance_pupil_m: float = 0.0, rms_px: float | None = None,
                        note: str = "") -> LensSample:
        k1, k2, p1, p2, k3 = (float(v) for v in cam.dist_k1k2p1p2k3)
        return LensSample(int(zoom_raw), int(focus_raw), float(cam.fx), float(cam.fy),
                          float(cam.cx), float(cam.cy), k1, k2, k3, p1, p2,
                          float(entrance_pupil_m), rms_px, note)

    def values(self) -> np.ndarray:
        return np.array([float(getattr(self, n)) for n in VALUE_FIELDS])

    def to_json(self) -> dict[str, Any]:
        d: dict[str, Any] = {"zoom_raw": self.zoom_raw, "focus_raw": self.focus_raw}
        d.update({n: float(getattr(self, n)) for n in VALUE_FIELDS})
        d["rms_px"] = self.rms_px
        d["note"] = self.note
        return d

    @staticmethod
    def from_json(d: Any, where: str) -> LensSample:
        if not isinstance(d, Mapping):
            raise LensError(f"{where}: expected an object, got {type(d).__name__}")
        missing = [k for k in ("zoom_raw", "focus_raw", "fx_px", "fy_px", "cx_px", "cy_px")
                   if k not in d]
        if missing:
            raise LensError(f"{where}: missing field {missing[0]!r}")
        unknown = sorted(set(d) - {"zoom_raw", "focus_raw", "rms_px", "note", *VALUE_FIELDS})
        if unknown:
            raise LensError(f"{where}: unknown field {unknown[0]!r}")
        kw: dict[str, Any] = {}
        for k in ("zoom_raw", "focus_raw"):
            v = d[k]
            if isinstance(v, float) and v.is_integer():
                v = int(v)
            kw[k] = v
        for k in VALUE_FIELDS:
            if k in d:
                v = d[k]
                if v is None or isinstance(v, bool) or not isinstance(v, int | float):
                    raise LensError(f"{where}.{k}: {v!r} is not a finite number")
                kw[k] = float(v)
        rms = d.get("rms_px")
        if rms is not None and (isinstance(rms, bool) or not isinstance(rms, int | float)):
            raise LensError(f"{where}.rms_px: {rms!r} is not a number")
        kw["rms_px"] = None if rms is None else float(rms)
        kw["note"] = str(d.get("note", ""))
        try:
            return LensSample(**kw)
        except LensError as exc:
            raise LensError(str(exc).replace("lens sample", where, 1)) from None


@dataclass(frozen=True, slots=True)
class LensState(FramePayload):
    """The lens at one frame: encoders and what the lens file gives for them."""

    zoom_raw: int
    focus_raw: int
    zoom_norm: float  # 0 wide .. 1 tele (encoder range of the file)
    focus_norm: float  # 0 .. 1 over the focus encoder range
    intrinsics: Intrinsics
    focal_length_mm: float
    entrance_pupil_m: float
    fov_h_deg: float
    fov_v_deg: float
    sensor_width_mm: float
    iris_raw: int | None = None

    @property
    def k1(self) -> float:
        return float(self.intrinsics.dist_k1k2p1p2k3[0])


@dataclass(frozen=True, slots=True)
class LensFile:
    """A lens table over zoom and focus encoders (see the module docstring)."""

    width: int
    height: int
    samples: tuple[LensSample, ...] = ()
    sensor_width_mm: float = 9.59
    zoom_range_raw: tuple[int, int] = (0, 65535)
    focus_range_raw: tuple[int, int] = (0, 65535)
    name: str = "lens"
    _grid: Any = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.samples, tuple):
            object.__setattr__(self, "samples", tuple(self.samples))
        for k in ("width", "height"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
                raise LensError(f"lens file {self.name!r}: image {k} {v!r} must be a "
                                "positive integer")
        if not (math.isfinite(self.sensor_width_mm) and self.sensor_width_mm > 0):
            raise LensError(f"lens file {self.name!r}: sensor_width_mm "
                            f"{self.sensor_width_mm!r} must be > 0")
        for k in ("zoom_range_raw", "focus_range_raw"):
            lo, hi = getattr(self, k)
            if not (isinstance(lo, int) and isinstance(hi, int) and 0 <= lo < hi <= U32_MAX):
                raise LensError(f"lens file {self.name!r}: {k} {(lo, hi)!r} must be two "
                                "increasing encoder counts")
        seen: dict[tuple[int, int], int] = {}
        for i, s in enumerate(self.samples):
            key = (s.zoom_raw, s.focus_raw)
            if key in seen:
                raise LensError(f"lens file {self.name!r}: samples[{i}] repeats zoom "
                                f"{key[0]}, focus {key[1]} of samples[{seen[key]}]")
            seen[key] = i

    # -- building ----------------------------------------------------------------------
    @staticmethod
    def fixed(cam: Intrinsics, sensor_width_mm: float = 9.59, name: str = "fixed lens",
              entrance_pupil_m: float = 0.0, note: str = "camera.json") -> LensFile:
        """A fixed lens: one sample that holds at every encoder value."""
        return LensFile(cam.width, cam.height,
                        (LensSample.from_intrinsics(cam, 0, 0, entrance_pupil_m, note=note),),
                        sensor_width_mm=sensor_width_mm, name=name)

    def with_sample(self, sample: LensSample) -> LensFile:
        """A new file with ``sample`` added (replacing one at the same zoom and focus)."""
        rest = tuple(s for s in self.samples
                     if (s.zoom_raw, s.focus_raw) != (sample.zoom_raw, sample.focus_raw))
        return replace(self, samples=tuple(sorted((*rest, sample),
                                                  key=lambda s: (s.zoom_raw, s.focus_raw))))

    def without_sample(self, zoom_raw: int, focus_raw: int) -> LensFile:
        return replace(self, samples=tuple(s for s in self.samples
                                           if (s.zoom_raw, s.focus_raw) != (zoom_raw, focus_raw)))

    # -- the grid ------------------------------------------------------------------------
    @property
    def zoom_axis(self) -> tuple[int, ...]:
        return tuple(sorted({s.zoom_raw for s in self.samples}))

    @property
    def focus_axis(self) -> tuple[int, ...]:
        return tuple(sorted({s.focus_raw for s in self.samples}))

    def missing_corners(self) -> list[tuple[int, int]]:
        have = {(s.zoom_raw, s.focus_raw) for s in self.samples}
        return [(z, f) for z in self.zoom_axis for f in self.focus_axis if (z, f) not in have]

    def check_complete(self, where: str | None = None) -> None:
        """Raise :class:`LensError` unless every (zoom, focus) grid point has a sample."""
        w = where or f"lens file {self.name!r}"
        if not self.samples:
            raise LensError(f"{w}: has no samples")
        missing = self.missing_corners()
        if missing:
            z, f = missing[0]
            raise LensError(f"{w}: missing corner zoom {z}, focus {f} ({len(missing)} grid "
                            "point(s) without a sample; calibrate them or delete the row)")

    @property
    def complete(self) -> bool:
        return bool(self.samples) and not self.missing_corners()

    def _table(self) -> tuple[tuple[int, ...], tuple[int, ...], np.ndarray]:
        grid: tuple[tuple[int, ...], tuple[int, ...], np.ndarray] | None = self._grid
        if grid is None:
            self.check_complete()
            za, fa = self.zoom_axis, self.focus_axis
            vals = np.empty((len(za), len(fa), len(VALUE_FIELDS)))
            for s in self.samples:
                vals[za.index(s.zoom_raw), fa.index(s.focus_raw)] = s.values()
            grid = (za, fa, vals)
            object.__setattr__(self, "_grid", grid)
        return grid

    def values_at(self, zoom_raw: float, focus_raw: float) -> dict[str, float]:
        """Bilinear interpolation of every value at the encoder pair (edges hold)."""
        za, fa, vals = self._table()
        iz, tz = _bracket(za, zoom_raw)
        jf, tf = _bracket(fa, focus_raw)
        iz1, jf1 = min(iz + 1, len(za) - 1), min(jf + 1, len(fa) - 1)
        v = ((1 - tz) * (1 - tf) * vals[iz, jf] + tz * (1 - tf) * vals[iz1, jf]
             + (1 - tz) * tf * vals[iz, jf1] + tz * tf * vals[iz1, jf1])
        return dict(zip(VALUE_FIELDS, (float(x) for x in v), strict=True))

    def intrinsics_at(self, zoom_raw: float, focus_raw: float = 0,
                      depth_scale: float = 5000.0) -> Intrinsics:
        v = self.values_at(zoom_raw, focus_raw)
        return Intrinsics(fx=v["fx_px"], fy=v["fy_px"], cx=v["cx_px"], cy=v["cy_px"],
                          width=self.width, height=self.height,
                          dist_k1k2p1p2k3=(v["k1"], v["k2"], v["p1"], v["p2"], v["k3"]),
                          depth_scale=depth_scale)

    def focal_length_mm(self, fx_px: float) -> float:
        return fx_px * self.sensor_width_mm / self.width

    def evaluate(self, zoom_raw: int, focus_raw: int = 0, iris_raw: int | None = None,
                 depth_scale: float = 5000.0) -> LensState:
        """The :class:`LensState` of one encoder pair."""
        cam = self.intrinsics_at(zoom_raw, focus_raw, depth_scale)
        epo = self.values_at(zoom_raw, focus_raw)["entrance_pupil_m"]
        return LensState(
            zoom_raw=int(zoom_raw), focus_raw=int(focus_raw),
            zoom_norm=_norm(zoom_raw, self.zoom_range_raw),
            focus_norm=_norm(focus_raw, self.focus_range_raw),
            intrinsics=cam, focal_length_mm=self.focal_length_mm(cam.fx),
            entrance_pupil_m=epo,
            fov_h_deg=math.degrees(2 * math.atan(cam.width / 2.0 / cam.fx)),
            fov_v_deg=math.degrees(2 * math.atan(cam.height / 2.0 / cam.fy)),
            sensor_width_mm=self.sensor_width_mm, iris_raw=iris_raw,
        )

    def curve(self, field_name: str, n: int = 100, focus_raw: float | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
        """(zoom values, interpolated ``field_name``) across the zoom axis (plots); field
        ``focal_length_mm`` and ``fov_h_deg`` are derived."""
        za, fa, _ = self._table()
        f = fa[0] if focus_raw is None else focus_raw
        z = np.linspace(za[0], za[-1], n) if len(za) > 1 else np.array([float(za[0])])
        out = []
        for zz in z:
            v = self.values_at(float(zz), float(f))
            if field_name == "focal_length_mm":
                out.append(self.focal_length_mm(v["fx_px"]))
            elif field_name == "fov_h_deg":
                out.append(math.degrees(2 * math.atan(self.width / 2.0 / v["fx_px"])))
            else:
                out.append(v[field_name])
        return z, np.asarray(out)

    # -- persistence --------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        return {
            "format": LENS_FORMAT,
            "version": LENS_VERSION,
            "name": self.name,
            "image": {"width": self.width, "height": self.height},
            "sensor_width_mm": self.sensor_width_mm,
            "encoder_range": {"zoom": list(self.zoom_range_raw),
                              "focus": list(self.focus_range_raw)},
            "zoom_raw": list(self.zoom_axis),
            "focus_raw": list(self.focus_axis),
            "samples": [s.to_json() for s in self.samples],
        }

    @staticmethod
    def from_json(d: Any, where: str = "lens file", require_complete: bool = True) -> LensFile:
        """Parse and check a lens document; every problem is one line naming ``where``."""
        if not isinstance(d, Mapping):
            raise LensError(f"{where}: expected a JSON object, got {type(d).__name__}")
        if d.get("format") != LENS_FORMAT:
            raise LensError(f"{where}: 'format' is {d.get('format')!r}, not {LENS_FORMAT!r}")
        ver = d.get("version")
        if isinstance(ver, bool) or not isinstance(ver, int) or ver < 1:
            raise LensError(f"{where}: 'version' must be a positive integer, got {ver!r}")
        if ver > LENS_VERSION:
            raise LensError(f"{where}: lens file version {ver} is newer than this StudioTrack "
                            f"supports ({LENS_VERSION})")
        img = d.get("image")
        if not isinstance(img, Mapping) or not all(k in img for k in ("width", "height")):
            raise LensError(f"{where}: 'image' must be {{'width': W, 'height': H}}")
        sw = d.get("sensor_width_mm", 9.59)
        if isinstance(sw, bool) or not isinstance(sw, int | float) or not math.isfinite(sw):
            raise LensError(f"{where}: 'sensor_width_mm' {sw!r} is not a finite number")
        rng = d.get("encoder_range", {"zoom": [0, 65535], "focus": [0, 65535]})
        ranges = []
        for axis in ("zoom", "focus"):
            r = rng.get(axis) if isinstance(rng, Mapping) else None
            if (not isinstance(r, list) or len(r) != 2
                    or not all(isinstance(x, int) and not isinstance(x, bool) for x in r)):
                raise LensError(f"{where}: 'encoder_range.{axis}' must be [lo, hi] counts")
            ranges.append((int(r[0]), int(r[1])))
        raw = d.get("samples")
        if not isinstance(raw, list):
            raise LensError(f"{where}: 'samples' must be a list")
        samples = tuple(LensSample.from_json(s, f"{where}: samples[{i}]")
                        for i, s in enumerate(raw))
        for axis in ("zoom_raw", "focus_raw"):
            ax = d.get(axis)
            if ax is None:
                continue
            if not isinstance(ax, list) or not all(
                    isinstance(x, int) and not isinstance(x, bool) for x in ax):
                raise LensError(f"{where}: '{axis}' axis must be a list of encoder counts")
            for i in range(1, len(ax)):
                if ax[i] <= ax[i - 1]:
                    raise LensError(f"{where}: '{axis}' axis is not strictly increasing at "
                                    f"index {i} ({ax[i]} after {ax[i - 1]})")
            have = sorted({getattr(s, axis) for s in samples})
            if list(ax) != have:
                extra = sorted(set(ax) ^ set(have))
                raise LensError(f"{where}: '{axis}' axis {ax} does not match the samples' "
                                f"values (differs at {extra[0]})")
        try:
            lf = LensFile(int(img["width"]), int(img["height"]), samples,
                          sensor_width_mm=float(sw), zoom_range_raw=ranges[0],
                          focus_range_raw=ranges[1], name=str(d.get("name", "lens")))
        except (TypeError, ValueError) as exc:
            raise LensError(f"{where}: {exc}") from None
        except LensError as exc:
            raise LensError(f"{where}: {str(exc).split(': ', 1)[-1]}") from None
        if require_complete:
            lf.check_complete(where)
        return lf

    def save(self, path: str | Path) -> None:
        from engine.persist import atomic_write_json

        atomic_write_json(Path(path), self.to_json())

    @staticmethod
    def load(path: str | Path, require_complete: bool = True) -> LensFile:
        from engine.persist import read_json_file

        p = Path(path)
        raw = read_json_file(p, LensError, missing="file not found", corrupt="corrupt JSON")
        return LensFile.from_json(raw, str(p), require_complete=require_complete)


def _bracket(axis: tuple[int, ...], x: float) -> tuple[int, float]:
    """Lower index and fraction of ``x`` in a strictly increasing axis (clamped)."""
    if len(axis) == 1 or x <= axis[0]:
        return 0, 0.0
    if x >= axis[-1]:
        return len(axis) - 1, 0.0
    i = bisect.bisect_right(axis, x) - 1
    return i, (x - axis[i]) / (axis[i + 1] - axis[i])


def _norm(raw: float, rng: tuple[int, int]) -> float:
    lo, hi = rng
    return float(min(1.0, max(0.0, (raw - lo) / (hi - lo))))


def samples_table(lens: LensFile) -> Iterable[tuple[int, int, float, float, float | None]]:
    """(zoom, focus, focal mm, k1, rms px) per sample, for lists in the GUI and the CLI."""
    for s in lens.samples:
        yield s.zoom_raw, s.focus_raw, lens.focal_length_mm(s.fx_px), s.k1, s.rms_px
