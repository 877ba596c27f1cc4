"""The studio floor seen by a second camera: floor calibration and the second view's payload.

The VR-TV paper's overhead camera (Sec. III-A) is "calibrated with respect to the robot base
frame, in order to estimate the current distance with respect to the robot". Here its
calibration is a floor homography ``H_floor_img`` (image px -> floor metres, z = 0 plane)
from four image points whose floor coordinates are known (clicked in the set-up, entered in
metres, saved in the studio project), plus the robot's floor position.

Locating the presenter: the homography alone maps a point *on the floor* (the feet), but a
camera looking down sees a walking person's feet spread by the stride and the body leaning
towards the image of the nadir. So the camera itself is recovered from the homography
(:func:`camera_from_homography`: K [r1 r2 t] ~ H^-1 with the principal point at the image
centre and the focal length given, or solved from r1 . r2 = 0 and |r1| = |r2|) and the
presenter is modelled as a vertical segment from (X, Y, 0) to (X, Y, height): the bottom
centre of the box is the image of its foot, the top centre of its head - four linear
equations in (X, Y, height), solved in the least-squares sense (:meth:`FloorCalibration.
locate`). The silhouette's lowest point is the front of the shoes and its top the far side of
the head, so the segment found is moved away from the camera by half the depth of a standing
adult (``BODY_HALF_DEPTH_M``, 0.1 m: anthropometry, not fitted). d is the floor distance of
(X, Y) from the robot.

A view with a zoom lens (issue 13): the homography holds only at the zoom the marks were
clicked at. Given the view's lens file (:class:`engine.lens.LensFile`, the project's) and the
encoders at the click, the calibration is a camera model instead: K and distortion from the
lens file at the encoders, the pose ``T_cam_floor`` from the four marks by PnP
(``cv2.SOLVEPNP_IPPE``, exact for four coplanar points). Each frame the view's current
encoders (:class:`engine.lens.LensEncoders` on the :class:`OverheadView`) give K and
distortion again and move the projection centre along the optical axis by the change of the
entrance pupil; the box corners are undistorted and located with that camera. Without a lens
the homography path above is used unchanged.

:class:`OverheadView` is the frame payload a two-view source attaches: the second camera's
image of the same instant (and its time stamp), the presenter's box in it on the first frame
(to initialise the second filter) and the floor calibration.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.errors import CalibrationError
from engine.frames import FramePayload, readonly

F64 = NDArray[np.float64]
#: half the front-to-back depth of a standing adult (chest about 0.2 m deep)
BODY_HALF_DEPTH_M = 0.1
#: fixed-point steps of :meth:`FloorCalibration.standing_box_px` (each at least halves the
#: error; from the current estimate a few px off, 8 leave well under 0.1 px)
STANDING_ITERATIONS = 8
FLOOR_FORMAT = "studiotrack.floor_homography"
#: 1: homography only; 2: adds the lens camera model (written only when a lens is used, so
#: an older StudioTrack refuses a zoom-lens calibration instead of ignoring its lens)
FLOOR_VERSION = 2


@dataclass(frozen=True, slots=True)
class FloorCalibration:
    """Homography image (px) -> floor (m), the four points it came from, the robot's floor
    position (m)."""

    H_floor_img: F64
    robot_floor_xy_m: tuple[float, float] = (0.0, 0.0)
    image_points_px: tuple[tuple[float, float], ...] = ()
    floor_points_m: tuple[tuple[float, float], ...] = ()
    image_wh: tuple[int, int] | None = None  # the second camera's image size
    f_px: float | None = None  # its focal length; None = solved from the homography
    #: the view's lens file (engine.lens.LensFile): the calibration is then a camera model
    lens: Any = None
    #: (zoom, focus) encoder counts when the marks were taken (lens model)
    encoders_raw: tuple[int, int] | None = None
    #: the lens is the studio project's lens file (re-attached when the project opens)
    lens_from_project: bool = False
    #: the view's pose from the four marks by PnP at ``encoders_raw`` (lens model)
    T_cam_floor: F64 | None = None
    #: reprojection error of the four marks through the PnP camera (px)
    pnp_rms_px: float | None = None

    def __post_init__(self) -> None:
        readonly(self.H_floor_img)
        if self.T_cam_floor is not None:
            readonly(self.T_cam_floor)

    @property
    def has_lens_model(self) -> bool:
        return self.lens is not None and self.T_cam_floor is not None

    def camera(self) -> F64 | None:
        """The 3x4 camera matrix P (floor frame, z up) or None if it cannot be recovered
        (homography path; a lens model's camera is :meth:`camera_at`)."""
        if self.image_wh is None:
            return None
        try:
            return camera_from_homography(self.H_floor_img, self.image_wh, self.f_px)
        except CalibrationError:
            return None

    def camera_at(self, encoders: Any = None) -> tuple[Any, F64] | None:
        """(intrinsics, T_cam_floor) of the lens model at the view's encoders
        (:class:`engine.lens.LensEncoders` or a (zoom, focus) pair; None = the calibration's).

        K and distortion from the lens file; the projection centre moves along the optical
        axis by the change of the entrance pupil since the calibration (forward for a
        positive change), the orientation is kept. None without a lens model."""
        if not self.has_lens_model:
            return None
        assert self.T_cam_floor is not None
        z0, f0 = self.encoders_raw or (0, 0)
        if encoders is None:
            z, f = z0, f0
        elif isinstance(encoders, tuple):
            z, f = encoders
        else:
            z, f = encoders.zoom_raw, encoders.focus_raw
        cam = self.lens.intrinsics_at(z, f)
        T = np.array(self.T_cam_floor, dtype=np.float64)
        if (z, f) != (z0, f0):
            shift = (self.lens.values_at(z, f)["entrance_pupil_m"]
                     - self.lens.values_at(z0, f0)["entrance_pupil_m"])
            T[2, 3] -= shift  # the centre at (0, 0, shift) of the calibration's camera
        return cam, T

    def locate(self, box_xywh: Sequence[float], encoders: Any = None, lean_px: float = 0.0
               ) -> tuple[float, float, float | None]:
        """(X, Y) on the floor and the height (m) of a standing person whose box this is.

        With a recovered camera the person is a vertical segment whose foot projects to the
        box's bottom centre and whose top to the top centre (least squares); without one,
        the bottom centre through the homography and no height. ``encoders``: the view's
        lens encoders at this frame (lens model only). ``lean_px``: the segment's lean in
        the image where it is known (top u minus foot u, :meth:`standing_box_px`; the box
        centre is then the segment's midpoint: foot at u - lean/2, top at u + lean/2).
        """
        x, y, w, h = (float(v) for v in box_xywh)
        u = x + 0.5 * w
        uf_px, ut_px = u - 0.5 * lean_px, u + 0.5 * lean_px
        model = self.camera_at(encoders)
        if model is not None:
            from engine.camera import pixels_to_normalized

            cam, T = model
            # normalised, undistorted coordinates: P = [R | t]
            (uf, vf), (uh, vh) = pixels_to_normalized(
                cam, np.array([[uf_px, y + h], [ut_px, y]]))
            return _segment_on_floor(T[:3, :], (uf, vf), (uh, vh))
        P = self.camera()
        if P is None:
            fx, fy = self.floor_point(uf_px, y + h)
            return (fx, fy, None)
        return _segment_on_floor(P, (uf_px, y + h), (ut_px, y))

    def standing_box_px(self, u: F64, v: F64, height_m: float, encoders: Any = None,
                        h_start_px: F64 | None = None) -> tuple[F64, F64] | None:
        """(height, lean) in px of a person ``height_m`` tall standing upright whose box
        centre is at (``u``, ``v``) (arrays): :meth:`locate`'s model, a vertical segment from
        the floor to ``height_m``, its foot the box's bottom and its top the box's top; lean =
        the top's u minus the foot's (verticals converge on the nadir's image, so a person
        off the image's middle column leans). NaN where the foot does not see the floor; None
        without a recovered camera (a bare homography knows no heights).

        Solved per point by the fixed point (h, lean) <- (v_foot - v_head, u_head - u_foot):
        the foot at (u - lean/2, v + h/2) on the floor, the head ``height_m`` above it
        projected back. Moving the foot down by dh/2 moves the head down by k dh/2
        (0 < k <= 1, the head being farther away), so each step shrinks h's error by
        (1 - k)/2 < 1/2; ``h_start_px`` (e.g. the current estimate) starts it near the
        answer.
        """
        uu = np.asarray(u, dtype=np.float64).reshape(-1)
        vv = np.asarray(v, dtype=np.float64).reshape(-1)
        ray_to_floor, project = self._floor_maps(encoders)
        if ray_to_floor is None or project is None:
            return None
        if h_start_px is None:
            h = np.full(len(uu), 0.25 * float((self.image_wh or (0, 480))[1]))
        else:
            h = np.asarray(h_start_px, dtype=np.float64).reshape(-1).copy()
        lean = np.zeros(len(uu))
        top = np.full(len(uu), float(height_m))
        for _ in range(STANDING_ITERATIONS):
            foot_u, foot_v = uu - 0.5 * lean, vv + 0.5 * h
            X, Y = ray_to_floor(foot_u, foot_v)
            head_u, head_v = project(X, Y, top)
            h, lean = foot_v - head_v, head_u - foot_u
        bad = ~(np.isfinite(h) & np.isfinite(lean)) | (h <= 0)
        h[bad] = np.nan
        lean[bad] = np.nan
        return h, lean

    def _floor_maps(self, encoders: Any = None) -> tuple[Any, Any]:
        """(image (u, v) arrays -> floor (X, Y) arrays, floor (X, Y, Z) arrays -> image (u, v)
        arrays) of this calibration's camera (lens model at ``encoders``); (None, None)
        without one."""
        model = self.camera_at(encoders)
        if model is not None:
            from engine.camera import pixels_to_normalized, project

            cam, T = model
            R, t = T[:3, :3], T[:3, 3]
            C = -R.T @ t

            def to_floor_lens(u: F64, v: F64) -> tuple[F64, F64]:
                xy = pixels_to_normalized(cam, np.stack([u, v], axis=1))
                ray = np.c_[xy, np.ones(len(u))] @ R  # R.T @ (x, y, 1) per row
                with np.errstate(divide="ignore", invalid="ignore"):
                    s = np.where(ray[:, 2] < -1e-12, -C[2] / ray[:, 2], np.nan)
                return C[0] + s * ray[:, 0], C[1] + s * ray[:, 1]

            def to_image_lens(X: F64, Y: F64, Z: F64) -> tuple[F64, F64]:
                uv = project(cam, np.stack([X, Y, Z], axis=1) @ R.T + t)
                return uv[:, 0], uv[:, 1]

            return to_floor_lens, to_image_lens
        P = self.camera()
        if P is None:
            return None, None
        Hm = self.H_floor_img

        def to_floor(u: F64, v: F64) -> tuple[F64, F64]:
            p = Hm @ np.stack([u, v, np.ones(len(u))])
            with np.errstate(divide="ignore", invalid="ignore"):
                return p[0] / p[2], p[1] / p[2]

        def to_image(X: F64, Y: F64, Z: F64) -> tuple[F64, F64]:
            q = P @ np.stack([X, Y, Z, np.ones(len(X))])
            with np.errstate(divide="ignore", invalid="ignore"):
                z = np.where(q[2] > 1e-12, q[2], np.nan)
                return q[0] / z, q[1] / z

        return to_floor, to_image

    def floor_point(self, u: float, v: float, encoders: Any = None) -> tuple[float, float]:
        """The floor point (m) seen at image point (u, v) (lens model: at ``encoders``)."""
        model = self.camera_at(encoders)
        if model is not None:
            from engine.camera import pixels_to_normalized

            cam, T = model
            xn, yn = pixels_to_normalized(cam, np.array([[u, v]]))[0]
            R, t = T[:3, :3], T[:3, 3]
            C = -R.T @ t
            ray = R.T @ np.array([xn, yn, 1.0])
            if ray[2] > -1e-12:
                raise CalibrationError(f"image point ({u:.1f}, {v:.1f}) does not see the "
                                       "floor")
            s = -C[2] / ray[2]
            return (float(C[0] + s * ray[0]), float(C[1] + s * ray[1]))
        p = self.H_floor_img @ np.array([u, v, 1.0])
        if abs(p[2]) < 1e-12:
            raise CalibrationError(f"image point ({u:.1f}, {v:.1f}) maps to infinity on the "
                                   "floor")
        return (float(p[0] / p[2]), float(p[1] / p[2]))

    def distance_m(self, u: float, v: float, encoders: Any = None) -> float:
        """d: floor distance of the image point (u, v) from the robot."""
        fx, fy = self.floor_point(u, v, encoders)
        return float(math.hypot(fx - self.robot_floor_xy_m[0], fy - self.robot_floor_xy_m[1]))

    def without_lens(self) -> FloorCalibration:
        """The same marks as a fixed homography (what a calibration without the lens file
        gives; the bench compares the two under a zoom)."""
        return calibrate_floor(self.image_points_px, self.floor_points_m,
                               self.robot_floor_xy_m, self.image_wh, self.f_px)

    def with_lens(self, lens: Any, encoders_raw: tuple[int, int] | None = None,
                  from_project: bool | None = None) -> FloorCalibration:
        """The same marks with another lens file (e.g. the project's, re-calibrated)."""
        return calibrate_floor(self.image_points_px, self.floor_points_m,
                               self.robot_floor_xy_m, self.image_wh, self.f_px, lens=lens,
                               encoders_raw=encoders_raw or self.encoders_raw,
                               lens_from_project=(self.lens_from_project
                                                  if from_project is None else from_project))

    def to_json(self) -> dict[str, Any]:
        doc: dict[str, Any] = {
            "format": FLOOR_FORMAT, "version": 1,
            "image_points_px": [list(map(float, p)) for p in self.image_points_px],
            "floor_points_m": [list(map(float, p)) for p in self.floor_points_m],
            "robot_floor_xy_m": list(self.robot_floor_xy_m),
            "H_floor_img": self.H_floor_img.tolist(),
            "image_wh": None if self.image_wh is None else list(self.image_wh),
            "f_px": self.f_px,
        }
        if self.lens is not None:
            doc["version"] = FLOOR_VERSION
            doc["lens"] = self.lens.to_json()
            doc["encoders_raw"] = None if self.encoders_raw is None else list(
                self.encoders_raw)
            doc["lens_from_project"] = bool(self.lens_from_project)
            doc["pnp_rms_px"] = self.pnp_rms_px
        return doc


def _segment_on_floor(P: F64, foot: tuple[float, float], head: tuple[float, float]
                      ) -> tuple[float, float, float]:
    """(X, Y, height) of a vertical segment from (X, Y, 0) to (X, Y, height) whose ends
    project through the 3x4 ``P`` to ``foot`` and ``head`` (least squares), moved away from
    the camera by ``BODY_HALF_DEPTH_M`` (the silhouette's near foot and far head)."""
    rows, rhs = [], []
    for (uo, vo), z in ((foot, 0.0), (head, None)):
        # u (P3 . X) = P1 . X and v (P3 . X) = P2 . X, X = (X, Y, z, 1); z unknown on top
        for k, obs in ((0, uo), (1, vo)):
            a = obs * P[2] - P[k]
            if z is None:
                rows.append([a[0], a[1], a[2]])
                rhs.append(-a[3])
            else:
                rows.append([a[0], a[1], 0.0])
                rhs.append(-(a[3] + a[2] * z))
    A, b = np.asarray(rows), np.asarray(rhs)
    # equal weight for the four equations: scale each to unit row norm
    n = np.maximum(np.linalg.norm(A, axis=1), 1e-12)
    sol, *_ = np.linalg.lstsq(A / n[:, None], b / n, rcond=None)
    C = -np.linalg.solve(P[:, :3], P[:, 3])
    away = sol[:2] - C[:2]
    norm = float(np.linalg.norm(away))
    xy = sol[:2] + (BODY_HALF_DEPTH_M * away / norm if norm > 1e-9 else 0.0)
    return (float(xy[0]), float(xy[1]), float(sol[2]))


def _focal_from_homography(A: F64) -> float:
    """f from r1 . r2 = 0 and |r1| = |r2| (A = floor -> image homography with the principal
    point at the origin): the two constraints of Zhang's calibration with one unknown."""
    h1, h2 = A[:, 0], A[:, 1]
    num, den = [], []
    # (h1x h2x + h1y h2y) / f^2 + h1z h2z = 0
    num.append(-(h1[0] * h2[0] + h1[1] * h2[1]))
    den.append(h1[2] * h2[2])
    # (|h1xy|^2 - |h2xy|^2) / f^2 + h1z^2 - h2z^2 = 0
    num.append(-(h1[0] ** 2 + h1[1] ** 2 - h2[0] ** 2 - h2[1] ** 2))
    den.append(h1[2] ** 2 - h2[2] ** 2)
    d = np.asarray(den)
    nn = np.asarray(num)
    # least squares in 1/f^2: den * f^2 = num  <=>  den = num * (1/f^2)
    inv_f2 = float(np.dot(nn, d) / max(float(np.dot(nn, nn)), 1e-300))
    if not inv_f2 > 0:
        raise CalibrationError("floor calibration: the focal length cannot be recovered from "
                               "the four points (camera looking straight down?); enter it")
    return 1.0 / math.sqrt(inv_f2)


def camera_from_homography(H_floor_img: F64, image_wh: Sequence[int],
                           f_px: float | None = None) -> F64:
    """P = K [r1 r2 r3 t] of the camera that sees the floor through ``H_floor_img``."""
    W, H = (int(v) for v in image_wh)
    cx, cy = (W - 1) / 2.0, (H - 1) / 2.0
    G = np.linalg.inv(np.asarray(H_floor_img, dtype=np.float64))  # floor -> image
    G0 = np.array([[1, 0, -cx], [0, 1, -cy], [0, 0, 1.0]]) @ G  # principal point at 0
    f = float(f_px) if f_px else _focal_from_homography(G0)
    K = np.array([[f, 0, cx], [0, f, cy], [0, 0, 1.0]])
    M = np.linalg.inv(K) @ G
    lam = 2.0 / (np.linalg.norm(M[:, 0]) + np.linalg.norm(M[:, 1]))
    if M[2, 2] * lam < 0:  # the floor origin in front of the camera
        lam = -lam
    r1, r2, t = lam * M[:, 0], lam * M[:, 1], lam * M[:, 2]
    R = np.stack([r1, r2, np.cross(r1, r2)], axis=1)
    U, _, Vt = np.linalg.svd(R)
    R = U @ Vt
    return np.asarray(K @ np.hstack([R, t[:, None]]), dtype=np.float64)


def calibrate_floor(image_pts_px: Sequence[Sequence[float]] | F64,
                    floor_pts_m: Sequence[Sequence[float]] | F64,
                    robot_floor_xy_m: Sequence[float] = (0.0, 0.0),
                    image_wh: Sequence[int] | None = None,
                    f_px: float | None = None, *, lens: Any = None,
                    encoders_raw: Sequence[int] | None = None,
                    lens_from_project: bool = False) -> FloorCalibration:
    """Homography from exactly four image points and their known floor coordinates.

    ``image_wh`` (the second camera's image size) and ``f_px`` (its focal length, or None to
    solve it) let :meth:`FloorCalibration.locate` recover the camera. With ``lens`` (the
    view's :class:`engine.lens.LensFile`) and ``encoders_raw`` (zoom, focus when the marks
    were taken; default 0, 0) the calibration is a camera model: K and distortion from the
    lens file, the pose from the marks by PnP.
    """
    try:
        img = np.asarray(image_pts_px, dtype=np.float64)
        flo = np.asarray(floor_pts_m, dtype=np.float64)
        robot = tuple(float(v) for v in robot_floor_xy_m)
    except (TypeError, ValueError) as exc:
        raise CalibrationError(f"floor calibration: points must be numbers ({exc})") from None
    if img.shape != (4, 2) or flo.shape != (4, 2):
        n_img = img.shape[0] if img.ndim else 0
        n_flo = flo.shape[0] if flo.ndim else 0
        raise CalibrationError(f"floor calibration needs 4 image and 4 floor points, got "
                               f"{n_img} and {n_flo}")
    if len(robot) != 2 or not all(math.isfinite(v) for v in robot):
        raise CalibrationError(f"floor calibration: robot position must be 2 numbers, got "
                               f"{list(robot_floor_xy_m)}")
    for name, pts in (("image", img), ("floor", flo)):
        if not np.all(np.isfinite(pts)):
            raise CalibrationError(f"floor calibration: {name} points must be finite")
        # any three collinear points make the homography degenerate
        for i in range(4):
            a, b, c = (pts[j] for j in range(4) if j != i)
            u, w = b - a, c - a
            if abs(u[0] * w[1] - u[1] * w[0]) < 1e-6 * max(1.0, float(np.ptp(pts)) ** 2):
                raise CalibrationError(f"floor calibration: three {name} points are collinear")
    wh = None
    if image_wh is not None:
        try:
            wh = (int(image_wh[0]), int(image_wh[1]))
        except (TypeError, ValueError, IndexError):
            raise CalibrationError(f"floor calibration: image size must be 2 integers, got "
                                   f"{image_wh!r}") from None
        if wh[0] <= 0 or wh[1] <= 0:
            raise CalibrationError(f"floor calibration: image size must be positive, got {wh}")
    if f_px is not None and not (math.isfinite(float(f_px)) and float(f_px) > 0):
        raise CalibrationError(f"floor calibration: focal length must be > 0 px, got {f_px}")
    H = cv2.getPerspectiveTransform(img.astype(np.float32), flo.astype(np.float32))
    calib = FloorCalibration(np.asarray(H, dtype=np.float64), (robot[0], robot[1]),
                             tuple((float(u), float(v)) for u, v in img),
                             tuple((float(x), float(y)) for x, y in flo), wh,
                             None if f_px is None else float(f_px))
    if lens is None:
        return calib
    return _with_pnp(calib, img, flo, lens, encoders_raw, lens_from_project)


def _with_pnp(calib: FloorCalibration, img: F64, flo: F64, lens: Any,
              encoders_raw: Sequence[int] | None, from_project: bool) -> FloorCalibration:
    """The calibration with the lens camera model: pose of the view from the four marks."""
    from dataclasses import replace

    from engine.geometry import make_T

    try:
        enc = (0, 0) if encoders_raw is None else (int(encoders_raw[0]),
                                                   int(encoders_raw[1]))
    except (TypeError, ValueError, IndexError):
        raise CalibrationError(f"floor calibration: encoders must be 2 integers (zoom, "
                               f"focus), got {encoders_raw!r}") from None
    lens_wh = (int(lens.width), int(lens.height))
    if calib.image_wh is not None and calib.image_wh != lens_wh:
        raise CalibrationError(f"floor calibration: the lens file {lens.name!r} is for "
                               f"{lens_wh[0]}x{lens_wh[1]} images, the view is "
                               f"{calib.image_wh[0]}x{calib.image_wh[1]}")
    cam = lens.intrinsics_at(*enc)  # an incomplete lens file raises its LensError here
    obj = np.c_[flo, np.zeros(4)].astype(np.float64)
    ok, rvec, tvec = cv2.solvePnP(obj, img.astype(np.float64), cam.K, cam.dist,
                                  flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        raise CalibrationError("floor calibration: no camera pose fits the four marks "
                               "through the lens file")
    R = np.asarray(cv2.Rodrigues(rvec)[0], dtype=np.float64)
    T = make_T(R, np.asarray(tvec, dtype=np.float64).reshape(3))
    if np.any((T[:3, :3] @ obj.T + T[:3, 3:4])[2] <= 0):
        raise CalibrationError("floor calibration: the PnP pose puts floor marks behind the "
                               "camera (check the marks' order and the lens file)")
    proj, _ = cv2.projectPoints(obj, rvec, tvec, cam.K, cam.dist)
    rms = float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1))))
    return replace(calib, image_wh=lens_wh, lens=lens, encoders_raw=enc,
                   lens_from_project=bool(from_project), T_cam_floor=T, pnp_rms_px=rms)


def floor_calibration_from_json(doc: Any, where: str = "floor calibration") -> FloorCalibration:
    """The calibration of :meth:`FloorCalibration.to_json` (rebuilt from its points)."""
    if not isinstance(doc, Mapping) or doc.get("format") != FLOOR_FORMAT:
        raise CalibrationError(f"{where}: not a {FLOOR_FORMAT} document")
    version = doc.get("version")
    if not isinstance(version, int) or version > FLOOR_VERSION:
        raise CalibrationError(f"{where}: version {version!r} is newer than this StudioTrack "
                               f"supports ({FLOOR_VERSION})")
    lens = None
    if doc.get("lens") is not None:
        from engine.lens import LensFile

        lens = LensFile.from_json(doc["lens"], f"{where}: lens")
    try:
        return calibrate_floor(doc["image_points_px"], doc["floor_points_m"],
                               doc.get("robot_floor_xy_m", (0.0, 0.0)), doc.get("image_wh"),
                               doc.get("f_px"), lens=lens,
                               encoders_raw=doc.get("encoders_raw"),
                               lens_from_project=bool(doc.get("lens_from_project", False)))
    except KeyError as exc:
        raise CalibrationError(f"{where}: missing {exc}") from None
    except CalibrationError as exc:
        raise CalibrationError(f"{where}: {exc}") from None


def save_floor_calibration(path: str | Path, calib: FloorCalibration) -> None:
    from engine.persist import atomic_write_json

    atomic_write_json(Path(path), calib.to_json())


def load_floor_calibration(path: str | Path) -> FloorCalibration:
    from engine.persist import read_json_file

    path = Path(path)
    doc = read_json_file(path, CalibrationError, missing="no such floor calibration")
    return floor_calibration_from_json(doc, str(path))


@dataclass(frozen=True, slots=True)
class OverheadView(FramePayload):
    """A second (overhead or side) camera's image of the same instant, for the floor distance.

    ``box_xywh`` is the presenter's box in it when known (the first frame's initialises the
    second filter; the built-in studio gives it every frame as truth); ``floor_calibration``
    maps its image to the floor; ``timestamp_s`` is the second camera's own time stamp (a
    two-view source pairs frames by it); ``floor_xy_m_true`` is the presenter's true floor
    position where a simulator knows it; ``lens_encoders`` the camera's zoom/focus
    encoders where it has a zoom lens. ``part_boxes`` are the presenter's patches in it
    (name, x y w h) where the source knows them (the built-in studio's labels stand in for
    the operator's patches, as on the frontal view); else the box is split.
    """

    light: ClassVar[bool] = False
    color_bgr: NDArray[np.uint8]
    box_xywh: tuple[float, float, float, float] | None = None
    floor_calibration: FloorCalibration | None = None
    timestamp_s: float | None = None
    floor_xy_m_true: tuple[float, float] | None = None
    part_boxes: tuple[tuple[str, tuple[float, float, float, float]], ...] = ()
    #: the second camera's lens encoders at this frame (engine.lens.LensEncoders) where it
    #: zooms; a floor calibration with a lens model takes K and distortion at them
    lens_encoders: Any = None

    def __post_init__(self) -> None:
        readonly(self.color_bgr)
