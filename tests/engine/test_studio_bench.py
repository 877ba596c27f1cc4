"""``studiotrack bench render`` runs end to end and ends with one JSON line (speed is not
asserted here: it is measured by the benchmark itself)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import pytest

from app.cli import main


def test_bench_render_json_and_preview(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    preview = tmp_path / "preview.png"
    rc = main(
        [
            "bench",
            "render",
            "--frames",
            "3",
            "--width",
            "160",
            "--height",
            "120",
            "--no-peer",
            "--preview",
            str(preview),
            "--json",
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out.strip().splitlines()
    res = json.loads(out[-1])
    for key in ("fps_median", "ms_median", "ms_p95", "width", "height"):
        assert key in res
    assert (res["width"], res["height"]) == (160, 120)
    assert res["ms_median"] > 0
    assert res["presenter"]["cpu_ms_median"] >= 0
    # the ray caster's own texture fetch as a peer, and how far its images are
    assert res["raycast"]["ms_median"] > 0
    assert res["ratio_raycast_over_presenter"] > 0
    agree = res["raycast_agreement"]
    assert agree["depth_abs_max_m"] == 0.0
    assert agree["labels_frac_differ"] == 0.0
    assert agree["colour_abs_max"] <= 6
    assert res["still"]["ms_median"] > 0  # the presenter seen by a camera standing still
    assert "open3d_depth_only" not in res  # the peer (open3d import ~8 s here) is skipped
    img = cv2.imread(str(preview))
    assert img.shape == (240, 320, 3)
    assert img.std() > 20
