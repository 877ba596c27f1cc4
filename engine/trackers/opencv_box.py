"""OpenCV's KCF, MIL and CSRT box trackers as peers of ``presenter`` (OpenCV 5 defaults).

Initialised from the first frame's ground-truth box (``Frame.gt_box_xywh``). When OpenCV
reports a failure the box holds its last value and the state is LOST.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from engine.arrays import u8, xywh
from engine.errors import ParamsError, TrackerError
from engine.frames import Frame
from engine.params import Params, param
from engine.trackers.base import Overlay, TrackerSpec, TrackResult, TrackState


@dataclass(frozen=True, slots=True)
class OpenCVBoxParams(Params):
    """OpenCV trackers run with their library defaults; only the initial box can be given."""

    init_box_xywh: tuple[float, float, float, float] | None = param(
        None, help="initial box; None = the first frame's ground truth")

    def validate(self) -> None:
        b = self.init_box_xywh
        if b is not None and (len(b) != 4 or b[2] <= 0 or b[3] <= 0):
            raise ParamsError(f"init_box_xywh must be x,y,w,h with w,h > 0, got {b}")


def _create(kind: str) -> Any:
    import cv2

    create: dict[str, Callable[[], Any]] = {
        "kcf": cv2.TrackerKCF.create, "mil": cv2.TrackerMIL.create, "csrt": cv2.TrackerCSRT.create}
    return create[kind]()  # OpenCV 5: TrackerX.create(), default parameters


class OpenCVBoxTracker:
    def __init__(self, kind: str, params: OpenCVBoxParams | None = None) -> None:
        self.name = kind
        self.kind = kind
        self._params = params or OpenCVBoxParams()
        self._cv: Any = None
        self._box: tuple[float, float, float, float] | None = None

    @property
    def params(self) -> OpenCVBoxParams:
        return self._params

    def set_params(self, params: OpenCVBoxParams) -> None:
        self._params = params

    def reset(self) -> None:
        self._cv = None
        self._box = None

    def track(self, frame: Frame) -> TrackResult:
        import cv2

        img = frame.color_bgr
        if img is None:
            raise TrackerError(f"{self.kind} tracker: frame {frame.index} has no image")
        if img.ndim == 2:
            img = u8(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
        if self._cv is None:
            box = self._params.init_box_xywh or frame.gt_box_xywh
            if box is None:
                return TrackResult(state=TrackState.INITIALIZING, message="no initial box")
            H, W = img.shape[:2]
            x, y, w, h = (float(v) for v in box)
            roi = _clip_box(x, y, w, h, W, H)
            if roi is None:
                raise TrackerError(
                    f"{self.kind} tracker: initial box x,y,w,h = {x:g},{y:g},{w:g},{h:g} does "
                    f"not overlap the {W}x{H} image of frame {frame.index} by 2x2 px or more"
                )
            self._cv = _create(self.kind)
            try:
                self._cv.init(img, roi)
            except cv2.error as exc:
                self._cv = None
                msg = " ".join(str(exc).split())[-160:]
                raise TrackerError(f"{self.kind} tracker: cannot start on the box {roi} of "
                                   f"frame {frame.index} ({msg})") from None
            self._box = (x, y, w, h)
            return self._result(TrackState.TRACKING)
        ok, box = self._cv.update(img)
        if ok:
            self._box = xywh(box)
        return self._result(TrackState.TRACKING if ok else TrackState.LOST)

    def _result(self, state: TrackState) -> TrackResult:
        assert self._box is not None
        return TrackResult(state=state, box_xywh=self._box,
                           overlay=Overlay(boxes_xywh=(self._box,), box_labels=(self.kind,)),
                           message="" if state is TrackState.TRACKING else
                           f"OpenCV {self.kind.upper()} reports a failure")


def _clip_box(x: float, y: float, w: float, h: float, W: int, H: int
              ) -> tuple[int, int, int, int] | None:
    """The part of box ``x,y,w,h`` inside a ``W x H`` image, in whole pixels (None when
    less than 2x2 px of it is inside, or a value is not finite)."""
    import math

    if not all(math.isfinite(v) for v in (x, y, w, h)):
        return None
    x0, y0 = max(round(x), 0), max(round(y), 0)
    x1, y1 = min(x0 + round(w), W), min(y0 + round(h), H)
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    return (x0, y0, x1 - x0, y1 - y0)


def _factory(kind: str) -> Any:
    return lambda params: OpenCVBoxTracker(kind, params)


TRACKERS = tuple(
    TrackerSpec(name=kind, description=f"OpenCV {kind.upper()} box tracker (OpenCV 5 defaults)",
                params_cls=OpenCVBoxParams, factory=_factory(kind), output="box")
    for kind in ("kcf", "mil", "csrt")
)
