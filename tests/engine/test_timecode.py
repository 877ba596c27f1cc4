"""SMPTE timecode: rates, drop frame, strict parsing, the generated clock, records."""

from __future__ import annotations

import numpy as np
import pytest

from engine.timecode import (
    TIMECODE_RATES,
    SourceTimecode,
    Timecode,
    TimecodeClock,
    TimecodeError,
    parse_rate,
    parse_timecode,
)


@pytest.mark.parametrize("rate", TIMECODE_RATES)
def test_every_rate_counts_and_wraps(rate):
    tc = parse_timecode("23:59:59:00", rate)
    last = tc.plus(int(tc.rate_rational[0] / tc.rate_rational[1] + 0.5) - 1)
    assert last.hours == 23
    assert last.plus(1) == Timecode(0, 0, 0, 0, rate)  # wraps at 24 h
    assert Timecode.from_frame_number(tc.frame_number, rate) == tc


def test_drop_frame_skips_labels_at_minutes_not_divisible_by_ten():
    assert str(parse_timecode("00:00:59;29", "29.97").plus(1)) == "00:01:00;02"
    assert str(parse_timecode("00:09:59;29", "29.97").plus(1)) == "00:10:00;00"
    assert str(parse_timecode("00:00:59;59", "59.94").plus(1)) == "00:01:00;04"
    # 23.976 counts 24 labels without dropping
    assert str(parse_timecode("00:00:59:23", "23.976").plus(1)) == "00:01:00:00"
    # one hour of 29.97 DF is 107892 frames (SMPTE ST 12-1)
    assert parse_timecode("01:00:00;00", "29.97").frame_number == 107892


@pytest.mark.parametrize(("text", "rate", "match"), [
    ("24:00:00:00", "25", "hours 24 is outside 0..23"),
    ("00:60:00:00", "25", "minutes 60"),
    ("00:00:00:25", "25", "frames 25 is outside 0..24 at 25 fps"),
    ("00:01:00;01", "29.97", "does not exist at 29.97 drop frame"),
    ("1:2:3", "25", "is not HH:MM:SS:FF"),
    ("ab:cd:ef:gh", "25", "is not HH:MM:SS:FF"),
    ("00:00:00:00", "27", "rate '27' is not one of"),
])
def test_malformed_timecode_is_one_line_naming_the_field(text, rate, match):
    with pytest.raises(TimecodeError, match=match) as exc:
        parse_timecode(text, rate, where="--timecode-start")
    assert "\n" not in str(exc.value)
    assert str(exc.value).startswith("--timecode-start")


def test_rates_parse_from_names_rationals_and_numbers():
    assert parse_rate("30000/1001") == "29.97"
    assert parse_rate(23.976) == "23.976"
    assert parse_rate("59.94df") == "59.94"
    assert Timecode(1, 2, 3, 4, "29.97").to_opentrackio() == {
        "hours": 1, "minutes": 2, "seconds": 3, "frames": 4,
        "frameRate": {"num": 30000, "denom": 1001}, "dropFrame": True}


def test_clock_generates_from_media_time_and_keeps_source_timecode():
    from engine.frames import Frame

    clock = TimecodeClock(parse_timecode("10:00:00:00", "25"))
    stamps = [clock.stamp(Frame(i, 1.0 + i / 25.0, None)) for i in range(4)]
    assert [str(s) for s in stamps] == ["10:00:00:00", "10:00:00:01", "10:00:00:02",
                                        "10:00:00:03"]
    # a tracker slower than the video rate: the label of the frame's own media time
    assert str(clock.stamp(Frame(9, 1.0 + 2.0, None))) == "10:00:02:00"
    own = Timecode(5, 0, 0, 7, "25")
    assert clock.stamp(Frame(10, 9.0, None, payloads=(SourceTimecode(own),))) == own
    # a start value at another rate is converted to the clock's rate
    assert TimecodeClock(Timecode(0, 0, 1, 0, "25"), "50").start == Timecode(0, 0, 1, 0, "50")


def test_every_record_carries_timecode_and_the_status_shows_it():
    from engine.pipeline import Pipeline
    from engine.sources import open_source
    from engine.trackers.ground_truth import GroundTruthParams, GroundTruthTracker

    src = open_source("synthetic:frames=3,width=64,height=48,fps=30")
    pipe = Pipeline(src, GroundTruthTracker(GroundTruthParams()),
                    timecode=TimecodeClock(parse_timecode("01:00:00:00", "30")))
    recs = list(pipe.records())
    assert [str(r.timecode) for r in recs] == ["01:00:00:00", "01:00:00:01", "01:00:00:02"]
    assert pipe.status().timecode == "01:00:00:02"
    # default: generated from 00:00:00:00 at the rate nearest the source's
    recs = list(Pipeline(open_source("synthetic:frames=2,width=64,height=48,fps=25"),
                         GroundTruthTracker(GroundTruthParams())).records())
    assert recs[1].timecode == Timecode(0, 0, 0, 1, "25")
    assert np.isfinite(recs[1].frame.timestamp_s)
