"""Recording a keyframe sweep of the empty studio (Tykkälä 2014 sec. 6.1).

The camera sweeps the static scene; it is tracked by the dense keyframe tracker building its
keyframes online (Algorithms 2 and 3 alternating: track against the nearest keyframe, add the
current frame as a keyframe when it is farther than ``kf_add_dist_m`` / ``kf_add_angle_deg``
from every existing one), driven by the engine loop (:func:`engine.loop.run_tracking`). The
keyframes and their poses are the store. One recorder serves ``studiotrack sweep`` and the
Keyframes page: per-frame progress records (state, new keyframe thumbnail), appending to an
existing store (a second sweep), and the non-keyframe frames with their tracked poses kept
for the depth fusion of Fig. 10. While the track is lost no keyframe is added (the dense
tracker adds keyframes only in the TRACKING state) and the record says so.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8
from engine.dense.params import DenseParams
from engine.errors import TrackerError
from engine.frames import readonly
from engine.keyframes.fusion import PosedFrame
from engine.keyframes.store import KeyframeStore
from engine.params import Params, param
from engine.sources.base import Source

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class SweepParams(Params):
    """Keyframe selection and frame keeping while recording (units in the names)."""

    kf_add_dist_m: float = param(0.15, lo=0.01, hi=5.0, step=0.01,
                                 help="add a keyframe when this far from all others (m)")
    kf_add_angle_deg: float = param(10.0, lo=0.5, hi=90.0, step=0.5,
                                    help="...or turned this much from all others (deg)")
    keep_every: int = param(2, lo=1, hi=30, help="keep every n-th tracked frame for depth fusion")
    max_kept_frames: int = param(400, lo=0, hi=5000,
                                 help="at most this many frames kept for fusion (memory)")
    max_frames: int = param(0, lo=0, help="stop after this many frames (0: all)")


@dataclass(frozen=True, slots=True)
class NewKeyframe:
    id: int
    T_world_cam: F64
    thumbnail: NDArray[np.uint8]  # grey, about 96 px wide
    valid_depth_fraction: float


@dataclass(frozen=True, slots=True)
class SweepProgress:
    """One processed frame of a recording (crosses threads: frozen, read-only arrays)."""

    frame_index: int
    frames: int
    keyframes: int
    lost_frames: int
    state: str  # TrackState name
    adding_paused: bool  # lost track: keyframe adding is paused
    T_world_cam: F64 | None
    new_keyframe: NewKeyframe | None
    source_len: int


@dataclass(frozen=True)
class SweepRecording:
    store: KeyframeStore
    frames: tuple[PosedFrame, ...]  # non-keyframe frames with tracked poses (for fusion)
    trajectory: dict[int, F64]  # frame index -> tracked T_world_cam (good frames)
    frames_processed: int
    lost_frames: int
    seconds: float
    stopped: bool


def thumbnail(gray: NDArray[np.uint8], width: int = 96) -> NDArray[np.uint8]:
    import cv2

    h, w = gray.shape[:2]
    out = cv2.resize(gray, (width, max(1, round(h * width / w))), interpolation=cv2.INTER_AREA)
    return readonly(u8(out))


def record_sweep(
    source: Source,
    params: SweepParams | None = None,
    *,
    store: KeyframeStore | None = None,
    dense_params: DenseParams | None = None,
    on_progress: Callable[[SweepProgress], None] | None = None,
    should_stop: Callable[[], bool] = lambda: False,
) -> SweepRecording:
    """Track ``source`` incrementally and add keyframes (appending to ``store`` if given).

    The keyframe thresholds of ``params`` replace those of ``dense_params``; ``store`` is
    not changed (the recording extends a copy). ``on_progress`` gets one record per frame;
    when ``should_stop()`` turns true the recording ends with ``stopped=True`` and keeps
    what it has.
    """
    import cv2

    from engine.dense.tracking import DenseKeyframeTracker
    from engine.loop import run_tracking

    p = params or SweepParams()
    dp = dataclasses.replace(
        dense_params or DenseParams(),
        keyframes_dir="",
        kf_add_dist_m=p.kf_add_dist_m,
        kf_add_angle_deg=p.kf_add_angle_deg,
    )
    # the caller's store changes only when the recording is accepted: extend a copy
    tracker = DenseKeyframeTracker(
        dp, None if store is None else store.copy(), extend_store=True
    )
    stopped = False

    def stop() -> bool:
        nonlocal stopped
        stopped = should_stop()
        return stopped

    t0 = time.perf_counter()
    n = lost = 0
    kept: list[PosedFrame] = []
    traj: dict[int, F64] = {}
    known = set() if store is None else {k.id for k in store.keyframes}
    for rec in run_tracking(
        source, tracker, should_stop=stop, max_frames=p.max_frames or None
    ):
        frame, res = rec.frame, rec.result
        n = rec.seq + 1
        good = res.state.is_good
        if not good:
            lost += 1
        new_kf = None
        st = tracker.store
        if st is not None:
            added = [k for k in st.keyframes if k.id not in known]
            if added:
                k = added[-1]
                new_kf = NewKeyframe(
                    k.id,
                    readonly(k.T_world_cam.copy()),
                    thumbnail(k.gray),
                    float(np.mean(k.depth_m > 0)),
                )
                known.update(a.id for a in added)
        if good and res.T_world_cam is not None:
            T = np.array(res.T_world_cam, dtype=np.float64)
            traj[frame.index] = T
            if (
                new_kf is None
                and frame.depth_m is not None
                and frame.color_bgr is not None
                and n % p.keep_every == 0
                and len(kept) < p.max_kept_frames
            ):
                gray = (
                    frame.color_bgr
                    if frame.color_bgr.ndim == 2
                    else u8(cv2.cvtColor(frame.color_bgr, cv2.COLOR_BGR2GRAY))
                )
                kept.append(PosedFrame(frame.index, gray, frame.depth_m, readonly(T)))
        if on_progress is not None:
            on_progress(
                SweepProgress(
                    frame.index,
                    n,
                    len(st) if st is not None else 0,
                    lost,
                    res.state.name,
                    not good,
                    None
                    if res.T_world_cam is None
                    else readonly(np.array(res.T_world_cam, dtype=np.float64)),
                    new_kf,
                    rec.source_len,
                )
            )
    st = tracker.store
    if st is None or len(st) == 0:
        raise TrackerError(f"sweep of {source.name}: no frames with depth, no keyframes")
    return SweepRecording(st, tuple(kept), traj, n, lost, time.perf_counter() - t0, stopped)
