"""Range-only particle-filter SLAM for 2D camera tracking (Yang, Wu, Moniri, Chibelushi 2007).

Each particle holds 2(n + 1) states, the camera position and n beacon ("feature") positions,
eq. (9)::

    x_t^m = (s_t^m, f_1,t^m, ..., f_n,t^m) = ((x, y)_t^m, (x, y)_1,t^m, ..., (x, y)_n,t^m)

One iteration (sec. III.B, fig. 5): motion model (2D zero-mean Gaussian on the camera),
weighting with the range observation model of eq. (8)::

    d = g(f, s) = sqrt((x_f - x_s)^2 + (y_f - y_s)^2) + w,   w ~ N(0, sigma_r^2)

(eq. (10) with each particle's point estimate of every beacon, so the integral over f_n is
the likelihood at that point), Map Adjustment, eq. (12), which moves every particle's beacon
estimate along the line through its camera so that the predicted range d' approaches the
measured d::

    movement = p * (d - d') / r        applied to the vector (f - s), r = |f - s| = d'

i.e. a step of length p * (d - d') along the unit vector from camera to beacon (p = 1 puts the
beacon on the measured circle), then normalisation and systematic resampling.

Initialisation (sec. III.B): the camera starts at the origin (the paper's assumption); the
first measurement puts each beacon on the circle of the measured radius. The paper's text on
the remaining ambiguity is about the *camera*: it uses "the first two measurements to obtain a
rough idea of where the next location states should be, i.e. in which quadrant the state is.
Then a random point is chosen in that quadrant to be the next location state" -- that is
:meth:`BeaconSlamFilter._first_move_quadrant` (the range changes between the first two
measurements, read against the beacons' bearings, give the signs of the first move). It says
nothing about where on its circle each beacon starts. Range-only data fix the map only up to
a rotation/reflection about the start, so something must choose the frame: here the
operator's rough layout does. With ``hint_sigma_m = 0`` (setting A of ``bench beacon``) only
each beacon's *quadrant* as seen from the start is used (our reading; the paper's own frame
choice is not described); the default ``hint_sigma_m = 3`` draws each beacon's initial bearing
around the layout's bearing with a 3 m spread at its range (a layout known to a few metres),
which fixes the frame; the beacon positions are still estimated. Without any layout beacons
start on the whole circle and the map comes out in an arbitrary rotation/reflection.

Start-up ambiguity (``hint_sigma_m = 0``): while the camera moves on a straight line, a beacon
and its mirror image about that line give identical ranges, so every beacon has two equally
good positions until the path turns (the paper's path turns at step ~20). The first version
drew one point per beacon per particle; weighting, resampling and the Liu-West shrinkage to
the cloud's mean then settled every particle on the *middle* of the two modes (all beacons
near 45 deg by step 10, beacon B(22, 0) ending near 50 deg, shape error ~6 m) and it never
left. Now each particle keeps, per beacon, a :class:`BearingRing`: ``ring_hypotheses`` bearings
per 90 deg on its first-range circle (a stratified grid with a random offset per particle),
weighted by Bayes with the range likelihood (eq. 10 with the particle's beacon distribution a
mixture: the particle's weight is the mixture likelihood, the hypotheses' weights are its
posterior; Map Adjustment, eq. 12, moves every hypothesis). Both mirror modes survive the
straight leg; after the turn the wrong one loses, and once the particles are sure (mean weight
of each particle's best hypothesis >= ``ring_commit``) the ring collapses to one point per
particle (drawn by weight) and the point filter below takes over. Because nothing fixes each
particle's rotation/mirror about the start in this setting, particles in different frames
would be averaged into a too-short, blurred path; ``gauge_aligned_estimate`` rotates/mirrors
each particle onto the previous estimate's map before averaging (the estimate only). Bench
(30 seeds, 200 particles, with MA, after the best rotation/mirror): path RMSE 0.98 -> 0.58 m,
final beacon error 6.1 -> 1.0 m.

Against particle collapse (the first version's map froze after a few steps: beacon spread
1-12 cm while the real error was 0.5-4 m, and the error grew over the run): eq. (10) is
implemented as written, i.e. the range likelihood is *integrated over the beacon's
distribution* (the map cloud's spread along the line of sight is added to sigma_r, see
:func:`marginal_range_sigma`) instead of being taken at each particle's point map, and after
resampling the beacon states get a Liu-West kernel move (:func:`liu_west_roughen`), noise
proportional to the cloud's own spread that keeps its mean and covariance. With both, the map
keeps improving as the camera moves (``bench beacon``: final beacon error 1.7 -> 0.6 m with the
3 m layout hint). Range-only data do not observe a common rotation/translation of camera and
map, so the absolute path error still grows slowly with the distance from the start while the
shape (path after rotation about the start) stays at ~0.25 m.

Beyond the paper: readings may be missing per step (only the beacons read are weighted and
adjusted); robust weighting (Gaussian/uniform mixture, plus a consensus gate that keeps
gross outliers out of Map Adjustment); a known-beacon mode (pure localisation) for surveyed
studios; and a live-changeable particle count (resampled to the new size).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from engine.errors import ParamsError

F64 = NDArray[np.float64]

#: consecutive outlier rejections after which a beacon is re-initialised (robust mode)
REINIT_AFTER = 5


@dataclass(frozen=True, slots=True)
class BeaconFilterParams:
    """Operator settings of the beacon SLAM filter (all changeable between steps)."""

    n_particles: int = field(
        default=200,
        metadata={"help": "number of particles M", "min": 2, "max": 100000, "step": 50},
    )
    motion_sigma_m: float = field(
        default=0.3,
        metadata={
            "help": "std of the 2D zero-mean Gaussian motion model per step (m)",
            "min": 0.0,
            "max": 10.0,
            "step": 0.05,
        },
    )
    range_sigma_m: float = field(
        default=0.3,
        metadata={
            "help": "std of the range noise w in eq. (8) used for weighting (m)",
            "min": 0.001,
            "max": 10.0,
            "step": 0.05,
        },
    )
    map_adjust_p: float = field(
        default=0.01,
        metadata={
            "help": "Map Adjustment gain p of eq. (12): 0 off, 1 puts the beacon on the range "
            "circle",
            "min": 0.0,
            "max": 1.0,
            "step": 0.05,
        },
    )
    map_adjustment: bool = field(
        default=True, metadata={"help": "apply Map Adjustment, eq. (12), each step"}
    )
    map_adjust_anneal: bool = field(
        default=False,
        metadata={
            "help": "beyond the paper: gain max(p, 1/(k+1)) for the k-th reading of a beacon, "
            "a running mean of the range circles that settles as the beacon is seen more"
        },
    )
    outlier_prob: float = field(
        default=0.05,
        metadata={
            "help": "robust weighting: prior probability that a range is an outlier "
            "(0 = plain Gaussian weighting and no outlier gate, as in the paper)",
            "min": 0.0,
            "max": 0.9,
            "step": 0.01,
        },
    )
    outlier_gate_sigma: float = field(
        default=4.0,
        metadata={
            "help": "a reading whose median residual over particles exceeds this many "
            "predicted std is an outlier this step (robust mode only)",
            "min": 1.0,
            "max": 100.0,
            "step": 0.5,
        },
    )
    max_range_m: float = field(
        default=60.0,
        metadata={"help": "range span of the uniform outlier density (m)", "min": 1.0,
                  "max": 1000.0, "step": 5.0},
    )
    hint_sigma_m: float = field(
        default=3.0,
        metadata={
            "help": "how well the layout's beacon positions are known at start (m): 0 uses "
            "only their quadrants (the paper); > 0 draws each beacon's initial bearing "
            "around the layout bearing with this spread",
            "min": 0.0,
            "max": 100.0,
            "step": 0.5,
        },
    )
    beacon_jitter_m: float = field(
        default=0.0,
        metadata={
            "help": "beyond the paper: std of the noise added to every particle's beacons "
            "after resampling (roughening against sample impoverishment; 0 = off)",
            "min": 0.0,
            "max": 5.0,
            "step": 0.01,
        },
    )
    map_spread_weighting: bool = field(
        default=True,
        metadata={
            "help": "eq. (10) integrates over each beacon's distribution: weight with "
            "sqrt(sigma_r^2 + the map cloud's variance along the line of sight) instead of "
            "each particle's point map (softer weights while the map is uncertain)"
        },
    )
    roughen_h: float = field(
        default=0.3,
        metadata={
            "help": "beyond the paper: after resampling, Liu-West kernel move of the beacon "
            "states, b <- a b + (1 - a) mean + h N(0, cov), a = sqrt(1 - h^2): keeps the map "
            "cloud's mean and spread while making duplicated particles distinct (0 = off)",
            "min": 0.0,
            "max": 1.0,
            "step": 0.05,
        },
    )
    ring_hypotheses: int = field(
        default=24,
        metadata={
            "help": "start-up without a layout hint (hint_sigma_m = 0): each particle keeps "
            "this many bearing hypotheses per beacon on its first-range circle (per 90 deg; "
            "a mixture weighted by Bayes, eq. 10) until one side dominates (0 = one point "
            "per beacon, the old start-up)",
            "min": 0,
            "max": 64,
            "step": 4,
        },
    )
    ring_commit: float = field(
        default=0.99,
        metadata={
            "help": "a beacon's ring collapses to one point per particle once the mean (over "
            "particles) weight of each particle's best hypothesis reaches this",
            "min": 0.5,
            "max": 1.0,
            "step": 0.01,
        },
    )
    gauge_aligned_estimate: bool = field(
        default=True,
        metadata={
            "help": "without a layout hint (hint_sigma_m = 0) range-only data leave every "
            "particle's frame free to rotate/mirror about the start: rotate/mirror each "
            "particle's camera and map onto the previous estimate's map before averaging "
            "(the estimate only; the particles are unchanged)"
        },
    )
    known_beacons: bool = field(
        default=False,
        metadata={"help": "beacons surveyed: use the layout as the map (localisation only)"},
    )
    quadrant_init: bool = field(
        default=True,
        metadata={"help": "initialise beacons/first move in the layout's quadrants (sec. III.B)"},
    )
    resample_ess_fraction: float = field(
        default=1.0,
        metadata={
            "help": "resample when the effective sample size drops below this fraction of M "
            "(1 = every step, as in the paper)",
            "min": 0.0,
            "max": 1.0,
            "step": 0.05,
        },
    )
    seed: int = field(default=0, metadata={"help": "random seed of the filter (reproducible)"})

    def __post_init__(self) -> None:
        if not 2 <= int(self.n_particles) <= 100000:
            raise ParamsError(f"n_particles must be in [2, 100000], got {self.n_particles}")
        checks = {
            "motion_sigma_m": (self.motion_sigma_m, 0.0, 10.0),
            "range_sigma_m": (self.range_sigma_m, 1e-3, 10.0),
            "map_adjust_p": (self.map_adjust_p, 0.0, 1.0),
            "outlier_prob": (self.outlier_prob, 0.0, 0.9),
            "outlier_gate_sigma": (self.outlier_gate_sigma, 1.0, 100.0),
            "max_range_m": (self.max_range_m, 1.0, 1000.0),
            "hint_sigma_m": (self.hint_sigma_m, 0.0, 100.0),
            "beacon_jitter_m": (self.beacon_jitter_m, 0.0, 5.0),
            "resample_ess_fraction": (self.resample_ess_fraction, 0.0, 1.0),
            "roughen_h": (self.roughen_h, 0.0, 1.0),
            "ring_commit": (self.ring_commit, 0.5, 1.0),
        }
        for name, (v, lo, hi) in checks.items():
            if not (math.isfinite(v) and lo <= v <= hi):
                raise ParamsError(f"{name} must be in [{lo}, {hi}], got {v}")
        if not 0 <= int(self.ring_hypotheses) <= 64:
            raise ParamsError(f"ring_hypotheses must be in [0, 64], got {self.ring_hypotheses}")


@dataclass(frozen=True, slots=True)
class FilterEstimate:
    """Weighted-mean camera and map with their spread after one step."""

    step: int  # 0 = initialisation; -1 = no valid reading yet (the filter has not started)
    cam_xy: F64  # (2,)
    cam_cov: F64  # (2, 2)
    beacons_xy: F64  # (n, 2), NaN for beacons never read
    beacons_cov: F64  # (n, 2, 2)
    used: NDArray[np.bool_]  # (n,) readings used for weighting this step
    outliers: NDArray[np.bool_]  # (n,) readings rejected as outliers this step
    ess: float  # effective sample size before resampling
    residual_rms_m: float  # weighted RMS of (d - d') over used readings, before Map Adjustment

    def __post_init__(self) -> None:
        for a in (self.cam_xy, self.cam_cov, self.beacons_xy, self.beacons_cov, self.used,
                  self.outliers):
            a.flags.writeable = False


def predicted_ranges(cam_xy: F64, beacons_xy: F64) -> F64:
    """Eq. (8) without noise: distance from each particle's camera to its beacons.

    ``cam_xy`` (M, 2), ``beacons_xy`` (M, k, 2) -> (M, k).
    """
    return np.hypot(beacons_xy[..., 0] - cam_xy[:, None, 0],
                    beacons_xy[..., 1] - cam_xy[:, None, 1])


def range_log_likelihood(
    residual_m: F64, sigma_m: float | F64, outlier_prob: float = 0.0, max_range_m: float = 60.0
) -> F64:
    """Log-likelihood of range residuals d - d' under w ~ N(0, sigma^2) of eq. (8).

    With ``outlier_prob`` > 0 the density is the robust mixture
    ``(1 - e) N(r; 0, sigma^2) + e / max_range`` so that one wild reading cannot zero a
    particle's weight.
    """
    gauss = -0.5 * (residual_m / sigma_m) ** 2 - np.log(math.sqrt(2.0 * math.pi) * sigma_m)
    if outlier_prob <= 0.0:
        return gauss
    return np.logaddexp(
        gauss + math.log1p(-outlier_prob), math.log(outlier_prob / max_range_m)
    )


def normalise_log_weights(log_w: F64) -> F64:
    """Normalise weights so they sum to 1 (sec. III.B), stable for very small likelihoods."""
    w = np.exp(log_w - np.max(log_w))
    return w / np.sum(w)


def systematic_resample(weights: F64, n_out: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """Indices of ``n_out`` particles drawn by systematic (low-variance) resampling.

    Particles with large weight are duplicated, small ones dropped (sec. III.B); the expected
    number of copies of particle m is ``n_out * weights[m]``.
    """
    positions = (rng.random() + np.arange(n_out)) / n_out
    cum = np.cumsum(weights)
    cum[-1] = 1.0
    return np.searchsorted(cum, positions, side="right").clip(0, len(weights) - 1)


def map_adjustment(
    cam_xy: F64, beacons_xy: F64, measured_m: F64, p: float | F64
) -> F64:
    """Eq. (12): move each beacon estimate along the camera->beacon line by p (d - d').

    ``cam_xy`` (M, 2), ``beacons_xy`` (M, k, 2), ``measured_m`` (k,) -> adjusted (M, k, 2).
    movement = p (d - d') / r applied to (f - s), with r = d' = |f - s|.
    """
    diff = beacons_xy - cam_xy[:, None, :]
    r = np.hypot(diff[..., 0], diff[..., 1])
    scale = np.asarray(p) * (measured_m[None, :] - r) / np.maximum(r, 1e-9)
    return beacons_xy + scale[:, :, None] * diff


def weighted_mean_cov(x: F64, w: F64) -> tuple[F64, F64]:
    """Weighted mean and covariance of samples ``x`` (M, ..., 2) with weights (M,)."""
    m = x.shape[0]
    flat = x.reshape(m, -1, x.shape[-1])  # (M, K, 2)
    mean = w @ flat.reshape(m, -1)
    mean = mean.reshape(flat.shape[1:])
    d = flat - mean
    cov = np.matmul((d * w[:, None, None]).transpose(1, 2, 0), d.transpose(1, 0, 2))
    return mean.reshape(x.shape[1:]), cov.reshape(*x.shape[1:], x.shape[-1])


def marginal_range_sigma(cam_xy: F64, beacons_xy: F64, weights: F64, sigma_m: float) -> F64:
    """Std of d - d' with the beacon integrated out, eq. (10).

    Eq. (10) weights a particle by the range likelihood integrated over the beacon's
    distribution, not at a point. With the map cloud's weighted covariance ``C`` of each
    beacon as that distribution, linearised along each particle's line of sight ``u``, the
    integral is a Gaussian of variance ``sigma_m^2 + u^T C u``: weights stay soft while the map
    is uncertain along the line of sight (no collapse onto a lucky map) and sharpen as it
    converges. ``cam_xy`` (M, 2), ``beacons_xy`` (M, k, 2), ``weights`` (M,) -> (M, k).
    """
    _, cov = weighted_mean_cov(beacons_xy, weights)  # (k, 2, 2)
    u = beacons_xy - cam_xy[:, None, :]
    u = u / np.maximum(np.hypot(u[..., 0], u[..., 1])[..., None], 1e-9)
    var = (u[..., 0] ** 2 * cov[None, :, 0, 0] + 2.0 * u[..., 0] * u[..., 1] * cov[None, :, 0, 1]
           + u[..., 1] ** 2 * cov[None, :, 1, 1])
    return np.sqrt(sigma_m**2 + np.maximum(var, 0.0))


def liu_west_roughen(x: F64, weights: F64, h: float, rng: np.random.Generator) -> F64:
    """Kernel move of resampled states ``x`` (M, k, 2) (Liu & West 2001 shrinkage).

    ``x <- a x + (1 - a) mean + h N(0, cov)`` with ``a = sqrt(1 - h^2)`` per 2D block: the
    weighted mean and covariance of the cloud are kept, but duplicated particles become
    distinct, so the map keeps exploring instead of collapsing onto a few resampled copies
    (sample impoverishment). The noise scales with the cloud's own spread: it shrinks as the
    map converges.
    """
    mean, cov = weighted_mean_cov(x, weights)  # (k, 2), (k, 2, 2)
    a = math.sqrt(1.0 - h * h)
    L = np.linalg.cholesky(cov + 1e-12 * np.eye(2))
    z = rng.standard_normal(x.shape)
    noise = np.einsum("kij,mkj->mki", L, z)
    return a * x + (1.0 - a) * mean[None] + h * noise


def _quadrant_range(angle_rad: float) -> tuple[float, float]:
    q = math.floor((angle_rad % (2 * math.pi)) / (math.pi / 2))
    return q * math.pi / 2, (q + 1) * math.pi / 2


@dataclass(slots=True)
class BearingRing:
    """One beacon's start-up mixture in every particle: K bearing hypotheses on the circle of
    the first measured range around that particle's camera, with per-particle log-weights.

    ``hyp`` (M, K, 2) points, ``log_w`` (M, K) normalised per particle, ``centre`` (M, 2) the
    camera at initialisation, ``var_t`` the tangential variance one hypothesis stands for
    ((r * spacing)^2 / 12: each is the centre of a bearing cell of that width).
    """

    hyp: F64
    log_w: F64
    centre: F64
    var_t: float

    def take(self, idx: NDArray[np.intp]) -> None:
        self.hyp, self.log_w, self.centre = self.hyp[idx], self.log_w[idx], self.centre[idx]

    def prune(self, min_weight: float = 1e-6) -> None:
        """Drop hypothesis columns below ``min_weight`` in every particle (speed only: the
        mass dropped is at most K * min_weight per particle), renormalise."""
        keep = np.max(self.log_w, axis=0) > math.log(min_weight)
        if keep.all() or not keep.any():
            return
        self.hyp = self.hyp[:, keep]
        lw = self.log_w[:, keep]
        self.log_w = lw - _logsumexp_rows(lw)[:, None]


def ring_log_likelihood(
    cam_xy: F64, ring: BearingRing, measured_m: float, sigma_m: float,
    outlier_prob: float = 0.0, max_range_m: float = 60.0,
) -> F64:
    """Log-likelihood (M, K) of one range for every hypothesis of a :class:`BearingRing`.

    A hypothesis stands for a bearing cell: its tangential spread changes the range seen from
    the camera by ``sin(alpha)`` times the offset, alpha the angle at the hypothesis between
    the directions to the ring's centre and to the camera (0 on the line through the centre,
    where the cell's width does not matter), so its variance ``var_t sin^2(alpha)`` is added
    to ``sigma_m^2``.
    """
    to_cam = cam_xy[:, None, :] - ring.hyp
    to_c = ring.centre[:, None, :] - ring.hyp
    r_cam = np.hypot(to_cam[..., 0], to_cam[..., 1])
    r_c = np.maximum(np.hypot(to_c[..., 0], to_c[..., 1]), 1e-9)
    sin_a = (to_cam[..., 0] * to_c[..., 1] - to_cam[..., 1] * to_c[..., 0]) / (
        np.maximum(r_cam, 1e-9) * r_c)
    sig = np.sqrt(sigma_m**2 + ring.var_t * sin_a**2)
    return range_log_likelihood(measured_m - r_cam, sig, outlier_prob, max_range_m)


def _logsumexp_rows(x: F64) -> F64:
    mx = np.max(x, axis=1)
    return mx + np.log(np.sum(np.exp(x - mx[:, None]), axis=1))


def trilaterate(
    beacons_xy: F64, ranges_m: F64, guess_xy: F64, iterations: int = 10
) -> F64 | None:
    """Gauss-Newton least-squares position from >= 3 known beacons (None if degenerate)."""
    if len(ranges_m) < 3:
        return None
    x = np.array(guess_xy, dtype=np.float64)
    for _ in range(iterations):
        diff = x[None, :] - beacons_xy
        r = np.maximum(np.linalg.norm(diff, axis=1), 1e-9)
        J = diff / r[:, None]
        res = ranges_m - r
        try:
            dx, *_ = np.linalg.lstsq(J, res, rcond=None)
        except np.linalg.LinAlgError:
            return None
        x = x + dx
        if float(np.linalg.norm(dx)) < 1e-6:
            break
    return x if np.all(np.isfinite(x)) else None


class BeaconSlamFilter:
    """The particle filter of sec. III, vectorised over particles with numpy.

    ``beacon_ids`` fixes the order of the n beacons; ``layout_xy`` (optional) is the
    operator's layout: only its quadrants are used in SLAM mode, its coordinates are the map
    in known-beacon mode. Call :meth:`step` once per time step with one range per beacon
    (NaN where missing).
    """

    def __init__(
        self,
        beacon_ids: Sequence[str],
        params: BeaconFilterParams | None = None,
        *,
        layout_xy: Mapping[str, Sequence[float]] | None = None,
        start_xy: Sequence[float] = (0.0, 0.0),
        seed: int | None = None,
    ) -> None:
        if len(beacon_ids) == 0:
            raise ParamsError("beacon SLAM needs at least one beacon id")
        if len(set(beacon_ids)) != len(beacon_ids):
            raise ParamsError(f"beacon ids must be unique, got {list(beacon_ids)}")
        self.ids: tuple[str, ...] = tuple(beacon_ids)
        self.n = len(self.ids)
        self.params = params or BeaconFilterParams()
        layout = dict(layout_xy or {})
        self.layout_xy = np.array(
            [layout.get(i, (math.nan, math.nan)) for i in self.ids], dtype=np.float64
        ).reshape(self.n, 2)
        self.start_xy = np.asarray(start_xy, dtype=np.float64).reshape(2)
        self._has_layout = bool(np.any(np.all(np.isfinite(self.layout_xy), axis=1)))
        self.seed = int(self.params.seed if seed is None else seed)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget everything; the next step re-initialises."""
        self.rng = np.random.default_rng(self.seed)
        self.t = 0
        m = int(self.params.n_particles)
        self.cam = np.tile(self.start_xy, (m, 1))
        self.beacons = np.full((m, self.n, 2), np.nan)
        self.known = np.zeros(self.n, dtype=bool)  # beacon initialised (read at least once)
        self.weights = np.full(m, 1.0 / m)
        self.first_ranges = np.full(self.n, np.nan)
        self.n_reads = np.zeros(self.n)  # readings used per beacon (annealed Map Adjustment)
        self.n_rejected = np.zeros(self.n, dtype=np.int64)  # consecutive outlier flags
        self.rings: dict[int, BearingRing] = {}  # beacons still multi-modal (start-up)
        self.gauge_ref = np.full((self.n, 2), np.nan)  # last estimate's map (gauge alignment)
        self.last: FilterEstimate | None = None

    def set_params(self, params: BeaconFilterParams) -> None:
        """New settings; a new particle count takes effect by resampling at the next step."""
        self.params = params

    @property
    def n_particles(self) -> int:
        return int(self.cam.shape[0])

    def _hint_angle(self, i: int, centre_xy: F64) -> tuple[float, float] | None:
        """Angle interval of beacon i's quadrant seen from ``centre_xy`` (None: no hint)."""
        if not self.params.quadrant_init or not np.all(np.isfinite(self.layout_xy[i])):
            return None
        d = self.layout_xy[i] - centre_xy
        return _quadrant_range(math.atan2(d[1], d[0]))

    def _init_beacon(self, i: int, r: float) -> None:
        """Put beacon i on the circle of radius r around each particle's camera (sec. III.B).

        The bearing is drawn in the layout's quadrant (or around the layout bearing with
        ``hint_sigma_m``); a beacon re-initialised after repeated outliers keeps each
        particle's previous bearing; with no hint at all, anywhere on the circle.
        """
        m = self.n_particles
        p = self.params
        if p.known_beacons and np.all(np.isfinite(self.layout_xy[i])):
            self.beacons[:, i, :] = self.layout_xy[i]
            self.known[i] = True
            return
        prev = self.beacons[:, i, :] - self.cam
        centre = np.average(self.cam, axis=0, weights=self.weights)
        span = self._hint_angle(i, centre)
        self.rings.pop(i, None)
        if (not np.all(np.isfinite(prev)) and p.ring_hypotheses > 0
                and (span is None or p.hint_sigma_m <= 0.0)):
            self._init_ring(i, r, span)
            return
        if np.all(np.isfinite(prev)):
            spread = max(p.hint_sigma_m, p.range_sigma_m) / max(r, 1e-3)
            theta = np.arctan2(prev[:, 1], prev[:, 0]) + self.rng.normal(0.0, spread, m)
        elif span is not None and p.hint_sigma_m > 0.0:
            d = self.layout_xy[i] - centre
            theta = math.atan2(d[1], d[0]) + self.rng.normal(0.0, p.hint_sigma_m / max(r, 1e-3), m)
        else:
            lo, hi = span if span is not None else (0.0, 2 * math.pi)
            theta = self.rng.uniform(lo, hi, m)
        rad = np.maximum(r + self.rng.normal(0.0, p.range_sigma_m, m), 0.0)
        self.beacons[:, i, 0] = self.cam[:, 0] + rad * np.cos(theta)
        self.beacons[:, i, 1] = self.cam[:, 1] + rad * np.sin(theta)
        self.known[i] = True

    def _init_ring(self, i: int, r: float, span: tuple[float, float] | None) -> None:
        """Multi-hypothesis start-up of beacon i (sec. III.B's first-range circle, kept
        multi-modal): K bearings per particle (a stratified grid with a random offset per
        particle, inside the layout's quadrant if any, else the whole circle), equal weights.
        Range-only data along a straight path cannot tell a beacon from its mirror image about
        the path line; the mixture keeps both until the path turns (eq. 10 integrates over it).
        """
        p = self.params
        m = self.n_particles
        lo, hi = span if span is not None else (0.0, 2 * math.pi)
        k = max(2, round(p.ring_hypotheses * (hi - lo) / (math.pi / 2)))
        spacing = (hi - lo) / k
        theta = lo + (np.arange(k)[None, :] + self.rng.random((m, 1))) * spacing
        rad = np.maximum(r + self.rng.normal(0.0, p.range_sigma_m, (m, 1)), 0.0)
        hyp = self.cam[:, None, :] + rad[..., None] * np.stack(
            [np.cos(theta), np.sin(theta)], axis=-1)
        self.rings[i] = BearingRing(hyp=hyp, log_w=np.full((m, k), -math.log(k)),
                                    centre=self.cam.copy(), var_t=(r * spacing) ** 2 / 12.0)
        self._ring_sample(i)
        self.known[i] = True

    def _ring_sample(self, i: int) -> None:
        """Each particle's beacon i := one hypothesis drawn by its weight (a sample of the
        particle's mixture; what the outlier gate and the first-move quadrant see)."""
        ring = self.rings[i]
        w = np.exp(ring.log_w)
        cum = np.cumsum(w, axis=1)
        u = self.rng.random(cum.shape[0]) * cum[:, -1]
        k = np.minimum(np.sum(cum < u[:, None], axis=1), cum.shape[1] - 1)
        self.beacons[:, i, :] = ring.hyp[np.arange(cum.shape[0]), k]

    def _commit_rings(self) -> None:
        """Collapse a ring to one point per particle once each particle is sure of its side."""
        for i in list(self.rings):
            conf = float(self.weights @ np.exp(np.max(self.rings[i].log_w, axis=1)))
            if conf >= self.params.ring_commit:
                self._ring_sample(i)
                del self.rings[i]

    def _gauge_free(self) -> bool:
        p = self.params
        return bool(p.gauge_aligned_estimate and not p.known_beacons and (
            p.hint_sigma_m <= 0.0 or not self._has_layout))

    def _gauge_rotations(self) -> F64 | None:
        """Per-particle 2x2 rotation or reflection about the start that best maps the
        particle's map onto the previous estimate's (None: gauge fixed by the layout hint, or
        nothing to align on). Ring beacons count with the particle's mixture mean."""
        if not self._gauge_free():
            return None
        ok = self.known & np.all(np.isfinite(self.gauge_ref), axis=1)
        if not np.any(ok):
            return None
        reps = self.beacons[:, ok, :] - self.start_xy
        for j, i in enumerate(np.flatnonzero(ok)):
            ring = self.rings.get(int(i))
            if ring is not None:
                w = np.exp(ring.log_w)
                reps[:, j, 0] = np.sum(w * ring.hyp[..., 0], axis=1) - self.start_xy[0]
                reps[:, j, 1] = np.sum(w * ring.hyp[..., 1], axis=1) - self.start_xy[1]
        ref = self.gauge_ref[ok]
        bx, by = reps[..., 0], reps[..., 1]
        dot = bx @ ref[:, 0] + by @ ref[:, 1]
        crs = bx @ ref[:, 1] - by @ ref[:, 0]
        dot_m = bx @ ref[:, 0] - by @ ref[:, 1]  # mirrored map (x, -y)
        crs_m = bx @ ref[:, 1] + by @ ref[:, 0]
        mirror = np.hypot(dot_m, crs_m) > np.hypot(dot, crs)
        th = np.where(mirror, np.arctan2(crs_m, dot_m), np.arctan2(crs, dot))
        c, s_ = np.cos(th), np.sin(th)
        sy = np.where(mirror, -1.0, 1.0)
        return np.stack([np.stack([c, -s_ * sy], axis=1), np.stack([s_, c * sy], axis=1)],
                        axis=1)  # R(th) @ diag(1, sy)

    def _rotated(self, rot: F64, x: F64) -> F64:
        """Points ``x`` (M, k, 2) of each particle mapped by its gauge matrix about the start."""
        d = x - self.start_xy
        r = rot[:, None]  # (M, 1, 2, 2)
        out = np.empty_like(d)
        out[..., 0] = r[..., 0, 0] * d[..., 0] + r[..., 0, 1] * d[..., 1] + self.start_xy[0]
        out[..., 1] = r[..., 1, 0] * d[..., 0] + r[..., 1, 1] * d[..., 1] + self.start_xy[1]
        return out

    def _resize(self, m_new: int) -> None:
        idx = systematic_resample(self.weights, m_new, self.rng)
        self.cam = self.cam[idx]
        self.beacons = self.beacons[idx]
        for ring in self.rings.values():
            ring.take(idx)
        self.weights = np.full(m_new, 1.0 / m_new)

    def _point_known(self) -> NDArray[np.bool_]:
        """Initialised beacons held as one point per particle (not in a start-up ring)."""
        if not self.rings:
            return self.known
        pk = self.known.copy()
        pk[list(self.rings)] = False
        return pk

    def _roughen(self, h: float) -> None:
        known = np.flatnonzero(self._point_known())
        if known.size == 0:
            return
        self.beacons[:, known, :] = liu_west_roughen(
            self.beacons[:, known, :], self.weights, h, self.rng
        )

    # ------------------------------------------------------------------ one step
    def _predict(self, ranges: F64, mask: NDArray[np.bool_]) -> None:
        """Motion model: camera += 2D zero-mean Gaussian (sec. III.A); the first move is
        drawn in the quadrant the first two measurements point to (sec. III.B)."""
        p = self.params
        m = self.n_particles
        noise = self.rng.normal(0.0, p.motion_sigma_m, (m, 2))
        if self.t == 1 and p.quadrant_init and not p.known_beacons:
            signs = self._first_move_quadrant(ranges, mask)
            if signs is not None:
                noise = np.abs(noise) * signs
        self.cam = self.cam + noise

    def _first_move_quadrant(self, ranges: F64, mask: NDArray[np.bool_]) -> F64 | None:
        """Signs (sx, sy) of the first camera move from the range changes between the first
        two measurements: r1 - r0 ~ -u . s1 with u the unit vectors to the beacons."""
        both = mask & np.isfinite(self.first_ranges) & self.known
        if np.count_nonzero(both) < 2:
            return None
        mean_b = np.nanmean(self.beacons[:, both, :], axis=0) - self.start_xy
        norms = np.linalg.norm(mean_b, axis=1, keepdims=True)
        if np.any(norms < 1e-6):
            return None
        u = mean_b / norms
        dr = ranges[both] - self.first_ranges[both]
        if self.params.outlier_prob > 0.0:
            # a range cannot change by more than the camera can move in one step
            ok = np.abs(dr) <= 3.0 * (self.params.motion_sigma_m + self.params.range_sigma_m)
            if np.count_nonzero(ok) < 2:
                return None
            u, dr = u[ok], dr[ok]
        s1, *_ = np.linalg.lstsq(-u, dr, rcond=None)
        if not np.all(np.isfinite(s1)) or float(np.linalg.norm(s1)) < 1e-9:
            return None
        return np.where(s1 >= 0.0, 1.0, -1.0)

    def _first_step(self, ranges: F64, mask: NDArray[np.bool_]) -> None:
        p = self.params
        if p.known_beacons:
            for i in range(self.n):
                if np.all(np.isfinite(self.layout_xy[i])):
                    self.beacons[:, i, :] = self.layout_xy[i]
                    self.known[i] = True
            usable = mask & self.known
            guess = self.start_xy
            pos = trilaterate(self.layout_xy[usable], ranges[usable], guess)
            if pos is not None:
                spread = max(p.range_sigma_m, 0.05)
                self.cam = pos + self.rng.normal(0.0, spread, (self.n_particles, 2))
        for i in np.flatnonzero(mask & ~self.known):
            self._init_beacon(int(i), float(ranges[i]))
        self.first_ranges = np.where(mask, ranges, np.nan)

    def step(self, ranges_m: Sequence[float] | F64) -> FilterEstimate:
        """One iteration of fig. 5 with one range per beacon in ``ids`` order (NaN = missing)."""
        p = self.params
        ranges = np.asarray(ranges_m, dtype=np.float64).reshape(self.n)
        mask = np.isfinite(ranges) & (ranges >= 0.0)
        if int(p.n_particles) != self.n_particles:
            self._resize(int(p.n_particles))
        m = self.n_particles
        used = np.zeros(self.n, dtype=bool)
        outliers = np.zeros(self.n, dtype=bool)
        residual_rms = math.nan
        log_w = np.zeros(m)
        if self.t == 0:
            if not np.any(mask):  # nothing read yet: stay before the first step
                self.t = -1
            else:
                self._first_step(ranges, mask)
            used = mask & self.known
        else:
            self._predict(ranges, mask)
            active = mask & self.known
            newly = mask & ~self.known
            idx = np.flatnonzero(active)
            if idx.size:
                d_pred = predicted_ranges(self.cam, self.beacons[:, idx, :])  # eq. (8)
                resid = ranges[idx][None, :] - d_pred
                inl = np.ones(idx.size, dtype=bool)
                if p.outlier_prob > 0.0 and idx.size >= 2:
                    # consensus gate: a reading that (nearly) all particles disagree with
                    med = np.median(resid, axis=0)
                    spread = np.std(d_pred, axis=0)
                    gate = p.outlier_gate_sigma * np.sqrt(p.range_sigma_m**2 + spread**2)
                    bad = np.abs(med) > gate
                    if not np.all(bad):  # all disagree: the filter, not the sensors, is off
                        inl = ~bad
                outliers[idx[~inl]] = True
                used[idx[inl]] = True
                self.n_rejected[idx[inl]] = 0
                self.n_rejected[idx[~inl]] += 1
                # weighting, eq. (10): prod over beacons
                is_ring = (np.array([int(j) in self.rings for j in idx], dtype=bool)
                           if self.rings else np.zeros(idx.size, dtype=bool))
                pt = inl & ~is_ring
                if np.any(pt):
                    sig: float | F64 = p.range_sigma_m
                    if p.map_spread_weighting:
                        sig = marginal_range_sigma(
                            self.cam, self.beacons[:, idx[pt], :], self.weights,
                            p.range_sigma_m)
                    ll = range_log_likelihood(resid[:, pt], sig, p.outlier_prob, p.max_range_m)
                    log_w = np.sum(ll, axis=1)
                for j in idx[inl & is_ring]:
                    # eq. (10) with the particle's mixture over beacon j: sum of its hypotheses
                    ring = self.rings[int(j)]
                    ll_k = ring.log_w + ring_log_likelihood(
                        self.cam, ring, float(ranges[j]), p.range_sigma_m, p.outlier_prob,
                        p.max_range_m)
                    ll_j = _logsumexp_rows(ll_k)
                    log_w = log_w + ll_j
                    ring.log_w = ll_k - ll_j[:, None]  # Bayes within the particle
                    ring.prune()
                w_tmp = normalise_log_weights(log_w)
                residual_rms = float(math.sqrt(np.sum(w_tmp @ (resid[:, inl] ** 2)) /
                                               max(int(np.count_nonzero(inl)), 1)))
                if p.map_adjustment and not p.known_beacons and p.map_adjust_p > 0.0:
                    adj = idx[pt]
                    if adj.size:
                        gain: float | F64 = p.map_adjust_p
                        if p.map_adjust_anneal:
                            gain = np.maximum(p.map_adjust_p, 1.0 / (self.n_reads[adj] + 1.0))

                        self.beacons[:, adj, :] = map_adjustment(
                            self.cam, self.beacons[:, adj, :], ranges[adj], gain
                        )  # eq. (12)
                    for j in idx[inl & is_ring]:  # eq. (12) on every hypothesis
                        ring = self.rings[int(j)]
                        g = p.map_adjust_p
                        if p.map_adjust_anneal:
                            g = max(p.map_adjust_p, 1.0 / (self.n_reads[j] + 1.0))
                        k = ring.hyp.shape[1]
                        ring.hyp = map_adjustment(self.cam, ring.hyp,
                                                  np.full(k, float(ranges[j])), g)
            self.n_reads[used] += 1.0
            if not p.known_beacons:
                # a beacon rejected REINIT_AFTER times in a row was initialised from an
                # outlier (or has been moved): start it again from the current reading
                stale = mask & (self.n_rejected >= REINIT_AFTER)
                self.known[stale] = False
                self.n_rejected[stale] = 0
                self.n_reads[stale] = 0.0
                newly = newly | stale
            for i in np.flatnonzero(newly):
                self._init_beacon(int(i), float(ranges[i]))
        # normalisation (sec. III.B); weights carry over when resampling is skipped
        self.weights = normalise_log_weights(np.log(np.maximum(self.weights, 1e-300)) + log_w)
        ess = float(1.0 / np.sum(self.weights**2))
        if self.rings:
            self._commit_rings()
            for i in self.rings:
                self._ring_sample(i)
        rot = self._gauge_rotations()
        cam = self.cam if rot is None else self._rotated(rot, self.cam[:, None, :])[:, 0]
        cam_xy, cam_cov = weighted_mean_cov(cam, self.weights)
        b_xy = np.full((self.n, 2), np.nan)
        b_cov = np.full((self.n, 2, 2), np.nan)
        pk = self._point_known()
        if np.any(pk):
            pts = self.beacons[:, pk, :]
            bm, bc = weighted_mean_cov(pts if rot is None else self._rotated(rot, pts),
                                       self.weights)
            b_xy[pk] = bm
            b_cov[pk] = bc
        for i, ring in self.rings.items():  # the mixture's mean and covariance
            wk = (self.weights[:, None] * np.exp(ring.log_w)).ravel()
            hyp = ring.hyp if rot is None else self._rotated(rot, ring.hyp)
            b_xy[i], b_cov[i] = weighted_mean_cov(hyp.reshape(-1, 2), wk / np.sum(wk))
        if self._gauge_free():
            self.gauge_ref = b_xy - self.start_xy
        est = FilterEstimate(
            step=self.t,
            cam_xy=cam_xy,
            cam_cov=cam_cov,
            beacons_xy=b_xy,
            beacons_cov=b_cov,
            used=used,
            outliers=outliers,
            ess=ess,
            residual_rms_m=residual_rms,
        )
        if self.t > 0 and ess < p.resample_ess_fraction * m + 1e-9:
            self._resize(m)  # systematic resampling (sec. III.B)
            if p.roughen_h > 0.0 and not p.known_beacons and np.any(self._point_known()):
                self._roughen(p.roughen_h)
            if p.beacon_jitter_m > 0.0 and not p.known_beacons:
                self.beacons = self.beacons + self.rng.normal(
                    0.0, p.beacon_jitter_m, self.beacons.shape
                )
        self.t += 1
        self.last = est
        return est
