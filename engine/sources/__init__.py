"""Open a frame source from a spec string.

Every kind of source is declared by a :class:`engine.sources.base.SourceSpec` in a module-level
``SOURCES`` tuple of the module that implements it; :data:`REGISTRY` finds them in this package
and in the modules named in :data:`SOURCE_PLACES` (sources that live with their algorithm).
Built in:

- ``synthetic[:key=value,...]`` - the built-in virtual studio (see ``engine.studio``)
- ``ptz-sim[:key=value,...]`` - ball on a circle seen by a stepping pan-tilt camera
  (``engine.ptz.sim``; closes the pan/tilt loop with the ``ptz`` tracker)
- ``robot-sim[:key=value,...]`` - the built-in studio from a robot-mounted camera obeying the
  presenter tracker (``engine.presenter.robot_sim``; closes the robot-camera loop)
- ``freed:PORT`` - FreeD D1 packets from a PTZ camera or tracker (``engine.outputs.
  freed_input``: pose, zoom/focus encoders, no image)
- ``camera:N`` - live webcam N through OpenCV
- ``realsense[:serial=...,width=...,...]`` - a RealSense depth camera through its SDK;
  ``path/to/file.bag`` - a RealSense recording (see ``engine.sources.realsense``)
- ``beacons[:...]``, ``beacons-csv:FILE[,...]``, ``beacons-udp:[...]`` - range beacons
  (see ``engine.sources.beacons``)
- a TUM RGB-D folder (has ``rgb.txt``)
- an OTB-style folder (has ``img/`` and ``groundtruth_rect.txt``) or a MIL folder (``imgs/``)
- a video file (``.mp4``, ``.avi``, ``.mov``, ``.mkv``)
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

from engine.errors import SourceError
from engine.registry import Registry
from engine.sources.base import Source, SourceSpec, parse_options

__all__ = [
    "REGISTRY",
    "Source",
    "SourceSpec",
    "available_sources",
    "open_source",
    "parse_options",
]

#: where source specs are declared: this package, and sources that live with their algorithm
SOURCE_PLACES = (__name__, "engine.ptz.sim", "engine.presenter.robot_sim",
                 "engine.outputs.freed_input")

REGISTRY: Registry[SourceSpec] = Registry(
    "source", "SOURCES", SourceSpec, places=SOURCE_PLACES, error=SourceError
)

_SCHEME = re.compile(r"[a-z][a-z0-9_-]*")


def available_sources() -> Mapping[str, SourceSpec]:
    """All registered source kinds by name."""
    return REGISTRY.specs()


def _expected(specs: Mapping[str, SourceSpec]) -> str:
    paths = [s.description for s in specs.values() if s.is_path]
    schemes = sorted(s.name for s in specs.values() if not s.is_path)
    return f"expected {', '.join(paths)} or a spec {', '.join(f'{n}:...' for n in schemes)}"


def open_source(spec: str) -> Source:
    """Open a source from its spec string; raises SourceError with a one-line reason."""
    spec = spec.strip()
    if not spec:
        raise SourceError("empty source spec")
    specs = available_sources()
    kind, _, rest = spec.partition(":")
    scheme = specs.get(kind)
    if scheme is not None and not scheme.is_path:
        return scheme.opener(rest)
    path = Path(spec).expanduser()
    if not path.exists():
        if _SCHEME.fullmatch(kind) and rest:
            raise SourceError(
                f"{spec}: no such file or folder, and {kind!r} is not a source scheme; "
                + _expected(specs)
            )
        raise SourceError(f"{path}: no such file or folder")
    matches = [s for s in specs.values() if s.detect is not None and s.detect(path)]
    if len(matches) > 1:
        names = ", ".join(s.name for s in matches)
        raise SourceError(f"{path}: looks like several kinds of source ({names})")
    if not matches:
        raise SourceError(f"{path}: unsupported source; " + _expected(specs))
    return matches[0].opener(str(path))
