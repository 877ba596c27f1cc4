"""Range-beacon camera tracking (Yang et al. 2007): particle-filter SLAM with Map Adjustment.

- :mod:`engine.beacons.params`: the operator settings and the switches of the extensions.
- :mod:`engine.beacons.filter`: the filter (particles of 2(n + 1) states, eq. 9), composing
- :mod:`engine.beacons.likelihood`: range model eq. (8), weighting eq. (10);
- :mod:`engine.beacons.map_adjustment`: Map Adjustment eq. (12);
- :mod:`engine.beacons.startup`: initialisation (sec. III.B) and the multi-hypothesis
  bearing start-up;
- :mod:`engine.beacons.gauge`: gauge alignment of the estimate;
- :mod:`engine.beacons.cloud`: weighted cloud statistics, the Liu-West kernel move.
- :mod:`engine.beacons.simulator`: the paper's four-beacon studio and camera path, with
  range noise, dropouts and outliers.
- :mod:`engine.beacons.io`: beacon layouts (JSON/CSV), CSV range logs and the UDP listener.

Resampling is :func:`engine.particles.systematic_resample` (shared with the presenter).
"""
