"""``bench lens`` end to end on a small sweep, and the new ``bench ptz`` loop keys."""

from __future__ import annotations

import argparse

import pytest


def test_bench_lens_small_sweep_reports_the_acceptance_keys():
    from engine.bench.lens import add_arguments, run

    p = argparse.ArgumentParser()
    add_arguments(p)
    out = run(p.parse_args(["--samples", "3", "--views", "8", "--frames", "8", "--width",
                            "320", "--height", "240", "--rate", "29.97", "--timecode-start",
                            "00:00:59;28"]))
    for key in ("focal_length_err_mm", "k1_err"):
        assert set(out[key]) == {"median", "max"}
        assert out[key]["median"] is not None
    assert out["timecode_ok"] is True  # crosses the drop-frame minute: 59;28 59;29 01:00;02
    assert out["freed_encoders_ok"] is True
    assert out["packets"] == {"opentrackio": 8, "freed": 8, "frames": 8}
    # calibration + 3 samples are worse than the truth sampled at those zooms, not absurd
    assert out["focal_length_err_mm"]["max"] < 1.5
    assert out["interp_only"]["k1_err"]["max"] <= out["k1_err"]["max"] + 1e-9


@pytest.mark.slow
def test_bench_ptz_visca_loop_keys():
    from engine.bench.ptz import run_visca_loop

    out = run_visca_loop(4.0, 50.0)
    assert out["pos_err_m_steady"] is not None
    assert out["updates_per_s"] > 0
    assert out["visca_commands_received"] >= 1
    assert out["freed_packets_received"] == out["frames"]
