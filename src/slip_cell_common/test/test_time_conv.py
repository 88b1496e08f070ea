"""The one time conversion: seconds, nanoseconds and ``builtin_interfaces/Time``."""
from __future__ import annotations

import math

import pytest

from slip_cell_common.time_conv import (nanoseconds_to_seconds, nanoseconds_to_stamp,
                                        seconds_to_nanoseconds, seconds_to_stamp,
                                        split_nanoseconds, stamp_to_nanoseconds,
                                        stamp_to_seconds)


def test_round_trips_keep_nanoseconds() -> None:
    stamp = seconds_to_stamp(12.000000007)
    assert (stamp.sec, stamp.nanosec) == (12, 7)
    assert stamp_to_nanoseconds(stamp) == 12_000_000_007
    assert stamp_to_seconds(stamp) == pytest.approx(12.000000007, abs=1e-12)
    assert stamp_to_nanoseconds(nanoseconds_to_stamp(1_700_000_000_123_456_789)) == \
        1_700_000_000_123_456_789


def test_nanoseconds_round_and_split() -> None:
    assert seconds_to_nanoseconds(0.1234567895) == 123456790      # nearest, not truncated
    assert split_nanoseconds(3_000_000_001) == (3, 1)
    assert split_nanoseconds(999_999_999) == (0, 999_999_999)
    assert nanoseconds_to_seconds(1_500_000_000) == 1.5


@pytest.mark.parametrize('bad', [0.0, -1.0, math.nan, math.inf])
def test_unusable_seconds_give_the_zero_stamp(bad: float) -> None:
    stamp = seconds_to_stamp(bad)
    assert (stamp.sec, stamp.nanosec) == (0, 0)


def test_readers_take_any_sec_nanosec_pair() -> None:
    class RosbagsTime:  # rosbags messages are plain dataclasses with the same fields
        sec = 2
        nanosec = 500_000_000
    assert stamp_to_seconds(RosbagsTime()) == 2.5
    assert stamp_to_nanoseconds(RosbagsTime()) == 2_500_000_000
