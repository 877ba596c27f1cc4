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
    for png in res["plots"]:
        assert Path(png).stat().st_size > 1000
