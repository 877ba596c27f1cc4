"""Pose outputs to render engines: FreeD D1, OpenTrackIO, the studio frame, timing, sender.

Module layout (issue 7):

- :mod:`engine.outputs.freed` - FreeD D1 packets (encode/decode, zoom/focus mapping)
- :mod:`engine.outputs.opentrackio` - OpenTrackIO samples, 16-byte header, segmentation
- :mod:`engine.outputs.studio_frame` - studio origin/axes and per-protocol conventions
- :mod:`engine.outputs.timing` - per-axis delay compensation, hold-while-LOST
- :mod:`engine.outputs.sender` - the sender thread, per-target statistics

Everything here is plain Python (no Qt); importing this package is cheap.
"""

from __future__ import annotations

from engine.errors import StudioTrackError


class OutputError(StudioTrackError):
    """An output cannot be configured, or a packet cannot be encoded or decoded."""
