"""The pan-tilt calibration chain as the live tracker uses it (Gaspar 2009 sec. 3).

What the set-up tools estimate and the project stores (:class:`PtzCalibration`):

- the line-based inverse radial distortion (sec. 3.3, :mod:`engine.ptz.distortion`),
  applied to every measurement before the pinhole model is used;
- the head geometry from DLTs (sec. 3.1-3.2): one DLT gives the optical centre and
  orientation at the motor angles it was taken at (:func:`engine.ptz.kinematics.
  head_from_dlt`, the optical-centre offset assumed); DLTs at two or more pan/tilt poses
  give the rotation centre *and* the offset (:func:`head_from_dlts`: the optical centres
  ``c_i = r + R_i o`` are linear in the rotation centre ``r`` and the offset ``o``);
- the reference points of known world position used to estimate pan and tilt in every
  frame where the head has no encoder (sec. 3.2, :func:`engine.ptz.kinematics.
  estimate_pan_tilt`), with the colour of their markers for the automatic detector
  (:func:`detect_markers`, :func:`identify_markers`).

JSON (the project's ``ptz.json``, versioned)::

    {"format": "studiotrack-ptz-calibration", "version": 1,
     "head": {"K": 3x3, "rotation_centre_world_m": [3], "optical_offset_cam_m": [3],
              "pan0_deg": .., "tilt0_deg": .., "roll_deg": ..},
     "distortion": {"model": "inverse_radial", "k": [...], "centre_px": [2], "r_norm_px": ..}
                   | null,
     "reference_points_world_m": [[x, y, z], ...], "marker_bgr": [b, g, r] | null,
     "dlt": {"poses": [{"pan_deg", "tilt_deg", "rmse_px", "points"}], "image_size": [w, h]}}
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.errors import CalibrationError
from engine.geometry import pan_tilt_roll_deg
from engine.ptz.distortion import RadialModel
from engine.ptz.dlt import DltDecomposition, project_P
from engine.ptz.kinematics import PtzHead, estimate_pan_tilt

F64 = NDArray[np.float64]
PTZ_FORMAT = "studiotrack-ptz-calibration"
PTZ_VERSION = 1


@dataclass(frozen=True, slots=True)
class DltPose:
    """One DLT of the chain: the motor angles it was taken at and its quality."""

    pan_deg: float
    tilt_deg: float
    rmse_px: float
    points: int


@dataclass(frozen=True, slots=True)
class PtzCalibration:
    """Everything the calibrated pan-tilt chain needs (see the module docstring)."""

    head: PtzHead | None  # None until a DLT was solved (the lines may come first)
    radial: RadialModel | None = None
    reference_points_world_m: F64 | None = None  # (N, 3)
    marker_bgr: tuple[int, int, int] | None = None
    dlt_poses: tuple[DltPose, ...] = ()
    image_size: tuple[int, int] | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)

    def undistort_px(self, uv: F64) -> F64:
        """Ideal (pinhole) pixels of measured pixels (sec. 3.3); identity without a model."""
        a = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        return a if self.radial is None else self.radial.undistort_px(a)

    # ------------------------------------------------------------------ persistence
    def to_json(self) -> dict[str, Any]:
        h = self.head
        return {
            "format": PTZ_FORMAT,
            "version": PTZ_VERSION,
            "head": None if h is None else {
                "K": np.asarray(h.K).tolist(),
                "rotation_centre_world_m": np.asarray(h.rotation_centre_world_m).tolist(),
                "optical_offset_cam_m": np.asarray(h.optical_offset_cam_m).tolist(),
                "pan0_deg": h.pan0_deg, "tilt0_deg": h.tilt0_deg, "roll_deg": h.roll_deg},
            "distortion": None if self.radial is None else self.radial.to_json_dict(),
            "reference_points_world_m": None if self.reference_points_world_m is None
            else np.asarray(self.reference_points_world_m).tolist(),
            "marker_bgr": None if self.marker_bgr is None else list(self.marker_bgr),
            "dlt": {"poses": [{"pan_deg": p.pan_deg, "tilt_deg": p.tilt_deg,
                               "rmse_px": p.rmse_px, "points": p.points}
                              for p in self.dlt_poses],
                    "image_size": None if self.image_size is None else list(self.image_size)},
        }

    @staticmethod
    def from_json(d: Any, where: str = "ptz calibration") -> PtzCalibration:
        """Parse and check; every problem is one line naming ``where`` and the field."""
        if not isinstance(d, Mapping) or d.get("format") != PTZ_FORMAT:
            raise CalibrationError(f"{where}: not a {PTZ_FORMAT} document")
        ver = d.get("version")
        if isinstance(ver, bool) or not isinstance(ver, int) or ver < 1:
            raise CalibrationError(f"{where}: 'version' must be a positive integer")
        if ver > PTZ_VERSION:
            raise CalibrationError(f"{where}: version {ver} is newer than this StudioTrack "
                                   f"supports ({PTZ_VERSION})")
        h = d.get("head")
        if h is not None and not isinstance(h, Mapping):
            raise CalibrationError(f"{where}: 'head' must be an object or null")
        head = None if h is None else _head_of(h, where)
        radial = None
        dist = d.get("distortion")
        if dist is not None:
            if not isinstance(dist, Mapping) or dist.get("model") != "inverse_radial":
                raise CalibrationError(f"{where}: distortion.model must be 'inverse_radial'")
            k = dist.get("k")
            if not isinstance(k, list) or not k:
                raise CalibrationError(f"{where}: distortion.k must be a list of numbers")
            c = _array(dist.get("centre_px"), (2,), f"{where}: distortion.centre_px")
            rn = _num(dist.get("r_norm_px"), f"{where}: distortion.r_norm_px")
            if rn <= 0:
                raise CalibrationError(f"{where}: distortion.r_norm_px must be > 0")
            radial = RadialModel(tuple(_num(v, f"{where}: distortion.k") for v in k),
                                 (float(c[0]), float(c[1])), rn)
        ref = d.get("reference_points_world_m")
        ref_a = None
        if ref is not None:
            ref_a = _array(ref, None, f"{where}: reference_points_world_m")
            if ref_a.ndim != 2 or ref_a.shape[1] != 3:
                raise CalibrationError(f"{where}: reference_points_world_m must be [[x,y,z]..]")
        mb = d.get("marker_bgr")
        marker = None
        if mb is not None:
            if (not isinstance(mb, list) or len(mb) != 3
                    or not all(isinstance(v, int) and 0 <= v <= 255 for v in mb)):
                raise CalibrationError(f"{where}: marker_bgr must be three integers 0..255")
            marker = (int(mb[0]), int(mb[1]), int(mb[2]))
        dlt = d.get("dlt") or {}
        poses = []
        for i, p in enumerate(dlt.get("poses", []) if isinstance(dlt, Mapping) else []):
            w = f"{where}: dlt.poses[{i}]"
            if not isinstance(p, Mapping):
                raise CalibrationError(f"{w}: expected an object")
            poses.append(DltPose(_num(p.get("pan_deg"), f"{w}.pan_deg"),
                                 _num(p.get("tilt_deg"), f"{w}.tilt_deg"),
                                 _num(p.get("rmse_px", 0.0), f"{w}.rmse_px"),
                                 int(_num(p.get("points", 0), f"{w}.points"))))
        size = dlt.get("image_size") if isinstance(dlt, Mapping) else None
        return PtzCalibration(head, radial, ref_a, marker, tuple(poses),
                              None if size is None else (int(size[0]), int(size[1])))


def _head_of(h: Mapping[str, Any], where: str) -> PtzHead:
    K = _array(h.get("K"), (3, 3), f"{where}: head.K")
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise CalibrationError(f"{where}: head.K focal lengths must be > 0")
    return PtzHead(
        K=K,
        rotation_centre_world_m=_array(h.get("rotation_centre_world_m"), (3,),
                                       f"{where}: head.rotation_centre_world_m"),
        optical_offset_cam_m=_array(h.get("optical_offset_cam_m"), (3,),
                                    f"{where}: head.optical_offset_cam_m"),
        pan0_deg=_num(h.get("pan0_deg"), f"{where}: head.pan0_deg"),
        tilt0_deg=_num(h.get("tilt0_deg"), f"{where}: head.tilt0_deg"),
        roll_deg=_num(h.get("roll_deg"), f"{where}: head.roll_deg"),
    )


def _num(v: Any, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise CalibrationError(f"{where}: {v!r} is not a finite number")
    return float(v)


def _array(v: Any, shape: tuple[int, ...] | None, where: str) -> F64:
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise CalibrationError(f"{where}: not an array of numbers") from None
    if shape is not None and a.shape != shape:
        raise CalibrationError(f"{where}: expected shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise CalibrationError(f"{where}: contains a non-finite value")
    return a


# --------------------------------------------------------------------- head from DLTs
def head_from_dlts(decs: Sequence[DltDecomposition],
                   motor_pan_tilt_deg: Sequence[tuple[float, float]]) -> PtzHead:
    """Head geometry from DLTs taken at known motor angles (sec. 3.2).

    Orientation: each DLT's pan/tilt/roll minus its motor angles gives the mount angles
    (averaged). Centres: ``c_i = r + R_i o`` for the rotation centre ``r`` (world) and the
    optical-centre offset ``o`` (turning with the head), least squares over the poses;
    with one pose (or poses that do not turn the head) the offset is taken as zero and
    ``r = c``. K is the mean of the DLTs' K.
    """
    if len(decs) != len(motor_pan_tilt_deg) or not decs:
        raise CalibrationError(f"head from DLTs needs one motor pose per DLT, got "
                               f"{len(decs)}/{len(motor_pan_tilt_deg)}")
    pans, tilts, rolls = [], [], []
    for dec, (mp, mt) in zip(decs, motor_pan_tilt_deg, strict=True):
        p, t, r = pan_tilt_roll_deg(dec.R_cam_world.T)
        pans.append(_wrap(p - mp))
        tilts.append(t - mt)
        rolls.append(r)
    pan0 = _circ_mean(pans)
    tilt0 = float(np.mean(tilts))
    roll = _circ_mean(rolls)
    K = np.mean([d.K for d in decs], axis=0)
    head0 = PtzHead(K=K, pan0_deg=pan0, tilt0_deg=tilt0, roll_deg=roll)
    A, b = [], []
    for dec, (mp, mt) in zip(decs, motor_pan_tilt_deg, strict=True):
        R = head0.R_world_cam(mp, mt)
        A.append(np.hstack([np.eye(3), R]))
        b.append(dec.camera_centre_world)
    A_m, b_v = np.vstack(A), np.concatenate(b)
    spread = max(abs(p[0] - motor_pan_tilt_deg[0][0]) + abs(p[1] - motor_pan_tilt_deg[0][1])
                 for p in motor_pan_tilt_deg)
    if len(decs) >= 2 and spread >= 5.0:
        sol, *_ = np.linalg.lstsq(A_m, b_v, rcond=None)
        r_c, off = sol[:3], sol[3:]
    else:
        r_c, off = np.mean([d.camera_centre_world for d in decs], axis=0), np.zeros(3)
    return PtzHead(K=K, rotation_centre_world_m=r_c, optical_offset_cam_m=off, pan0_deg=pan0,
                   tilt0_deg=tilt0, roll_deg=roll)


def _wrap(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


def _circ_mean(deg: Sequence[float]) -> float:
    r = np.radians(np.asarray(deg, dtype=np.float64))
    return float(np.degrees(np.arctan2(np.sin(r).mean(), np.cos(r).mean())))


# ---------------------------------------------------------------- reference markers
def detect_markers(image_bgr: NDArray[np.uint8], marker_bgr: tuple[int, int, int],
                   min_area_px: int = 3, max_area_px: int = 2000) -> F64:
    """Centroids (N, 2) of blobs of the marker colour (score-weighted, sub-pixel)."""
    import cv2

    from engine.ptz.snake import colour_score

    score = colour_score(image_bgr, marker_bgr)
    mask = (score > 0.5).astype(np.uint8)
    n, _labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    out = []
    for i in range(1, n):
        area = int(stats[i, cv2.CC_STAT_AREA])
        if not min_area_px <= area <= max_area_px:
            continue
        x, y, w, h = (int(stats[i, k]) for k in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP,
                                                 cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT))
        x0, y0 = max(0, x - 1), max(0, y - 1)
        roi = score[y0:y + h + 1, x0:x + w + 1].astype(np.float64)
        roi = np.where(roi > 0.2, roi, 0.0)
        m = float(roi.sum())
        if m <= 0:
            continue
        yy, xx = np.mgrid[0:roi.shape[0], 0:roi.shape[1]]
        out.append(((roi * xx).sum() / m + x0, (roi * yy).sum() / m + y0))
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


def identify_markers(detections_px: F64, X_world: F64, P_guess: F64, max_px: float = 25.0
                     ) -> tuple[F64, F64, NDArray[np.int64]]:
    """Match detections to known points by their predicted pixels (mutual nearest within
    ``max_px``). Returns (world (M, 3), pixels (M, 2), indices of the world points)."""
    det = np.asarray(detections_px, dtype=np.float64).reshape(-1, 2)
    X = np.asarray(X_world, dtype=np.float64).reshape(-1, 3)
    if len(det) == 0 or len(X) == 0:
        return np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0, np.int64)
    Xh = np.hstack([X, np.ones((len(X), 1))]) @ np.asarray(P_guess).T
    front = Xh[:, 2] > 0
    pred = np.where(front[:, None], Xh[:, :2] / np.where(front, Xh[:, 2], 1.0)[:, None],
                    np.inf)
    d = np.linalg.norm(pred[:, None, :] - det[None, :, :], axis=2)
    d[~np.isfinite(d)] = np.inf
    best_det = np.argmin(d, axis=1)
    best_pt = np.argmin(d, axis=0)
    idx = [i for i in range(len(X)) if d[i, best_det[i]] <= max_px
           and best_pt[best_det[i]] == i]
    sel = np.asarray(idx, dtype=np.int64)
    return X[sel], det[best_det[sel]], sel


@dataclass(frozen=True, slots=True)
class PanTiltEstimate:
    pan_deg: float
    tilt_deg: float
    rms_px: float
    points: int


def pan_tilt_from_markers(cal: PtzCalibration, image_bgr: NDArray[np.uint8],
                          guesses: Sequence[tuple[float, float]], max_px: float = 30.0,
                          min_points: int = 5, max_rms_px: float = 2.0
                          ) -> PanTiltEstimate | None:
    """Motor pan/tilt of a frame from the reference markers it shows (sec. 3.2): detect,
    undistort (sec. 3.3), identify against the prediction at each guess (the last estimate,
    the last command, or a search grid), Gauss-Newton; the guess that explains the most
    markers wins. None when fewer than ``min_points`` markers fit within ``max_rms_px``."""
    if cal.reference_points_world_m is None or cal.marker_bgr is None or cal.head is None:
        return None
    det = detect_markers(image_bgr, cal.marker_bgr)
    if len(det) < min_points:
        return None
    und = cal.undistort_px(det)
    best: PanTiltEstimate | None = None
    for g in guesses:
        est = _fit_markers(cal, und, g, max_px, min_points)
        if est is None or est.rms_px > max_rms_px:
            continue
        if best is None or (est.points, -est.rms_px) > (best.points, -best.rms_px):
            best = est
    return best


def search_guesses(pan_range_deg: tuple[float, float] = (-60.0, 60.0),
                   tilt_range_deg: tuple[float, float] = (-30.0, 30.0), step_deg: float = 4.0
                   ) -> list[tuple[float, float]]:
    """A grid of motor-angle guesses for the first frame (no estimate yet, no encoder)."""
    return [(float(p), float(t)) for t in np.arange(tilt_range_deg[0], tilt_range_deg[1] + 1e-9,
                                                    step_deg)
            for p in np.arange(pan_range_deg[0], pan_range_deg[1] + 1e-9, step_deg)]


def _fit_markers(cal: PtzCalibration, und: F64, g: tuple[float, float], max_px: float,
                 min_points: int) -> PanTiltEstimate | None:
    assert cal.reference_points_world_m is not None
    assert cal.head is not None
    head = cal.head
    X, uv, _ = identify_markers(und, cal.reference_points_world_m, head.P(g[0], g[1]), max_px)
    if len(X) < min_points:
        return None
    pan, tilt, _ = estimate_pan_tilt(head, X, uv, g)
    # re-identify at the estimate (more markers fall inside the gate), drop gross mismatches
    X, uv, _ = identify_markers(und, cal.reference_points_world_m, head.P(pan, tilt),
                                max_px / 3)
    if len(X) < min_points:
        return None
    pan, tilt, rms = estimate_pan_tilt(head, X, uv, (pan, tilt))
    res = np.linalg.norm(project_P(head.P(pan, tilt), X) - uv, axis=1)
    keep = res <= max(1.5, 3.0 * float(np.median(res)))
    if keep.sum() >= min_points and not keep.all():
        pan, tilt, rms = estimate_pan_tilt(head, X[keep], uv[keep], (pan, tilt))
    return PanTiltEstimate(pan, tilt, rms, int(keep.sum()))
