"""``twoview:`` - a frontal and an overhead camera given together, frame-synchronised by time.

For a real rig (the VR-TV paper's Fig. 2): the frontal (robot-mounted) camera drives the run;
each of its frames carries the overhead camera's frame nearest in time as an
:class:`engine.floor.OverheadView` payload (none when the nearest is further than
``max_dt_s``: the tracker then runs on the frontal view alone for that frame). Example::

    twoview:front=takes/front.mp4,over=takes/over.mp4,floor=project/floor.json,over_box=200:80:60:120

Options:

=================  ======================================================================
front, over        any source spec (a video, an OTB/TUM folder, ``camera:N``; write ``;``
                   for the ``,`` between its own options) or a plain folder of images
                   (sorted by name; a name that is a number of seconds, e.g.
                   ``1305031102.175304.png``, is its time stamp, else index / fps)
floor              the overhead camera's floor calibration (engine.floor JSON); the
                   presenter tracker's ``floor_path`` (a file or a studio project) wins
over_box           x:y:w:h of the presenter in the first overhead frame (initialises the
                   second filter; else the overhead source's own first box, if it has one)
max_dt_s           largest time difference of a pair (default: half a frontal frame period)
over_offset_s      added to the overhead time stamps (a known delay between the cameras)
fps                frame rate of plain image folders (30)
=================  ======================================================================

Times: the frames' ``timestamp_s`` for recordings; for two live cameras their capture times
(``Frame.capture_mono_s``, one clock for both).
"""

from __future__ import annotations

import collections
import re
import threading
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

from engine.camera import Intrinsics
from engine.errors import CalibrationError, SourceError
from engine.floor import FloorCalibration, OverheadView, load_floor_calibration
from engine.frames import Frame
from engine.sources.base import Source, SourceSpec, parse_options

_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")
_SECONDS = re.compile(r"^\d+(\.\d+)?$")


class ImageFolderSource(Source):
    """A plain folder of images (one view of a two-view rig)."""

    def __init__(self, folder: Path, fps: float = 30.0) -> None:
        self.folder = folder
        self.files = sorted(p for p in folder.iterdir() if p.suffix.lower() in _IMAGE_SUFFIXES)
        if not self.files:
            raise SourceError(f"{folder}: no images ({', '.join(_IMAGE_SUFFIXES)})")
        self.nominal_fps = fps
        self.name = f"image folder {folder.name}"
        stems = [p.stem for p in self.files]
        self._stamped = all(_SECONDS.match(s) for s in stems)

    @property
    def intrinsics(self) -> Intrinsics | None:
        return None

    def __len__(self) -> int:
        return len(self.files)

    def frames(self) -> Iterator[Frame]:
        from engine.sources.images import read_color_bgr

        for i, path in enumerate(self.files):
            t = float(path.stem) if self._stamped else i / self.nominal_fps
            yield Frame(index=i, timestamp_s=t, color_bgr=read_color_bgr(path))


def _open_view(spec: str, what: str, fps: float) -> Source:
    from engine.sources import open_source

    spec = spec.replace(";", ",")  # a nested spec's own options
    path = Path(spec).expanduser()
    if path.is_dir():
        try:
            return open_source(spec)
        except SourceError:
            return ImageFolderSource(path, fps)
    try:
        return open_source(spec)
    except SourceError as exc:
        raise SourceError(f"twoview {what}: {exc}") from None


def _time(f: Frame, live: bool) -> float:
    return float(f.capture_mono_s) if live else float(f.timestamp_s)


class _LiveLatest:
    """Reads a live overhead source on a thread; keeps its recent frames for pairing."""

    def __init__(self, src: Source) -> None:
        self._src = src
        self._frames: collections.deque[Frame] = collections.deque(maxlen=8)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="twoview-overhead",
                                        daemon=True)
        self._thread.start()

    def _run(self) -> None:
        for f in self._src.frames():
            if self._stop.is_set():
                return
            if f.color_bgr is not None:
                with self._lock:
                    self._frames.append(f)

    def nearest(self, t: float) -> Frame | None:
        with self._lock:
            frames = list(self._frames)
        return min(frames, key=lambda f: abs(f.capture_mono_s - t), default=None)

    def stop(self) -> None:
        self._stop.set()


class TwoViewSource(Source):
    """Frontal frames with the time-nearest overhead frame attached (see the module doc)."""

    def __init__(self, front: Source, over: Source, *,
                 floor: FloorCalibration | None = None,
                 over_box: tuple[float, float, float, float] | None = None,
                 max_dt_s: float | None = None, over_offset_s: float = 0.0) -> None:
        self.front = front
        self.over = over
        self.floor = floor
        self.over_box = over_box
        self.nominal_fps = front.nominal_fps
        self.live = bool(front.live)
        self.max_dt_s = max_dt_s if max_dt_s is not None else 0.5 / max(front.nominal_fps, 1.0)
        self.over_offset_s = over_offset_s
        self.name = f"two views ({front.name} + {over.name})"
        self.pairs = 0  # frames that got an overhead view
        self.unpaired = 0

    @property
    def intrinsics(self) -> Intrinsics | None:
        return self.front.intrinsics

    def __len__(self) -> int:
        return len(self.front)

    def close(self) -> None:
        self.front.close()
        self.over.close()

    def _payload(self, f: Frame, first: bool) -> OverheadView:
        box = self.over_box if first and self.over_box is not None else (
            f.gt_box_xywh if first else None)
        assert f.color_bgr is not None
        from engine.lens import LensEncoders

        # a zooming overhead camera that reports its encoders (a lens-model floor
        # calibration follows them)
        return OverheadView(color_bgr=f.color_bgr, box_xywh=box,
                            floor_calibration=self.floor,
                            timestamp_s=f.timestamp_s + self.over_offset_s,
                            lens_encoders=f.payload(LensEncoders))

    def frames(self) -> Iterator[Frame]:
        live = self.front.live and self.over.live
        first = True
        if live:
            reader = _LiveLatest(self.over)
            try:
                for f in self.front.frames():
                    o = reader.nearest(f.capture_mono_s)
                    if o is None or abs(o.capture_mono_s - f.capture_mono_s) > self.max_dt_s:
                        self.unpaired += 1
                        yield f
                        continue
                    self.pairs += 1
                    yield replace(f, payloads=(*f.payloads, self._payload(o, first)))
                    first = False
            finally:
                reader.stop()
            return
        over_iter = iter(self.over.frames())
        cur: Frame | None = next(over_iter, None)
        nxt: Frame | None = next(over_iter, None)
        off = self.over_offset_s
        for f in self.front.frames():
            t = _time(f, False)
            while nxt is not None and _time(nxt, False) + off <= t:
                cur, nxt = nxt, next(over_iter, None)
            best = cur
            if nxt is not None and (best is None or abs(_time(nxt, False) + off - t)
                                    < abs(_time(best, False) + off - t)):
                best = nxt
            if best is None or best.color_bgr is None \
                    or abs(_time(best, False) + off - t) > self.max_dt_s:
                self.unpaired += 1
                yield f
                continue
            self.pairs += 1
            yield replace(f, payloads=(*f.payloads, self._payload(best, first)))
            first = False


def _box(text: str) -> tuple[float, float, float, float]:
    try:
        x, y, w, h = (float(v) for v in text.split(":"))
    except ValueError:
        raise SourceError(f"twoview: over_box={text!r}: expected x:y:w:h") from None
    if w <= 0 or h <= 0:
        raise SourceError(f"twoview: over_box={text!r}: width and height must be > 0")
    return (x, y, w, h)


def open_twoview(rest: str) -> TwoViewSource:
    opts: dict[str, Any] = parse_options(rest)
    known = {"front", "over", "floor", "over_box", "max_dt_s", "over_offset_s", "fps"}
    unknown = sorted(set(opts) - known)
    if unknown:
        raise SourceError(f"twoview: unknown option {unknown[0]!r} (known: "
                          f"{', '.join(sorted(known))})")
    for key in ("front", "over"):
        if not opts.get(key):
            raise SourceError(f"twoview: needs {key}=SPEC (a video, folder or camera:N)")
    try:
        fps = float(opts.get("fps", 30.0))
        max_dt = float(opts["max_dt_s"]) if "max_dt_s" in opts else None
        offset = float(opts.get("over_offset_s", 0.0))
    except ValueError as exc:
        raise SourceError(f"twoview: {exc}") from None
    floor = None
    if opts.get("floor"):
        try:
            floor = load_floor_calibration(opts["floor"])
        except CalibrationError as exc:
            raise SourceError(f"twoview floor: {exc}") from None
    front = _open_view(opts["front"], "front", fps)
    over = _open_view(opts["over"], "over", fps)
    return TwoViewSource(front, over, floor=floor,
                         over_box=_box(opts["over_box"]) if opts.get("over_box") else None,
                         max_dt_s=max_dt, over_offset_s=offset)


SOURCES = (
    SourceSpec(
        name="twoview",
        description="a frontal and an overhead camera, synchronised by time",
        opener=open_twoview,
        example="twoview:front=front.mp4,over=over.mp4,floor=floor.json",
    ),
)
