"""``studiotrack demo-data``: the built-in studio written as a TUM RGB-D folder."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from app.cli import main
from engine.camera import load_camera_json
from engine.sources import open_source

OPTS = "width=160,height=120"


@pytest.fixture(scope="module")
def demo_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("demo") / "studio"
    rc = main(
        [
            "demo-data",
            str(out),
            "--frames",
            "6",
            "--seed",
            "2",
            "--presenter",
            "1",
            "--options",
            OPTS,
        ]
    )
    assert rc == 0
    return out


def test_layout_and_formats(demo_folder: Path) -> None:
    for name in ("rgb.txt", "depth.txt", "groundtruth.txt", "camera.json", "presenter.txt"):
        assert (demo_folder / name).is_file(), name
    rows = [
        ln.split()
        for ln in (demo_folder / "rgb.txt").read_text().splitlines()
        if not ln.startswith("#")
    ]
    assert len(rows) == 6
    assert [float(r[0]) for r in rows] == pytest.approx([i / 30 for i in range(6)], abs=1e-6)
    depth_rows = [
        ln.split()
        for ln in (demo_folder / "depth.txt").read_text().splitlines()
        if not ln.startswith("#")
    ]
    d = cv2.imread(str(demo_folder / depth_rows[0][1]), cv2.IMREAD_UNCHANGED)
    assert d.dtype == np.uint16
    assert d.shape == (120, 160)
    assert 2.0 < d.max() / 5000.0 < 8.0
    cam_raw = json.loads((demo_folder / "camera.json").read_text())
    assert set(cam_raw) >= {"fx", "fy", "cx", "cy", "width", "height", "distortion", "depth_scale"}
    assert len(cam_raw["distortion"]) == 5
    cam = load_camera_json(demo_folder / "camera.json")
    assert (cam.width, cam.height, cam.fx) == (160, 120, 131.25)
    gt = [
        ln.split()
        for ln in (demo_folder / "groundtruth.txt").read_text().splitlines()
        if not ln.startswith("#")
    ]
    assert len(gt) == 6
    assert all(len(r) == 8 for r in gt)


def test_evo_reads_the_ground_truth(demo_folder: Path) -> None:
    from evo.tools import file_interface

    traj = file_interface.read_tum_trajectory_file(str(demo_folder / "groundtruth.txt"))
    assert traj.num_poses == 6
    src = open_source(f"synthetic:frames=6,seed=2,presenter=1,{OPTS}")
    for i, T in enumerate(traj.poses_se3):
        np.testing.assert_allclose(T, src.studio.T_world_cam(i), atol=1e-8)


def test_tum_source_round_trip(demo_folder: Path) -> None:
    tum = open_source(str(demo_folder))
    syn = open_source(f"synthetic:frames=6,seed=2,presenter=1,{OPTS}")
    assert len(tum) == len(syn) == 6
    assert tum.intrinsics == syn.intrinsics
    for a, b in zip(tum.frames(), syn.frames(), strict=True):
        assert a.timestamp_s == pytest.approx(b.timestamp_s, abs=1e-6)
        assert np.array_equal(a.color_bgr, b.color_bgr)
        assert np.max(np.abs(a.depth_m - b.depth_m)) <= 0.5 / 5000 + 1e-6
        assert a.gt_T_world_cam is not None
        np.testing.assert_allclose(a.gt_T_world_cam, b.gt_T_world_cam, atol=1e-8)


def test_presenter_boxes_written(demo_folder: Path) -> None:
    rows = [
        ln.split()
        for ln in (demo_folder / "presenter.txt").read_text().splitlines()
        if not ln.startswith("#")
    ]
    syn = open_source(f"synthetic:frames=6,seed=2,presenter=1,{OPTS}")
    for row, f in zip(rows, syn.frames(), strict=True):
        vals = [float(v) for v in row[1:]]
        if f.gt_box_xywh is None:
            assert all(np.isnan(vals))
        else:
            assert vals == pytest.approx(list(f.gt_box_xywh))
    assert any(f.gt_box_xywh is not None for f in syn.frames())


def test_refuses_a_non_empty_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "x.txt").write_text("keep me")
    rc = main(["demo-data", str(tmp_path), "--frames", "2", "--options", OPTS])
    assert rc == 2
    assert "not empty" in capsys.readouterr().err
    assert (tmp_path / "x.txt").read_text() == "keep me"


def test_bad_option_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc = main(["demo-data", str(tmp_path / "o"), "--frames", "2", "--options", "bogus=1"])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert "bogus" in err
    assert len(err.splitlines()) == 1
