"""``studiotrack bench beacon --quick --json`` ends with the documented JSON keys."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from app.cli import main


def test_bench_beacon_json_keys(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    rc = main(["bench", "beacon", "--quick", "--seeds", "2", "--json", "--plots", str(tmp_path)])
    assert rc == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    res = json.loads(last)
    for key in ("path_rmse", "beacon_err_final"):
        assert isinstance(res["with_ma"][key], float)
        assert isinstance(res["without_ma"][key], float)
    need = res["particles_for_paper_accuracy"]
    assert "with_ma" in need
    assert "without_ma" in need
    assert need["definition"]
    assert res["steps_per_s"] > 0
    assert len(res["with_ma"]["err_over_time_mean"]) == 13  # every 10th of 121 steps
    # the paper's method as published beside ours, on the studio simulation
    for name in ("paper", "default"):
        for ma in ("with_ma", "without_ma"):
            row = res[name][ma]
            for key in ("path_rmse", "beacon_err_final"):
                assert isinstance(row[key], float)
                lo, hi = row["ci95"][key]
                assert lo <= row[key] <= hi
    assert res["paper"]["params"]["outlier_prob"] == 0.0
    assert res["paper"]["params"]["roughen_h"] == 0.0
    pfa = res["particles_for_accuracy"]
    assert pfa["metric"].startswith("p75")
    assert set(pfa["ci95"]) >= {"with_ma", "without_ma"}
    assert "with_ma" in pfa
    assert "without_ma" in pfa
    rows = {r["name"]: r for r in res["ablation"]["rows"]}
    assert "default (all on)" in rows
    assert "minus_default" in rows["without robust_weighting"]
    assert res["ablation"]["added"][0]["name"] == "paper (all off)"
    # MA's own effect in every variant (which extension takes over what MA does)
    for r in [*res["ablation"]["rows"], *res["ablation"]["added"]]:
        if "beacon_err_final" in r:
            eff = r["ma_effect_paired"]["beacon_err_final"]
            assert eff["ci95"][0] <= eff["mean_diff"] <= eff["ci95"][1]
    for png in res["plots"]:
        assert Path(png).stat().st_size > 1000
