from __future__ import annotations

import numpy as np
import pytest

from engine.trackers.base import Overlay
from widgets.image_view import N_WEIGHT_BUCKETS, ImageView, bucket_weights, weight_colour


@pytest.fixture
def view(qtbot):  # type: ignore[no-untyped-def]
    v = ImageView()
    qtbot.addWidget(v)
    v.resize(400, 300)
    v.show()
    return v


def test_weight_colours_run_from_red_to_green() -> None:
    red, green = weight_colour(0.0), weight_colour(1.0)
    assert red.red() > 200
    assert red.green() < 100
    assert green.green() > 200
    assert green.red() < 100
    assert list(bucket_weights(np.array([0.0, 0.49, 1.0, np.nan, 2.0]))) == [
        0,
        N_WEIGHT_BUCKETS // 2 - 1,
        N_WEIGHT_BUCKETS - 1,
        0,
        N_WEIGHT_BUCKETS - 1,
    ]


def test_image_is_shown_rgb(view: ImageView) -> None:
    bgr = np.zeros((48, 64, 3), np.uint8)
    bgr[..., 0] = 255  # blue in BGR
    bgr.flags.writeable = False  # frames cross threads read-only
    view.set_image(bgr)
    assert view.image_rgb is not None
    assert tuple(view.image_rgb[0, 0]) == (0, 0, 255)
    image = view.grab().toImage()
    centre = image.pixelColor(image.width() // 2, image.height() // 2)
    assert centre.blue() > 200
    assert centre.red() < 50


def test_overlay_points_boxes_polylines_crosshair(view: ImageView) -> None:
    view.set_image(np.full((48, 64, 3), 128, np.uint8))
    pts = np.array([[1, 1], [2, 2], [3, 3], [4, 4]], np.float32)
    w = np.array([0.0, 0.0, 0.6, 1.0], np.float32)
    ov = Overlay(
        points_uv=pts,
        point_weights=w,
        boxes_xywh=((5, 5, 10, 10), (20, 20, 5, 5)),
        box_labels=("target", "ball"),
        polylines_uv=(np.array([[0, 0], [10, 10], [20, 0]], np.float32),),
        crosshair_uv=(32, 24),
    )
    view.set_overlay(ov, gt_box_xywh=(4, 4, 12, 12))
    counts = view.point_counts()
    assert sum(counts) == 4
    assert counts[0] == 2
    assert counts[-1] == 1
    assert view.visible_boxes() == 3  # two tracker boxes and the GT box
    assert view.crosshair.isVisible()
    # clearing: an empty overlay hides everything
    view.set_overlay(None)
    assert sum(view.point_counts()) == 0
    assert view.visible_boxes() == 0
    assert not view.crosshair.isVisible()


def test_points_without_weights_are_green(view: ImageView) -> None:
    view.set_points(np.zeros((5, 2), np.float32), None)
    assert view.point_counts()[-1] == 5
