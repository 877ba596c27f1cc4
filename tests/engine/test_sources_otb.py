"""OtbSource on OTB Girl/KiteSurf, the MIL david sequence and generated folders."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from engine.errors import SourceError
from engine.frames import SourceFiles
from engine.sources import open_source
from engine.sources.otb import OtbSource, read_box_file
from tests.conftest import shared_path


def _gt_lines(path: Path) -> list[list[float]]:
    import re

    return [
        [float(v) for v in re.split(r"[,\t ]+", ln.strip())]
        for ln in path.read_text().splitlines()
        if ln.strip()
    ]


def test_otb_girl_tab_separated() -> None:
    folder = shared_path("otb_girl")
    src = open_source(str(folder))
    assert isinstance(src, OtbSource)
    assert len(src) == 500
    assert src.intrinsics is None
    expected = _gt_lines(folder / "groundtruth_rect.txt")
    assert src.boxes_xywh[0] == (57.0, 21.0, 31.0, 45.0)
    assert [list(b) for b in src.boxes_xywh if b is not None] == expected
    frames = []
    for frame in src.frames():
        frames.append(frame)
        if len(frames) == 20:
            break
    assert frames[0].color_bgr is not None
    assert frames[0].color_bgr.shape == (96, 128, 3)
    assert frames[0].payload(SourceFiles).color_path.endswith("img/0001.jpg")
    assert frames[19].gt_box_xywh == tuple(expected[19])
    assert frames[1].timestamp_s == pytest.approx(1 / 30)


def test_otb_kitesurf_comma_separated() -> None:
    folder = shared_path("otb_kitesurf")
    src = OtbSource(folder)
    frames = list(src.frames())
    assert len(frames) == 84
    assert frames[0].color_bgr is not None
    assert frames[0].color_bgr.shape == (270, 480, 3)
    expected = _gt_lines(folder / "groundtruth_rect.txt")
    assert [list(f.gt_box_xywh) for f in frames if f.gt_box_xywh] == expected  # type: ignore[arg-type]


def test_mil_david_every_fifth_frame_labelled() -> None:
    folder = shared_path("mil_david")
    src = open_source(str(folder))
    assert isinstance(src, OtbSource)
    assert src.layout == "mil"
    assert len(src) == 462
    boxes = src.boxes_xywh
    assert boxes[0] == (122.0, 58.0, 75.0, 97.0)
    labelled = [i for i, b in enumerate(boxes) if b is not None]
    assert len(labelled) == 93  # SOURCE.txt: 93 labelled frames
    assert all(i % 5 == 0 for i in labelled)
    it = src.frames()
    first = next(it)
    assert first.payload(SourceFiles).color_path.endswith("imgs/img00001.png")
    assert first.color_bgr is not None
    assert first.color_bgr.shape == (240, 320, 3)
    assert first.gt_box_xywh == boxes[0]
    assert next(it).gt_box_xywh is None


def _make_otb(
    folder: Path, n: int, gt_text: str | None, size_wh: tuple[int, int] = (40, 30)
) -> Path:
    (folder / "img").mkdir(parents=True)
    w, h = size_wh
    for i in range(n):
        cv2.imwrite(str(folder / "img" / f"{i + 1:04d}.jpg"), np.full((h, w, 3), 40 * i, np.uint8))
    if gt_text is not None:
        (folder / "groundtruth_rect.txt").write_text(gt_text)
    return folder


@pytest.mark.parametrize(
    "gt_text",
    [
        "1,2,3,4\n5,6,7,8\n",
        "1\t2\t3\t4\r\n5\t6\t7\t8\r\n",
        "1 2 3 4\n5  6 7 8\n\n\n",
        "1, 2, 3, 4\n5,\t6,7,8",
    ],
)
def test_separators(tmp_path: Path, gt_text: str) -> None:
    src = OtbSource(_make_otb(tmp_path / "seq", 3, gt_text))
    frames = list(src.frames())
    assert [f.gt_box_xywh for f in frames] == [(1, 2, 3, 4), (5, 6, 7, 8), None]  # beyond GT


def test_no_groundtruth_file_gives_no_boxes(tmp_path: Path) -> None:
    src = OtbSource(_make_otb(tmp_path / "seq", 2, None))
    assert src.groundtruth_path is None
    assert [f.gt_box_xywh for f in src.frames()] == [None, None]


def test_zero_and_nan_boxes_mean_unlabelled(tmp_path: Path) -> None:
    src = OtbSource(_make_otb(tmp_path / "seq", 3, "0,0,0,0\nNaN,NaN,NaN,NaN\n1,1,5,5\n"))
    assert src.boxes_xywh == [None, None, (1, 1, 5, 5)]


@pytest.mark.parametrize("bad", ["1,2,3", "1,2,3,x", "", "1,2,3,4,5"])
def test_bad_gt_line_names_line_number(tmp_path: Path, bad: str) -> None:
    folder = _make_otb(tmp_path / "seq", 3, f"1,2,3,4\n{bad}\n5,6,7,8\n")
    with pytest.raises(SourceError) as exc:
        OtbSource(folder)
    msg = str(exc.value)
    assert f"{folder / 'groundtruth_rect.txt'}:2: expected 4 numbers" in msg
    assert "\n" not in msg


def test_missing_and_empty_folders(tmp_path: Path) -> None:
    with pytest.raises(SourceError, match="no such folder"):
        OtbSource(tmp_path / "nope")
    (tmp_path / "bare").mkdir()
    with pytest.raises(SourceError, match=r"bare: no img/ \(OTB\) or imgs/ \(MIL\)"):
        OtbSource(tmp_path / "bare")
    (tmp_path / "noimg" / "img").mkdir(parents=True)
    with pytest.raises(SourceError, match=r"img: no images"):
        OtbSource(tmp_path / "noimg")


def test_truncated_jpeg_and_size_change(tmp_path: Path) -> None:
    folder = _make_otb(tmp_path / "seq", 3, "1,2,3,4\n")
    victim = folder / "img" / "0002.jpg"
    data = victim.read_bytes()
    victim.write_bytes(data[: len(data) // 2])  # cv2.imread would half-decode this silently
    it = OtbSource(folder).frames()
    next(it)
    with pytest.raises(SourceError, match=r"0002.jpg: truncated JPEG"):
        next(it)
    cv2.imwrite(str(victim), np.zeros((10, 20, 3), np.uint8))
    it = OtbSource(folder).frames()
    next(it)
    with pytest.raises(
        SourceError, match=r"0002.jpg: image is 20x10 but the sequence started at 40x30"
    ):
        next(it)


def test_grey_images_become_bgr(tmp_path: Path) -> None:
    folder = tmp_path / "seq"
    (folder / "img").mkdir(parents=True)
    cv2.imwrite(str(folder / "img" / "0001.png"), np.full((30, 40), 77, np.uint8))
    frame = next(OtbSource(folder).frames())
    assert frame.color_bgr is not None
    assert frame.color_bgr.shape == (30, 40, 3)
    assert int(frame.color_bgr[0, 0, 2]) == 77


def test_mil_layout_with_frame_range(tmp_path: Path) -> None:
    folder = tmp_path / "toy"
    (folder / "imgs").mkdir(parents=True)
    for i in range(6):
        cv2.imwrite(str(folder / "imgs" / f"img{i + 1:05d}.png"), np.full((8, 8, 3), i, np.uint8))
    (folder / "toy_gt.txt").write_text("1,1,2,2\n0,0,0,0\n3,3,2,2\n0,0,0,0\n5,5,2,2\n0,0,0,0\n")
    (folder / "toy_frames.txt").write_text("3,5\n")
    src = OtbSource(folder)
    frames = list(src.frames())
    assert [int(f.color_bgr[0, 0, 0]) for f in frames] == [2, 3, 4]  # type: ignore[index]
    assert [f.gt_box_xywh for f in frames] == [(3, 3, 2, 2), None, (5, 5, 2, 2)]
    (folder / "toy_frames.txt").write_text("3,9\n")
    with pytest.raises(SourceError, match=r"toy_frames.txt: frame range 3,9 but imgs/ holds 6"):
        OtbSource(folder)
    (folder / "toy_frames.txt").write_text("three\n")
    with pytest.raises(SourceError, match=r"toy_frames.txt:1: expected 'first,last'"):
        OtbSource(folder)


def test_read_box_file_interior_blank_line_is_error(tmp_path: Path) -> None:
    path = tmp_path / "gt.txt"
    path.write_text("1,2,3,4\n\n1,2,3,4\n")
    with pytest.raises(SourceError, match=r"gt.txt:2:"):
        read_box_file(path)
