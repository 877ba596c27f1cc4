"""The dense trackers: incremental (Algorithm 2) and keyframe (Algorithm 3), with loss
detection, a DEGRADED state and relocalisation.

Quality report. The frame's *inliers* are its points whose Tukey weight (eq. (9)-(10)) times
depth weight (eq. (12)) exceeds 0.1 with the scale set by the sequence's *typical* median
residual (an average over good, not DEGRADED frames, never below one grey level), not by the
frame's own median: a frame that went wrong (a covered lens) inflates its own scale of eq.
(9) until nearly every point looks like an inlier to the optimiser, but not against what
good frames of this camera look like. ``TrackResult.inlier_fraction`` and the overlay's
point weights are these, also on a LOST frame (they are that frame's own attempt);
``details.inlier_fraction_weights`` is the optimiser's own view. ``residual`` is the median
|residual| (grey levels), ``details.residual_ratio`` that over the typical one, and the
keyframe tracker reports ``details.keyframe_distance_px`` (eq. (21) between the frame's pose
and its keyframe's) and ``keyframe_in_range`` (eq. (20)).

States. A frame is *bad* (LOST, holding the last good pose, never extrapolated) when the
linear system cannot be solved, the pose is not finite, the inliers fall below
``min_inlier_fraction``, the median |residual| exceeds ``residual_ratio`` times the typical
one (at least 4 grey levels) or ``max_median_residual``, the removed brightness offset
exceeds ``max_brightness_offset``, or the pose jumps more than ``max_step_m`` /
``max_step_deg`` from its initial guess (divergence). A good frame is DEGRADED (the pose is
sent, flagged) when the inliers fall below ``degraded_inlier_fraction`` (most of the view
occluded or changed), the median residual exceeds ``degraded_residual_ratio`` times the
typical one, or (keyframe tracker) no keyframe lies within ``theta_max_deg`` / ``d_max_m``
(eq. (20): the camera has left the keyframe model); ``details.degraded_reason`` and
``TrackResult.message`` say which. Otherwise TRACKING. While lost, each frame tries the
nearest keyframes to the last good pose (``relocalize_candidates``, eq. (21) order); a
success is reported as RELOCALIZING for ``relock_confirm_frames`` frames. ``details``
(:class:`engine.dense.details.DenseDetails`) carries ``frames_to_relock`` on the frame that
relocked.

Depth timing (beyond the paper). A depth image showing another instant than the colour image
(``Frame.depth_timestamp_s``: TUM pairs by the instant the depth shows, see
:mod:`engine.sources.tum`) is registered to the wrong view while the camera moves; the
reference's photometric points are moved by the tracker's velocity over ``t_depth -
t_colour`` (``compensate_depth_delay``). The geometric term (``geometric_weight``) compares
depth with depth at the depth instants and is not moved: its relative poses are the colour
images' at constant velocity, and moving the current depth by the tracker's own velocity
estimate diverged on TUM paired by stamps (there the depth showed the scene 35-40 ms, more
than a frame, before the colour).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics
from engine.dense import photometric as ph
from engine.dense.details import DenseDetails
from engine.dense.params import DenseParams
from engine.dense.pyramid import gray_u8
from engine.dense.reference_cache import ReferenceCache
from engine.errors import TrackerError
from engine.frames import Frame
from engine.geometry import invert, rotation_angle_rad, se3_exp, se3_log
from engine.keyframes.store import (
    Keyframe,
    KeyframeStore,
    KeyframeStoreError,
    pose_distance,
    same_camera,
)
from engine.results import Overlay, TrackResult, TrackState

F64 = NDArray[np.float64]

#: the smallest typical residual (grey levels) the quality report measures against
QUALITY_FLOOR_GREY = 1.0
#: the rolling-shutter model takes the velocity from the previous frame only if it came
#: at most this long before (a few dropped frames; after a longer gap, or a loss, none)
RS_MAX_GAP_S = 0.2


@dataclass(frozen=True, slots=True)
class _Attempt:
    res: ph.AlignResult
    good: bool
    why: str


def _check(
    res: ph.AlignResult, T0: F64, p: DenseParams, max_residual: float
) -> tuple[bool, str]:
    if not res.ok or not np.all(np.isfinite(res.T_cur_ref)):
        return False, "diverged (singular system)"
    if res.inlier_fraction < p.min_inlier_fraction:
        return False, f"inliers {res.inlier_fraction:.2f} < {p.min_inlier_fraction:.2f}"
    if res.median_abs_e > max_residual:
        return False, f"residual {res.median_abs_e:.1f} > {max_residual:.1f}"
    if abs(res.brightness_offset) > p.max_brightness_offset:
        # an exposure step is a few grey levels; a covered or swapped view is not
        return False, f"brightness jump {res.brightness_offset:.1f}"
    dT = invert(T0) @ res.T_cur_ref
    if float(np.linalg.norm(dT[:3, 3])) > p.max_step_m:
        return False, "diverged (translation jump)"
    if math.degrees(rotation_angle_rad(dT[:3, :3])) > p.max_step_deg:
        return False, "diverged (rotation jump)"
    return True, ""


class _DenseBase:
    """Shared frame handling, state machine and result assembly."""

    name = "dense-base"

    def __init__(self, params: DenseParams) -> None:
        if not isinstance(params, DenseParams):
            raise TrackerError(f"{self.name}: expected DenseParams, got {type(params).__name__}")
        self._params = params
        self._pending: DenseParams | None = None
        self.reset()

    @property
    def params(self) -> DenseParams:
        return self._pending or self._params

    def set_params(self, params: Any) -> None:
        if not isinstance(params, DenseParams):
            raise TrackerError(f"{self.name}: expected DenseParams, got {type(params).__name__}")
        self._pending = params

    def reset(self) -> None:
        self._intr: Intrinsics | None = None
        self._T_world_good: F64 | None = None
        self._lost_frames = 0
        self._confirm_left = 0
        self._velocity: F64 | None = None
        self._last_good_stamped: tuple[float, F64] | None = None
        self._last_step: F64 | None = None
        self._typical_residual: float | None = None

    def _apply_pending(self) -> bool:
        """Swap in new params; True if the reference must be rebuilt."""
        if self._pending is None:
            return False
        old, self._params, self._pending = self._params, self._pending, None
        def key(p: DenseParams) -> tuple[object, ...]:
            return (p.n_points, p.min_depth_m, p.max_depth_m, p.edge_depth_ratio,
                    p.geometric_weight > 0, p.geometric_points, p.geometric_noise_model)

        return key(old) != key(self._params)

    def _prepare(self, frame: Frame) -> ph.Preprocessed:
        if frame.color_bgr is None:
            raise TrackerError(f"{self.name}: frame {frame.index} has no image")
        if frame.depth_m is None:
            raise TrackerError(f"{self.name}: frame {frame.index} has no depth (needs RGB-D)")
        intr = frame.intrinsics or self._intr
        if intr is None:
            raise TrackerError(f"{self.name}: frame {frame.index} has no intrinsics")
        self._intr = intr
        return ph.preprocess(gray_u8(frame.color_bgr), frame.depth_m, intr)

    def _build_reference(
        self, pre: ph.Preprocessed, frame: Frame | None = None,
        twist_per_s: F64 | None = None,
    ) -> ph.Reference:
        p = self._params
        return ph.build_reference(
            pre, p.n_points, min_depth_m=p.min_depth_m, max_depth_m=p.max_depth_m,
            max_edge_depth_ratio=p.edge_depth_ratio,
            T_color_depth=self._depth_delay_transform(frame),
            with_normals=p.geometric_weight > 0, geometric_points=p.geometric_points,
            geometric_noise_model=p.geometric_noise_model,
            rs_ref=self._reference_motion(
                twist_per_s if twist_per_s is not None
                else self._velocity if frame is not None else None),
        )

    def _readout_s(self) -> float:
        """The camera's rolling-shutter readout time where the model is on, else 0."""
        intr = self._intr
        if not self._params.rolling_shutter or intr is None:
            return 0.0
        return intr.rolling_shutter_s  # validated >= 0 (engine.camera)

    def _needs_motion(self, frame: Frame | None) -> bool:
        """A reference built from ``frame`` now would lack its rolling-shutter motion (the
        camera's velocity is not known yet: the first frame, or the first after a loss)."""
        return frame is not None and self._readout_s() > 0.0 and self._velocity is None

    def _reference_motion(self, twist_per_s: F64 | None) -> F64 | None:
        """The rolling-shutter model's ``rs_ref`` of a reference taken while the camera
        moved with ``twist_per_s`` (body twist per second, (v, w); a new reference: the last
        good step's, a stored keyframe: its own), or None (unknown, or no model)."""
        readout = self._readout_s()
        if twist_per_s is None or readout <= 0.0 or self._intr is None:
            return None
        xi = twist_per_s
        return np.array([*ph.rs_rows(self._intr, readout), *xi[:3], *xi[3:]],
                        dtype=np.float64)

    def _note_good_pose(
        self, frame: Frame, T_world_cam: F64, res: ph.AlignResult | None = None,
        typical: bool = True,
    ) -> None:
        """Remember the last two good poses (motion model, depth-delay compensation) and,
        from frames that are not DEGRADED (``typical``), the typical residual."""
        prev = self._last_good_stamped
        self._last_step = None
        if prev is not None and frame.timestamp_s > prev[0]:
            dt = frame.timestamp_s - prev[0]
            step = invert(prev[1]) @ T_world_cam
            xi = se3_log(step) / dt  # body twist per second
            self._velocity = xi if np.all(np.isfinite(xi)) else None
            if self._lost_frames == 0 and self._velocity is not None:
                self._last_step = step
        self._last_good_stamped = (frame.timestamp_s, np.array(T_world_cam))
        if res is not None and typical:
            r = res.median_abs_e
            t = self._typical_residual
            self._typical_residual = r if t is None else 0.9 * t + 0.1 * r

    def _depth_delay_transform(self, frame: Frame | None) -> F64 | None:
        if frame is None or not self._params.compensate_depth_delay or self._velocity is None:
            return None
        t_depth = frame.depth_timestamp_s
        if t_depth is None:
            return None
        dt = float(t_depth) - float(frame.timestamp_s)
        if not math.isfinite(dt) or abs(dt) > 0.1:
            return None
        return se3_exp(self._velocity * dt)  # T_color_depth = exp(xi (t_d - t_c))

    def _rolling_shutter(self, frame: Frame | None, T_world_ref: F64 | None
                         ) -> tuple[float, F64 | None, float]:
        """``(readout_s, T_prev_ref, dt_s)`` for :func:`ph.align`: the camera's readout time
        and the previous frame's pose against the reference, if that frame was tracked and
        is recent (no rolling-shutter model otherwise)."""
        readout = self._readout_s()
        prev = self._last_good_stamped
        if (readout <= 0.0 or frame is None or T_world_ref is None or prev is None
                or self._lost_frames > 0):
            return 0.0, None, 0.0
        dt = float(frame.timestamp_s) - prev[0]
        if not (0.0 < dt <= RS_MAX_GAP_S):
            return 0.0, None, 0.0
        return readout, invert(prev[1]) @ T_world_ref, dt

    def _align(
        self, ref: ph.Reference, pre: ph.Preprocessed, T0: F64, frame: Frame | None = None,
        T_world_ref: F64 | None = None,
    ) -> _Attempt:
        p = self._params
        readout, T_prev_ref, dt_prev = self._rolling_shutter(frame, T_world_ref)
        # the geometric term compares depth with depth, both at the depth instant: no
        # T_color_depth (moving the current depth by the tracker's own velocity estimate
        # extrapolates more than a frame on TUM, depth ~35 ms behind colour, and diverged)
        res = ph.align(
            ref, pre, T0, p.iterations_fine_to_coarse, tau_m=p.tau_m,
            use_depth=p.use_depth_weights, min_residual_scale=p.min_residual_scale,
            scale_over_kept=p.scale_over_kept, threads=p.threads,
            brightness_offset=p.brightness_offset, geo_weight=p.geometric_weight,
            min_geo_scale_m=p.min_geometric_scale_m,
            brightness_gain=p.brightness_gain,
            stop_px=p.stop_px, level_fraction=p.level_fraction_fine_to_coarse,
            quality_scale=self._quality_scale(), rolling_shutter_s=readout,
            T_prev_ref=T_prev_ref, dt_prev_s=dt_prev,
        )
        good, why = _check(res, T0, p, self._max_residual())
        return _Attempt(res, good, why)

    def _quality_scale(self) -> float:
        """Median residual the quality report measures against: the sequence's typical one,
        never below one grey level (the 8-bit quantisation); 0 before the first good frame."""
        t = self._typical_residual
        return 0.0 if t is None else max(t, QUALITY_FLOOR_GREY)

    def _max_residual(self) -> float:
        """Loss threshold on the median |residual|: the absolute cap, or a multiple of the
        residual typical of this sequence when that is lower (synthetic images have tiny
        residuals; a wrong relock there is still far below the absolute cap)."""
        p = self._params
        if self._typical_residual is None:
            return p.max_median_residual
        return min(p.max_median_residual, max(4.0, p.residual_ratio * self._typical_residual))

    def _predict(self) -> F64:
        """Initial guess of the current pose: constant velocity from the last two good
        frames (``motion_model``) or the last good pose. Only an initial guess: the output
        is never extrapolated."""
        assert self._T_world_good is not None
        if not self._params.motion_model or self._last_step is None:
            return self._T_world_good
        return self._T_world_good @ self._last_step

    def _initial_pose(self, frame: Frame) -> F64:
        if self._params.anchor_to_ground_truth and frame.gt_T_world_cam is not None:
            return np.array(frame.gt_T_world_cam, dtype=np.float64)
        return np.eye(4)

    def _degraded_reasons(self, res: ph.AlignResult, kf_in_range: bool | None) -> list[str]:
        """Why a good frame is DEGRADED (empty: TRACKING); see the module docstring."""
        p = self._params
        why = []
        if res.inlier_fraction < p.degraded_inlier_fraction:
            why.append(f"inliers {res.inlier_fraction:.2f} < {p.degraded_inlier_fraction:.2f}")
        t = self._quality_scale()
        if t > 0.0 and res.median_abs_e > p.degraded_residual_ratio * t:
            why.append(
                f"residual {res.median_abs_e:.1f} > {p.degraded_residual_ratio:g} x typical "
                f"{t:.1f}"
            )
        if kf_in_range is False:
            why.append("no keyframe within theta_max_deg / d_max_m (eq. 20)")
        return why

    def _good_state(self, extras: dict[str, Any], degraded: list[str]) -> TrackState:
        """State after a good frame: RELOCALIZING while a relock is being confirmed, else
        DEGRADED when there are reasons, else TRACKING."""
        if self._lost_frames > 0:
            extras["frames_to_relock"] = self._lost_frames
            self._lost_frames = 0
            self._confirm_left = self._params.relock_confirm_frames
        if degraded:
            extras["degraded_reason"] = "; ".join(degraded)
        if self._confirm_left > 0:
            self._confirm_left -= 1
            return TrackState.RELOCALIZING
        return TrackState.DEGRADED if degraded else TrackState.TRACKING

    def _result(
        self,
        state: TrackState,
        T_world_cam: F64 | None,
        att: _Attempt | None,
        kf_id: int | None,
        timings: dict[str, float],
        extras: dict[str, Any],
    ) -> TrackResult:
        t0 = time.perf_counter()
        overlay = None
        residual = inlier = None
        if att is not None:
            r = att.res
            residual = r.median_abs_e
            inlier = r.inlier_fraction
            uv = r.uv_full
            intr = self._intr
            w, h = (intr.width, intr.height) if intr is not None else (np.inf, np.inf)
            u, v = uv[:, 0], uv[:, 1]
            # (NaN compares False: non-finite points are outside)
            inside = (u >= 0) & (v >= 0) & (u <= w - 1) & (v <= h - 1)
            # the selected points that land in the current image, coloured by W (Fig. 15);
            # boolean indexing copies
            overlay = Overlay(points_uv=uv[inside], point_weights=r.weights[inside])
            t = self._quality_scale()
            extras.update(
                rms_residual=r.rms, valid_fraction=r.valid_fraction, iterations=r.iterations,
                n_points=int(r.weights.shape[0]),
                inlier_fraction_weights=r.weights_inlier_fraction,
                residual_ratio=r.median_abs_e / t if t > 0.0 else None,
            )
            if not att.good:
                extras["lost_reason"] = att.why
        timings["result"] = (time.perf_counter() - t0) * 1e3
        if "total" in timings:
            timings["total"] += timings["result"]
        return TrackResult(
            state=state,
            T_world_cam=None if T_world_cam is None else np.array(T_world_cam),
            residual=residual,
            inlier_fraction=inlier,
            keyframe_id=kf_id,
            timings_ms=timings,
            overlay=overlay,
            details=DenseDetails(**extras),
            message=extras.get("lost_reason", "") or extras.get("degraded_reason", ""),
        )


class DenseIncrementalTracker(_DenseBase):
    """Algorithm 2: minimise against the reference, update the reference when signalled."""

    name = "dense-incremental"

    def reset(self) -> None:
        super().reset()
        self._ref: ph.Reference | None = None
        self._ref_pre: ph.Preprocessed | None = None
        self._T_world_ref: F64 = np.eye(4)
        self._T_cur_ref: F64 = np.eye(4)
        self._ref_id = -1
        self._ref_frame: Frame | None = None  # a reference to rebuild once moving (RS)

    def track(self, frame: Frame) -> TrackResult:
        t_start = time.perf_counter()
        rebuild = self._apply_pending()
        p = self._params
        pre = self._prepare(frame)
        timings = {"preprocess": (time.perf_counter() - t_start) * 1e3}
        extras: dict[str, Any] = {}
        if self._ref is None or self._ref_pre is None:
            t = time.perf_counter()
            self._T_world_ref = self._initial_pose(frame)
            self._set_reference(pre, self._T_world_ref, frame)
            timings["select"] = (time.perf_counter() - t) * 1e3
            self._T_world_good = self._T_world_ref.copy()
            self._note_good_pose(frame, self._T_world_good)
            timings["total"] = (time.perf_counter() - t_start) * 1e3
            return self._result(
                TrackState.TRACKING, self._T_world_good, None, self._ref_id, timings, extras
            )
        if rebuild:
            self._ref = self._build_reference(self._ref_pre)
        elif self._ref_frame is not None and self._velocity is not None:
            # the reference came before the camera's velocity was known (rolling shutter):
            # the last good step's stands for its own
            self._ref = self._build_reference(self._ref_pre, self._ref_frame)
            self._ref_frame = None
        t = time.perf_counter()
        T0 = invert(self._predict()) @ self._T_world_ref
        att = self._align(self._ref, pre, T0, frame, self._T_world_ref)
        if not att.good and self._lost_frames > 0:
            # relocalise: also try from the reference pose itself
            alt = self._align(self._ref, pre, np.eye(4), frame)
            if alt.good or alt.res.median_abs_e < att.res.median_abs_e:
                att = alt
        timings["minimize"] = (time.perf_counter() - t) * 1e3
        T_world_cam: F64 | None  # while LOST: the last good pose (None before the first)
        if att.good:
            self._T_cur_ref = att.res.T_cur_ref
            T_world_cam = ph.orthonormalize(self._T_world_ref @ invert(self._T_cur_ref))
            degraded = self._degraded_reasons(att.res, None)
            self._note_good_pose(frame, T_world_cam, att.res, typical=not degraded)
            self._T_world_good = T_world_cam
            state = self._good_state(extras, degraded)
            th = math.degrees(rotation_angle_rad(self._T_cur_ref[:3, :3]))
            d = float(np.linalg.norm(self._T_cur_ref[:3, 3]))
            if (
                d > p.ref_update_dist_m
                or th > p.ref_update_angle_deg
                or att.res.inlier_fraction < p.ref_update_inlier_fraction
            ):
                t = time.perf_counter()
                self._set_reference(pre, T_world_cam, frame)  # Algorithm 2 lines 4-7
                timings["select"] = (time.perf_counter() - t) * 1e3
        else:
            self._lost_frames += 1
            self._confirm_left = 0
            state = TrackState.LOST
            T_world_cam = self._T_world_good
        timings["total"] = (time.perf_counter() - t_start) * 1e3
        return self._result(state, T_world_cam, att, self._ref_id, timings, extras)

    def _set_reference(self, pre: ph.Preprocessed, T_world_ref: F64, frame: Frame) -> None:
        self._ref = self._build_reference(pre, frame)
        # built before the camera's velocity was known (rolling-shutter model): rebuilt
        # after the next good frame
        self._ref_frame = frame if self._needs_motion(frame) else None

        self._ref_pre = pre
        self._T_world_ref = np.array(T_world_ref)
        self._T_cur_ref = np.eye(4)
        self._ref_id += 1


class DenseKeyframeTracker(_DenseBase):
    """Algorithm 3: track against the nearest keyframe (eq. (19)-(21)) of a store.

    Without a store (none given, no ``keyframes_dir``) it builds its keyframes online (sec.
    6.1: Algorithms 2 and 3 alternating). ``extend_store=True`` keeps adding keyframes to a
    given or loaded store too (a second sweep appends to the first); the tracker adds them to
    that store object, so pass a copy (:meth:`KeyframeStore.copy`) to keep the original.

    A new keyframe (the reference built from the frame: selection, normals, pyramid; ~30 ms
    at 640x480 against the ~8 ms of tracking a frame) is built after the frame's result has
    gone out: :meth:`after_frame`, which the pipeline calls once the record reached the sinks,
    or else the next :meth:`track` first. Results are the same either way (the keyframe is
    in the store before the next frame is tracked); only the frame that made the keyframe
    no longer waits for it. :attr:`store` includes it.
    """

    name = "dense"

    def __init__(
        self,
        params: DenseParams,
        store: KeyframeStore | None = None,
        *,
        extend_store: bool = False,
    ) -> None:
        self._given_store = store
        self._extend_store = extend_store
        super().__init__(params)

    def reset(self) -> None:
        super().reset()
        self._store: KeyframeStore | None = self._given_store
        self._store_dir = ""
        self._online = self._given_store is None or self._extend_store
        self._refs = ReferenceCache(self._params.max_resident_references)
        self._kf_id: int | None = None
        # a keyframe decided on but not built yet: (frame, its pre-processing, pose)
        self._pending_kf: tuple[Frame, ph.Preprocessed, F64] | None = None
        # keyframes whose reference was built before the camera's velocity was known (the
        # rolling-shutter model): rebuilt once it is (kf id -> its frame, pre-processing)
        self._unmoved: dict[int, tuple[Frame, ph.Preprocessed]] = {}
        self._started = False
        self._have_good = False
        if self._store is None and self._params.keyframes_dir:
            self._load_store(self._params.keyframes_dir)

    @property
    def store(self) -> KeyframeStore | None:
        self.after_frame()  # the store as the next frame will see it
        return self._store

    def after_frame(self) -> None:
        """Build the keyframe the last frame decided on, if any (work its result did not
        wait for; see the class docstring)."""
        pending = self._pending_kf
        if pending is not None:
            self._pending_kf = None
            self._add_keyframe(*pending)
        if self._unmoved and self._velocity is not None:
            # the velocity at the next good frame stands for the keyframe's own
            for kf_id, (frame, pre) in list(self._unmoved.items()):
                self._refs.keep(kf_id, self._build_reference(pre, frame))
                if self._store is not None:
                    self._store.set_twist(kf_id, self._velocity)
            self._unmoved.clear()

    def _load_store(self, folder: str) -> None:
        # lazily: each keyframe's images are read once, for its reference (memory)
        self._store = KeyframeStore.load(Path(folder), lazy=True)
        self._store_dir = folder
        self._online = self._extend_store
        self._refs.clear()

    def _reference(self, kf: Keyframe) -> ph.Reference:
        ref = self._refs.get(kf.id)
        if ref is None:
            assert self._store is not None
            pre = ph.preprocess(kf.gray, kf.depth_m, self._store.intrinsics)
            ref = self._build_reference(pre, twist_per_s=kf.twist_per_s)
            self._refs.keep_rebuildable(kf.id, ref)
        return ref

    def track(self, frame: Frame) -> TrackResult:
        t_start = time.perf_counter()
        # the last frame's new keyframe, where nothing built it between the frames (a caller
        # without a pipeline): with the parameters it was decided under, as before
        deferred = self._pending_kf is not None
        self.after_frame()
        select_ms = (time.perf_counter() - t_start) * 1e3
        if self._apply_pending():
            self._refs.clear()
        self._refs.capacity = self._params.max_resident_references
        p = self._params
        if p.keyframes_dir and p.keyframes_dir != self._store_dir and self._given_store is None:
            self._load_store(p.keyframes_dir)
            self._started = False
        pre = self._prepare(frame)
        if self._store is not None and not same_camera(self._store.intrinsics, pre.intrinsics):
            raise KeyframeStoreError(
                f"{self._store_dir or 'keyframe store'}: built for a different camera "
                f"({self._store.intrinsics.width}x{self._store.intrinsics.height} "
                f"fx={self._store.intrinsics.fx}) than frame {frame.index}'s"
            )
        timings = {"preprocess": (time.perf_counter() - t_start) * 1e3 - select_ms}
        if deferred:
            timings["select"] = select_ms
        extras: dict[str, Any] = {}
        if self._store is None:
            self._store = KeyframeStore(pre.intrinsics)
            self._online = True
        if not self._started:
            return self._first_frame(frame, pre, timings, extras, t_start)
        assert self._T_world_good is not None
        if self._lost_frames > 0:
            t = time.perf_counter()
            att, kf = self._relocalize(pre, p.relocalize_candidates)
            timings["minimize"] = (time.perf_counter() - t) * 1e3
        else:
            t = time.perf_counter()
            kf, _ = self._store.nearest(
                self._predict(), math.radians(p.theta_max_deg), p.d_max_m
            )
            assert kf is not None
            ref = self._reference(kf)
            timings["keyframe"] = (time.perf_counter() - t) * 1e3
            t = time.perf_counter()
            T0 = invert(self._predict()) @ kf.T_world_cam  # T^ = T_cur (T*)^-1, Alg. 3
            att = self._align(ref, pre, T0, frame, kf.T_world_cam)
            timings["minimize"] = (time.perf_counter() - t) * 1e3
        return self._finish(frame, pre, att, kf, timings, extras, t_start)

    def _finish(
        self,
        frame: Frame,
        pre: ph.Preprocessed,
        att: _Attempt | None,
        kf: Keyframe | None,
        timings: dict[str, float],
        extras: dict[str, Any],
        t_start: float,
    ) -> TrackResult:
        p = self._params
        assert self._store is not None
        T_world_cam: F64 | None  # None while never located against the store
        if att is not None and att.good and kf is not None:
            # T_cur = T^ T*, Alg. 3 (in our T_world_cam convention)
            T_world_cam = ph.orthonormalize(kf.T_world_cam @ invert(att.res.T_cur_ref))
            # keyframe distance of this frame: eq. (21) pixels and eq. (20) range
            th, dist = pose_distance(T_world_cam, kf.T_world_cam)
            in_range = th < math.radians(p.theta_max_deg) and dist < p.d_max_m
            extras["keyframe_distance_px"] = self._store.metric_to(kf, T_world_cam)
            extras["keyframe_in_range"] = in_range
            degraded = self._degraded_reasons(att.res, in_range)
            self._note_good_pose(frame, T_world_cam, att.res, typical=not degraded)
            self._T_world_good = T_world_cam
            self._kf_id = kf.id
            state = self._good_state(extras, degraded)
            # the view has changed so much that the residual nears the loss threshold
            # (an occluding presenter lowers the inlier fraction but hardly the median)
            weak = att.res.median_abs_e > 0.5 * p.max_median_residual
            if (
                self._online
                and state.is_good
                and (
                    weak
                    or self._store.far_from_all(
                        T_world_cam, math.radians(p.kf_add_angle_deg), p.kf_add_dist_m
                    )
                )
            ):
                # built after this frame's result went out (after_frame)
                self._pending_kf = (frame, pre, T_world_cam)
                extras["keyframe_added"] = True
        else:
            self._lost_frames += 1
            self._confirm_left = 0
            if self._have_good:
                state = TrackState.LOST
                T_world_cam = self._T_world_good
            else:  # never located against the store yet: no pose to hold
                state = TrackState.INITIALIZING
                T_world_cam = None
        if state.is_good or state == TrackState.RELOCALIZING:
            self._have_good = True
        extras["keyframes"] = len(self._store) + (self._pending_kf is not None)
        timings["total"] = (time.perf_counter() - t_start) * 1e3
        return self._result(state, T_world_cam, att, self._kf_id, timings, extras)

    def _add_keyframe(self, frame: Frame, pre: ph.Preprocessed, T_world_cam: F64) -> Keyframe:
        assert self._store is not None
        assert frame.color_bgr is not None
        assert frame.depth_m is not None
        gray = np.array(gray_u8(frame.color_bgr), dtype=np.uint8)
        kf = self._store.add(T_world_cam, gray, np.array(frame.depth_m, dtype=np.float32),
                             twist_per_s=self._velocity)
        self._refs.keep(kf.id, self._build_reference(pre, frame))
        if self._needs_motion(frame):
            self._unmoved[kf.id] = (frame, pre)
        self._kf_id = kf.id
        return kf

    def _first_frame(
        self,
        frame: Frame,
        pre: ph.Preprocessed,
        timings: dict[str, float],
        extras: dict[str, Any],
        t_start: float,
    ) -> TrackResult:
        assert self._store is not None
        self._started = True
        T_init = self._initial_pose(frame)
        if len(self._store) == 0:
            # online map: the first frame is the first keyframe
            t = time.perf_counter()
            self._add_keyframe(frame, pre, T_init)
            timings["select"] = (time.perf_counter() - t) * 1e3
            self._T_world_good = T_init
            self._have_good = True
            self._note_good_pose(frame, T_init)
            extras["keyframes"] = 1
            timings["total"] = (time.perf_counter() - t_start) * 1e3
            return self._result(TrackState.TRACKING, T_init, None, self._kf_id, timings, extras)
        # a store: its keyframe pre-computations (Alg. 3) all at start-up, so that switching
        # keyframes later costs no frame time (about 3.5 ms per keyframe, once)
        t = time.perf_counter()
        for stored in self._store.keyframes:
            self._reference(stored)
        timings["select"] = (time.perf_counter() - t) * 1e3
        # start at the known pose or the first keyframe (Alg. 3, T^ = I) and relocalise over
        # all keyframes nearest first
        self._T_world_good = (
            T_init
            if self._params.anchor_to_ground_truth and frame.gt_T_world_cam is not None
            else self._store.keyframes[0].T_world_cam.copy()
        )
        t = time.perf_counter()
        att, kf = self._relocalize(pre, len(self._store))
        timings["minimize"] = (time.perf_counter() - t) * 1e3
        if att is None or not att.good:
            self._lost_frames = 1
            extras["keyframes"] = len(self._store)
            timings["total"] = (time.perf_counter() - t_start) * 1e3
            return self._result(TrackState.INITIALIZING, None, att, None, timings, extras)
        self._lost_frames = 0
        return self._finish(frame, pre, att, kf, timings, extras, t_start)

    def _relocalize(
        self, pre: ph.Preprocessed, n_candidates: int
    ) -> tuple[_Attempt | None, Keyframe | None]:
        """Try the keyframes nearest to the last good pose; best good attempt wins."""
        assert self._store is not None
        assert self._T_world_good is not None
        best: tuple[_Attempt, Keyframe] | None = None
        fallback: tuple[_Attempt, Keyframe] | None = None
        for _, kf in self._store.ranked(self._T_world_good)[:n_candidates]:
            ref = self._reference(kf)
            for T0 in (invert(self._T_world_good) @ kf.T_world_cam, np.eye(4)):
                att = self._align(ref, pre, T0)
                if not att.res.ok:
                    continue
                if att.good:
                    # the divergence test is relative to the guess; while relocalising,
                    # keep it against the last good pose
                    if best is None or att.res.median_abs_e < best[0].res.median_abs_e:
                        best = (att, kf)
                elif fallback is None or att.res.median_abs_e < fallback[0].res.median_abs_e:
                    fallback = (att, kf)
        if best is not None:
            return best
        if fallback is not None:
            return fallback
        return None, None
