"""OTB box metrics: IoU, success AUC over 21 thresholds, precision at 20 px."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from engine.errors import EvaluationError
from engine.evaluation.boxes import (
    SUCCESS_THRESHOLDS,
    box_scores,
    centre_error_px,
    iou_xywh,
    read_boxes,
    write_boxes,
)


def test_iou_known_values() -> None:
    a = np.array([[0, 0, 10, 10], [0, 0, 10, 10], [0, 0, 10, 10], [0, 0, 10, 10]], float)
    b = np.array([[0, 0, 10, 10], [5, 0, 10, 10], [20, 20, 5, 5], [0, 0, 0, 0]], float)
    np.testing.assert_allclose(iou_xywh(a, b), [1.0, 50 / 150, 0.0, 0.0])


def test_centre_error_uses_otb_centre() -> None:
    a = np.array([[0, 0, 11, 11]], float)  # centre (5, 5)
    b = np.array([[3, 4, 11, 11]], float)  # centre (8, 9)
    assert centre_error_px(a, b)[0] == pytest.approx(5.0)
    assert np.isinf(centre_error_px(a, np.array([[np.nan] * 4]))[0])


def test_thresholds_are_otb() -> None:
    assert SUCCESS_THRESHOLDS.size == 21
    np.testing.assert_allclose(SUCCESS_THRESHOLDS[[0, 1, -1]], [0.0, 0.05, 1.0])


def test_perfect_tracker_scores_twenty_of_twenty_one() -> None:
    """OTB counts IoU strictly above each threshold: IoU 1 fails the threshold 1.0."""
    gt = np.array([[10, 10, 40, 30]] * 5, float)
    sc = box_scores(gt, gt)
    assert sc.success_auc == pytest.approx(20 / 21)
    assert sc.precision_20px == 1.0


def test_scores_of_a_known_mix() -> None:
    gt = np.array([[0, 0, 10, 10]] * 4, float)
    est = np.array([[0, 0, 10, 10], [5, 0, 10, 10], [100, 100, 10, 10], [np.nan] * 4])
    sc = box_scores(gt, est)
    ious = np.array([1.0, 1 / 3, 0.0, 0.0])
    expected = np.mean([np.mean(ious > t) for t in SUCCESS_THRESHOLDS])
    assert sc.success_auc == pytest.approx(expected)
    assert sc.precision_20px == pytest.approx(0.5)  # frames 0 and 1 (5 px) only


def test_frames_without_ground_truth_are_left_out() -> None:
    gt = np.array([[0, 0, 10, 10], [0, 0, 0, 0], [np.nan] * 4], float)
    est = np.array([[0, 0, 10, 10], [50, 50, 5, 5], [50, 50, 5, 5]], float)
    sc = box_scores(gt, est)
    assert sc.n_frames == 1
    assert sc.precision_20px == 1.0
    with pytest.raises(EvaluationError, match="no frame has a valid ground-truth box"):
        box_scores(gt[1:], est[1:])


def test_box_file_round_trip_and_errors(tmp_path: Path) -> None:
    boxes = np.array([[1.5, 2, 30, 40], [np.nan] * 4])
    p = tmp_path / "b.txt"
    write_boxes(p, boxes)
    assert p.read_text() == "1.5,2,30,40\n0,0,0,0\n"
    np.testing.assert_allclose(read_boxes(p), [[1.5, 2, 30, 40], [0, 0, 0, 0]])
    tab = tmp_path / "tab.txt"
    tab.write_text("1\t2\t3\t4\n")
    np.testing.assert_allclose(read_boxes(tab), [[1, 2, 3, 4]])
    bad = tmp_path / "bad.txt"
    bad.write_text("1,2,3,4\n1,2,3\n")
    with pytest.raises(EvaluationError, match=r"bad.txt: line 2: expected 4 values"):
        read_boxes(bad)
    with pytest.raises(EvaluationError, match="file not found"):
        read_boxes(tmp_path / "none.txt")
    with pytest.raises(EvaluationError, match="2 estimated boxes but 1"):
        box_scores(np.zeros((1, 4)), np.zeros((2, 4)))
