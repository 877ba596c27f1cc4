"""Trajectory and box evaluation: TUM file I/O, association, ATE/RPE, OTB box metrics.

- :mod:`engine.evaluation.trajectory` - TUM trajectory files and timestamp association
- :mod:`engine.evaluation.metrics` - ATE and RPE as the TUM RGB-D benchmark defines them
- :mod:`engine.evaluation.boxes` - OTB box metrics (IoU, success AUC, precision at 20 px)
"""
