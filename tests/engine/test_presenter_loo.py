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
