"""TumSource on the real fr1_xyz excerpt and on small generated folders with each bad input."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.camera import TUM_DEFAULTS, Intrinsics, save_camera_json
from engine.errors import CalibrationError, SourceError, StudioTrackError
from engine.frames import SourceFiles
from engine.geometry import R_from_quat_xyzw, make_T, quat_xyzw_from_R, so3_exp
from engine.sources import open_source
from engine.sources.tum import (
    TUM_KINECT_DEPTH_LATENCY_S,
    GroundTruth,
    TumSource,
    associate_one_to_one,
    read_tum_groundtruth,
)
from tests.conftest import shared_path

W, H = 32, 24
SMALL_CAM = Intrinsics(fx=30.0, fy=30.0, cx=15.5, cy=11.5, width=W, height=H)


def associate_reference(first: dict[float, str], second: dict[float, str], max_difference: float):
    """TUM's associate.py (Sturm 2011), ported line by line: the oracle for the association."""
    first_keys = list(first.keys())
    second_keys = list(second.keys())
    potential_matches = [
        (abs(a - b), a, b) for a in first_keys for b in second_keys if abs(a - b) < max_difference
    ]
    potential_matches.sort()
    matches = []
    for _diff, a, b in potential_matches:
        if a in first_keys and b in second_keys:
            first_keys.remove(a)
            second_keys.remove(b)
            matches.append((a, b))
    matches.sort()
    return matches


def make_tum(
    folder: Path,
    rgb_times: list[float],
    depth_times: list[float] | None = None,
    *,
    camera: Intrinsics | None = SMALL_CAM,
    depth_size_wh: tuple[int, int] = (W, H),
    gt_rows: list[list[float]] | None = None,
) -> Path:
    """A TUM folder with tiny PNGs; depth pixel value = 1000 * (frame index + 1)."""
    (folder / "rgb").mkdir(parents=True)
    rgb_lines = ["# color images", "# timestamp filename"]
    for i, t in enumerate(rgb_times):
        name = f"rgb/{t:.6f}.png"
        cv2.imwrite(str(folder / name), np.full((H, W, 3), (i * 10) % 256, np.uint8))
        rgb_lines.append(f"{t:.6f} {name}")
    (folder / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    if depth_times is not None:
        (folder / "depth").mkdir()
        depth_lines = ["# depth maps"]
        dw, dh = depth_size_wh
        for i, t in enumerate(depth_times):
            name = f"depth/{t:.6f}.png"
            cv2.imwrite(str(folder / name), np.full((dh, dw), 1000 * (i + 1), np.uint16))
            depth_lines.append(f"{t:.6f} {name}")
        (folder / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    if camera is not None:
        save_camera_json(camera, folder / "camera.json")
    if gt_rows is not None:
        lines = ["# timestamp tx ty tz qx qy qz qw"]
        lines += [" ".join(f"{v:.9f}" for v in row) for row in gt_rows]
        (folder / "groundtruth.txt").write_text("\n".join(lines) + "\n")
    return folder


def good_folder(tmp_path: Path, name: str = "seq") -> Path:
    times = [100.0 + 0.033 * i for i in range(4)]
    return make_tum(tmp_path / name, times, [t + 0.004 for t in times])


def test_depth_latency_pairs_by_the_instant_the_depth_shows(tmp_path: Path) -> None:
    """Our own folders have no depth latency (stamps as written); a benchmark recording's
    depth.txt names its bag and gets TUM_KINECT_DEPTH_LATENCY_S: pairs by stamp - latency,
    depth_timestamp_s is that instant; an explicit depth_latency_s wins."""
    times = [100.0 + 0.033 * i for i in range(4)]
    depth_times = [t + 0.021 for t in times]  # each shows the scene ~1 ms after its colour
    ours = TumSource(make_tum(tmp_path / "ours", times, depth_times))
    assert ours.depth_latency_s == 0.0
    # by stamps colour k + 1 pairs with depth k (12 ms apart): 3 frames
    np.testing.assert_array_equal(ours.timestamps_s, times[1:])
    assert [f.depth_timestamp_s for f in ours.frames()] == depth_times[:3]
    bench = make_tum(tmp_path / "bench", times, depth_times)
    lines = (bench / "depth.txt").read_text().splitlines()
    lines.insert(1, "# file: 'rgbd_dataset_freiburg1_xyz.bag'")
    (bench / "depth.txt").write_text("\n".join(lines) + "\n")
    src = TumSource(bench)
    assert src.depth_latency_s == TUM_KINECT_DEPTH_LATENCY_S
    frames = list(src.frames())
    assert len(frames) == 4
    for f, t_depth in zip(frames, depth_times, strict=True):
        assert f.depth_timestamp_s == pytest.approx(t_depth - TUM_KINECT_DEPTH_LATENCY_S)
    assert TumSource(bench, depth_latency_s=0.0).depth_latency_s == 0.0


# --- real data -------------------------------------------------------------------------------


def test_real_fr1_xyz_association_depth_gt_and_intrinsics() -> None:
    folder = shared_path("tum_fr1_xyz_37")
    src = open_source(str(folder))
    assert isinstance(src, TumSource)
    assert src.intrinsics == TUM_DEFAULTS["freiburg1"]

    def read(name: str) -> dict[float, str]:
        out = {}
        for line in (folder / name).read_text().splitlines():
            if line.strip() and not line.startswith("#"):
                t, f = line.split()
                out[float(t)] = f
        return out

    rgb, depth = read("rgb.txt"), read("depth.txt")
    assert len(rgb) == 37
    t_rgb_all, t_depth_all = sorted(rgb), sorted(depth)
    # by stamps the 37 frames pair one by one (rgb k with depth k, one gap 20.2 ms outside
    # the 20 ms window): TUM's greedy associate.py strands 5 frames there, ours keeps 36
    stamps = TumSource(folder, depth_latency_s=0.0)
    assert stamps.depth_latency_s == 0.0
    by_stamp = [
        (t_rgb_all[k], t_depth_all[k])
        for k in range(37)
        if abs(t_rgb_all[k] - t_depth_all[k]) < 0.02
    ]
    assert len(by_stamp) == 36 > len(associate_reference(rgb, depth, 0.02))
    np.testing.assert_array_equal(stamps.timestamps_s, [a for a, _ in by_stamp])
    # a benchmark recording (the header names its bag): the depth shows the scene 20 ms
    # before its stamp, so colour k pairs with the depth image after, k + 1 (within 5 ms of
    # what it shows instead of 12-17 ms of its stamp); the last colour image has none
    assert src.depth_latency_s == TUM_KINECT_DEPTH_LATENCY_S == 0.02
    expected = [
        (t_rgb_all[k], t_depth_all[k + 1])
        for k in range(36)
        if abs(t_rgb_all[k] - (t_depth_all[k + 1] - 0.02)) < 0.02
    ]
    assert len(expected) == 36
    assert len(src) == len(expected)
    assert src.dropped_rgb == 37 - len(expected)
    np.testing.assert_array_equal(src.timestamps_s, [a for a, _ in expected])
    assert 27.0 < src.nominal_fps < 33.0  # fr1 records at 30 Hz

    frames = list(src.frames())
    assert len(frames) == len(expected)
    for frame, (t_rgb, t_depth) in zip(frames, expected, strict=True):
        assert frame.timestamp_s == t_rgb
        assert frame.depth_timestamp_s == pytest.approx(t_depth - 0.02, abs=1e-9)
        assert abs(frame.depth_timestamp_s - t_rgb) < 0.006
        assert frame.payload(SourceFiles).depth_path.endswith(depth[t_depth])
        assert frame.color_bgr is not None
        assert frame.color_bgr.shape == (480, 640, 3)
        assert frame.color_bgr.dtype == np.uint8
        assert frame.depth_m is not None
        assert frame.depth_m.dtype == np.float32
        assert frame.depth_m.shape == (480, 640)
        assert not frame.color_bgr.flags.writeable
        assert frame.intrinsics == src.intrinsics
    f0 = frames[0]
    raw = cv2.imread(f0.payload(SourceFiles).depth_path, cv2.IMREAD_UNCHANGED)
    np.testing.assert_allclose(f0.depth_m, raw.astype(np.float32) / 5000.0, rtol=1e-6)
    assert np.all((f0.depth_m == 0) == (raw == 0))
    assert 1.0 < float(np.median(f0.depth_m[f0.depth_m > 0])) < 1.4  # SOURCE.txt: ~1.18 m

    # Ground truth at 100 Hz: every frame has a pose, equal to an independent interpolation
    # (numpy per-axis lerp, scipy's Slerp).
    from scipy.spatial.transform import Rotation, Slerp

    gt = read_tum_groundtruth(folder / "groundtruth.txt")
    slerp = Slerp(gt.timestamps_s, Rotation.from_matrix(gt.R_world_cam))
    for frame in frames:
        assert frame.gt_T_world_cam is not None
        t = frame.timestamp_s
        assert np.min(np.abs(gt.timestamps_s - t)) < 0.006
        lerp = [np.interp(t, gt.timestamps_s, gt.t_world_cam[:, k]) for k in range(3)]
        np.testing.assert_allclose(frame.gt_T_world_cam[:3, 3], lerp, atol=1e-9)
        R_ref = slerp([t]).as_matrix()[0]
        np.testing.assert_allclose(frame.gt_T_world_cam[:3, :3], R_ref, atol=1e-9)
    # first GT line of the file, read independently
    first = next(
        ln
        for ln in (folder / "groundtruth.txt").read_text().splitlines()
        if not ln.startswith("#")
    )
    row = np.array([float(v) for v in first.split()])
    assert gt.timestamps_s[0] == row[0]
    np.testing.assert_allclose(gt.R_world_cam[0], R_from_quat_xyzw(row[4:8]))


# --- association and interpolation -----------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.integers(0, 2000), min_size=0, max_size=25, unique=True),
    st.lists(st.integers(0, 2000), min_size=0, max_size=25, unique=True),
)
def test_association_is_maximal_and_ordered(a_ms: list[int], b_ms: list[int]) -> None:
    # Millisecond grid plus distinct sub-ms offsets keeps the gaps free of ties, where the
    # greedy order (and so the result) would depend on how ties are broken.
    t_a = sorted(x / 1000.0 + 1e-7 for x in a_ms)
    t_b = sorted(x / 1000.0 + 3.3e-7 * (k + 1) / 26 for k, x in enumerate(sorted(b_ms)))
    got = associate_one_to_one(np.array(t_a), np.array(t_b), 0.02)
    assert len({i for i, _ in got}) == len(got) == len({j for _, j in got})
    assert all(abs(t_a[i] - t_b[j]) < 0.02 for i, j in got)
    assert [j for _, j in got] == sorted(j for _, j in got)  # time order preserved
    assert len(got) == _max_monotone_matching(t_a, t_b, 0.02)


def _max_monotone_matching(t_a: list[float], t_b: list[float], max_dt: float) -> int:
    """Brute-force oracle: largest order-preserving one-to-one pairing (LCS-style DP)."""
    n, m = len(t_a), len(t_b)
    best = [[0] * (m + 1) for _ in range(n + 1)]
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            match = best[i - 1][j - 1] + 1 if abs(t_a[i - 1] - t_b[j - 1]) < max_dt else 0
            best[i][j] = max(best[i - 1][j], best[i][j - 1], match)
    return best[n][m]


def test_association_is_one_to_one_and_drops_unmatched(tmp_path: Path) -> None:
    # rgb at 0, 11, 50 ms; depth at 5 and 52 ms. Gaps: (50,52)=2, (0,5)=5, (11,5)=6 ms:
    # depth 5 ms goes to rgb 0 ms, so rgb 11 ms (whose nearest depth it also is) is dropped.
    folder = make_tum(tmp_path / "fr1_a", [1.000, 1.011, 1.050], [1.005, 1.052])
    src = TumSource(folder)
    assert len(src) == 2
    assert src.dropped_rgb == 1
    np.testing.assert_allclose(src.timestamps_s, [1.000, 1.050])
    depths = [float(f.depth_m[0, 0]) for f in src.frames()]  # type: ignore[index]
    np.testing.assert_allclose(depths, [1000 / 5000, 2000 / 5000])


def test_groundtruth_interpolation_slerp_and_gaps() -> None:
    R0 = so3_exp(np.array([0.1, -0.2, 0.3]))
    R1 = R0 @ so3_exp(np.array([0.0, 0.0, 0.4]))
    gt = GroundTruth(
        np.array([10.0, 10.02, 10.2]),
        np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [5.0, 5.0, 5.0]]),
        np.array([R0, R1, R1]),
    )
    T = gt.pose_at(10.005)
    assert T is not None
    np.testing.assert_allclose(T[:3, 3], [0.25, 0.5, 0.75], atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], R0 @ so3_exp(np.array([0.0, 0.0, 0.1])), atol=1e-12)
    exact = gt.pose_at(10.02)
    assert exact is not None
    np.testing.assert_array_equal(exact, make_T(R1, [1.0, 2.0, 3.0]))
    assert gt.pose_at(9.99) is None  # before the trajectory
    assert gt.pose_at(10.21) is None  # after it
    assert gt.pose_at(10.11) is None  # 180 ms mocap gap: both neighbours > 50 ms away
    assert gt.pose_at(10.06) is None  # previous sample 40 ms, next 140 ms away
    assert gt.pose_at(10.19) is None


def test_frames_carry_groundtruth_pose(tmp_path: Path) -> None:
    times = [100.0, 100.03, 100.06, 100.2]
    q = quat_xyzw_from_R(so3_exp(np.array([0.0, 0.3, 0.0])))
    gt_rows = [[99.99, 0, 0, 0, *q], [100.05, 0.6, 0, 0, *q]]
    folder = make_tum(tmp_path / "fr2_gt", times, [t + 0.001 for t in times], gt_rows=gt_rows)
    frames = list(TumSource(folder).frames())
    assert frames[0].gt_T_world_cam is not None
    np.testing.assert_allclose(frames[0].gt_T_world_cam[:3, 3], [0.1, 0, 0], atol=1e-9)
    np.testing.assert_allclose(frames[1].gt_T_world_cam[:3, 3], [0.4, 0, 0], atol=1e-9)  # type: ignore[index]
    assert frames[2].gt_T_world_cam is None  # after the last GT sample
    assert frames[3].gt_T_world_cam is None


def test_nominal_fps_and_colour_only_folder(tmp_path: Path) -> None:
    folder = make_tum(tmp_path / "fr3_rgb_only", [5.0 + 0.04 * i for i in range(5)], None)
    src = TumSource(folder)
    assert src.has_depth is False
    assert src.nominal_fps == pytest.approx(25.0)
    frames = list(src.frames())
    assert len(frames) == 5
    assert all(f.depth_m is None for f in frames)


def test_intrinsics_defaults_by_folder_name(tmp_path: Path) -> None:
    times = [1.0, 1.033]
    f2 = make_tum(tmp_path / "rgbd_dataset_freiburg2_desk", times, times, camera=None)
    assert TumSource(f2).intrinsics == TUM_DEFAULTS["freiburg2"]
    f3 = make_tum(tmp_path / "my_fr3_walk", times, times, camera=None)
    assert TumSource(f3).intrinsics == TUM_DEFAULTS["freiburg3"]
    plain = make_tum(tmp_path / "studio_take1", times, times, camera=None)
    with pytest.raises(SourceError, match=r"studio_take1: no camera.json"):
        TumSource(plain)


# --- bad input: one-line errors naming the file and the problem -------------------------------


def _one_line(exc: pytest.ExceptionInfo[BaseException]) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


def test_missing_folder(tmp_path: Path) -> None:
    with pytest.raises(SourceError, match="no such folder") as exc:
        TumSource(tmp_path / "nope")
    assert str(tmp_path / "nope") in _one_line(exc)
    with pytest.raises(SourceError, match="no such file or folder"):
        open_source(str(tmp_path / "nope"))


def test_empty_folder(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(SourceError, match=r"empty: folder is empty") as exc:
        TumSource(tmp_path / "empty")
    _one_line(exc)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("x")
    with pytest.raises(SourceError, match=r"other: no rgb.txt"):
        TumSource(tmp_path / "other")


def test_rgb_txt_without_entries(tmp_path: Path) -> None:
    folder = good_folder(tmp_path)
    (folder / "rgb.txt").write_text("# only comments\n")
    with pytest.raises(SourceError, match=r"rgb.txt: lists no images"):
        TumSource(folder)


@pytest.mark.parametrize(
    "bad_line",
    ["100.066 rgb/a.png extra", "abc rgb/x.png", "100.066", "nan rgb/x.png"],
)
def test_malformed_rgb_line_names_file_and_line(tmp_path: Path, bad_line: str) -> None:
    folder = good_folder(tmp_path)
    lines = (folder / "rgb.txt").read_text().splitlines()
    lines.insert(4, bad_line)  # file line 5
    (folder / "rgb.txt").write_text("\n".join(lines) + "\n")
    with pytest.raises(SourceError) as exc:
        TumSource(folder)
    msg = _one_line(exc)
    assert f"{folder / 'rgb.txt'}:5: expected 'timestamp filename'" in msg


@pytest.mark.parametrize("name", ["rgb.txt", "depth.txt"])
def test_non_monotonic_timestamps(tmp_path: Path, name: str) -> None:
    folder = good_folder(tmp_path)
    lines = (folder / name).read_text().splitlines()
    data = [i for i, ln in enumerate(lines) if not ln.startswith("#")]
    lines[data[1]], lines[data[2]] = lines[data[2]], lines[data[1]]
    (folder / name).write_text("\n".join(lines) + "\n")
    with pytest.raises(SourceError) as exc:
        TumSource(folder)
    msg = _one_line(exc)
    assert f"{folder / name}:{data[2] + 1}:" in msg
    assert "is not after the previous one" in msg


def test_duplicate_timestamp_is_non_monotonic(tmp_path: Path) -> None:
    folder = make_tum(tmp_path / "fr1", [1.0, 1.0], [1.0, 1.01])
    with pytest.raises(SourceError, match=r"rgb.txt:4: timestamp 1.000000 is not after"):
        TumSource(folder)


@pytest.mark.parametrize("kind", ["rgb", "depth"])
def test_missing_image_file(tmp_path: Path, kind: str) -> None:
    folder = good_folder(tmp_path)
    victim = sorted((folder / kind).iterdir())[2]
    victim.unlink()
    with pytest.raises(SourceError) as exc:
        TumSource(folder)
    msg = _one_line(exc)
    assert f"{kind}.txt:" in msg
    assert f"{kind}/{victim.name} does not exist" in msg


@pytest.mark.parametrize("kind", ["rgb", "depth"])
def test_truncated_png_fails_while_reading(tmp_path: Path, kind: str) -> None:
    folder = good_folder(tmp_path)
    victim = sorted((folder / kind).iterdir())[1]
    data = victim.read_bytes()
    victim.write_bytes(data[: len(data) // 2])
    src = TumSource(folder)  # the header lists are fine; the pixels are not
    it = src.frames()
    assert next(it).index == 0
    with pytest.raises(SourceError) as exc:
        next(it)
    msg = _one_line(exc)
    assert str(victim) in msg
    assert "truncated PNG" in msg


def test_png_missing_only_its_end_chunk_is_truncated(tmp_path: Path) -> None:
    folder = good_folder(tmp_path)
    victim = sorted((folder / "rgb").iterdir())[0]
    victim.write_bytes(victim.read_bytes()[:-12])  # drop exactly the IEND chunk
    with pytest.raises(SourceError, match=r"truncated PNG"):
        next(TumSource(folder).frames())


def test_garbage_image_is_undecodable(tmp_path: Path) -> None:
    folder = good_folder(tmp_path)
    victim = sorted((folder / "rgb").iterdir())[0]
    victim.write_bytes(b"this is not an image")
    with pytest.raises(SourceError, match=r"cannot decode image") as exc:
        next(TumSource(folder).frames())
    assert str(victim) in _one_line(exc)


def test_depth_size_mismatch_names_both_sizes(tmp_path: Path) -> None:
    times = [100.0, 100.033]
    folder = make_tum(tmp_path / "fr1", times, times, depth_size_wh=(W // 2, H // 2))
    with pytest.raises(SourceError) as exc:
        next(TumSource(folder).frames())
    msg = _one_line(exc)
    assert f"depth image is {W // 2}x{H // 2}" in msg
    assert f"is {W}x{H}" in msg
    assert "depth/100.000000.png" in msg


def test_8bit_depth_is_rejected(tmp_path: Path) -> None:
    folder = good_folder(tmp_path)
    victim = sorted((folder / "depth").iterdir())[0]
    cv2.imwrite(str(victim), np.zeros((H, W), np.uint8))
    with pytest.raises(SourceError, match=r"expected a 16-bit single-channel depth image"):
        next(TumSource(folder).frames())


def test_colour_size_differs_from_camera_json(tmp_path: Path) -> None:
    times = [100.0]
    folder = make_tum(tmp_path / "seq", times, times, camera=SMALL_CAM.scaled(2.0))
    with pytest.raises(SourceError, match=rf"image is {W}x{H} but the intrinsics say"):
        next(TumSource(folder).frames())


def test_no_depth_partner_at_all(tmp_path: Path) -> None:
    folder = make_tum(tmp_path / "seq", [1.0, 1.033], [2.0, 2.033])
    with pytest.raises(SourceError, match=r"no colour image has a depth image within 20 ms"):
        TumSource(folder)


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ('{"fx": 30, "fy": 30,', "malformed JSON at line"),
        ("[1, 2, 3]", "expected a JSON object"),
        (
            '{"fx": 30, "fy": 30, "cx": 1, "cy": 1, "width": 32, "height": "x"}',
            "'height' must be an integer",
        ),
        (
            '{"fx": 30, "fy": 30, "cx": 1, "cy": 1, "width": 32, "height": 24, "distortion": [0]}',
            "list of 5",
        ),
        (
            '{"fx": -30, "fy": 30, "cx": 1, "cy": 1, "width": 32, "height": 24}',
            "'fx' must be > 0",
        ),
    ],
)
def test_malformed_camera_json(tmp_path: Path, text: str, problem: str) -> None:
    folder = good_folder(tmp_path, "fr1_bad_cam")  # the fr1 default must not hide the error
    (folder / "camera.json").write_text(text)
    with pytest.raises(CalibrationError) as exc:
        TumSource(folder)
    msg = _one_line(exc)
    assert msg.startswith(str(folder / "camera.json"))
    assert problem in msg


def test_camera_json_missing_key(tmp_path: Path) -> None:
    folder = good_folder(tmp_path)
    d = json.loads((folder / "camera.json").read_text())
    del d["cy"]
    (folder / "camera.json").write_text(json.dumps(d))
    with pytest.raises(StudioTrackError, match=r"camera.json: missing key\(s\) cy") as exc:
        open_source(str(folder))
    _one_line(exc)


@pytest.mark.parametrize("bad", ["1.0 0 0 0 0 0 0", "1.0 0 0 0 0 0 0 0", "1.0 0 0 0 0 0 x 1"])
def test_malformed_groundtruth(tmp_path: Path, bad: str) -> None:
    folder = good_folder(tmp_path)
    (folder / "groundtruth.txt").write_text(f"# gt\n100.0 0 0 0 0 0 0 1\n{bad}\n")
    with pytest.raises(SourceError) as exc:
        TumSource(folder)
    assert (
        f"{folder / 'groundtruth.txt'}:3: expected 'timestamp tx ty tz qx qy qz qw'"
        in _one_line(exc)
    )


def test_good_folder_reads_all_frames(tmp_path: Path) -> None:
    folder = good_folder(tmp_path)
    src = open_source(str(folder))
    assert isinstance(src, TumSource)
    frames = list(src)
    assert [f.index for f in frames] == [0, 1, 2, 3]
    assert src.dropped_rgb == 0
    assert src.intrinsics == SMALL_CAM
    assert [int(f.color_bgr[0, 0, 0]) for f in frames] == [0, 10, 20, 30]  # type: ignore[index]
    np.testing.assert_allclose([float(f.depth_m[0, 0]) for f in frames], [0.2, 0.4, 0.6, 0.8])  # type: ignore[index]
    assert len(list(src.frames())) == 4  # restartable
