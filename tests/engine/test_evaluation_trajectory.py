"""TUM trajectory files and timestamp association."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.errors import EvaluationError
from engine.evaluation.trajectory import Trajectory, associate, read_tum, tum_text, write_tum
from engine.geometry import se3_exp


def _random_traj(n: int, seed: int = 0, t0: float = 100.0) -> Trajectory:
    rng = np.random.default_rng(seed)
    stamps = t0 + np.cumsum(rng.uniform(0.02, 0.05, n))
    poses = [se3_exp(rng.normal(0, 0.5, 6)) for _ in range(n)]
    return Trajectory.from_poses(stamps, poses, "random")


def test_write_read_round_trip(tmp_path: Path) -> None:
    tr = _random_traj(20)
    p = tmp_path / "traj.txt"
    write_tum(p, tr)
    back = read_tum(p)
    assert len(back) == 20
    np.testing.assert_allclose(back.timestamps_s, tr.timestamps_s, atol=1e-6)
    np.testing.assert_allclose(back.T_world_cam, tr.T_world_cam, atol=1e-8)
    assert p.read_text().startswith("# timestamp tx ty tz qx qy qz qw\n")


def test_reads_comments_tabs_commas_and_blank_lines(tmp_path: Path) -> None:
    p = tmp_path / "t.txt"
    p.write_text(
        "# header\n\n1.0 0 0 0 0 0 0 1\n2.0\t1\t2\t3\t0\t0\t0\t2\n3.0,0,0,0,0,0,1,0\n"
    )
    tr = read_tum(p)
    np.testing.assert_allclose(tr.timestamps_s, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(tr.T_world_cam[1], np.array(
        [[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1.0]]))  # quaternion normalised
    np.testing.assert_allclose(tr.T_world_cam[2, :3, :3], np.diag([-1.0, -1.0, 1.0]), atol=1e-12)


def test_repeated_timestamp_keeps_the_later_line_as_tum(tmp_path: Path) -> None:
    p = tmp_path / "t.txt"
    p.write_text("1.0 0 0 0 0 0 0 1\n1.0 5 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1\n")
    tr = read_tum(p)
    assert len(tr) == 2
    assert tr.T_world_cam[0, 0, 3] == 5.0


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("", "no poses"),
        ("# only a comment\n", "no poses"),
        ("1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n", "line 2: expected 8 values"),
        ("1.0 0 0 0 0 0 0 1\n2.0 0 0 x 0 0 0 1\n", "line 2: 'x' is not a number"),
        ("1.0 0 0 0 0 0 0 1\n2.0 0 0 nan 0 0 0 1\n", "line 2: non-finite"),
        ("1.0 0 0 0 0 0 0 0\n", "line 1: zero quaternion"),
        ("# h\n2.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n", "line 3: timestamp 1.0 is not after"),
    ],
)
def test_bad_files_raise_one_line_naming_file_and_problem(
    tmp_path: Path, text: str, expected: str
) -> None:
    p = tmp_path / "bad.txt"
    p.write_text(text)
    with pytest.raises(EvaluationError, match=expected) as info:
        read_tum(p)
    msg = str(info.value)
    assert str(p) in msg
    assert "\n" not in msg


def test_missing_file_and_folder(tmp_path: Path) -> None:
    with pytest.raises(EvaluationError, match="file not found"):
        read_tum(tmp_path / "nope.txt")
    with pytest.raises(EvaluationError, match="not a file"):
        read_tum(tmp_path)


def test_binary_file(tmp_path: Path) -> None:
    p = tmp_path / "b.txt"
    p.write_bytes(b"\xff\xfe\x00\x81")
    with pytest.raises(EvaluationError, match="not a text file"):
        read_tum(p)


def test_from_poses_rejects_non_increasing() -> None:
    with pytest.raises(EvaluationError, match="not after the previous"):
        Trajectory.from_poses([0.0, 1.0, 1.0], [np.eye(4)] * 3, "x")


def test_tum_text_quaternion_has_non_negative_w() -> None:
    tr = Trajectory.from_poses([0.0], [se3_exp(np.array([0, 0, 0, 0, 0, 3.0]))])
    line = tum_text(tr).splitlines()[1]
    assert float(line.split()[-1]) >= 0.0


def _tum_associate_reference(
    a: list[float], b: list[float], offset: float, max_diff: float
) -> list[tuple[float, float]]:
    """TUM associate.py's all-pairs greedy matching, written out directly."""
    first, second = list(a), list(b)
    cands = sorted(
        (abs(x - (y + offset)), x, y) for x in first for y in second
        if abs(x - (y + offset)) < max_diff
    )
    matches = []
    for _, x, y in cands:
        if x in first and y in second:
            first.remove(x)
            second.remove(y)
            matches.append((x, y))
    matches.sort()
    return matches


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.integers(0, 400), min_size=0, max_size=40, unique=True),
    st.lists(st.integers(0, 400), min_size=0, max_size=40, unique=True),
    st.sampled_from([0.0, 0.013, -0.021]),
    st.sampled_from([0.02, 0.035]),
)
def test_associate_matches_tum_greedy(
    ia: list[int], ib: list[int], offset: float, max_diff: float
) -> None:
    a = sorted(x * 0.01 for x in ia)
    b = sorted(x * 0.01 + 0.003 for x in ib)
    ra, rb = associate(np.array(a), np.array(b), max_diff, offset)
    got = [(a[i], b[j]) for i, j in zip(ra, rb, strict=True)]
    assert got == _tum_associate_reference(a, b, offset, max_diff)


def test_associate_on_real_stamps(shared_data: Path) -> None:
    gt = read_tum(shared_data / "tum_trajectories" / "freiburg1_xyz-groundtruth.txt")
    est = read_tum(shared_data / "tum_trajectories" / "freiburg1_xyz-rgbdslam.txt")
    ig, ie = associate(gt.timestamps_s, est.timestamps_s)
    assert ig.size == 786
    assert np.all(np.abs(gt.timestamps_s[ig] - est.timestamps_s[ie]) < 0.02)
    assert np.all(np.diff(gt.timestamps_s[ig]) > 0)
    # The fast search agrees with TUM's all-pairs greedy on a real slice of the data.
    a = list(gt.timestamps_s[:400])
    b = list(est.timestamps_s[:60])
    ra, rb = associate(np.array(a), np.array(b))
    assert [(a[i], b[j]) for i, j in zip(ra, rb, strict=True)] == _tum_associate_reference(
        a, b, 0.0, 0.02
    )
