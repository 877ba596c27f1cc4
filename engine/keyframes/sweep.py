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
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.arrays import u8
from engine.dense.params import DenseParams
from engine.errors import TrackerError
from engine.frames import readonly
from engine.keyframes.fusion import PosedFrame
from engine.keyframes.store import KeyframeStore
from engine.params import Params, param
from engine.pipeline import SinkBase
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


def sweep_tracker(params: SweepParams | None = None, *, store: KeyframeStore | None = None,
                  dense_params: DenseParams | None = None) -> Any:
    """The dense keyframe tracker of a sweep: keyframes added online (the thresholds of
    ``params`` replace those of ``dense_params``), extending a copy of ``store`` if given."""
    from engine.dense.tracking import DenseKeyframeTracker

    p = params or SweepParams()
    dp = dataclasses.replace(
        dense_params or DenseParams(),
        keyframes_dir="",
        kf_add_dist_m=p.kf_add_dist_m,
        kf_add_angle_deg=p.kf_add_angle_deg,
    )
    # the caller's store changes only when the recording is accepted: extend a copy
    return DenseKeyframeTracker(dp, None if store is None else store.copy(), extend_store=True)


class SweepRecorder(SinkBase):
    """A pipeline sink that turns the sweep tracker's records into a :class:`SweepRecording`.

    On the engine thread it notes each frame (new keyframe thumbnails, poses, the frames kept
    for fusion); ``progress`` is the latest :class:`SweepProgress` and :meth:`take_new`
    the keyframes added since the last call (the window draws them at its own rate);
    ``on_progress`` (optional) gets every progress record. :meth:`recording` gives the result.
    """

    name = "sweep recorder"

    def __init__(self, tracker: Any, params: SweepParams | None = None, *,
                 store: KeyframeStore | None = None,
                 on_progress: Callable[[SweepProgress], None] | None = None) -> None:
        self.tracker = tracker
        self.params = params or SweepParams()
        self.on_progress = on_progress
        self._known = set() if store is None else {k.id for k in store.keyframes}
        self._lock = threading.Lock()
        self._new: list[NewKeyframe] = []
        self.progress: SweepProgress | None = None
        self.kept: list[PosedFrame] = []
        self.trajectory: dict[int, F64] = {}
        self.frames = 0
        self.lost = 0
        self._t0 = time.perf_counter()

    def open(self, run: Any) -> None:
        self._t0 = time.perf_counter()

    def on_record(self, rec: Any) -> None:
        import cv2

        p = self.params
        frame, res = rec.frame, rec.result
        n = self.frames = rec.seq + 1
        good = res.state.is_good
        if not good:
            self.lost += 1
        new_kf = None
        st = self.tracker.store
        if st is not None:
            added = [k for k in st.keyframes if k.id not in self._known]
            if added:
                k = added[-1]
                new_kf = NewKeyframe(
                    k.id,
                    readonly(k.T_world_cam.copy()),
                    thumbnail(k.gray),
                    float(np.mean(k.depth_m > 0)),
                )
                self._known.update(a.id for a in added)
        if good and res.T_world_cam is not None:
            T = np.array(res.T_world_cam, dtype=np.float64)
            self.trajectory[frame.index] = T
            if (
                new_kf is None
                and frame.depth_m is not None
                and frame.color_bgr is not None
                and n % p.keep_every == 0
                and len(self.kept) < p.max_kept_frames
            ):
                gray = (
                    frame.color_bgr
                    if frame.color_bgr.ndim == 2
                    else u8(cv2.cvtColor(frame.color_bgr, cv2.COLOR_BGR2GRAY))
                )
                self.kept.append(PosedFrame(frame.index, gray, frame.depth_m, readonly(T)))
        prog = SweepProgress(
            frame.index,
            n,
            len(st) if st is not None else 0,
            self.lost,
            res.state.name,
            not good,
            None
            if res.T_world_cam is None
            else readonly(np.array(res.T_world_cam, dtype=np.float64)),
            new_kf,
            rec.source_len,
        )
        with self._lock:
            self.progress = prog
            if new_kf is not None:
                self._new.append(new_kf)
        if self.on_progress is not None:
            self.on_progress(prog)

    def take_new(self) -> list[NewKeyframe]:
        """Keyframes added since the last call (any thread)."""
        with self._lock:
            out, self._new = self._new, []
        return out

    def recording(self, source_name: str, stopped: bool) -> SweepRecording:
        """The result; raises TrackerError when the sweep made no keyframe."""
        st = self.tracker.store
        if st is None or len(st) == 0:
            raise TrackerError(f"sweep of {source_name}: no frames with depth, no keyframes")
        return SweepRecording(st, tuple(self.kept), dict(self.trajectory), self.frames,
                              self.lost, time.perf_counter() - self._t0, stopped)


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
    what it has. The window runs the same :class:`SweepRecorder` sink through its run owner.
    """
    from engine.loop import run_tracking

    p = params or SweepParams()
    tracker = sweep_tracker(p, store=store, dense_params=dense_params)
    sink = SweepRecorder(tracker, p, store=store, on_progress=on_progress)
    stopped = False

    def stop() -> bool:
        nonlocal stopped
        stopped = should_stop()
        return stopped

    for _rec in run_tracking(
        source, tracker, should_stop=stop, max_frames=p.max_frames or None, sinks=[sink]
    ):
        pass
    return sink.recording(source.name, stopped)
