"""The built-in virtual studio: a procedural TV studio set rendered as RGB-D with exact truth.

Modules: ``scene`` (set layout, baked textures), ``textures`` (procedural materials),
``render`` (numba ray caster), ``paths`` (camera paths), ``presenter``, ``ball``, ``sensor``
(depth noise, dropouts), ``sim`` (config -> Frames). The frame source is
``engine.sources.synthetic`` (spec ``synthetic:key=value,...``). Importing ``render`` or
``sim`` imports numba (about half a second): import them inside functions where start-up
time matters.
"""
