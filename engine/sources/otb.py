"""Single-object tracking sequences: OTB folders (Wu, Lim, Yang 2013/2015) and Babenko's
MIL sequences (Babenko, Yang, Belongie 2011).

OTB layout: ``img/0001.jpg ...`` and ``groundtruth_rect.txt`` with one ``x,y,w,h`` box per
frame (top-left corner, pixels), separated by commas, tabs or spaces depending on the
sequence. MIL layout: ``imgs/img00001.png ...``, ``<name>_gt.txt`` with one ``x,y,w,h`` line
per frame where only every 5th frame is labelled (the others are ``0,0,0,0``), and
``<name>_frames.txt`` holding the ``first,last`` frame numbers (1-based) of the sequence.

Boxes with a non-positive width/height or NaN are "no ground truth" (``None``), as are
frames beyond the last box line. Timestamps are ``index / nominal_fps`` (the datasets do not
record times; 30 fps is a nominal guess). Intrinsics are unknown (None).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from pathlib import Path

from engine.camera import Intrinsics
from engine.errors import SourceError
from engine.frames import Frame, SourceFiles
from engine.sources.base import Source, SourceSpec
from engine.sources.images import read_color_bgr

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp")
NOMINAL_FPS = 30.0
_SEPARATORS = re.compile(r"[,\s]+")

BoxXYWH = tuple[float, float, float, float]


def read_box_file(path: Path) -> list[BoxXYWH | None]:
    """Boxes ``x,y,w,h`` one per line (comma/tab/space separated); empty box -> None.

    Trailing blank lines are ignored; a blank or malformed line in the middle is an error
    with its line number, since it would shift every later box onto the wrong frame.
    """
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise SourceError(f"{path}: cannot read ({exc})") from None
    lines = text.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    boxes: list[BoxXYWH | None] = []
    for line_no, raw in enumerate(lines, start=1):
        parts = [p for p in _SEPARATORS.split(raw.strip()) if p]
        try:
            if len(parts) != 4:
                raise ValueError
            x, y, w, h = (float(p) for p in parts)
        except ValueError:
            raise SourceError(
                f"{path}:{line_no}: expected 4 numbers 'x,y,w,h', got {raw.strip()[:60]!r}"
            ) from None
        if any(math.isinf(v) for v in (x, y, w, h)):
            raise SourceError(f"{path}:{line_no}: infinite value in box {raw.strip()!r}")
        if any(math.isnan(v) for v in (x, y, w, h)) or w <= 0 or h <= 0:
            boxes.append(None)  # target absent / frame not labelled
        else:
            boxes.append((x, y, w, h))
    return boxes


def _frame_range(path: Path) -> tuple[int, int]:
    """``first,last`` (1-based, inclusive) of a MIL ``*_frames.txt``."""
    try:
        text = path.read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise SourceError(f"{path}: cannot read ({exc})") from None
    parts = [p for p in _SEPARATORS.split(text) if p]
    try:
        if len(parts) != 2:
            raise ValueError
        first, last = int(parts[0]), int(parts[1])
    except ValueError:
        raise SourceError(
            f"{path}:1: expected 'first,last' frame numbers, got {text[:40]!r}"
        ) from None
    if first < 1 or last < first:
        raise SourceError(f"{path}:1: frame range {first},{last} is empty or starts before 1")
    return first, last


def _list_images(folder: Path) -> list[Path]:
    return sorted(
        p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES
    )


class OtbSource(Source):
    """Colour frames with the ground-truth target box of an OTB or MIL sequence folder."""

    def __init__(self, path: str | Path) -> None:
        folder = Path(path).expanduser()
        if not folder.exists():
            raise SourceError(f"{folder}: no such folder")
        if not folder.is_dir():
            raise SourceError(f"{folder}: not a folder (an OTB source is a folder with img/)")
        self.folder = folder
        self.name = f"OTB folder {folder.name}"
        self.nominal_fps = NOMINAL_FPS
        boxes: list[BoxXYWH | None] = []
        if (folder / "img").is_dir():
            self.layout = "otb"
            images = _list_images(folder / "img")
            gt = folder / "groundtruth_rect.txt"
            self.groundtruth_path: Path | None = gt if gt.is_file() else None
            if self.groundtruth_path is not None:
                boxes = read_box_file(self.groundtruth_path)
        elif (folder / "imgs").is_dir():
            self.layout = "mil"
            self.name = f"MIL folder {folder.name}"
            images = _list_images(folder / "imgs")
            gts = sorted(folder.glob("*_gt.txt"))
            if len(gts) > 1:
                raise SourceError(
                    f"{folder}: several *_gt.txt files ({', '.join(p.name for p in gts)})"
                )
            self.groundtruth_path = gts[0] if gts else None
            if self.groundtruth_path is not None:
                boxes = read_box_file(self.groundtruth_path)
            ranges = sorted(folder.glob("*_frames.txt"))
            if len(ranges) == 1:
                first, last = _frame_range(ranges[0])
                if last > len(images):
                    raise SourceError(
                        f"{ranges[0]}: frame range {first},{last} but imgs/ holds "
                        f"{len(images)} images"
                    )
                # Box line i belongs to the i-th image in sorted order (the labelled ones
                # check out visually), so both are cut to the same range.
                images = images[first - 1 : last]
                boxes = boxes[first - 1 : last]
        else:
            raise SourceError(f"{folder}: no img/ (OTB) or imgs/ (MIL) subfolder")
        if not images:
            sub = "img" if self.layout == "otb" else "imgs"
            raise SourceError(f"{folder / sub}: no images (.jpg, .png, .bmp)")
        self._images = images
        self._boxes = boxes + [None] * max(0, len(images) - len(boxes))
        #: box lines beyond the last image (ignored)
        self.extra_box_lines = max(0, len(boxes) - len(images))

    def input_paths(self) -> tuple[Path, ...]:
        return (*super().input_paths(), *sorted({Path(p).parent for p in self._images}))

    @property
    def intrinsics(self) -> Intrinsics | None:
        return None

    @property
    def boxes_xywh(self) -> list[BoxXYWH | None]:
        """Ground-truth box per frame (None where unlabelled)."""
        return list(self._boxes[: len(self._images)])

    def __len__(self) -> int:
        return len(self._images)

    def frames(self) -> Iterator[Frame]:
        size_wh: tuple[int, int] | None = None
        for index, (img_path, box) in enumerate(zip(self._images, self._boxes, strict=False)):
            image = read_color_bgr(img_path)
            wh = (int(image.shape[1]), int(image.shape[0]))
            if size_wh is None:
                size_wh = wh
            elif wh != size_wh:
                raise SourceError(
                    f"{img_path}: image is {wh[0]}x{wh[1]} but the sequence started at "
                    f"{size_wh[0]}x{size_wh[1]}"
                )
            yield Frame(
                index=index,
                timestamp_s=index / self.nominal_fps,
                color_bgr=image,
                gt_box_xywh=box,
                payloads=(SourceFiles(color_path=str(img_path)),),
            )


def _is_otb_folder(path: Path) -> bool:
    return path.is_dir() and ((path / "img").is_dir() or (path / "imgs").is_dir())


SOURCES = (
    SourceSpec(
        name="otb",
        description="an OTB/MIL folder (img/ or imgs/)",
        opener=OtbSource,
        detect=_is_otb_folder,
        example="otb_girl",
    ),
)
