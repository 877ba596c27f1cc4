"""Operator settings of the beacon SLAM filter (Yang 2007) and the switches of its extensions.

Every field can change between steps (see :mod:`engine.trackers.beacon_slam` for when each
takes effect). :data:`EXTENSIONS` lists what goes beyond the paper, each with the overrides
that switch it off (the paper's behaviour for that part); they are the switches a
``preset=paper`` and an ablation over the extensions are built from.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import ClassVar

from engine.params import Params, Preset, param

#: the filter's extensions beyond the paper, each as the overrides that switch it off (the
#: paper's computation for that part); the functions they switch are named in the help
EXTENSIONS: Mapping[str, Preset] = MappingProxyType({
    "robust_weighting": Preset(
        "Gaussian/uniform mixture for eq. (8) and a consensus gate against outlier ranges "
        "(likelihood.range_log_likelihood, likelihood.consensus_inliers), re-initialising a "
        "beacon rejected 5 times in a row", outlier_prob=0.0),
    "map_spread_weighting": Preset(
        "eq. (10) integrated over the map cloud's spread along the line of sight "
        "(likelihood.marginal_range_sigma)", map_spread_weighting=False),
    "ring_startup": Preset(
        "multi-hypothesis bearing start-up of each beacon without a layout hint "
        "(startup.BearingRing)", ring_hypotheses=0),
    "gauge_alignment": Preset(
        "particles rotated/mirrored onto the previous map before averaging "
        "(gauge.gauge_rotations)", gauge_aligned_estimate=False),
    "liu_west_roughening": Preset(
        "Liu-West kernel move of the beacon states after resampling "
        "(cloud.liu_west_roughen)", roughen_h=0.0),
    "layout_hint": Preset(
        "initial beacon bearings drawn around the operator's layout (startup.point_bearings); "
        "off: only the layout's quadrants", hint_sigma_m=0.0),
    "kalman_map_adjustment": Preset(
        "each particle's beacon a Gaussian kernel moved and narrowed by a Kalman step "
        "(map_adjustment.kalman_map_adjustment), the weighting integrated over it",
        map_adjust_gain="fixed"),
    "annealed_map_adjustment": Preset(
        "Map Adjustment gain max(p, 1/(k+1)) (map_adjustment.annealed_gain); off by default",
        map_adjust_anneal=False),
    "beacon_jitter": Preset(
        "Gaussian jitter of the beacons after resampling; off by default", beacon_jitter_m=0.0),
    "ess_resampling": Preset(
        "resampling only below an effective sample size; off by default (the paper resamples "
        "every step)", resample_ess_fraction=1.0),
})


#: Map Adjustment gain p of the paper preset. The paper: "p is a parameter which must be
#: specified manually based on experiments" (sec. III.B, eq. 12). Chosen on training seeds
#: of the studio simulation split from those reported (``studiotrack bench beacon --tune-p``:
#: seeds 1000-1029, 200 particles, the p75 over seeds of path RMSE plus the p75 of the final
#: beacon error, after the best rotation/reflection about the start): 0.2 (0.01: 8.0 m,
#: 0.02: 7.6 m, 0.05: 7.8 m, 0.1: 7.2 m, 0.2: 5.9 m, 0.3: 6.5 m; without MA 8.8 m). The
#: default's 0.01 is confirmed the same way (0.89 m; 0.02: 0.98 m, 0.05: 1.02 m, 0.1:
#: 1.26 m; without MA 0.91 m) for the fixed gain; the default's 'kalman' gain has no p to
#: choose (p > 0 only switches it on): its kernel width ``kernel_frac`` 0.5 is chosen the same
#: way (0.09: 0.68 m, 0.25: 0.59 m, 0.5: 0.58 m, 1.0: 0.60 m; without MA 0.91 m).
PAPER_MAP_ADJUST_P = 0.2


def _paper_preset() -> Preset:
    """Every extension off (its :data:`EXTENSIONS` values), the paper's particle count and
    its Map Adjustment; see the preset's help for what the paper leaves open."""
    values: dict[str, object] = {}
    for ext in EXTENSIONS.values():
        values.update(ext.values)
    values.update(n_particles=200, map_adjustment=True, map_adjust_p=PAPER_MAP_ADJUST_P,
                  quadrant_init=True, known_beacons=False)
    return Preset(
        "Yang 2007 as published: 200 particles (fig. 8), Gaussian range model eq. (8) with "
        "each particle's point map in eq. (10), Map Adjustment eq. (12) with p = "
        f"{PAPER_MAP_ADJUST_P} (the paper: 'specified manually based on experiments'; ours "
        "chosen on training seeds), resampling every step, the first move in the quadrant "
        "the first two measurements point to; no extension. The paper gives no value for "
        "the motion and range std (kept as set) nor where on its first-range circle a "
        "beacon starts (here: uniformly in its layout quadrant)", **values)


@dataclass(frozen=True, slots=True)
class BeaconFilterParams(Params):
    """Operator settings of the beacon SLAM filter (all changeable between steps)."""

    n_particles: int = param(200, lo=2, hi=100000, step=50, help="number of particles M")
    motion_sigma_m: float = param(0.3, lo=0.0, hi=10.0, step=0.05,
                                  help="std of the 2D zero-mean Gaussian motion model per step "
                                  "(m)")
    range_sigma_m: float = param(0.3, lo=0.001, hi=10.0, step=0.05,
                                 help="std of the range noise w in eq. (8) used for weighting (m)")
    map_adjust_p: float = param(0.01, lo=0.0, hi=1.0, step=0.05,
                                help="Map Adjustment gain p of eq. (12): 0 off, 1 puts the "
                                "beacon on the range circle")
    map_adjustment: bool = param(True, help="apply Map Adjustment, eq. (12), each step")
    map_adjust_gain: str = param("kalman", choices=("fixed", "kalman"),
                                 help="Map Adjustment's gain: 'fixed' = p along the line of "
                                 "sight (eq. 12); 'kalman' (beyond the paper) = each "
                                 "particle's beacon a Gaussian kernel, moved by its Kalman "
                                 "gain and narrowed by each reading (FastSLAM-style; p "
                                 "only switches it on; map_spread_weighting then integrates "
                                 "over the particle's kernel)")
    kernel_frac: float = param(0.5, lo=0.0001, hi=1.0, step=0.01,
                               help="'kalman' gain: a new beacon's kernel covariance as this "
                               "fraction of its initial cloud's covariance (a kernel "
                               "bandwidth h^2)")
    map_adjust_anneal: bool = param(False,
                                    help="beyond the paper, with the 'fixed' gain: gain "
                                    "max(p, 1/(k+1)) for the k-th "
                                    "reading of a beacon, a running mean of the range circles "
                                    "that settles as the beacon is seen more")
    outlier_prob: float = param(0.05, lo=0.0, hi=0.9, step=0.01,
                                help="robust weighting: prior probability that a range is an "
                                "outlier (0 = plain Gaussian weighting and no outlier gate, as "
                                "in the paper)")
    outlier_gate_sigma: float = param(4.0, lo=1.0, hi=100.0, step=0.5,
                                      help="a reading whose median residual over particles "
                                      "exceeds this many predicted std is an outlier this step "
                                      "(robust mode only)")
    max_range_m: float = param(60.0, lo=1.0, hi=1000.0, step=5.0,
                               help="range span of the uniform outlier density (m)")
    hint_sigma_m: float = param(3.0, lo=0.0, hi=100.0, step=0.5,
                                help="how well the layout's beacon positions are known at start "
                                "(m): 0 uses only their quadrants (the paper); > 0 draws each "
                                "beacon's initial bearing around the layout bearing with this "
                                "spread")
    beacon_jitter_m: float = param(0.0, lo=0.0, hi=5.0, step=0.01,
                                   help="beyond the paper: std of the noise added to every "
                                   "particle's beacons after resampling (roughening against "
                                   "sample impoverishment; 0 = off)")
    map_spread_weighting: bool = param(True,
                                       help="eq. (10) integrates over each beacon's "
                                       "distribution: weight with sqrt(sigma_r^2 + the map "
                                       "cloud's variance along the line of sight) instead of "
                                       "each particle's point map (softer weights while the map "
                                       "is uncertain)")
    roughen_h: float = param(0.3, lo=0.0, hi=1.0, step=0.05,
                             help="beyond the paper: after resampling, Liu-West kernel move of "
                             "the beacon states, b <- a b + (1 - a) mean + h N(0, cov), a = "
                             "sqrt(1 - h^2): keeps the map cloud's mean and spread while making "
                             "duplicated particles distinct (0 = off)")
    ring_hypotheses: int = param(24, lo=0, hi=64, step=4,
                                 help="start-up without a layout hint (hint_sigma_m = 0): each "
                                 "particle keeps this many bearing hypotheses per beacon on its "
                                 "first-range circle (per 90 deg; a mixture weighted by Bayes, "
                                 "eq. 10) until one side dominates (0 = one point per beacon, "
                                 "the old start-up)")
    ring_commit: float = param(0.99, lo=0.5, hi=1.0, step=0.01,
                               help="a beacon's ring collapses to one point per particle once "
                               "the mean (over particles) weight of each particle's best "
                               "hypothesis reaches this")
    gauge_aligned_estimate: bool = param(True,
                                         help="without a layout hint (hint_sigma_m = 0) "
                                         "range-only data leave every particle's frame free to "
                                         "rotate/mirror about the start: rotate/mirror each "
                                         "particle's camera and map onto the previous estimate's "
                                         "map before averaging (the estimate only; the particles "
                                         "are unchanged)")
    known_beacons: bool = param(False,
                                help="beacons surveyed: use the layout as the map (localisation "
                                "only)")
    quadrant_init: bool = param(True,
                                help="initialise beacons/first move in the layout's quadrants "
                                "(sec. III.B)")
    resample_ess_fraction: float = param(1.0, lo=0.0, hi=1.0, step=0.05,
                                         help="resample when the effective sample size drops "
                                         "below this fraction of M (1 = every step, as in the "
                                         "paper)")
    seed: int = param(0, help="random seed of the filter (reproducible)")

    PRESETS: ClassVar[Mapping[str, Preset]] = MappingProxyType({"paper": _paper_preset()})
