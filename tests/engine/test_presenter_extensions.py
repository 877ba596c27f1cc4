"""Pieces beyond the VR-TV paper: output-width fit, background-weighted reference, slow
anchored model update, Pref from the first tracked frames."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from engine.frames import Frame
from engine.presenter.extent import measure_extent
from engine.presenter.likelihood import apply_gains, direct_histogram
from engine.presenter.model import auto_patches, build_model
from engine.presenter.params import PresenterParams
from engine.presenter.scene import presenter_frames
from engine.presenter.view import ViewTracker
from engine.trackers import create_tracker


def _walker(stride_px: int) -> np.ndarray:
    """Grey-green backdrop; red torso 40 px wide, blue legs spread to ``stride_px``."""
    img = np.full((240, 320, 3), (90, 130, 80), np.uint8)
    cv2.rectangle(img, (150, 40), (170, 70), (120, 170, 230), -1)  # head (skin)
    cv2.rectangle(img, (140, 70), (180, 140), (40, 40, 200), -1)  # torso (red)
    half = stride_px // 2
    cv2.line(img, (155, 140), (160 - half + 6, 200), (150, 60, 30), 12)  # legs (blue)
    cv2.line(img, (165, 140), (160 + half - 6, 200), (150, 60, 30), 12)
    return img


def _fg_hist(img: np.ndarray) -> np.ndarray:
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    h = direct_histogram(hsv, (140, 40, 40, 160), 10)
    return h / h.sum()


def test_extent_follows_a_stride_and_keeps_a_standing_width() -> None:
    standing, striding = _walker(24), _walker(80)
    xyh = np.array([160.0, 120.0, 160.0])
    aspect = 40.0 / 160.0  # 40 px wide model
    fg = _fg_hist(standing)
    _, w_stand = measure_extent(standing, None, xyh, aspect, fg, 10)  # type: ignore[misc]
    _, w_stride = measure_extent(striding, None, xyh, aspect, fg, 10)  # type: ignore[misc]
    assert 36 <= w_stand <= 48
    assert 60 <= w_stride <= 88  # thin leg ends fill few rows of a column


def test_extent_is_not_measured_without_background_beside_the_target() -> None:
    img = _walker(24)
    # the target fills the strip: no outer columns inside the image
    assert measure_extent(img[:, 130:190], None, np.array([30.0, 120.0, 160.0]), 0.25,
                          _fg_hist(img), 10) is None


def _tracker(img: np.ndarray, **kw: object) -> ViewTracker:
    main = (140.0, 40.0, 40.0, 160.0)
    model = build_model(img, main, auto_patches(main, 3), 10)
    return ViewTracker(model, PresenterParams(**kw), 30.0)  # type: ignore[arg-type]


def test_background_weights_down_weight_ring_colours_only() -> None:
    img = _walker(24)
    img[:, 100:140] = (40, 40, 200)  # red walls beside the red torso: the commonest
    img[:, 180:220] = (40, 40, 200)  # colour of the ring around the box
    view = _tracker(img, bg_weighting=1.0)
    view.step(img)
    w = view._bin_w
    assert w is not None
    hsv = cv2.cvtColor(apply_gains(img, view._gains), cv2.COLOR_BGR2HSV)  # grey-world frame
    red = int(np.argmax(direct_histogram(hsv, (145, 80, 30, 50), 10)))
    blue = int(np.argmax(direct_histogram(hsv, (150, 185, 10, 10), 10)))
    assert w[red] < 0.1
    assert w[blue] > 5 * w[red]  # the legs' blue is not around the box
    off = _tracker(img, bg_weighting=0.0, loss_bg_weighting=0.0)
    off.step(img)
    assert off._bin_w is None
    # the loss test's reference alone: the ring's red counts less there, not in the tracking
    loss_only = _tracker(img, bg_weighting=0.0, loss_bg_weighting=1.0)
    loss_only.step(img)
    assert loss_only._bin_w is not None
    assert not np.allclose(loss_only._sqrt_ref0, loss_only._sqrt_ref)
    assert np.allclose(loss_only._sqrt_ref, off._sqrt_ref)


def test_model_update_is_anchored_and_guarded() -> None:
    img = _walker(24)
    view = _tracker(img, model_update_rate=1.0, model_anchor=0.5)
    view.step(img)
    # a different torso colour at the estimate: the reference moves at most half-way
    other = img.copy()
    other[70:140, 140:180] = (40, 200, 40)
    ctx = view._evaluate(other, np.array([[160.0, 120.0, 160.0]]))[2]
    view._update_model(ctx, np.array([160.0, 120.0, 160.0]))
    ref = np.square(view._sqrt_ref)
    torso0 = view._hist0[1]
    assert 0.3 < float(np.sum(np.sqrt(ref[1] * torso0))) < 0.95
    frozen = _tracker(img, model_update_rate=0.0)
    frozen.step(img)
    before = frozen._sqrt_ref.copy()
    frozen._update_model(ctx, np.array([160.0, 120.0, 160.0]))
    np.testing.assert_array_equal(frozen._sqrt_ref, before)


def test_pref_comes_from_the_first_tracked_frames() -> None:
    frames = [Frame(index=f.index, timestamp_s=f.index / 30.0, color_bgr=f.bgr,
                    gt_box_xywh=f.box_xywh) for f in presenter_frames(14, 320, 240, seed=1)]
    params = PresenterParams(pref_init_frames=10)
    tracker = create_tracker("presenter", params)
    p_cols = [tracker.track(f).details for f in frames]
    first_self_match = p_cols[0].p_ref
    boot = [e.p_col for e in p_cols[1:11]]
    assert p_cols[10].p_ref == np.median(boot)
    assert p_cols[10].p_ref <= first_self_match
    tracker0 = create_tracker("presenter", dataclasses.replace(params, pref_init_frames=0,
                                                               model_update_rate=0.0))
    refs = [tracker0.track(f).details.p_ref for f in frames[:3]]
    assert refs[1] >= 0.6 * refs[0]  # the paper's rule: Pref from the first frame
