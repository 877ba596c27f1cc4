"""Sparse bundle adjustment (Tykkälä 2014 sec. 6.1, Fig. 11) on generated keyframes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from engine.bench.keyframes import synthetic_problem
from engine.camera import TUM_DEFAULTS
from engine.keyframes.sba import (
    Observation,
    SBAError,
    SBAParams,
    bundle_adjust,
    reprojection_errors,
)
from engine.project import AnnotatedPoint


def _err(T: dict, T_true: dict, ids) -> float:  # type: ignore[no-untyped-def]
    return float(np.mean([np.linalg.norm(T[k][:3, 3] - T_true[k][:3, 3]) for k in ids]))


@pytest.mark.parametrize(("distortion", "robust_k"), [(False, 2.385), (True, 2.385), (False, 0.0)])
def test_sba_removes_injected_end_of_sweep_error(distortion: bool, robust_k: float) -> None:
    """robust_k 0: the fixed tight robust scales (0.1 px, 0.1 depth sigma) on 0.1 px noise."""
    intr = TUM_DEFAULTS["freiburg1"] if distortion else None
    pr = synthetic_problem(
        12,
        20,
        seed=1,
        n_perturbed=4,
        err_m=0.08,
        err_deg=2.0,
        pixel_noise=0.1,
        depth_noise_rel=0.001,
        intrinsics=intr,
    )
    res = bundle_adjust(
        pr.intrinsics,
        pr.T_world_cam_noisy,
        pr.observations,
        depth_maps=pr.depth_maps,
        params=SBAParams(robust_k=robust_k),
    )
    pert = range(8, 12)
    before = _err(pr.T_world_cam_noisy, pr.T_world_cam_true, pert)
    after = _err(res.T_world_cam_after, pr.T_world_cam_true, pert)
    assert 1.0 - after / before >= 0.9, (before, after)
    assert res.rmse_before_px > 2.0
    assert res.rmse_after_px < 0.3
    np.testing.assert_array_equal(res.T_world_cam_after[0], pr.T_world_cam_noisy[0])  # gauge
    assert res.pose_change[11][0] > res.pose_change[8][0] > 0.0
    for pid, X in res.X_world_after.items():
        assert np.linalg.norm(X - pr.X_world_true[pid]) < 0.03
    assert max(res.point_rmse_after_px.values()) < 0.5


def test_sba_is_robust_to_a_misclick() -> None:
    pr = synthetic_problem(
        12, 20, seed=2, n_perturbed=4, err_m=0.08, pixel_noise=0.1, depth_noise_rel=0.001
    )
    clean = bundle_adjust(
        pr.intrinsics, pr.T_world_cam_noisy, pr.observations, depth_maps=pr.depth_maps
    )
    obs = list(pr.observations)
    o = obs[40]
    obs[40] = dataclasses.replace(o, u=o.u + 25.0)  # a wrong click, 25 px off
    res = bundle_adjust(pr.intrinsics, pr.T_world_cam_noisy, obs, depth_maps=pr.depth_maps)
    pert = range(8, 12)
    e_clean = _err(clean.T_world_cam_after, pr.T_world_cam_true, pert)
    e_bad = _err(res.T_world_cam_after, pr.T_world_cam_true, pert)
    assert e_bad < e_clean + 0.002, (e_clean, e_bad)
    assert res.point_rmse_after_px[o.point_id] > 5.0  # the operator sees which point is bad


def _few() -> tuple:  # type: ignore[type-arg]
    pr = synthetic_problem(4, 20, seed=3, n_perturbed=1)
    return pr, list(pr.observations)


def test_too_few_points_names_what_is_missing() -> None:
    pr, obs = _few()
    obs = [o for o in obs if o.point_id in {o.point_id for o in obs[:4]}]
    with pytest.raises(
        SBAError, match=r"4 point\(s\) are annotated in 2\+ keyframes.*annotate 2 more"
    ):
        bundle_adjust(pr.intrinsics, pr.T_world_cam_noisy, obs)


def test_keyframe_with_too_few_points_is_named() -> None:
    pr, obs = _few()
    kf3 = [o for o in obs if o.kf_id == 3][:2]
    obs = [o for o in obs if o.kf_id != 3] + kf3
    with pytest.raises(SBAError, match=r"keyframe 3 has 2.*at least 3"):
        bundle_adjust(pr.intrinsics, pr.T_world_cam_noisy, obs)


def test_gauge_without_points_and_disconnected_keyframes() -> None:
    pr, obs = _few()
    with pytest.raises(SBAError, match="gauge keyframe 0"):
        bundle_adjust(pr.intrinsics, pr.T_world_cam_noisy, [o for o in obs if o.kf_id != 0])
    split = [
        o for o in obs if (o.kf_id < 2 and o.point_id < 10) or (o.kf_id >= 2 and o.point_id >= 10)
    ]
    with pytest.raises(SBAError, match=r"keyframe\(s\) \[2, 3\] share no annotated point"):
        bundle_adjust(pr.intrinsics, pr.T_world_cam_noisy, split)


def test_collinear_points_are_degenerate() -> None:
    pr = synthetic_problem(3, 8, seed=4, n_perturbed=1)
    obs = [Observation(j, k, 100.0 + 30 * j, 200.0 + 0.1 * k) for j in range(8) for k in range(3)]
    with pytest.raises(SBAError, match=r"lie .*on one line"):
        bundle_adjust(pr.intrinsics, pr.T_world_cam_noisy, obs)


def test_unknown_keyframe_and_unannotated_keyframes() -> None:
    pr, obs = _few()
    with pytest.raises(SBAError, match=r"keyframe\(s\) \[9\] that are not in the store"):
        bundle_adjust(pr.intrinsics, pr.T_world_cam_noisy, [*obs, Observation(0, 9, 1.0, 1.0)])
    res = bundle_adjust(
        pr.intrinsics,
        pr.T_world_cam_noisy,
        [o for o in obs if o.kf_id != 2],
        depth_maps=pr.depth_maps,
    )
    assert res.unadjusted_ids == (2,)
    np.testing.assert_array_equal(res.T_world_cam_after[2], pr.T_world_cam_noisy[2])


def test_params_validation_and_per_point_errors() -> None:
    with pytest.raises(ValueError, match="loss"):
        SBAParams(loss="l3")
    pr, obs = _few()
    pts = [
        AnnotatedPoint(
            j, {o.kf_id: (o.u, o.v) for o in obs if o.point_id == j}, pr.X_world_true[j]
        )
        for j in range(3)
    ]
    errs = reprojection_errors(pr.intrinsics, pr.T_world_cam_true, pts)
    assert all(e < 1.5 for e in errs.values())
