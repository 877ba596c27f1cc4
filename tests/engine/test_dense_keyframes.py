"""Keyframe store (persistence, errors) and nearest-keyframe search, eq. (19)-(21)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from engine.dense.params import DenseParams
from engine.dense.testscene import PlaneScene, small_intrinsics
from engine.geometry import R_from_pan_tilt_roll_deg, make_T, se3_exp
from engine.keyframes.store import (
    INDEX_NAME,
    KeyframeStore,
    KeyframeStoreError,
    frustum_metric,
    frustum_test_points,
)
from engine.keyframes.sweep import SweepParams, record_sweep
from engine.sources.base import Source
from engine.trackers import create_tracker
from engine.trackers.base import TrackState


def _store(n: int = 3) -> KeyframeStore:
    intr = small_intrinsics()
    rng = np.random.default_rng(0)
    st = KeyframeStore(intr)
    for k in range(n):
        T = se3_exp(np.array([0.1 * k, 0.0, 0.0, 0.0, 0.02 * k, 0.0]))
        gray = rng.integers(0, 255, (intr.height, intr.width), dtype=np.uint8)
        depth = rng.uniform(0.5, 4.0, (intr.height, intr.width)).astype(np.float32)
        depth[0, :10] = 0.0
        st.add(T, gray, depth)
    return st


def test_round_trip(tmp_path: Path) -> None:
    st = _store()
    st.save(tmp_path / "kf")
    back = KeyframeStore.load(tmp_path / "kf")
    assert len(back) == 3
    assert back.intrinsics == st.intrinsics
    for a, b in zip(st.keyframes, back.keyframes, strict=True):
        assert a.id == b.id
        np.testing.assert_allclose(a.T_world_cam, b.T_world_cam, atol=1e-12)
        np.testing.assert_array_equal(a.gray, b.gray)
        np.testing.assert_allclose(a.depth_m, b.depth_m, atol=1.0 / 5000)
    # only JSON + PNG, no pickle
    assert sorted(p.suffix for p in (tmp_path / "kf").iterdir()) == [".json"] + [".png"] * 6


def test_lazy_load_reads_the_images_on_demand(tmp_path: Path) -> None:
    """load(lazy=True) checks each PNG's header (type, size) without decoding; the images
    are read when used, and edits keep (or, for new depth, end) the laziness."""
    import cv2

    folder = tmp_path / "kf"
    _store().save(folder)
    eager = KeyframeStore.load(folder)
    lazy = KeyframeStore.load(folder, lazy=True)
    for a, b in zip(eager.keyframes, lazy.keyframes, strict=True):
        assert a.resident
        assert not b.resident
        np.testing.assert_array_equal(a.T_world_cam, b.T_world_cam)
        np.testing.assert_array_equal(a.gray, b.gray)
        np.testing.assert_array_equal(a.depth_m, b.depth_m)
    assert not lazy.with_poses({0: np.eye(4)}).keyframes[0].resident
    assert not lazy.copy().keyframes[1].resident
    assert lazy.with_depths({0: eager.keyframes[0].depth_m}).keyframes[0].resident
    intr = lazy.intrinsics
    cv2.imwrite(str(folder / "kf_0002_gray.png"), np.zeros((10, 12), np.uint8))
    with pytest.raises(KeyframeStoreError, match=r"kf_0002_gray\.png: size 12x10 does not"):
        KeyframeStore.load(folder, lazy=True)
    cv2.imwrite(str(folder / "kf_0002_gray.png"), np.zeros((intr.height, intr.width), np.uint16))
    with pytest.raises(KeyframeStoreError, match="expected an 8-bit grey image"):
        KeyframeStore.load(folder, lazy=True)
    (folder / "kf_0002_gray.png").unlink()
    with pytest.raises(KeyframeStoreError, match=r"kf_0002_gray\.png: missing"):
        KeyframeStore.load(folder, lazy=True)


def test_tracker_keeps_references_not_images(tmp_path: Path) -> None:
    """A store given as keyframes_dir is loaded lazily: after the first frame (which builds
    every keyframe's reference) no keyframe image is held."""
    intr = small_intrinsics(distorted=True)
    scene = PlaneScene(intr, room_scale=0.45)
    st = KeyframeStore(intr)
    for k in range(3):
        T = se3_exp(np.array([0.03 * k, 0.0, 0.0, 0.0, 0.01 * k, 0.0]))
        gray, depth = scene.render(T)
        st.add(T, gray, depth)
    st.save(tmp_path / "kf")
    tr = create_tracker("dense", keyframes_dir=str(tmp_path / "kf"), n_points=1024)
    res = tr.track(scene.frame(0, se3_exp(np.array([0.01, 0.0, 0.0, 0.0, 0.0, 0.0]))))
    assert res.state == TrackState.TRACKING
    assert len(tr.store) == 3
    assert not any(k.resident for k in tr.store.keyframes)
    assert len(tr._refs) == 3


def test_corrupt_and_incompatible_stores_fail_clearly(tmp_path: Path) -> None:
    folder = tmp_path / "kf"
    _store().save(folder)
    index = folder / INDEX_NAME
    good = index.read_text()
    index.write_text(good[: len(good) // 2])
    with pytest.raises(KeyframeStoreError, match=r"keyframes\.json: corrupt JSON"):
        KeyframeStore.load(folder)
    raw = json.loads(good)
    raw["version"] = 99
    index.write_text(json.dumps(raw))
    with pytest.raises(KeyframeStoreError, match="version 99 is not supported"):
        KeyframeStore.load(folder)
    raw = json.loads(good)
    index.write_text(json.dumps(raw))
    (folder / "kf_0001_depth.png").write_bytes(b"not a png")
    with pytest.raises(KeyframeStoreError, match=r"kf_0001_depth\.png: missing or not a readable"):
        KeyframeStore.load(folder)
    with pytest.raises(KeyframeStoreError, match="not found"):
        KeyframeStore.load(tmp_path / "nowhere")
    # the tracker reports the same error when built on a broken store
    with pytest.raises(KeyframeStoreError):
        create_tracker("dense", keyframes_dir=str(folder))


def test_nearest_keyframe_eq19_21() -> None:
    intr = small_intrinsics()
    st = KeyframeStore(intr)
    blank = np.zeros((intr.height, intr.width), np.uint8)
    depth = np.ones((intr.height, intr.width), np.float32)
    for x in (0.0, 0.5, 1.0, 1.5):
        st.add(make_T(np.eye(3), [x, 0.0, 0.0]), blank, depth)
    kf, in_omega = st.nearest(make_T(np.eye(3), [0.6, 0.0, 0.05]), math.radians(30), 0.4)
    assert kf is not None
    assert kf.id == 1
    assert in_omega
    # Omega empty (too far from all): the overall nearest is returned, flagged
    kf, in_omega = st.nearest(make_T(np.eye(3), [3.0, 0.0, 0.0]), math.radians(30), 0.4)
    assert kf is not None
    assert kf.id == 3
    assert not in_omega
    # rotation about the optical axis is seen by the test-point metric (eq. 21)
    pts = frustum_test_points(intr)
    assert pts.shape[0] == 3 * 30
    T0 = np.eye(4)
    R0 = R_from_pan_tilt_roll_deg(0, 0, 0)
    T_roll = make_T(R_from_pan_tilt_roll_deg(0, 0, 5) @ R0.T, [0, 0, 0])
    assert frustum_metric(intr, T_roll, T0, pts) > 1.0
    assert frustum_metric(intr, T0, T0, pts) == pytest.approx(0.0)


def test_compiled_nearest_keyframe_is_the_vectorised_search() -> None:
    """The per-frame search (compiled) picks the keyframe and metric of the numpy eq. (19)-
    (21) search (``ranked``/_scores) on random poses, with and without an empty Omega; the
    single-keyframe metric is :func:`frustum_metric`."""
    intr = small_intrinsics()
    st = KeyframeStore(intr)
    blank = np.zeros((intr.height, intr.width), np.uint8)
    depth = np.ones((intr.height, intr.width), np.float32)
    rng = np.random.default_rng(5)
    for _ in range(25):
        st.add(se3_exp(rng.normal(0.0, [0.5, 0.1, 0.5, 0.1, 0.3, 0.1])), blank, depth)
    pts = frustum_test_points(intr)
    for _ in range(40):
        T = se3_exp(rng.normal(0.0, [0.6, 0.1, 0.6, 0.1, 0.4, 0.1]))
        for theta_max, d_max in ((math.radians(30), 0.5), (math.radians(1), 0.01)):
            kf, in_omega, m = st.nearest_with_metric(T, theta_max, d_max)
            theta, dist, metric = st._scores(T)
            omega = (theta < theta_max) & (dist < d_max)
            pool = np.flatnonzero(omega) if omega.any() else np.arange(len(st))
            k = int(pool[np.argmin(metric[pool])])
            assert kf is st.keyframes[k]
            assert in_omega == bool(omega.any())
            assert m == pytest.approx(float(metric[k]), rel=1e-9, abs=1e-9)
            assert st.metric_to(kf, T) == pytest.approx(
                frustum_metric(intr, T, kf.T_world_cam, pts), rel=1e-9, abs=1e-9)


class _ListSource(Source):
    def __init__(self, frames: list) -> None:  # type: ignore[type-arg]
        self._frames = frames
        self.name = "test frames"

    @property
    def intrinsics(self):  # type: ignore[no-untyped-def]
        return self._frames[0].intrinsics

    def __len__(self) -> int:
        return len(self._frames)

    def frames(self):  # type: ignore[no-untyped-def]
        yield from self._frames


def test_sweep_builds_a_store_that_dense_tracks_against(tmp_path: Path) -> None:
    scene = PlaneScene(small_intrinsics(), room_scale=0.45)

    def pose(i: int) -> np.ndarray:
        return make_T(np.eye(3), [0.01 * i, 0.0, 0.0])

    frames = [scene.frame(i, pose(i)) for i in range(0, 24)]
    res = record_sweep(
        _ListSource(frames),
        SweepParams(kf_add_dist_m=0.08, max_kept_frames=0),
        dense_params=DenseParams(n_points=1024),
    )
    assert res.frames == ()  # none kept
    assert len(res.store) >= 3
    res.store.save(tmp_path / "kf")
    tr = create_tracker("dense", n_points=1024, keyframes_dir=str(tmp_path / "kf"))
    out = [tr.track(scene.frame(i, pose(i) @ make_T(np.eye(3), [0, 0.01, 0]))) for i in (5, 6, 7)]
    assert all(r.state.is_good or r.state == TrackState.RELOCALIZING for r in out)
    for i, r in zip((5, 6, 7), out, strict=True):
        assert r.keyframe_id is not None
        assert np.linalg.norm(r.T_world_cam[:3, 3] - (pose(i)[:3, 3] + [0, 0.01, 0])) < 2e-3


def test_store_for_another_camera_is_refused(tmp_path: Path) -> None:
    _store().save(tmp_path / "kf")
    tr = create_tracker("dense", n_points=1024, keyframes_dir=str(tmp_path / "kf"))
    other = small_intrinsics(distorted=False)  # same size, different distortion
    scene = PlaneScene(other, room_scale=0.45)
    with pytest.raises(KeyframeStoreError, match="different camera"):
        tr.track(scene.frame(0, np.eye(4)))


def test_store_edits_return_new_stores() -> None:
    st = _store()
    poses = [k.T_world_cam.copy() for k in st.keyframes]
    depth1 = st.by_id(1).depth_m
    moved = st.with_poses({1: np.eye(4)})
    fused = st.with_depths({1: np.zeros_like(depth1)})
    fewer = st.without(0)
    np.testing.assert_array_equal(moved.by_id(1).T_world_cam, np.eye(4))
    assert not fused.by_id(1).depth_m.any()
    assert [k.id for k in fewer.keyframes] == [1, 2]
    # the original is untouched by all three
    assert len(st) == 3
    assert st.by_id(1).depth_m is depth1
    for k, T in zip(st.keyframes, poses, strict=True):
        np.testing.assert_array_equal(k.T_world_cam, T)
    with pytest.raises(KeyError):
        st.without(7)
    copy = st.copy()
    copy.add(np.eye(4), st.by_id(0).gray, depth1)
    assert len(copy) == 4
    assert len(st) == 3


def test_tracker_extends_a_given_store_only_when_asked() -> None:
    from engine.dense.tracking import DenseKeyframeTracker

    scene = PlaneScene(small_intrinsics(), room_scale=0.45)

    def pose(i: int) -> np.ndarray:
        return make_T(np.eye(3), [0.02 * i, 0.0, 0.0])

    base = record_sweep(
        _ListSource([scene.frame(i, pose(i)) for i in range(3)]),
        SweepParams(kf_add_dist_m=0.5, max_kept_frames=0),
        dense_params=DenseParams(n_points=1024),
    ).store
    assert len(base) == 1
    later = [scene.frame(i, pose(i)) for i in range(0, 12)]
    params = DenseParams(n_points=1024, kf_add_dist_m=0.05)
    fixed = DenseKeyframeTracker(params, base.copy())
    growing = DenseKeyframeTracker(params, base.copy(), extend_store=True)
    for f in later:
        fixed.track(f)
        growing.track(f)
    assert fixed.store is not None
    assert len(fixed.store) == 1
    assert growing.store is not None
    assert len(growing.store) >= 3
    assert len(base) == 1


def test_a_new_keyframe_is_built_after_its_frame_and_tracking_is_unchanged() -> None:
    """The frame that decides on a keyframe returns before the keyframe is built (the
    pipeline's after_frame, once the record reached the sinks; else the next track()): the
    same poses and store either way, the store read in between includes it."""
    from engine.dense.tracking import DenseKeyframeTracker
    from engine.loop import run_tracking

    scene = PlaneScene(small_intrinsics(), room_scale=0.45)
    frames = [scene.frame(i, make_T(np.eye(3), [0.015 * i, 0.0, 0.0])) for i in range(16)]
    params = DenseParams(n_points=1024, kf_add_dist_m=0.05)

    direct = DenseKeyframeTracker(params)
    direct_poses, added = [], []
    for f in frames:
        r = direct.track(f)
        direct_poses.append(r.T_world_cam)
        if r.details is not None and r.details.keyframe_added:
            n_before = len(direct._store) if direct._store is not None else 0
            added.append(f.index)
            # counted in this frame's details, built when the store is read
            assert r.details.keyframes == n_before + 1
            assert direct.store is not None
            assert len(direct.store) == n_before + 1
            assert np.array_equal(direct.store.keyframes[-1].T_world_cam, r.T_world_cam)
    assert len(added) >= 2

    piped = DenseKeyframeTracker(params)
    recs = list(run_tracking(_ListSource(frames), piped))
    assert all(np.array_equal(r.result.T_world_cam, T) for r, T in zip(recs, direct_poses,
                                                                        strict=True))
    assert piped.store is not None
    assert direct.store is not None
    assert len(piped.store) == len(direct.store)


def test_references_beyond_the_bound_are_dropped_and_rebuilt_the_same(tmp_path: Path) -> None:
    """max_resident_references bounds a loaded store's references (least recently used
    dropped); a dropped one is rebuilt from the store when the camera comes back, and the
    poses are bit for bit those of a tracker holding every reference."""
    intr = small_intrinsics(distorted=True)
    scene = PlaneScene(intr, room_scale=0.45)
    st = KeyframeStore(intr)
    for k in range(5):
        T = se3_exp(np.array([0.03 * k, 0.0, 0.0, 0.0, 0.0, 0.0]))
        gray, depth = scene.render(T)
        st.add(T, gray, depth)
    st.save(tmp_path / "kf")
    xs = np.concatenate([np.linspace(0.0, 0.12, 13), np.linspace(0.12, 0.0, 13)[1:]])
    frames = [scene.frame(i, se3_exp(np.array([x, 0.0, 0.0, 0.0, 0.0, 0.0])))
              for i, x in enumerate(xs)]

    def run(bound: int) -> tuple[list[np.ndarray], list[int], set[int]]:
        tr = create_tracker("dense", keyframes_dir=str(tmp_path / "kf"), n_points=1024,
                            max_resident_references=bound)
        poses, resident, used = [], [], set()
        for f in frames:
            r = tr.track(f)
            assert r.state.is_good
            assert r.T_world_cam is not None
            poses.append(r.T_world_cam)
            resident.append(len(tr._refs))
            used.add(r.keyframe_id)
        return poses, resident, used

    bounded, resident, used = run(2)
    full, resident_full, _ = run(100)
    assert len(used) >= 4  # the sweep there and back uses most keyframes
    assert max(resident) == 2  # never more than the bound
    assert max(resident_full) == 5
    for a, b in zip(bounded, full, strict=True):
        np.testing.assert_array_equal(a, b)


def test_reference_cache_keeps_online_references_and_drops_the_least_recent() -> None:
    from engine.dense.photometric import Reference
    from engine.dense.reference_cache import ReferenceCache

    def ref() -> Reference:
        z = np.zeros((3, 4), np.float32)
        return Reference(z, z, np.zeros((3, 6, 4), np.float32), np.zeros((4, 2), np.float32),
                         small_intrinsics(), 4)

    c = ReferenceCache(2)
    a, b, d, e = ref(), ref(), ref(), ref()
    c.keep(0, a)  # online: never dropped
    c.keep_rebuildable(1, b)
    c.keep_rebuildable(2, d)
    assert c.get(1) is b  # 1 now the most recent
    c.keep_rebuildable(3, e)  # drops 2, the least recently used
    assert c.get(2) is None
    assert c.get(0) is a
    assert c.get(1) is b
    assert c.get(3) is e  # now the most recent, 1 the least
    assert len(c) == 3
    c.capacity = 1
    assert c.get(1) is None
    assert c.get(3) is e
    assert c.get(0) is a
    assert c.nbytes == 2 * a.nbytes
    c.clear()
    assert len(c) == 0
