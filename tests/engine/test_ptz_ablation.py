"""The pan-tilt tracker's extensions beyond Gaspar 2009 (``EXTENSIONS``), the paper preset
built from them, and the ablation table of ``bench ptz``."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from engine.ptz.paper_sim import PAPER_OMEGA_RAD_S, paper_circle
from engine.trackers.ptz import EXTENSIONS, PtzParams


def _small(sc: object, **kw: object) -> object:
    """A shortened, small-image version of a scenario without lens distortion."""
    return dataclasses.replace(sc, width=320, height=240, distortion_k3=0.0,  # type: ignore
                               **kw)


def _base(sc: object) -> PtzParams:
    return PtzParams(target_b=sc.ball_bgr[0], target_g=sc.ball_bgr[1],  # type: ignore
                     target_r=sc.ball_bgr[2], target_radius_m=sc.ball_radius_m)  # type: ignore


def test_paper_preset_is_every_extension_off() -> None:
    p = PtzParams().with_preset("paper")
    for name, ext in EXTENSIONS.items():
        for k, v in ext.values.items():
            assert getattr(p, k) == v, (name, k)
    # the switches name real fields and their off values are valid
    for ext in EXTENSIONS.values():
        dataclasses.replace(PtzParams(), **ext.values)  # type: ignore[arg-type]


def test_every_extension_switch_is_live() -> None:
    """Each entry of EXTENSIONS turns a live part of the tracker off: on a run where the
    extension is on (and has something to do), switching it off changes the estimate."""
    from engine.bench.ptz_paper import track

    beyond = _small(paper_circle(), fps=10.0, duration_s=12.0, period_s=1.0 / 0.08,
                    radius_m=1.2)
    on_values: dict[str, dict[str, object]] = {  # off by default, or idle on a clean run
        "model_prob_floor": {"min_model_prob": 0.05},
        "gvf_force": {"external_force": "gvf"},
        # re-initialisation acts when the filter diverges: with the paper's tiny process
        # noise on a target turning faster than the bank's largest model
        "nis_reinit": {"q_jerk_psd": EXTENSIONS["process_noise"].values["q_jerk_psd"]},
    }
    assert set(on_values) <= set(EXTENSIONS)
    base = _base(beyond)
    for name, ext in EXTENSIONS.items():
        on = dataclasses.replace(base, **on_values.get(name, {}))  # type: ignore[arg-type]
        off = dataclasses.replace(on, **ext.values)  # type: ignore[arg-type]
        assert off != on, name
        a, b = track(beyond, on)["pos_err"], track(beyond, off)["pos_err"]
        assert not np.allclose(a, b, equal_nan=True), f"switching off {name} changed nothing"


def test_ablation_rows_are_paired_per_seed_differences() -> None:
    from engine.bench.ptz_ablation import METRICS, ablation

    sc = _small(paper_circle(), duration_s=24.0)
    abl = ablation(table={"short": (sc, PAPER_OMEGA_RAD_S)}, seeds=(3, 4), added_on=("short",))
    assert abl["seeds"] == [3, 4]
    s = abl["scenarios"]["short"]
    on = [n for n, e in abl["extensions"].items() if e["on_by_default"]]
    assert {"process_noise", "moments_centre", "nis_reinit"} <= set(on)
    assert "gvf_force" not in on
    assert [r["extension"] for r in s["rows"][1:]] == on
    assert [r["extension"] for r in s["added"][1:]] == on
    ref, pap = s["rows"][0], s["added"][0]
    for r in s["rows"][1:]:
        for k in METRICS:
            d = np.subtract(r[f"{k}_per_seed"], ref[f"{k}_per_seed"])
            assert r["minus_default"][k]["mean_diff"] == pytest.approx(float(np.mean(d)))
            lo, hi = r["minus_default"][k]["ci95"]
            assert lo <= float(np.mean(d)) <= hi
        if not r["active"]:
            assert r["pos_err_m_steady_per_seed"] == ref["pos_err_m_steady_per_seed"]
        assert s["attribution"][r["extension"]]["removed_from_default_m"] == pytest.approx(
            r["minus_default"]["pos_err_m_steady"]["mean_diff"])
    total = np.subtract(pap["pos_err_m_steady_per_seed"], ref["pos_err_m_steady_per_seed"])
    assert s["attribution"]["paper_minus_default_pos_err_m"]["mean_diff"] == pytest.approx(
        float(np.mean(total)))
    # the centre from the colour mass is what our set gains most on the paper's circle
    moments = next(r for r in s["rows"] if r.get("extension") == "moments_centre")
    assert moments["minus_default"]["pos_err_m_steady"]["mean_diff"] > 0.0
    assert all(math.isfinite(r["pos_err_m_steady"]) for r in s["rows"] + s["added"])


def test_bench_ptz_quick_plan_and_bad_scenario() -> None:
    """``--quick`` reduces the ablation to one seed of the paper's circle; the full run keeps
    every scenario and its seeds; an unknown scenario is one line naming it."""
    import argparse

    from engine.bench import ptz
    from engine.errors import ParamsError

    parser = argparse.ArgumentParser()
    ptz.add_arguments(parser)
    seeds, names = ptz._ablation_plan(parser.parse_args(["--quick"]))
    assert list(seeds) == [3]
    assert names == ["paper_experiment"]
    seeds, names = ptz._ablation_plan(parser.parse_args([]))
    assert len(seeds) == ptz.FULL_ABLATION_SEEDS >= 4
    assert names is None
    seeds, names = ptz._ablation_plan(parser.parse_args(
        ["--quick", "--ablation-seeds", "2", "--ablation-scenarios", "paper_range"]))
    assert list(seeds) == [3, 4]
    assert names == ["paper_range"]
    with pytest.raises(ParamsError, match="unknown nope; available: paper_experiment"):
        ptz._ablation_plan(parser.parse_args(["--ablation-scenarios", "paper_range,nope"]))
