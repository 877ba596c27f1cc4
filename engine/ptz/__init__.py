"""Pan-tilt camera target tracking after Gaspar & Oliveira 2009 (VISAPP), "A single pan and
tilt camera architecture for indoor positioning and tracking".

Modules follow the paper's sections:
- :mod:`engine.ptz.dlt` - Faugeras DLT calibration and decomposition (sec. 3.1, eq. (1))
- :mod:`engine.ptz.kinematics` - pan/tilt/roll head geometry, P at any pan/tilt (sec. 3.2)
- :mod:`engine.ptz.distortion` - line-based inverse radial distortion (sec. 3.3)
- :mod:`engine.ptz.chessboard` - OpenCV chessboard calibration (convenience)
- :mod:`engine.ptz.segment`, :mod:`engine.ptz.snake` - colour segmentation, snake, (u, v, d)
  measurements (sec. 4.1-4.2, eq. (2))
- :mod:`engine.ptz.ekf`, :mod:`engine.ptz.mmae` - constant-turn EKF and multiple-model
  adaptive estimation (sec. 5.1-5.2)
- :mod:`engine.ptz.control` - pan/tilt decision with discrete steps (sec. 6.1)
- :mod:`engine.ptz.sim` - red ball on a circle seen by a simulated stepping pan-tilt camera

Heavy imports stay inside functions; importing this package is cheap.
"""
