from __future__ import annotations

import numpy as np
import pytest

from engine.geometry import R_from_pan_tilt_roll_deg, make_T
from widgets.pose_plots import (
    PosePlots,
    ResidualPlots,
    RingBuffer,
    pose_channels,
    time_range,
    value_range,
)


def test_ring_buffer_keeps_the_newest_in_order() -> None:
    rb = RingBuffer(3, 1)
    for i in range(5):
        rb.append(float(i), [10.0 * i])
    t, v = rb.data()
    assert list(t) == [2.0, 3.0, 4.0]
    assert list(v[:, 0]) == [20.0, 30.0, 40.0]
    assert len(rb) == 3
    assert rb.total == 5


def test_pose_channels_give_metres_and_degrees() -> None:
    T = make_T(R_from_pan_tilt_roll_deg(10.0, -5.0, 2.0), np.array([1.0, 2.0, 3.0]))
    assert pose_channels(T) == pytest.approx([1, 2, 3, 10, -5, 2])
    assert np.all(np.isnan(pose_channels(None)))


def test_plots_move_and_gt_is_aligned_at_first_frame(qtbot) -> None:  # type: ignore[no-untyped-def]
    plots = PosePlots(capacity=100)
    qtbot.addWidget(plots)
    R = R_from_pan_tilt_roll_deg(0.0, 0.0, 0.0)
    offset = np.array([5.0, 0.0, 0.0])  # the estimate's world is shifted by 5 m
    errors = []
    for i in range(10):
        t_gt = np.array([0.1 * i, 0.0, 1.5])
        T_gt = make_T(R, t_gt)
        T_est = make_T(R, t_gt + offset + np.array([0.0, 0.001 * i, 0.0]))
        errors.append(plots.append(100.0 + i / 30, T_est, T_gt))
    plots.redraw()
    assert plots.curve_lengths() == [10] * 6
    assert plots.has_gt
    # aligned: GT x starts where the estimate starts, and the error is the injected drift
    assert plots.gt_curves[0].yData[0] == pytest.approx(plots.est_curves[0].yData[0])
    assert errors[-1] == pytest.approx(0.009)
    assert plots.est_curves[0].xData[0] == pytest.approx(0.0)  # time relative to the run
    # time going backwards (a restarted source) starts a new history
    plots.append(0.0, T_est, None)
    plots.redraw()
    assert plots.curve_lengths() == [1] * 6
    assert not plots.has_gt


def test_residual_plots(qtbot) -> None:  # type: ignore[no-untyped-def]
    plots = ResidualPlots(capacity=50)
    qtbot.addWidget(plots)
    for i in range(5):
        plots.append(i / 30, 1.0 / (i + 1), 0.8, None)
    plots.redraw()
    assert plots.curve_lengths() == [5, 5, 0]  # no ground truth: no error curve
    assert plots.curves[1].yData[0] == pytest.approx(80.0)  # percent
    plots.clear_data()
    assert plots.curve_lengths() == [0, 0, 0]


def test_residual_plots_say_when_a_tracker_has_no_data(qtbot) -> None:  # type: ignore[no-untyped-def]
    plots = ResidualPlots(capacity=50)
    qtbot.addWidget(plots)
    for i in range(5):
        plots.append(i / 30, None, None, 0.001 * i)
    plots.redraw()
    assert [t.isVisible() for t in plots.no_data] == [True, True, False]
    # the error plot's time axis follows its own data (not an empty plot's default range)
    plots.plots[2].getViewBox().autoRange()
    x0, x1 = plots.plots[2].viewRange()[0]
    assert x0 <= 0.0
    assert x1 >= 4 / 30


def test_time_axis_moves_in_whole_pages() -> None:
    assert time_range(0.0, 0.3) == (0.0, 10.0)
    assert time_range(0.0, 9.9) == (0.0, 10.0)
    assert time_range(0.0, 10.0) == (0.0, 20.0)
    assert time_range(12.5, 71.0) == (10.0, 80.0)


def test_value_range_holds_until_the_data_leave_or_shrink() -> None:
    first = value_range(0.0, 1.0, None)
    assert first is not None
    assert first[0] < 0.0 < 1.0 < first[1]
    assert value_range(0.1, 0.9, first) == first  # inside, not much smaller: kept
    moved = value_range(0.0, 1.5, first)  # left the range: a new one around the data
    assert moved is not None
    assert moved != first
    assert moved[1] > 1.5
    shrunk = value_range(0.4, 0.45, first)  # a tenth of the span: zoom in
    assert shrunk is not None
    assert shrunk[1] - shrunk[0] < 0.2
    # a unit's smallest span: a still camera's jitter stays a flat line
    small = value_range(1.0, 1.0001, None, min_span=0.05)
    assert small is not None
    assert small[1] - small[0] >= 0.05
    assert value_range(1.0, 1.0002, small, min_span=0.05) == small
    assert value_range(float("nan"), 1.0, None) is None


def test_plot_ranges_follow_the_data_in_steps_and_keep_a_user_zoom(qtbot) -> None:  # type: ignore[no-untyped-def]
    plots = ResidualPlots(capacity=600)
    qtbot.addWidget(plots)
    for i in range(30):
        plots.append(i / 30, 1.0 + 0.01 * i, 0.9, 0.001)
    plots.redraw()
    (x0, x1), (y0, y1) = plots.plots[0].viewRange()
    assert (x0, x1) == (0.0, 10.0)
    assert y0 <= 1.0
    assert y1 >= 1.29
    before = plots.plots[0].viewRange()
    plots.append(1.0, 1.1, 0.9, 0.001)  # inside the range: nothing moves
    plots.redraw()
    assert plots.plots[0].viewRange() == before
    assert plots.plots[1].viewRange()[1] == pytest.approx((-2.0, 102.0))  # inliers: fixed
    # the operator zooms y: the plot keeps that range while data come in
    vb = plots.plots[0].getViewBox()
    vb.sigRangeChangedManually.emit([False, True])
    vb.setYRange(5.0, 6.0, padding=0.0)
    plots.append(1.1, 1.2, 0.9, 0.001)
    plots.redraw()
    assert plots.plots[0].viewRange()[1] == pytest.approx((5.0, 6.0))
    plots.clear_data()  # a new run follows again
    plots.append(0.0, 1.0, 0.9, 0.001)
    plots.redraw()
    assert plots.plots[0].viewRange()[1][0] < 1.0 < plots.plots[0].viewRange()[1][1]


def test_grid_lines_sit_at_the_ticks(qtbot) -> None:  # type: ignore[no-untyped-def]
    plots = PosePlots(capacity=100)
    qtbot.addWidget(plots)
    plots.resize(600, 400)
    plots.plots[0].getViewBox().setRange(xRange=(0.0, 10.0), yRange=(0.0, 1.0), padding=0.0)
    grid = next(g for g in plots.grids if g.plot is plots.plots[0])
    assert all(item in plots.plots[0].items for item in grid.items)
    x, y = grid.items[0].getData()
    assert x is not None
    assert len(x) >= 4
    assert len(x) % 2 == 0
    assert np.nanmin(y) == pytest.approx(0.0)
    assert np.nanmax(y) == pytest.approx(1.0)
