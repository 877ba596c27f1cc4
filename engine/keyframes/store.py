"""Keyframe store of Tykkälä 2014 sec. 6: storage, nearest-keyframe search, edits.

Store layout (a folder, written atomically file by file, ``keyframes.json`` last so that it
is the commit point)::

    keyframes.json        {"format": "studiotrack-keyframes", "version": 1,
                           "intrinsics": {...camera.json keys...},
                           "keyframes": [{"id": 0, "T_world_cam": [[...4x4...]],
                                          "gray": "kf_0000_gray.png",
                                          "depth": "kf_0000_depth.png"}, ...]}
    kf_0000_gray.png      8-bit grey image (full resolution)
    kf_0000_depth.png     16-bit depth, metres * depth_scale (0 = invalid)

Nearest keyframe (sec. 6.2): pre-selection by angle and distance, eq. (19)-(20), then the
view-frustum test-point metric of eq. (21) over three 2D point grids at depths spanning the
sensor range (Fig. 12).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8
from engine.camera import Intrinsics
from engine.errors import TrackerError
from engine.geometry import invert, rotation_angle_rad, rotation_angle_rad_batch
from engine.persist import read_json_file

F64 = NDArray[np.float64]

STORE_FORMAT = "studiotrack-keyframes"
STORE_VERSION = 1
INDEX_NAME = "keyframes.json"

#: depths (m) of the three test-point grids of eq. (21), uniform in a Kinect-like range
FRUSTUM_DEPTHS_M = (1.0, 2.5, 4.0)
_GRID_NX, _GRID_NY = 6, 5


class KeyframeStoreError(TrackerError):
    """A keyframe store cannot be read or written (missing, corrupt or incompatible)."""


@dataclass(frozen=True, slots=True)
class KeyframeFiles:
    """Where a lazily loaded keyframe's images are (a store folder's two PNGs)."""

    gray_path: Path
    depth_path: Path
    depth_scale: float
    width: int
    height: int

    def _read_png(self, path: Path, dtype: type[np.generic], what: str) -> NDArray[Any]:
        """One single-channel PNG of this keyframe, checked for dtype and size."""
        import cv2

        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise KeyframeStoreError(f"{path}: missing or not a readable PNG")
        if img.dtype != dtype or img.ndim != 2:
            raise KeyframeStoreError(f"{path}: expected {what}")
        self._check_size(path, img.shape)
        return img

    def read_gray(self) -> NDArray[np.uint8]:
        return u8(self._read_png(self.gray_path, np.uint8, "an 8-bit grey image"))

    def read_depth_m(self) -> NDArray[np.float32]:
        img = self._read_png(self.depth_path, np.uint16, "a 16-bit depth image")
        out: NDArray[np.float32] = img.astype(np.float32) / np.float32(self.depth_scale)
        return out

    def _check_size(self, path: Path, shape: tuple[int, ...]) -> None:
        if shape != (self.height, self.width):
            raise KeyframeStoreError(
                f"{path}: size {shape[1]}x{shape[0]} does not match the store's "
                f"{self.width}x{self.height}"
            )


@dataclass(frozen=True, slots=True, init=False, eq=False)
class Keyframe:
    """One keyframe K = {P*, c*, T*} (the points are selected from the images when a tracker
    first needs them).

    The images are either held (``Keyframe(id, T, gray, depth_m)``: a keyframe recorded in
    this session, a store loaded eagerly) or read from the store's files on each access
    (``files``, :meth:`KeyframeStore.load` with ``lazy=True``): a tracker reads them once to
    precompute its reference and keeps only that (``resident`` tells which).
    """

    id: int
    T_world_cam: F64
    _gray: NDArray[np.uint8] | None
    _depth_m: NDArray[np.float32] | None
    files: KeyframeFiles | None
    #: the camera's body twist per second (v, w) when the keyframe was taken, for a
    #: rolling-shutter camera's reference (engine.dense.photometric.build_reference); None
    #: = not known
    twist_per_s: F64 | None

    def __init__(
        self,
        id: int,
        T_world_cam: F64,
        gray: NDArray[np.uint8] | None = None,
        depth_m: NDArray[np.float32] | None = None,
        *,
        files: KeyframeFiles | None = None,
        twist_per_s: F64 | None = None,
    ) -> None:
        if (gray is None or depth_m is None) and files is None:
            raise KeyframeStoreError(f"keyframe {id}: needs its images or their files")
        object.__setattr__(self, "id", id)
        object.__setattr__(self, "T_world_cam", T_world_cam)
        object.__setattr__(self, "_gray", gray)
        object.__setattr__(self, "_depth_m", depth_m)
        object.__setattr__(self, "files", files)
        object.__setattr__(self, "twist_per_s", None if twist_per_s is None
                           else np.array(twist_per_s, dtype=np.float64).reshape(6))

    @property
    def gray(self) -> NDArray[np.uint8]:
        """8-bit grey image (full resolution); read from the file each time if lazy."""
        if self._gray is not None:
            return self._gray
        assert self.files is not None
        return self.files.read_gray()

    @property
    def depth_m(self) -> NDArray[np.float32]:
        """Depth in metres (0 = invalid); read from the file each time if lazy."""
        if self._depth_m is not None:
            return self._depth_m
        assert self.files is not None
        return self.files.read_depth_m()

    @property
    def resident(self) -> bool:
        """Whether the images are held in memory (else read from ``files`` on access)."""
        return self._gray is not None and self._depth_m is not None

    def with_pose(self, T_world_cam: F64) -> Keyframe:
        """This keyframe at another pose (images, or their files, shared)."""
        return Keyframe(
            self.id, np.array(T_world_cam, dtype=np.float64), self._gray, self._depth_m,
            files=self.files, twist_per_s=self.twist_per_s,
        )

    def with_depth(self, depth_m: NDArray[np.float32]) -> Keyframe:
        """This keyframe with another depth map (now held in memory)."""
        return Keyframe(self.id, self.T_world_cam.copy(), self.gray, depth_m,
                        twist_per_s=self.twist_per_s)

    def with_twist(self, twist_per_s: F64 | None) -> Keyframe:
        """This keyframe with the camera's velocity when it was taken."""
        return Keyframe(self.id, self.T_world_cam, self._gray, self._depth_m,
                        files=self.files, twist_per_s=twist_per_s)

    def __repr__(self) -> str:
        where = "resident" if self.resident else f"lazy {self.files}"
        return f"Keyframe(id={self.id}, {where})"


def _f64(a: NDArray[np.floating]) -> F64:
    """C-contiguous float64 (the one argument type of the compiled search)."""
    return np.ascontiguousarray(a, dtype=np.float64)


def frustum_test_points(intr: Intrinsics, depths_m: tuple[float, ...] = FRUSTUM_DEPTHS_M) -> F64:
    """Three 2D grids of 3D points along viewing rays at the given depths (Fig. 12)."""
    us = np.linspace(0.1, 0.9, _GRID_NX) * intr.width
    vs = np.linspace(0.1, 0.9, _GRID_NY) * intr.height
    u, v = np.meshgrid(us, vs)
    x = (u.ravel() - intr.cx) / intr.fx
    y = (v.ravel() - intr.cy) / intr.fy
    pts = [np.stack([x * z, y * z, np.full_like(x, z)], axis=1) for z in depths_m]
    return np.concatenate(pts, axis=0)


def _pinhole(intr: Intrinsics, p: F64) -> F64:
    z = np.maximum(p[:, 2], 1e-6)
    return np.stack([intr.fx * p[:, 0] / z + intr.cx, intr.fy * p[:, 1] / z + intr.cy], axis=1)


def frustum_metric(intr: Intrinsics, T_world_cam: F64, T_world_kf: F64, test_pts: F64) -> float:
    """Eq. (21): mean 2D discrepancy ||w(P; dT_k) - w(P; I)|| of the test points (pixels)."""
    T_kf_cam = invert(T_world_kf) @ T_world_cam  # eq. (19) in our T_world_cam convention
    q = test_pts @ T_kf_cam[:3, :3].T + T_kf_cam[:3, 3]
    behind = q[:, 2] <= 0.05
    d = np.linalg.norm(_pinhole(intr, q) - _pinhole(intr, test_pts), axis=1)
    d[behind] = 10.0 * (intr.width + intr.height)
    return float(np.mean(d))


def pose_distance(T_a: F64, T_b: F64) -> tuple[float, float]:
    """(angle rad, distance m) between two poses: theta_k and ||d_k|| of eq. (19)."""
    dT = invert(T_b) @ T_a
    return rotation_angle_rad(dT[:3, :3]), float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3]))


class KeyframeStore:
    """Keyframes of one camera with the eq. (19)-(21) search.

    :meth:`add` appends in place (the tracker building its keyframes online, a sweep);
    every edit of a finished store (:meth:`without`, :meth:`with_poses`,
    :meth:`with_depths`, :meth:`subset`, :meth:`copy`) returns a new store and leaves this one
    as it was, so a store shown or saved elsewhere never changes under it.
    """

    def __init__(self, intrinsics: Intrinsics, keyframes: list[Keyframe] | None = None) -> None:
        self.intrinsics = intrinsics
        self.keyframes: list[Keyframe] = list(keyframes or [])
        self._test_pts = _f64(frustum_test_points(intrinsics))
        self._test_uv = _f64(_pinhole(intrinsics, self._test_pts))
        self._cam = _f64(np.array([intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy]))
        self._far_px = 10.0 * (intrinsics.width + intrinsics.height)  # behind the camera
        # keyframe poses stacked for the search (K, 4, 4), rebuilt when keyframes are added
        self._poses: F64 = np.zeros((0, 4, 4))

    def __len__(self) -> int:
        return len(self.keyframes)

    @property
    def test_points(self) -> F64:
        """The view-frustum test points of eq. (21) (Fig. 12), in the camera frame."""
        return self._test_pts

    def by_id(self, kf_id: int) -> Keyframe:
        for kf in self.keyframes:
            if kf.id == kf_id:
                return kf
        raise KeyError(kf_id)

    def add(
        self, T_world_cam: F64, gray: NDArray[np.uint8], depth_m: NDArray[np.float32],
        twist_per_s: F64 | None = None,
    ) -> Keyframe:
        kf_id = 1 + max((k.id for k in self.keyframes), default=-1)
        kf = Keyframe(kf_id, np.array(T_world_cam, dtype=np.float64), gray, depth_m,
                      twist_per_s=twist_per_s)
        self.keyframes.append(kf)
        return kf

    def set_twist(self, kf_id: int, twist_per_s: F64 | None) -> Keyframe:
        """Record the camera's velocity at keyframe ``kf_id`` (known only a frame later)."""
        for i, k in enumerate(self.keyframes):
            if k.id == kf_id:
                self.keyframes[i] = k.with_twist(twist_per_s)
                return self.keyframes[i]
        raise KeyError(kf_id)

    def subset(self, ids: Iterable[int]) -> KeyframeStore:
        """A new store with only the given keyframes (images shared)."""
        keep = set(ids)
        return KeyframeStore(self.intrinsics, [k for k in self.keyframes if k.id in keep])

    # -- new stores (this one is left unchanged) ----------------------------------------
    def copy(self) -> KeyframeStore:
        """A new store with the same keyframes (images shared, poses copied): adding to it
        leaves this store unchanged."""
        return KeyframeStore(
            self.intrinsics,
            [k.with_pose(k.T_world_cam) for k in self.keyframes],
        )

    def without(self, kf_id: int) -> KeyframeStore:
        """A new store without keyframe ``kf_id`` (KeyError if absent)."""
        self.by_id(kf_id)
        return KeyframeStore(self.intrinsics, [k for k in self.keyframes if k.id != kf_id])

    def with_poses(self, T_world_cam: Mapping[int, F64]) -> KeyframeStore:
        """A new store with some keyframe poses replaced (e.g. after SBA)."""
        return KeyframeStore(
            self.intrinsics,
            [k.with_pose(T_world_cam.get(k.id, k.T_world_cam)) for k in self.keyframes],
        )

    def with_depths(self, depth_m: Mapping[int, NDArray[np.float32]]) -> KeyframeStore:
        """A new store with some keyframe depth maps replaced (e.g. after fusion)."""
        return KeyframeStore(
            self.intrinsics,
            [
                k.with_depth(depth_m[k.id]) if k.id in depth_m else k.with_pose(k.T_world_cam)
                for k in self.keyframes
            ],
        )

    # -- search, sec. 6.2 ------------------------------------------------------------------
    def _stacked_poses(self) -> F64:
        if self._poses.shape[0] != len(self.keyframes):
            self._poses = _f64(np.stack([k.T_world_cam for k in self.keyframes]))
        return self._poses

    def _angles_distances(self, T_world_cam: F64) -> tuple[F64, F64, F64, F64]:
        """(theta_k rad, ||d_k|| m) of eq. (19)-(20) for every keyframe, with the relative
        rotations and translations dT_k = T_kf_cam = T_kf_world T_world_cam."""
        Tk = self._stacked_poses()
        RkT = Tk[:, :3, :3].transpose(0, 2, 1)
        d = T_world_cam[:3, 3] - Tk[:, :3, 3]
        R_kc = RkT @ T_world_cam[:3, :3]
        t_kc = (RkT @ d[:, :, None])[:, :, 0]
        theta = rotation_angle_rad_batch(R_kc)
        return theta, np.sqrt(np.sum(d * d, axis=1)), R_kc, t_kc

    def _metric(self, R_kc: F64, t_kc: F64) -> F64:
        """Eq. (21) for the given relative poses: mean pixel discrepancy of the test points."""
        intr = self.intrinsics
        q = self._test_pts @ R_kc.transpose(0, 2, 1) + t_kc[:, None, :]  # (K, n, 3)
        z = np.maximum(q[..., 2], 1e-6)
        du = intr.fx * q[..., 0] / z + intr.cx - self._test_uv[:, 0]
        dv = intr.fy * q[..., 1] / z + intr.cy - self._test_uv[:, 1]
        d = np.sqrt(du * du + dv * dv)
        d[q[..., 2] <= 0.05] = 10.0 * (intr.width + intr.height)
        return np.asarray(d.mean(axis=1))

    def _scores(self, T_world_cam: F64) -> tuple[F64, F64, F64]:
        """(theta_k rad, ||d_k|| m, eq. (21) metric px) of every keyframe, vectorised."""
        theta, dist, R_kc, t_kc = self._angles_distances(T_world_cam)
        return theta, dist, self._metric(R_kc, t_kc)

    def ranked(self, T_world_cam: F64) -> list[tuple[float, Keyframe]]:
        """All keyframes sorted by the eq. (21) metric from ``T_world_cam``."""
        if not self.keyframes:
            return []
        _, _, metric = self._scores(T_world_cam)
        order = np.argsort(metric, kind="stable")
        return [(float(metric[i]), self.keyframes[i]) for i in order]

    def nearest(
        self, T_world_cam: F64, theta_max_rad: float, d_max_m: float
    ) -> tuple[Keyframe | None, bool]:
        """Nearest keyframe s of eq. (21) among the pre-selected set Omega of eq. (20).

        Returns (keyframe, in_omega); when Omega is empty the overall nearest keyframe is
        returned with ``in_omega=False``.
        """
        kf, in_omega, _ = self.nearest_with_metric(T_world_cam, theta_max_rad, d_max_m)
        return kf, in_omega

    def nearest_with_metric(
        self, T_world_cam: F64, theta_max_rad: float, d_max_m: float
    ) -> tuple[Keyframe | None, bool, float]:
        """:meth:`nearest` and its eq. (21) metric (pixels; inf without keyframes). The
        metric is evaluated only on Omega (the pre-selection prunes distant keyframes)."""
        if not self.keyframes:
            return None, False, float("inf")
        # eq. (20) pre-selection, then the eq. (21) minimum: compiled, as it runs once per
        # tracked frame (the same sums as _angles_distances and _metric)
        from engine.keyframes import search_kernel

        k, in_omega, m = search_kernel.nearest(
            self._stacked_poses(), _f64(T_world_cam), self._test_pts, self._test_uv,
            self._cam, self._far_px, float(theta_max_rad), float(d_max_m),
        )
        return self.keyframes[k], bool(in_omega), float(m)

    def metric_to(self, kf: Keyframe, T_world_cam: F64) -> float:
        """Eq. (21) between a pose and one keyframe (pixels), as :func:`frustum_metric`."""
        from engine.keyframes import search_kernel

        return float(search_kernel.metric(
            _f64(kf.T_world_cam[None]), _f64(T_world_cam), self._test_pts, self._test_uv,
            self._cam, self._far_px,
        ))

    def far_from_all(self, T_world_cam: F64, angle_rad: float, dist_m: float) -> bool:
        """True if the pose differs from every keyframe by more than the angle or distance."""
        for k in self.keyframes:
            th, d = pose_distance(T_world_cam, k.T_world_cam)
            if th < angle_rad and d < dist_m:
                return False
        return True

    # -- persistence ---------------------------------------------------------------------
    def save(self, folder: str | Path) -> Path:
        """Write the store atomically (images first, the JSON index last)."""
        from engine.persist import atomic_write_json, atomic_write_png

        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        scale = self.intrinsics.depth_scale
        entries = []
        for kf in self.keyframes:
            gname = f"kf_{kf.id:04d}_gray.png"
            dname = f"kf_{kf.id:04d}_depth.png"
            atomic_write_png(folder / gname, np.ascontiguousarray(kf.gray, dtype=np.uint8))
            d16 = np.clip(np.nan_to_num(kf.depth_m) * scale, 0, 65535).round().astype(np.uint16)
            atomic_write_png(folder / dname, d16)
            entry: dict[str, object] = {"id": kf.id, "T_world_cam": kf.T_world_cam.tolist(),
                                        "gray": gname, "depth": dname}
            if kf.twist_per_s is not None:
                entry["twist_per_s"] = kf.twist_per_s.tolist()
            entries.append(entry)
        index = {
            "format": STORE_FORMAT,
            "version": STORE_VERSION,
            "intrinsics": self.intrinsics.to_json_dict(),
            "keyframes": entries,
        }
        atomic_write_json(folder / INDEX_NAME, index)
        return folder / INDEX_NAME

    @classmethod
    def load(cls, folder: str | Path, *, lazy: bool = False) -> KeyframeStore:
        """Read a store; a missing, corrupt or incompatible one raises KeyframeStoreError.

        ``lazy``: read the index and check each PNG's header (type, size) only; the images
        are decoded when a keyframe's ``gray``/``depth_m`` is read (a tracker reads each once
        to precompute its reference), so a large store costs little memory.
        """
        import cv2

        folder = Path(folder)
        index_path = folder / INDEX_NAME
        if not folder.is_dir():
            raise KeyframeStoreError(f"{folder}: keyframe store folder not found")
        raw = read_json_file(
            index_path,
            KeyframeStoreError,
            missing="not found (not a keyframe store?)",
            corrupt="corrupt JSON",
        )
        if not isinstance(raw, dict) or raw.get("format") != STORE_FORMAT:
            raise KeyframeStoreError(f"{index_path}: not a {STORE_FORMAT} index")
        version = raw.get("version")
        if version != STORE_VERSION:
            raise KeyframeStoreError(
                f"{index_path}: store version {version!r} is not supported "
                f"(expected {STORE_VERSION})"
            )
        intr = _intrinsics_from(raw.get("intrinsics"), index_path)
        entries = raw.get("keyframes")
        if not isinstance(entries, list) or not entries:
            raise KeyframeStoreError(f"{index_path}: 'keyframes' must be a non-empty list")
        kfs: list[Keyframe] = []
        for n, ent in enumerate(entries):
            where = f"{index_path}: keyframe #{n}"
            try:
                kf_id = int(ent["id"])
                T = np.asarray(ent["T_world_cam"], dtype=np.float64)
                gname, dname = str(ent["gray"]), str(ent["depth"])
            except (KeyError, TypeError, ValueError) as exc:
                raise KeyframeStoreError(f"{where} is malformed ({exc!s})") from None
            if T.shape != (4, 4) or not np.all(np.isfinite(T)):
                raise KeyframeStoreError(f"{where}: T_world_cam must be a finite 4x4 matrix")
            twist = _twist_from(ent.get("twist_per_s"), where)
            R = T[:3, :3]
            if not np.allclose(R.T @ R, np.eye(3), atol=1e-5) or not math.isclose(
                float(np.linalg.det(R)), 1.0, abs_tol=1e-5
            ):
                raise KeyframeStoreError(f"{where}: T_world_cam rotation is not orthonormal")
            for name in (gname, dname):
                if "/" in name or "\\" in name or name.startswith("."):
                    raise KeyframeStoreError(f"{where}: bad file name {name!r}")
            if lazy:
                files = KeyframeFiles(
                    folder / gname, folder / dname, intr.depth_scale, intr.width, intr.height
                )
                _check_png_header(files.gray_path, 8, (intr.width, intr.height))
                _check_png_header(files.depth_path, 16, (intr.width, intr.height))
                kfs.append(Keyframe(kf_id, T, files=files, twist_per_s=twist))
                continue
            gray = cv2.imread(str(folder / gname), cv2.IMREAD_UNCHANGED)
            depth = cv2.imread(str(folder / dname), cv2.IMREAD_UNCHANGED)
            if gray is None:
                raise KeyframeStoreError(f"{folder / gname}: missing or not a readable PNG")
            if depth is None:
                raise KeyframeStoreError(f"{folder / dname}: missing or not a readable PNG")
            if gray.dtype != np.uint8 or gray.ndim != 2:
                raise KeyframeStoreError(f"{folder / gname}: expected an 8-bit grey image")
            if depth.dtype != np.uint16 or depth.ndim != 2:
                raise KeyframeStoreError(f"{folder / dname}: expected a 16-bit depth image")
            if gray.shape != (intr.height, intr.width) or depth.shape != gray.shape:
                raise KeyframeStoreError(
                    f"{folder / gname}: size {gray.shape[1]}x{gray.shape[0]} does not match the "
                    f"store's {intr.width}x{intr.height}"
                )
            depth_m = depth.astype(np.float32) / np.float32(intr.depth_scale)
            kfs.append(Keyframe(kf_id, T, u8(gray), depth_m, twist_per_s=twist))
        ids = [k.id for k in kfs]
        if len(set(ids)) != len(ids):
            raise KeyframeStoreError(f"{index_path}: duplicate keyframe ids")
        return cls(intr, kfs)


def _twist_from(raw: object, where: str) -> F64 | None:
    """A keyframe's optional ``twist_per_s``: six finite numbers (m/s, rad/s), or absent."""
    if raw is None:
        return None
    from engine.validate import number

    if not isinstance(raw, list) or len(raw) != 6:
        raise KeyframeStoreError(f"{where}: 'twist_per_s' must be a list of 6 numbers")
    return np.array([number(v, f"{where}: 'twist_per_s'[{i}]", lo=-1e3, hi=1e3,
                            error=KeyframeStoreError) for i, v in enumerate(raw)],
                    dtype=np.float64)


def _check_png_header(path: Path, bit_depth: int, size_wh: tuple[int, int]) -> None:
    """A grey PNG of the given bit depth and size, from its IHDR chunk (no decoding)."""
    try:
        with path.open("rb") as fh:
            head = fh.read(26)
    except OSError:
        raise KeyframeStoreError(f"{path}: missing or not a readable PNG") from None
    if len(head) < 26 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        raise KeyframeStoreError(f"{path}: missing or not a readable PNG")
    w = int.from_bytes(head[16:20], "big")
    h = int.from_bytes(head[20:24], "big")
    if head[24] != bit_depth or head[25] != 0:
        kind = "an 8-bit grey image" if bit_depth == 8 else "a 16-bit depth image"
        raise KeyframeStoreError(f"{path}: expected {kind}")
    if (w, h) != size_wh:
        raise KeyframeStoreError(
            f"{path}: size {w}x{h} does not match the store's {size_wh[0]}x{size_wh[1]}"
        )


def _intrinsics_from(d: object, where: Path) -> Intrinsics:
    from engine.camera import intrinsics_from_json

    if not isinstance(d, dict):
        raise KeyframeStoreError(f"{where}: 'intrinsics' must be an object")
    return intrinsics_from_json(d, f"{where}: intrinsics", KeyframeStoreError)


def same_camera(a: Intrinsics, b: Intrinsics, tol: float = 1e-6) -> bool:
    """Whether two calibrations are interchangeable for a keyframe store."""
    va = [a.fx, a.fy, a.cx, a.cy, a.width, a.height, *a.dist_k1k2p1p2k3]
    vb = [b.fx, b.fy, b.cx, b.cy, b.width, b.height, *b.dist_k1k2p1p2k3]
    return all(abs(x - y) <= tol * max(1.0, abs(x)) for x, y in zip(va, vb, strict=True))
