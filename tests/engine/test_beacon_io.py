"""Beacon inputs: layouts, CSV range logs (errors counted), the UDP listener on loopback."""

from __future__ import annotations

import json
import socket
from pathlib import Path

import pytest

from engine.beacons.io import (
    InputStats,
    UdpRangeListener,
    load_layout,
    parse_datagram,
    parse_range_csv,
    read_range_csv,
    save_layout,
    send_ranges,
)
from engine.beacons.simulator import PAPER_LAYOUT
from engine.errors import SourceError


@pytest.mark.parametrize("suffix", [".json", ".csv"])
def test_layout_round_trip(tmp_path: Path, suffix: str) -> None:
    p = tmp_path / f"layout{suffix}"
    save_layout(p, PAPER_LAYOUT)
    assert load_layout(p) == PAPER_LAYOUT


def test_layout_errors_are_one_line(tmp_path: Path) -> None:
    p = tmp_path / "bad.json"
    p.write_text('{"beacons": [{"id": "A"}]}')
    with pytest.raises(SourceError, match=r"bad\.json"):
        load_layout(p)
    with pytest.raises(SourceError, match="not found"):
        load_layout(tmp_path / "missing.csv")


def test_csv_parser_groups_steps_and_counts_errors() -> None:
    lines = [
        "timestamp,beacon_id,range_m",  # header
        "# comment",
        "0.0, A, 14.1",
        "0.0, B, 22.0",
        "0.1, A, 14.0",
        "0.1, B, not-a-number",  # malformed
        "0.1, Z, 5.0",  # unknown id
        "0.1, A, 14.2",  # duplicate within the step
        "0.1, C",  # malformed: 2 fields
        "0.05, C, 20.0",  # out of order
        "0.2, C, -1.0",  # malformed: negative range
        "0.2, D, 15.0",
    ]
    steps, stats = parse_range_csv(lines, known_ids=PAPER_LAYOUT)
    assert [s.timestamp_s for s in steps] == [0.0, 0.1, 0.2]
    assert dict(steps[0].ranges_m) == {"A": 14.1, "B": 22.0}
    assert dict(steps[1].ranges_m) == {"A": 14.2}
    assert dict(steps[2].ranges_m) == {"D": 15.0}
    assert stats.malformed == 3
    assert stats.unknown_ids == 1
    assert stats.unknown_id_names == {"Z"}
    assert stats.duplicates == 1
    assert stats.out_of_order == 1
    assert stats.steps == 3
    assert len(stats.first_errors) == 6


def test_csv_window_groups_nearby_timestamps(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    p.write_text("0.00,A,1\n0.01,B,2\n0.02,C,3\n0.5,A,1\n")
    steps, stats = read_range_csv(p, window_s=0.05)
    assert len(steps) == 2
    assert set(steps[0].ranges_m) == {"A", "B", "C"}
    assert stats.malformed == 0


def test_datagram_parser_counts_bad_messages() -> None:
    stats = InputStats()
    ok = parse_datagram(
        json.dumps({"timestamp_s": 1.5, "ranges_m": {"A": 3.0, "Q": 1.0, "B": "x"},
                    "gt_xy": [1, 2]}).encode(),
        PAPER_LAYOUT,
        stats,
    )
    assert ok is not None
    assert dict(ok.ranges_m) == {"A": 3.0}
    assert ok.gt_xy == (1.0, 2.0)
    assert parse_datagram(b"{not json", PAPER_LAYOUT, stats) is None
    assert parse_datagram(b'{"timestamp_s": 1.0}', PAPER_LAYOUT, stats) is None
    assert stats.malformed == 3
    assert stats.unknown_ids == 1


def test_udp_listener_receives_on_loopback() -> None:
    with UdpRangeListener("127.0.0.1", 0, known_ids=PAPER_LAYOUT) as listener:
        assert listener.host == "127.0.0.1"
        assert listener.port > 0
        send_ranges(listener.port, 2.0, {"A": 14.0, "D": 15.5})
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.sendto(b"garbage", ("127.0.0.1", listener.port))
        step = None
        for _ in range(20):
            step = listener.receive(0.2)
            if step is not None:
                break
        assert step is not None
        assert step.timestamp_s == 2.0
        assert dict(step.ranges_m) == {"A": 14.0, "D": 15.5}
        assert listener.receive(0.5) is None  # the garbage datagram: counted, not raised
        assert listener.stats.malformed == 1
        assert listener.receive(0.05) is None  # timeout
