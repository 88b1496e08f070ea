"""Named QoS profiles of the cell (ros_interfaces spec §4.1).

A best-effort subscriber matches a reliable publisher, never the reverse, so drivers always
publish reliable and high-rate consumers subscribe best effort.

Deviation from the spec's table: SENSOR_PUB keeps the last 100 samples, not 10. With reliable
delivery the writer's history is the only slack a slow reader has; 10 samples are 20 ms at
500 Hz, and a Python recorder or estimator on a loaded 2-core machine lost data with it.
"""
from __future__ import annotations

from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)
from rclpy.qos_overriding_options import QoSOverridingOptions

SENSOR_PUB = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)
SENSOR_SUB = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5,
                        reliability=ReliabilityPolicy.BEST_EFFORT,
                        durability=DurabilityPolicy.VOLATILE)
COMMAND = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)
LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
DIAGNOSTICS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
CLOCK = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                   reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.VOLATILE)


def overridable() -> QoSOverridingOptions:
    """Publisher option that lets users change reliability/depth/durability from YAML."""
    return QoSOverridingOptions.with_default_policies()
