"""Range-beacon camera tracking (Yang et al. 2007): particle-filter SLAM with Map Adjustment.

- :mod:`engine.beacons.model`: the filter (particles of 2(n + 1) states, eq. 9; range
  observation eq. 8; weighting eq. 10; Map Adjustment eq. 12; systematic resampling).
- :mod:`engine.beacons.simulator`: the paper's four-beacon studio and camera path, with
  range noise, dropouts and outliers.
- :mod:`engine.beacons.io`: beacon layouts (JSON/CSV), CSV range logs and the UDP listener.
"""
