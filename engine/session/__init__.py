"""Recording and deterministic replay of tracking sessions (issue 7).

A session folder::

    SESSION/
      index.json      versioned description: source, intrinsics, tracker + params, status
      records.jsonl   one JSON object per tracked frame (pose, state, residuals, timings,
                      outputs sent); appended and flushed per frame
      frames/NNNNNN.png   colour input, lossless (not written for video sources)
      depth/NNNNNN.png    16-bit depth, units of 1/depth_scale m (when the source has depth)
      input<.ext>     the video file itself, copied as-is (video sources)
      outputs.json    sender statistics at the end (when outputs were on)

Modules: :mod:`.recorder` (write), :mod:`.reader` (index, records, replay source),
:mod:`.replay` (run the same engine again), :mod:`.export` (TUM, CSV, JSON).
"""

from __future__ import annotations

from engine.errors import StudioTrackError

FORMAT_NAME = "studiotrack-session"
FORMAT_VERSION = 1


class SessionError(StudioTrackError):
    """A session folder cannot be written or read (disk full, malformed index...)."""


class RecordingStopped(SessionError):
    """Recording stopped on a write error; what was written before stays readable."""
