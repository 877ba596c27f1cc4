"""Leave-one-sequence-out choice of the presenter tracker's defaults.

The protocol (run by ``studiotrack bench presenter``; nothing here is fixed by hand):

1. a small set of knobs that matter (``COARSE`` grid, then ``FINE`` one-knob-at-a-time moves
   from the coarse winner), every other parameter at its default;
2. a candidate is scored on the first ``search_frames`` frames of each labelled sequence
   (success AUC) and must meet the loss goals on the ``check`` loss scenarios (other seeds,
   looks and image sizes than the reported ones, ``engine.bench.presenter_scenarios``);
3. the score of a candidate on a set of sequences is the mean AUC of the studio sequences and
   the mean AUC of the real ones, averaged (so six studio variants do not outvote three real
   sequences);
4. fold *k* chooses on every sequence but *k* (coarse grid, then fine moves, feasible
   candidates only) and runs its choice on the whole of sequence *k*: that sequence's
   ``success_auc_heldout``;
5. the global choice is the same procedure on all sequences; it is what ``PresenterParams``
   ships as defaults, and the bench says whether the shipped defaults equal it.

Every (candidate, sequence) run is done once and shared by the folds: the folds differ only in
which columns of the (candidate x sequence) AUC table they average, so the whole selection is
a handful of distinct candidates' runs (the bench also keeps the table on disk, keyed by the
candidate and a fingerprint of the code and data it depends on, ``engine.bench.presenter``).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.progress import log

Overrides = tuple[tuple[str, Any], ...]


@dataclass(frozen=True, slots=True)
class Knob:
    name: str
    values: tuple[Any, ...]
    start: Any = None  # fine knobs: where the moves start (independent of shipped defaults)


#: coarse grid: the scale random walk, the ring (scale) term, the model-update gate
COARSE: tuple[Knob, ...] = (
    Knob("sigma_h_frac", (0.005, 0.015, 0.03)),
    Knob("ring_weight", (0.0, 0.5, 1.0)),
    Knob("model_update_ratio", (0.3, 0.7)),
)
#: fine moves from the coarse winner, one knob at a time, in this order
FINE: tuple[Knob, ...] = (
    Knob("lambda_col", (0.1, 0.15, 0.22), start=0.15),
    Knob("loss_contrast", (0.4, 0.5, 0.7), start=0.5),
    Knob("loss_bg_quantile", (0.1, 0.3, 0.5), start=0.1),
    Knob("loss_reference", ("first", "anchored"), start="first"),
    Knob("loss_bg_weighting", (0.0, 0.5, 1.0), start=1.0),
    Knob("loss_motion", (0.0, 0.1, 0.2, 0.3), start=0.2),
    Knob("loss_frames", (2, 3, 4), start=2),
    Knob("model_update_rate", (0.02, 0.05, 0.1), start=0.05),
    Knob("reacquire_frames", (1, 2), start=2),
    Knob("velocity_gain", (0.25, 0.5, 0.75), start=0.5),
    Knob("fit_width", (True, False), start=True),
    Knob("fit_width_max_frac", (1.6, 2.2), start=2.2),
    Knob("mode_seek", (False, True), start=False),
    Knob("trajectory_share", (0.0, 0.2), start=0.0),
    Knob("exposure_normalise", (False, True), start=False),
)


def coarse_grid() -> list[Overrides]:
    grid: list[Overrides] = [()]
    for k in COARSE:
        grid = [(*g, (k.name, v)) for g in grid for v in k.values]
    start = tuple((k.name, k.start) for k in FINE)
    return [(*g, *start) for g in grid]


def _with(c: Overrides, name: str, value: Any) -> Overrides:
    return tuple((k, value if k == name else v) for k, v in c)


AucFn = Callable[[Overrides, str], float]
FeasibleFn = Callable[[Overrides], bool]


@dataclass
class Selection:
    """Scores shared by every fold: AUC per (candidate, sequence), feasibility per candidate."""

    auc: AucFn
    feasible: FeasibleFn
    studio: frozenset[str]
    evaluated: int = 0

    def score(self, c: Overrides, train: Sequence[str]) -> float:
        groups = [[s for s in train if s in self.studio], [s for s in train
                                                          if s not in self.studio]]
        means = [float(np.mean([self.auc(c, s) for s in g])) for g in groups if g]
        return float(np.mean(means))

    def choose(self, train: Sequence[str]) -> tuple[Overrides, float]:
        """Coarse grid, then fine moves; feasible candidates only (ties: the earlier one).

        Feasibility is asked only of a candidate that would be taken (the best-scoring coarse
        ones in turn, a fine move that improves): the same choice as checking all of them,
        for a fraction of the loss-scenario runs.
        """
        grid = coarse_grid()
        scores = [self.score(c, train) for c in grid]
        best: Overrides | None = None
        best_score = -np.inf
        for i in sorted(range(len(grid)), key=lambda i: (-scores[i], i)):
            if self.feasible(grid[i]):
                best, best_score = grid[i], scores[i]
                break
        if best is None:
            raise RuntimeError("no candidate meets the loss goals on the check scenarios")
        for knob in FINE:
            for v in knob.values:
                c = _with(best, knob.name, v)
                if c == best:
                    continue
                sc = self.score(c, train)
                if sc > best_score + 1e-9 and self.feasible(c):
                    best, best_score = c, sc
        return best, best_score


def run_loo(sequences: Sequence[str], studio: Sequence[str], auc: AucFn,
            feasible: FeasibleFn, heldout_auc: AucFn) -> dict[str, Any]:
    """Every fold's choice and held-out AUC, and the global choice (see the module doc)."""
    sel = Selection(auc=auc, feasible=feasible, studio=frozenset(studio))
    folds: dict[str, Any] = {}
    for held in sequences:
        train = [s for s in sequences if s != held]
        choice, train_score = sel.choose(train)
        folds[held] = {"choice": dict(choice), "train_score": round(train_score, 4),
                       "success_auc_heldout": round(heldout_auc(choice, held), 4)}
        log(f"  fold {held}: held-out AUC {folds[held]['success_auc_heldout']:.3f} "
            f"with {dict(choice)}")
    choice, score = sel.choose(list(sequences))
    return {"folds": folds, "global_choice": dict(choice), "global_score": round(score, 4)}


def shipped_matches(choice: Mapping[str, Any], defaults: Any) -> bool:
    return all(getattr(defaults, k) == v for k, v in choice.items())


# ------------------------------------------------------------------------------ disk cache

#: what a (candidate, sequence) score depends on besides the candidate and the frames (which
#: are hashed themselves, ``frames_fingerprint``): the tracker and the scoring. Not the
#: parameter file: a candidate sets every knob itself, so only the other parameters'
#: defaults count (``code_fingerprint``), and shipping a new default keeps the table; not the
#: second view's and the robot's modules (no sequence or check scenario uses them)
FINGERPRINT_PATHS = ("engine/presenter", "engine/evaluation", "engine/trackers/presenter.py",
                     "engine/trackers/base.py", "engine/particles.py", "engine/arrays.py",
                     "engine/frames.py", "engine/bench/presenter_scenarios.py")
_NOT_FINGERPRINTED = frozenset({"params.py", "twoview.py", "robot_sim.py"})


def frames_fingerprint(frames: Sequence[Any]) -> str:
    """sha1 of what a tracker and the scoring see of the frames: pixels, times, truth."""
    from engine.studio.sim import StudioTruth

    h = hashlib.sha1()
    for f in frames:
        h.update(repr((f.index, f.timestamp_s, f.gt_box_xywh)).encode())
        if f.color_bgr is not None:
            h.update(np.ascontiguousarray(f.color_bgr).data)
        t = f.payload(StudioTruth)
        if t is not None:
            h.update(repr((t.presenter_pixels, t.presenter_part_boxes)).encode())
    return h.hexdigest()[:16]


def knob_names() -> frozenset[str]:
    return frozenset(k.name for k in (*COARSE, *FINE))


def code_fingerprint(extra: str = "", root: Path | None = None) -> str:
    """sha1 over the sources in ``FINGERPRINT_PATHS`` (``engine/presenter/params.py`` only
    through the defaults of the parameters no knob sets and the presets), ``extra`` (the
    bench's own scoring code) and the numpy/OpenCV versions: any change to what a score
    depends on starts a new table."""
    import dataclasses

    import cv2

    from engine.presenter.params import PresenterParams

    root = root or Path(__file__).resolve().parents[2]
    h = hashlib.sha1(f"{np.__version__} {cv2.__version__}".encode())
    h.update(extra.encode())
    names = knob_names()
    fixed = {f.name: getattr(PresenterParams(), f.name)
             for f in dataclasses.fields(PresenterParams) if f.name not in names}
    h.update(repr(sorted(fixed.items())).encode())
    h.update(repr({k: sorted(v.values.items())
                   for k, v in PresenterParams.PRESETS.items()}).encode())
    for rel in FINGERPRINT_PATHS:
        p = root / rel
        files = sorted(p.rglob("*.py")) if p.is_dir() else [p]
        for f in files:
            if f.is_file() and f.name not in _NOT_FINGERPRINTED:
                h.update(str(f.relative_to(root)).encode())
                h.update(f.read_bytes())
    return h.hexdigest()[:16]


class ScoreCache:
    """(key -> number) table kept in one JSON file per code fingerprint under ``folder``
    (written atomically after each new entry, so an interrupted run resumes); ``folder``
    None = in memory only."""

    def __init__(self, folder: Path | None, fingerprint: str) -> None:
        self.path = None if folder is None else folder / f"presenter_loo_{fingerprint}.json"
        self.fingerprint = fingerprint
        self.table: dict[str, Any] = {}
        self.hits = 0
        self.misses = 0
        if self.path is not None and self.path.is_file():
            try:
                data = json.loads(self.path.read_text())
                if data.get("fingerprint") == fingerprint:
                    self.table = dict(data.get("scores", {}))
            except (OSError, ValueError):
                self.table = {}  # unreadable: start afresh (it is only a cache)

    @staticmethod
    def key(*parts: Any) -> str:
        return hashlib.sha1(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()

    def get(self, key: str, compute: Callable[[], Any]) -> Any:
        if key in self.table:
            self.hits += 1
            return self.table[key]
        self.misses += 1
        value = compute()
        self.table[key] = value
        if self.path is not None:
            from engine.persist import atomic_write_json

            self.path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_json(self.path, {"fingerprint": self.fingerprint,
                                          "scores": self.table})
        return value
