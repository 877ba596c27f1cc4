"""A source seen through a lens file: each frame's intrinsics from its zoom/focus encoders.

:class:`LensedSource` wraps any source. For every frame it takes the encoder values - the
frame's own :class:`engine.lens.LensEncoders` (a zoom sweep, a FreeD input, a PTZ camera's
position inquiry), else the operator's typed values (:meth:`LensedSource.set_encoders`),
else the lens file's first sample - evaluates the :class:`engine.lens.LensFile` there and
yields the frame with ``intrinsics`` replaced by the lens file's and the
:class:`engine.lens.LensState` added as a payload. Trackers keep reading
``frame.intrinsics``; the outputs send the state (OpenTrackIO ``lens``, FreeD zoom/focus).

Example::

    src = LensedSource(open_source("synthetic:zoom=sweep"), LensFile.load("lens.json"))
"""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from engine.camera import Intrinsics
from engine.frames import Frame
from engine.lens import LensEncoders, LensError, LensFile, LensState
from engine.sources.base import Source


class LensedSource(Source):
    """``inner`` with every frame's intrinsics from ``lens`` at the frame's encoders."""

    def __init__(self, inner: Source, lens: LensFile,
                 typed: tuple[int, int] | None = None) -> None:
        lens.check_complete()
        self.inner = inner
        self.name = inner.name
        self.nominal_fps = inner.nominal_fps
        self.live = inner.live
        self._lock = threading.Lock()
        self._lens = lens
        self._typed = typed
        self.last_state: LensState | None = None

    def __getattr__(self, name: str) -> Any:
        # what a pipeline or page asks of the wrapped source (head_port, studio...)
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    @property
    def lens(self) -> LensFile:
        with self._lock:
            return self._lens

    def set_lens(self, lens: LensFile) -> None:
        """Swap the lens file in (from the next frame)."""
        lens.check_complete()
        with self._lock:
            self._lens = lens

    def set_encoders(self, zoom_raw: int | None, focus_raw: int = 0) -> None:
        """Typed encoder values for frames that carry none (None: the file's first sample)."""
        with self._lock:
            self._typed = None if zoom_raw is None else (int(zoom_raw), int(focus_raw))

    @property
    def intrinsics(self) -> Intrinsics | None:
        return self.lens_state(None).intrinsics

    def __len__(self) -> int:
        return len(self.inner)

    def lens_state(self, enc: LensEncoders | None) -> LensState:
        with self._lock:
            lens, typed = self._lens, self._typed
        if enc is not None:
            return lens.evaluate(enc.zoom_raw, enc.focus_raw, enc.iris_raw)
        if typed is not None:
            return lens.evaluate(*typed)
        first = lens.samples[0]
        return lens.evaluate(first.zoom_raw, first.focus_raw)

    def apply(self, frame: Frame) -> Frame:
        """The frame with the lens file's intrinsics and its :class:`LensState`."""
        state = self.lens_state(frame.payload(LensEncoders))
        cam = state.intrinsics
        got = frame.intrinsics
        if got is not None and (got.width, got.height) != (cam.width, cam.height):
            raise LensError(f"lens file {self.lens.name!r} is for {cam.width}x{cam.height} "
                            f"px images, {self.name} gives {got.width}x{got.height}: calibrate "
                            "the lens at this camera mode (or remove it from the project)")
        if frame.intrinsics is not None and frame.intrinsics.depth_scale != cam.depth_scale:
            cam = dataclasses.replace(cam, depth_scale=frame.intrinsics.depth_scale)
            state = dataclasses.replace(state, intrinsics=cam)
        self.last_state = state
        payloads = tuple(p for p in frame.payloads if not isinstance(p, LensState))
        return dataclasses.replace(frame, intrinsics=cam, payloads=(*payloads, state))

    def frames(self) -> Iterator[Frame]:
        for f in self.inner.frames():
            yield self.apply(f)

    def input_paths(self) -> tuple[Path, ...]:
        return self.inner.input_paths()

    def end_notes(self) -> tuple[str, ...]:
        return self.inner.end_notes()

    def sinks(self) -> Sequence[Any]:
        return self.inner.sinks()

    def close(self) -> None:
        self.inner.close()
