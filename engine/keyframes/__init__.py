"""The keyframe model of the dense tracker, prepared before a show (Tykkälä 2014 sec. 6).

Modules: ``store`` (the keyframe store, eq. (19)-(21) search, immutable edits), ``sweep``
(recording a sweep of the empty studio on the engine loop, sec. 6.1), ``fusion`` and
``fusion_kernels`` (depth map fusion, Fig. 10), ``annotate`` (semi-automatic point
annotation), ``depth_sample`` (depth at an annotated pixel), ``sba`` and ``sba_residuals``
(sparse bundle adjustment of keyframe poses, Fig. 11). The studio project that saves the
model is :mod:`engine.project`; the tracker that uses it is :mod:`engine.dense.tracking`.
"""
