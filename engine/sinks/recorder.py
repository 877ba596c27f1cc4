"""The session recorder as a sink (``studiotrack record``, session recording in the window).

The sink (:class:`engine.session.recorder.RecorderSink`) lives with the recorder: each record
is written (images first, then its JSON line) with the studio pose the outputs sent; a write
error stops the recording and disables the sink (reported), tracking goes on.
"""

from __future__ import annotations

from engine.session.recorder import RecorderSink
from engine.sinks import SinkSpec

SINKS = (SinkSpec("recorder", "records a replayable session folder", RecorderSink),)
