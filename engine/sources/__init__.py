"""Open a frame source from a spec string.

Specs:
- ``synthetic[:key=value,...]`` - the built-in virtual studio (see ``engine.studio``)
- ``ptz-sim[:key=value,...]`` - ball on a circle seen by a stepping pan-tilt camera
  (``engine.ptz.sim``; closes the pan/tilt loop with the ``ptz`` tracker)
- ``camera:N`` - live webcam N through OpenCV
- ``beacons[:...]``, ``beacons-csv:FILE[,...]``, ``beacons-udp:[...]`` - range beacons
  (see ``engine.sources.beacons``)
- a TUM RGB-D folder (has ``rgb.txt``)
- an OTB-style folder (has ``img/`` and ``groundtruth_rect.txt``) or a MIL folder (``imgs/``)
- a video file (``.mp4``, ``.avi``, ``.mov``, ``.mkv``)
"""

from __future__ import annotations

from pathlib import Path

from engine.errors import SourceError
from engine.sources.base import Source

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v")


def parse_options(text: str) -> dict[str, str]:
    """``"a=1,b=x"`` -> ``{"a": "1", "b": "x"}``; a malformed item raises SourceError."""
    out: dict[str, str] = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise SourceError(f"source option {item!r} is not key=value")
        out[key.strip()] = value.strip()
    return out


def open_source(spec: str) -> Source:
    """Open a source from its spec string; raises SourceError with a one-line reason."""
    spec = spec.strip()
    if not spec:
        raise SourceError("empty source spec")
    kind, _, rest = spec.partition(":")
    if kind == "synthetic":
        from engine.sources.synthetic import SyntheticSource

        return SyntheticSource.from_options(parse_options(rest))
    if kind == "ptz-sim":
        from engine.ptz.sim import open_ptz_sim

        return open_ptz_sim(parse_options(rest))
    if kind in ("beacons", "beacons-csv", "beacons-udp"):
        from engine.sources.beacons import open_beacon_source

        return open_beacon_source(kind, rest)
    if kind == "camera":
        from engine.sources.camera_live import CameraSource

        try:
            index = int(rest or "0")
        except ValueError:
            msg = f"camera spec {spec!r}: expected camera:N with N an integer"
            raise SourceError(msg) from None
        return CameraSource(index)
    path = Path(spec).expanduser()
    if not path.exists():
        raise SourceError(f"{path}: no such file or folder")
    if path.is_dir():
        if (path / "rgb.txt").exists():
            from engine.sources.tum import TumSource

            return TumSource(path)
        if (path / "img").is_dir() or (path / "imgs").is_dir():
            from engine.sources.otb import OtbSource

            return OtbSource(path)
        raise SourceError(
            f"{path}: not a TUM folder (no rgb.txt) nor an OTB/MIL folder (no img/ or imgs/)"
        )
    if path.suffix.lower() in VIDEO_SUFFIXES:
        from engine.sources.video import VideoSource

        return VideoSource(path)
    suffixes = ", ".join(VIDEO_SUFFIXES)
    raise SourceError(f"{path}: unsupported source (expected a folder or {suffixes})")
