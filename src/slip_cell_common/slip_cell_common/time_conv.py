# SPDX-License-Identifier: Apache-2.0
"""The one conversion between float seconds and ``builtin_interfaces/Time``.

Cores carry time as float seconds on the node clock (simulated time under ``use_sim_time``);
messages carry ``builtin_interfaces/Time``. Every node, bag tool and test converts here.
"""
from __future__ import annotations

import math

from builtin_interfaces.msg import Time

NS_PER_S = 1_000_000_000


def seconds_to_stamp(t: float) -> Time:
    """Float seconds → ``builtin_interfaces/Time`` (non-finite or non-positive → zero stamp)."""
    if not math.isfinite(t) or t <= 0.0:
        return Time()
    return nanoseconds_to_stamp(int(round(t * 1e9)))


def stamp_to_seconds(stamp: Time) -> float:
    """``builtin_interfaces/Time`` → float seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def nanoseconds_to_stamp(ns: int) -> Time:
    """Integer nanoseconds (e.g. ``Clock.now().nanoseconds``) → ``builtin_interfaces/Time``."""
    return Time(sec=ns // NS_PER_S, nanosec=ns % NS_PER_S)


def stamp_to_nanoseconds(stamp: Time) -> int:
    """``builtin_interfaces/Time`` → integer nanoseconds."""
    return stamp.sec * NS_PER_S + stamp.nanosec
