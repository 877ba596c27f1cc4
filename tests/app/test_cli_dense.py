"""CLI: ``studiotrack sweep`` builds a keyframe store; ``track --tracker dense --keyframes``
uses it; a corrupt store is a one-line error with exit code 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from app.cli import main

SRC = "synthetic:frames=24,width=320,height=240,seed=3,path=rail,cycle_s=4"


def test_sweep_then_track_with_keyframes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    kf = tmp_path / "kf"
    assert main(["sweep", SRC, "--out", str(kf), "--points", "2048", "--kf-dist", "0.1",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["keyframes"] >= 2
    assert (kf / "keyframes.json").is_file()
    traj = tmp_path / "traj.txt"
    rc = main(["track", SRC, "--tracker", "dense", "--keyframes", str(kf), "--points", "2048",
               "--out", str(traj), "--json"])
    assert rc == 0
    res = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert res["lost_frames"] == 0
    assert len(traj.read_text().strip().splitlines()) >= 20


def test_track_with_corrupt_store_is_a_clear_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    kf = tmp_path / "kf"
    kf.mkdir()
    (kf / "keyframes.json").write_text("{ not json")
    rc = main(["track", SRC, "--tracker", "dense", "--keyframes", str(kf),
               "--out", str(tmp_path / "t.txt")])
    assert rc == 2
    err = capsys.readouterr().err
    assert "studiotrack: error:" in err
    assert "keyframes.json: corrupt JSON" in err
