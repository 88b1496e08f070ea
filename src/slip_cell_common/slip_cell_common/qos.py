"""Named QoS profiles of the cell (ros_interfaces §4.1).

A best-effort subscriber matches a reliable publisher, never the reverse, so drivers always
publish reliable and high-rate consumers subscribe best effort.

Deviation from the spec's table: SENSOR_PUB keeps the last 100 samples, not 10. With reliable
delivery the writer's history is the only slack a slow reader has; 10 samples are 20 ms at
500 Hz, and a Python recorder or estimator on a loaded 2-core machine lost data with it.
"""
from __future__ import annotations

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
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

# No default QoS-event handlers on hot-path entities. rclpy gives every publisher and
# subscription two event waitables and rebuilds the wait set in Python on every executor
# iteration; on the high-rate nodes that dominated the executor's cost. Nothing is lost: a
# best-effort volatile subscription cannot be QoS-incompatible, and for a reliable publisher
# the stricter peer reports the mismatch. Latched and command endpoints keep their handlers.
QUIET_SUB = SubscriptionEventCallbacks(use_default_callbacks=False)
QUIET_PUB = PublisherEventCallbacks(use_default_callbacks=False)
