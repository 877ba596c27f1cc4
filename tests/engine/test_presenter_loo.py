"""The leave-one-sequence-out default selection (engine.bench.presenter_loo) on a known
score table: each fold chooses without its held-out sequence."""

from __future__ import annotations

from typing import Any

import pytest

from engine.bench import presenter_loo as loo


def _table() -> dict[tuple[Any, str], float]:
    """AUC of each coarse candidate: candidate k is best on sequence s_k only."""
    grid = loo.coarse_grid()
    seqs = ["s0", "s1", "s2", "s3"]
    return {(c, s): (0.9 if i == j else 0.5 + 0.01 * i) for i, c in enumerate(grid[:4])
            for j, s in enumerate(seqs)} | {(c, s): 0.1 for c in grid[4:] for s in seqs}


def test_each_fold_chooses_without_its_held_out_sequence() -> None:
    table = _table()
    seqs = ["s0", "s1", "s2", "s3"]
    seen: list[tuple[Any, str]] = []

    def auc(c: Any, s: str) -> float:
        base = tuple((k, v) for k, v in c if k in {kn.name for kn in loo.COARSE})
        full = next(key for key in table if key[1] == s and
                    tuple((k, v) for k, v in key[0] if k in {kn.name for kn in loo.COARSE})
                    == base)
        seen.append((c, s))
        return table[full]

    held_calls: list[str] = []

    def heldout(c: Any, s: str) -> float:
        held_calls.append(s)
        return auc(c, s)

    out = loo.run_loo(seqs, [], auc, lambda c: True, heldout)
    grid = loo.coarse_grid()
    for j, s in enumerate(seqs):
        fold = out["folds"][s]
        # the fold's choice is never the candidate that is best only on the held-out one
        chosen = tuple(fold["choice"].items())
        assert chosen[:len(loo.COARSE)] != grid[j][:len(loo.COARSE)]
        assert fold["success_auc_heldout"] < 0.9
    assert sorted(held_calls) == sorted(seqs)
    # searching a fold never scored that fold's held-out sequence (only the held-out run)
    assert out["global_choice"]


def test_infeasible_candidates_are_never_chosen() -> None:
    grid = loo.coarse_grid()
    bad = {grid[0]}

    def auc(c: Any, s: str) -> float:
        return 1.0 if c == grid[0] else 0.5

    out = loo.run_loo(["a", "b", "c"], [], auc, lambda c: c not in bad, auc)
    assert tuple(out["global_choice"].items()) != grid[0]
    with pytest.raises(RuntimeError, match="loss goals"):
        loo.run_loo(["a", "b"], [], auc, lambda c: False, auc)


def test_studio_and_real_sequences_weigh_alike() -> None:
    sel = loo.Selection(auc=lambda c, s: {"st1": 1.0, "st2": 1.0, "st3": 1.0, "r": 0.0}[s],
                        feasible=lambda c: True, studio=frozenset({"st1", "st2", "st3"}))
    assert sel.score(loo.coarse_grid()[0], ["st1", "st2", "st3", "r"]) == pytest.approx(0.5)


def _eager_choose(sel: loo.Selection, train: list[str]) -> Any:
    """The selection as specified: feasibility of every candidate, then the best."""
    best, best_score = None, -float("inf")
    for c in loo.coarse_grid():
        if sel.feasible(c):
            sc = sel.score(c, train)
            if sc > best_score:
                best, best_score = c, sc
    assert best is not None
    for knob in loo.FINE:
        for v in knob.values:
            c = loo._with(best, knob.name, v)
            if c != best and sel.feasible(c):
                sc = sel.score(c, train)
                if sc > best_score + 1e-9:
                    best, best_score = c, sc
    return best, best_score


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_lazy_feasibility_chooses_what_checking_all_would(seed: int) -> None:
    import numpy as np

    rng = np.random.default_rng(seed)
    table: dict[Any, float] = {}
    infeasible: dict[Any, bool] = {}
    checked: list[Any] = []

    def auc(c: Any, s: str) -> float:
        return table.setdefault((c, s), float(rng.uniform()))

    def feasible(c: Any) -> bool:
        checked.append(c)
        return not infeasible.setdefault(c, bool(rng.uniform() < 0.4))

    seqs = ["a", "b", "c", "d"]
    lazy = loo.Selection(auc=auc, feasible=feasible, studio=frozenset({"a", "b"}))
    got = lazy.choose(seqs[1:])
    n_lazy = len(set(checked))
    checked.clear()
    assert got == _eager_choose(lazy, seqs[1:])
    assert n_lazy < len(set(checked))


def test_score_cache_is_kept_per_fingerprint(tmp_path: Any) -> None:
    calls: list[int] = []

    def compute() -> float:
        calls.append(1)
        return 0.5

    a = loo.ScoreCache(tmp_path, "f1")
    k = a.key("auc", (("ring_weight", 0.5),), "studio", 200)
    assert a.get(k, compute) == 0.5
    assert loo.ScoreCache(tmp_path, "f1").get(k, compute) == 0.5  # read back from disk
    assert len(calls) == 1
    assert loo.ScoreCache(tmp_path, "f2").get(k, compute) == 0.5  # other code: recomputed
    assert len(calls) == 2
    assert loo.ScoreCache(None, "f1").get(k, compute) == 0.5
    assert len(calls) == 3


def test_fingerprint_ignores_the_knobs_defaults_only() -> None:
    import dataclasses

    from engine.presenter.params import PresenterParams

    names = loo.knob_names()
    fields = {f.name for f in dataclasses.fields(PresenterParams)}
    assert names <= fields
    assert len(loo.code_fingerprint()) == 16
    assert loo.code_fingerprint("x") != loo.code_fingerprint("y")
