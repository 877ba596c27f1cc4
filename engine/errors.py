"""Exception types of the engine. Every user-facing message is one line naming what and where."""

from __future__ import annotations


class StudioTrackError(Exception):
    """Base class of all errors the engine raises on purpose."""


class SourceError(StudioTrackError):
    """A frame source cannot be opened or read (missing file, bad format, wrong size...)."""


class CalibrationError(StudioTrackError):
    """Camera calibration data is missing, malformed or degenerate."""


class TrackerError(StudioTrackError):
    """A tracker cannot be created or configured."""


class EvaluationError(StudioTrackError):
    """Trajectories cannot be read, associated or compared."""


class ParamsError(StudioTrackError, ValueError):
    """A parameter value is out of range or inconsistent."""
