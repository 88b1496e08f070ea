# SPDX-License-Identifier: Apache-2.0
"""The one conversion between float seconds and ``builtin_interfaces/Time``.

Cores carry time as float seconds on the node clock (simulated time under ``use_sim_time``);
messages carry ``builtin_interfaces/Time``. Every node, bag tool and test converts here. The
readers (`stamp_to_seconds`, `stamp_to_nanoseconds`) take any object with ``sec`` and
``nanosec`` (rclpy and rosbags messages alike); `split_nanoseconds` serves writers of other
message classes (rosbags).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from builtin_interfaces.msg import Time

if TYPE_CHECKING:
    from rclpy.clock import Clock

NS_PER_S = 1_000_000_000


def seconds_to_nanoseconds(t: float) -> int:
    """Float seconds → integer nanoseconds (rounded to the nearest)."""
    return int(round(t * 1e9))


def split_nanoseconds(ns: int) -> tuple[int, int]:
    """Integer nanoseconds → ``(sec, nanosec)`` with ``0 <= nanosec < 1e9``."""
    return ns // NS_PER_S, ns % NS_PER_S


def seconds_to_stamp(t: float) -> Time:
    """Float seconds → ``builtin_interfaces/Time`` (non-finite or non-positive → zero stamp)."""
    if not math.isfinite(t) or t <= 0.0:
        return Time()
    return nanoseconds_to_stamp(seconds_to_nanoseconds(t))


def stamp_to_seconds(stamp: Any) -> float:
    """``builtin_interfaces/Time`` (or any ``sec``/``nanosec`` pair) → float seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def nanoseconds_to_stamp(ns: int) -> Time:
    """Integer nanoseconds (e.g. ``Clock.now().nanoseconds``) → ``builtin_interfaces/Time``."""
    sec, nanosec = split_nanoseconds(ns)
    return Time(sec=sec, nanosec=nanosec)


def nanoseconds_to_seconds(ns: int) -> float:
    """Integer nanoseconds (a clock reading or a duration) → float seconds."""
    return ns * 1e-9


def clock_seconds(clock: Clock) -> float:
    """The current time of an rclpy clock (``node.get_clock()``) in float seconds."""
    return nanoseconds_to_seconds(clock.now().nanoseconds)


def stamp_to_nanoseconds(stamp: Any) -> int:
    """``builtin_interfaces/Time`` → integer nanoseconds."""
    return stamp.sec * NS_PER_S + stamp.nanosec
