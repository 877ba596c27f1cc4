"""Depth map fusion into keyframes (Tykkälä 2014 sec. 6.1, Fig. 10).

"The intermediate point clouds, which are not selected as keyframes, are warped into a
nearest keyframe [...] A large portion of the outlier points can be neglected based on color
deviation to the keyframe pixels. The initial depth map is obtained as the median of the
warped depths [...] The inverse depth samples within z_m +- delta are averaged to find the
robust estimate (Figure 10)."

For each non-keyframe frame with a pose: back-project its depth (inverse Caltech model),
transform into its nearest keyframe (sec. 6.2 metric, eq. (19)-(21)), project with eq. (2)-(4)
to the nearest keyframe pixel, and keep the sample when the frame's grey value at the source
pixel is within ``color_tol`` of the keyframe's grey value at the target pixel. Per keyframe
pixel, the median inverse depth ``m`` of all samples (the keyframe's own depth included) is
found and the samples with ``|1/z - m| <= delta`` are averaged. Pixels with fewer than
``min_samples`` such samples keep their original depth (or stay holes).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import ClassVar, Protocol

import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8
from engine.camera import Intrinsics, pixels_to_normalized
from engine.errors import ParamsError, StudioTrackError
from engine.frames import Frame
from engine.geometry import invert
from engine.keyframes.store import KeyframeStore
from engine.params import Params, Preset, param

F64 = NDArray[np.float64]


class FusionError(StudioTrackError):
    """Depth fusion cannot run (no keyframes, no frames with depth and pose...)."""


@dataclass(frozen=True, slots=True)
class FusionParams(Params):
    """Depth fusion settings (one group; units in the names)."""

    delta_inv_m: float = param(0.01, lo=1e-4, hi=1.0, step=0.001, label="delta inv. depth (1/m)",
                               help="inverse-depth window delta around the median (1/m); about "
                               "3x the sensor's inverse-depth noise (Kinect: ~0.003 1/m)")
    color_tol: float = param(20.0, lo=1.0, hi=255.0,
                             help="reject samples whose grey value differs more from the "
                             "keyframe pixel (grey levels)")
    min_samples: int = param(2, lo=1, hi=100,
                             help="samples within +-delta needed for a fused depth")
    min_depth_m: float = param(0.3, lo=0.0, help="nearest usable depth (m)")
    max_depth_m: float = param(8.0, lo=0.1, help="farthest usable depth (m)")
    pixel_stride: int = param(1, lo=1, hi=8, help="use every n-th frame pixel in x and y (speed)")

    PRESETS: ClassVar[Mapping[str, Preset]] = {
        "paper": Preset(
            "Tykkälä 2014 sec. 6.1, Fig. 10 as published (the fusion has no extension): "
            "samples warped into the nearest keyframe, colour-deviation test, median inverse "
            "depth, mean of the samples within +-delta. The paper gives no value for delta "
            "('user-specified', depends on the sensor noise: 0.01 1/m), the colour tolerance "
            "(20 grey levels) or the samples needed (2); every frame pixel is used",
            delta_inv_m=0.01, color_tol=20.0, min_samples=2, pixel_stride=1,
        ),
    }

    def validate(self) -> None:
        if not self.min_depth_m < self.max_depth_m:
            raise ParamsError(
                f"fusion depth range [{self.min_depth_m}, {self.max_depth_m}] m is empty"
            )


@dataclass(frozen=True, slots=True)
class PosedFrame:
    """A non-keyframe frame of the sweep: grey image, depth (m, 0 invalid), pose."""

    index: int
    gray: NDArray[np.uint8]
    depth_m: NDArray[np.float32]
    T_world_cam: F64


@dataclass(frozen=True, slots=True)
class KeyframeFusionStats:
    kf_id: int
    frames: int
    samples: int
    hole_fraction_before: float
    hole_fraction_after: float
    noise_before_m: float
    noise_after_m: float


@dataclass(frozen=True)
class FusionResult:
    depth_m: dict[int, NDArray[np.float32]]  # fused depth per keyframe id
    stats: tuple[KeyframeFusionStats, ...]
    frames_used: int
    frames_skipped: int
    cancelled: bool
    seconds: float

    @property
    def hole_fraction_before(self) -> float:
        return float(np.mean([s.hole_fraction_before for s in self.stats])) if self.stats else 0.0

    @property
    def hole_fraction_after(self) -> float:
        return float(np.mean([s.hole_fraction_after for s in self.stats])) if self.stats else 0.0

    def apply_to(self, store: KeyframeStore) -> KeyframeStore:
        """A new store: ``store`` with the fused depth maps."""
        return store.with_depths(self.depth_m)


def hole_fraction(depth_m: NDArray[np.floating]) -> float:
    """Fraction of pixels without a valid depth."""
    d = np.asarray(depth_m)
    return float(np.mean(~(np.isfinite(d) & (d > 0))))


def depth_noise_m(depth_m: NDArray[np.floating], size: int = 5) -> float:
    """Truth-free depth noise: robust std (1.4826 MAD) of depth minus its median filter,
    over pixels whose whole window is valid (surfaces are locally smooth in a studio)."""
    import cv2

    d = np.nan_to_num(np.asarray(depth_m, dtype=np.float32))
    valid = (d > 0).astype(np.uint8)
    full = cv2.erode(valid, np.ones((size, size), np.uint8)) > 0
    if not full.any():
        return math.nan
    med = cv2.medianBlur(d, size) if size <= 5 else cv2.blur(d, (size, size))
    r = (d - med)[full]
    return float(1.4826 * np.median(np.abs(r - np.median(r))))


class FrameSet(Protocol):
    """Random-access posed frames: poses are read first (cheap), each frame is loaded once."""

    def __len__(self) -> int: ...
    def pose(self, i: int) -> F64: ...
    def load(self, i: int) -> PosedFrame: ...


class PosedFrames:
    """A :class:`FrameSet` over frames held in memory."""

    def __init__(self, frames: Sequence[PosedFrame]) -> None:
        self.frames = list(frames)

    def __len__(self) -> int:
        return len(self.frames)

    def pose(self, i: int) -> F64:
        return self.frames[i].T_world_cam

    def load(self, i: int) -> PosedFrame:
        return self.frames[i]


class RandomAccessSource(Protocol):
    """A source that reads or renders any frame by index (e.g. the built-in studio)."""

    def frame(self, index: int) -> Frame: ...


class SourceFrames:
    """A :class:`FrameSet` of a random-access source (``source.frame(i)``, e.g. the built-in
    studio) with known poses (tracked or ground truth), rendered/read on demand."""

    def __init__(self, source: RandomAccessSource, poses: Mapping[int, F64],
                 skip: Iterable[int] = ()) -> None:
        self.source = source
        skip_set = set(skip)
        self.indices = sorted(i for i in poses if i not in skip_set)
        self.poses = {i: np.asarray(poses[i], dtype=np.float64) for i in self.indices}

    def __len__(self) -> int:
        return len(self.indices)

    def pose(self, i: int) -> F64:
        return self.poses[self.indices[i]]

    def load(self, i: int) -> PosedFrame:
        import cv2

        fr = self.source.frame(self.indices[i])
        if fr.depth_m is None or fr.color_bgr is None:
            raise FusionError(f"fusion: frame {fr.index} of {self.source} has no image or depth")
        gray = (
            fr.color_bgr
            if fr.color_bgr.ndim == 2
            else u8(cv2.cvtColor(fr.color_bgr, cv2.COLOR_BGR2GRAY))
        )
        return PosedFrame(fr.index, gray, fr.depth_m, self.poses[self.indices[i]])


def fuse_depth(
    store: KeyframeStore,
    frames: FrameSet | Sequence[PosedFrame],
    params: FusionParams | None = None,
    *,
    progress: Callable[[int, int], None] | None = None,
    should_stop: Callable[[], bool] = lambda: False,
) -> FusionResult:
    """Fuse posed frames into their nearest keyframes of ``store``.

    Frames are grouped by nearest keyframe (sec. 6.2) from their poses, then each keyframe is
    fused from its frames (one sample buffer in memory at a time). ``progress(done, total)``
    is called per frame; when ``should_stop()`` turns true the fusion stops and returns
    ``cancelled=True`` with the original depth maps (nothing half-fused).
    """
    from engine.keyframes.fusion_kernels import robust_inverse_depth, warp_into_keyframe

    p = params or FusionParams()
    t0 = time.perf_counter()
    fs = PosedFrames(frames) if isinstance(frames, Sequence) else frames
    kfs = list(store.keyframes)
    intr: Intrinsics = store.intrinsics
    if not kfs:
        raise FusionError("fusion: the keyframe store is empty: record a sweep first")
    n = len(fs)
    groups: dict[int, list[int]] = {k.id: [] for k in kfs}
    for i in range(n):
        kf, _ = store.nearest(fs.pose(i), math.pi, 1e9)
        assert kf is not None  # the store is not empty
        groups[kf.id].append(i)
    vs, us = np.mgrid[0 : intr.height, 0 : intr.width]
    uv = np.stack([us.ravel(), vs.ravel()], axis=1).astype(np.float64)
    rays = pixels_to_normalized(intr, uv).reshape(intr.height, intr.width, 2)
    kin = np.array([intr.fx, intr.fy, intr.cx, intr.cy])
    dist = np.asarray(intr.dist, dtype=np.float64)
    n_pix = intr.width * intr.height
    done = 0
    out: dict[int, NDArray[np.float32]] = {}
    stats = []
    for k in kfs:
        idx = groups[k.id]
        cap = min(64, 2 * (len(idx) + 1))
        buf = np.zeros((n_pix, cap), np.float32)
        cnt = np.zeros(n_pix, np.int32)
        d0 = np.asarray(k.depth_m, dtype=np.float32)
        own = ((d0 > p.min_depth_m) & (d0 < p.max_depth_m)).ravel()
        buf[own, 0] = 1.0 / d0.ravel()[own]  # the keyframe's own depth is one sample
        cnt[own] = 1
        kf_gray = np.ascontiguousarray(k.gray, dtype=np.uint8)
        T_kf_world = invert(k.T_world_cam)
        samples = int(own.sum())
        for i in idx:
            if should_stop():
                return FusionResult(
                    {kk.id: kk.depth_m for kk in kfs}, (), done, 0, True, time.perf_counter() - t0
                )
            f = fs.load(i)
            T = T_kf_world @ np.asarray(f.T_world_cam, dtype=np.float64)
            samples += warp_into_keyframe(
                buf,
                cnt,
                np.ascontiguousarray(f.depth_m, dtype=np.float32),
                np.ascontiguousarray(f.gray, dtype=np.uint8),
                kf_gray,
                rays,
                T,
                kin,
                dist,
                intr.has_distortion,
                p.pixel_stride,
                p.min_depth_m,
                p.max_depth_m,
                int(p.color_tol),
            )
            done += 1
            if progress is not None:
                progress(done, n)
        fused = np.zeros(n_pix, np.float32)
        robust_inverse_depth(buf, cnt, p.delta_inv_m, p.min_samples, fused)
        base = d0.ravel().copy()
        good = fused > 0
        base[good] = 1.0 / fused[good]
        d_new = base.reshape(intr.height, intr.width)
        out[k.id] = d_new
        stats.append(
            KeyframeFusionStats(
                k.id,
                len(idx),
                samples,
                hole_fraction(d0),
                hole_fraction(d_new),
                depth_noise_m(d0),
                depth_noise_m(d_new),
            )
        )
    return FusionResult(out, tuple(stats), done, 0, False, time.perf_counter() - t0)
