"""Pan-tilt head commands: the tracker's :class:`engine.ptz.head.PanTiltCommand` to a head.

The sink (:class:`engine.ptz.head.HeadCommandSink`) lives with the head types; the ``ptz-sim``
source offers its simulated head through :meth:`engine.sources.base.Source.sinks`, so any
pipeline running it closes the loop; a real head driver (VISCA) plugs in as another
:class:`engine.ptz.head.HeadPort`.
"""

from __future__ import annotations

from engine.ptz.head import HeadCommandSink
from engine.sinks import SinkSpec

SINKS = (SinkSpec("pan-tilt-head", "moves a pan-tilt head on the tracker's commands",
                  HeadCommandSink),)
