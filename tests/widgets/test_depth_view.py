from __future__ import annotations

import numpy as np
import pytest

from widgets.depth_view import compose_view, depth_to_bgr


def test_depth_false_colour_near_and_far_differ_and_holes_are_black() -> None:
    d = np.tile(np.linspace(0.5, 6.0, 64, dtype=np.float32), (8, 1))
    d[0, 0] = 0.0
    d[1, 1] = np.nan
    out = depth_to_bgr(d)
    assert out.shape == (8, 64, 3)
    assert out.dtype == np.uint8
    assert out[0, 0].tolist() == [0, 0, 0]
    assert out[1, 1].tolist() == [0, 0, 0]
    assert np.abs(out[4, 2].astype(int) - out[4, 60].astype(int)).sum() > 100
    assert depth_to_bgr(np.zeros((4, 4), np.float32)).max() == 0


def test_compose_modes() -> None:
    c = np.full((6, 8, 3), 7, np.uint8)
    d = np.full((6, 8), 2.0, np.float32)
    assert compose_view(c, d, "colour") is c
    assert compose_view(c, None, "depth") is c  # no depth: colour
    assert compose_view(c, d, "depth").shape == (6, 8, 3)
    both = compose_view(c, d, "both")
    assert both.shape == (6, 16, 3)
    assert (both[:, :8] == 7).all()
    with pytest.raises(ValueError, match="not one of"):
        compose_view(c, d, "ir")
