"""A studio-like range-beacon simulation: a camera crane/dolly move in a 3D studio.

The paper's own simulation (sec. IV.C) moved a virtual camera in a Maya studio: "the initial
camera position [is] (0, 0, 4), and the Z axis is [constant]. The distance of [the] blue
screen from the camera is 20, and the distance of the character from the camera is 15"; the
filter is 2D (eq. 8: ranges in the floor plane). Here:

- **Studio** (:data:`STUDIO_BEACONS_XYZ`): floor x in [-12, 12] m, y in [-4, 20] m, the
  camera's start mark at the origin, the blue screen (back wall) at y = 20 m. Six beacons at
  different heights: four on the walls (2.2-4.5 m), one on the blue-screen wall, one on the
  lighting rig (7 m).
- **Camera move** (:func:`studio_camera_path`): 1.5 s on the start mark, then a dolly in
  towards the set, a crane up to 3.6 m arcing left over the set, down again and back near the
  start; smooth (a cubic Hermite curve through the way-points), at most 1.1 m/s, sampled at
  the ranging rate (10 Hz).
- **Ranging** (:class:`StudioRangingConfig`, defaults typical of UWB two-way ranging, preset
  ``ultrasonic``): 3D ranges with Gaussian noise; non-line-of-sight episodes (someone or
  something between camera and beacon, a two-state Markov chain per beacon) that lengthen the
  range by an exponential bias (multipath is never shorter than the direct path); bursty
  dropouts (a second Markov chain per beacon: blocked for a few readings) plus independent
  losses; no reading beyond ``max_range_m``. These are assumed typical figures, not a
  measured sensor.
- **Projection to the floor plane** (:func:`project_to_floor`), the paper's 2D model made
  explicit: ``d_floor = sqrt(d^2 - (z_beacon - z_camera)^2)`` with the surveyed beacon heights
  and the crane's height encoder, each known to ``height_sigma_m``. The filter reads
  ``d_floor``: the noise grows as ``d / d_floor`` for beacons nearly overhead.

Every run returns a :class:`~engine.beacons.simulator.SimRun` in the floor plane (what the 2D
filter and its evaluation use) inside a :class:`StudioRun` with the 3D truth and raw ranges.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from engine.beacons.simulator import SimRun
from engine.params import Params, Preset, param

F64 = NDArray[np.float64]
B = NDArray[np.bool_]

#: the studio's beacons (x, y, z) in metres, floor frame with the camera's start mark at the
#: origin, y towards the blue screen (back wall at y = 20 m), z up
STUDIO_BEACONS_XYZ: Mapping[str, tuple[float, float, float]] = MappingProxyType({
    "W1": (-8.0, 20.0, 3.0),   # blue-screen wall, left
    "W2": (9.0, 20.0, 4.5),    # blue-screen wall, right
    "W3": (-12.0, 6.0, 2.5),   # left wall
    "W4": (12.0, 10.0, 3.5),   # right wall
    "W5": (-4.0, -4.0, 2.2),   # front wall behind the cameras
    "R1": (3.0, 9.0, 7.0),     # lighting rig above the set
})

#: the camera move's way-points: (time s, x m, y m, z m) after the hold on the start mark
STUDIO_WAYPOINTS: tuple[tuple[float, float, float, float], ...] = (
    (0.0, 0.0, 0.0, 1.6),    # start mark, pedestal height
    (6.0, 1.5, 4.0, 1.6),    # dolly in
    (11.5, 3.5, 7.5, 2.2),   # crane starts rising
    (18.5, 0.5, 10.0, 3.6),  # crane up, arcing left over the set
    (25.0, -4.0, 8.0, 3.0),
    (30.0, -5.5, 3.5, 2.0),  # crane down, track back
    (34.0, -3.5, 2.0, 1.6),  # near the start again
)
HOLD_S = 1.5


def studio_layout_xy() -> dict[str, tuple[float, float]]:
    """The beacons' floor positions (x, y): the operator's layout of the studio."""
    return {k: (v[0], v[1]) for k, v in STUDIO_BEACONS_XYZ.items()}


def hermite_path(knots_t: F64, knots_xyz: F64, t: F64) -> F64:
    """Positions at times ``t`` on the cubic Hermite curve through the knots with
    Catmull-Rom tangents (zero at both ends: at rest), (len(t), 3)."""
    m = np.zeros_like(knots_xyz)
    m[1:-1] = (knots_xyz[2:] - knots_xyz[:-2]) / (knots_t[2:] - knots_t[:-2])[:, None]
    i = np.clip(np.searchsorted(knots_t, t, side="right") - 1, 0, len(knots_t) - 2)
    h = knots_t[i + 1] - knots_t[i]
    s = ((t - knots_t[i]) / h)[:, None]
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    return np.asarray(h00 * knots_xyz[i] + h10 * h[:, None] * m[i] + h01 * knots_xyz[i + 1]
                      + h11 * h[:, None] * m[i + 1], dtype=np.float64)


def studio_camera_path(rate_hz: float = 10.0, hold_s: float = HOLD_S) -> F64:
    """(T, 3) camera positions (x, y, z) at the ranging rate: the hold, then the crane move
    (a cubic Hermite curve through :data:`STUDIO_WAYPOINTS`, at rest at both ends)."""
    wp = np.asarray(STUDIO_WAYPOINTS, dtype=np.float64)
    n_hold = round(hold_s * rate_hz)
    t = np.arange(round(wp[-1, 0] * rate_hz) + 1) / rate_hz
    move = hermite_path(wp[:, 0], wp[:, 1:], t)
    return np.vstack([np.repeat(move[:1], n_hold, axis=0), move])


def project_to_floor(ranges_3d_m: F64, dz_m: F64) -> F64:
    """Eq. (8)'s planar range from a 3D range and the height difference beacon - camera:
    ``sqrt(max(d^2 - dz^2, 0))`` (NaN stays NaN)."""
    return np.sqrt(np.maximum(ranges_3d_m**2 - dz_m**2, 0.0))


@dataclass(frozen=True, slots=True)
class StudioRangingConfig(Params):
    """Range sensor of the studio simulation (defaults: typical UWB two-way ranging)."""

    rate_hz: float = param(10.0, lo=1.0, hi=200.0, help="ranging rate = filter steps per s")
    noise_sigma_m: float = param(0.08, lo=0.0, hi=2.0, help="line-of-sight range noise std")
    nlos_enter_prob: float = param(0.01, lo=0.0, hi=1.0,
                                   help="per reading: a clear line of sight becomes blocked")
    nlos_exit_prob: float = param(0.1, lo=0.0, hi=1.0,
                                  help="per reading: a blocked line of sight clears")
    nlos_bias_mean_m: float = param(0.4, lo=0.0, hi=10.0,
                                    help="mean of the exponential extra length of a blocked "
                                    "(multipath) range")
    burst_enter_prob: float = param(0.02, lo=0.0, hi=1.0,
                                    help="per reading: a beacon starts a dropout burst")
    burst_exit_prob: float = param(0.25, lo=0.0, hi=1.0,
                                   help="per reading: a dropout burst ends")
    dropout_prob: float = param(0.02, lo=0.0, hi=1.0, help="independent loss of a reading")
    max_range_m: float = param(30.0, lo=0.1, hi=1000.0, help="no reading beyond this range")
    height_sigma_m: float = param(0.02, lo=0.0, hi=1.0,
                                  help="error of the surveyed beacon heights and of the "
                                  "crane's height encoder used for the floor projection")
    seed: int = param(0, help="random seed")

    PRESETS: ClassVar[Mapping[str, Preset]] = MappingProxyType({
        "ultrasonic": Preset(
            "ultrasonic ranging: finer noise, more reflections and losses, shorter reach",
            noise_sigma_m=0.02, nlos_enter_prob=0.02, nlos_exit_prob=0.15,
            nlos_bias_mean_m=0.3, burst_enter_prob=0.03, dropout_prob=0.05,
            max_range_m=20.0),
    })


@dataclass(frozen=True, slots=True)
class StudioRun:
    """A simulated studio run: ``floor`` (what the 2D filter reads and is scored against),
    the 3D truth, the raw 3D ranges and which readings were non-line-of-sight."""

    floor: SimRun
    beacons_xyz: F64  # (n, 3)
    path_xyz: F64  # (T, 3)
    ranges_3d_m: F64  # (T, n), NaN = missing
    nlos: B  # (T, n) reading taken while the line of sight was blocked


def _markov_states(rng: np.random.Generator, shape: tuple[int, int], p_enter: float,
                   p_exit: float) -> B:
    """(T, n) two-state Markov chains per column starting in the stationary distribution."""
    t_n, n = shape
    u = rng.random(shape)
    p_on = p_enter / (p_enter + p_exit) if p_enter + p_exit > 0 else 0.0
    out = np.zeros(shape, dtype=bool)
    state = rng.random(n) < p_on
    for t in range(t_n):
        state = np.where(state, u[t] >= p_exit, u[t] < p_enter)
        out[t] = state
    return out


def simulate_studio(config: StudioRangingConfig | None = None,
                    beacons_xyz: Mapping[str, tuple[float, float, float]] | None = None
                    ) -> StudioRun:
    """Ranges from every beacon along :func:`studio_camera_path`, projected to the floor."""
    cfg = config or StudioRangingConfig()
    lay = dict(beacons_xyz if beacons_xyz is not None else STUDIO_BEACONS_XYZ)
    ids = tuple(lay)
    bxyz = np.array([lay[i] for i in ids], dtype=np.float64).reshape(len(ids), 3)
    path = studio_camera_path(cfg.rate_hz)
    rng = np.random.default_rng(cfg.seed)
    shape = (len(path), len(ids))
    true3 = np.linalg.norm(bxyz[None, :, :] - path[:, None, :], axis=2)
    nlos = _markov_states(rng, shape, cfg.nlos_enter_prob, cfg.nlos_exit_prob)
    bias = rng.exponential(max(cfg.nlos_bias_mean_m, 1e-12), shape) * nlos
    r3 = true3 + rng.normal(0.0, cfg.noise_sigma_m, shape) + bias
    lost = (_markov_states(rng, shape, cfg.burst_enter_prob, cfg.burst_exit_prob)
            | (rng.random(shape) < cfg.dropout_prob) | (true3 > cfg.max_range_m))
    r3 = np.where(lost, np.nan, np.maximum(r3, 0.0))
    # floor projection with the surveyed beacon heights and the crane's height encoder
    z_beacon = bxyz[:, 2] + rng.normal(0.0, cfg.height_sigma_m, len(ids))
    z_cam = path[:, 2] + rng.normal(0.0, cfg.height_sigma_m, len(path))
    floor = project_to_floor(r3, z_beacon[None, :] - z_cam[:, None])
    run = SimRun(ids=ids, beacons_xy=bxyz[:, :2].copy(), path_xy=path[:, :2].copy(),
                 ranges_m=floor, outlier_mask=nlos & ~lost)
    for a in (run.beacons_xy, run.path_xy, run.ranges_m, run.outlier_mask, bxyz, path, r3):
        a.flags.writeable = False
    nl = nlos & ~lost
    nl.flags.writeable = False
    return StudioRun(floor=run, beacons_xyz=bxyz, path_xyz=path, ranges_3d_m=r3, nlos=nl)
