"""The soak bench runs end to end on a short run (numbers are measured, not asserted)."""

from __future__ import annotations

import argparse

from engine.bench import available_benches


def test_soak_bench_short_run_sends_one_packet_per_frame():
    soak = available_benches()["soak"]
    p = argparse.ArgumentParser()
    soak.add_arguments(p)
    args = p.parse_args(["--frames", "40", "--window", "10", "--warmup", "10"])
    res = soak.run(args)
    print(res)  # shown on failure
    for key in ("frames", "fps_median", "rss_growth_mb", "packets_sent"):
        assert key in res
    assert res["frames"] == 40
    assert res["packets_sent"] == 40
    assert res["opentrackio_datagrams_sent"] == 40
    assert res["freed_received"] == 40
    assert res["opentrackio_received"] == 40
    assert res["last_packets_decode"] is True
    assert res["send_errors"] == 0
    assert len(res["fps_over_time"]) == 4
