"""Presenter (moderator) tracking after the VR-TV multi-camera paper.

``../shared/papers/vrtv_multicamera_presenter_tracking.txt``: a multi-patch colour + motion
particle filter per camera view (Sec. III-C), loss detection with an adaptive reference
likelihood (III-C.7), a jitter low-pass on the output (III-C.6), the overhead floor distance
and the robot-camera control errors (III-D, eq. 7-8).

Modules: ``model`` (patch model + HS histograms), ``likelihood`` (integral histograms,
Bhattacharyya eq. 2-3, motion history eq. 4), ``filter`` (particle filter eq. 1, 5, 6),
``view`` (one view's tracker with loss handling), ``jitter``, ``twoview``, ``control``.
"""

from __future__ import annotations

from engine.errors import TrackerError


class PresenterError(TrackerError):
    """A presenter model, selection or control setting is invalid."""
