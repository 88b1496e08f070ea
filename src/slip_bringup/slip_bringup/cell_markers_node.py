# SPDX-License-Identifier: Apache-2.0
"""``cell_markers``: what the cell does, drawn for RViz and Foxglove (``cell/markers``).

Subscribes to ``finger_k/ft/wrench``, ``finger_k/slip/twist`` and ``slip_control/tracking``
and publishes a ``visualization_msgs/MarkerArray`` of the pads, contact forces, slip
velocities and the slip target at ``rate`` Hz (pictures and frames in
`slip_bringup.core.cell_markers`). It works on hardware and in simulation alike; the
simulator adds the object and the table on ``sim/markers``. View both together with the TF
tree (``/tf``, ``/tf_static``) and ``robot_description``, fixed frame ``tool0`` (or ``world``
in simulation).

Inputs are polled, not called back: the wrenches alone arrive at 2 × 500 Hz, and a Python
callback per message cost about a fifth of a core for a 20 Hz picture. The subscriptions keep
only the newest sample (depth 1) in a callback group the executor never runs, and the timer
takes that sample from each one (`take_latest`); nothing wakes the node between frames.
Freshness is judged against the newest data stamp seen (simulated time in simulation), so the
node needs no clock of its own: under ``use_sim_time`` its ``/clock`` subscription (another
500 Hz) is dropped and the timer runs on the steady clock.
"""
from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

from geometry_msgs.msg import TwistStamped, WrenchStamped
from rclpy.callback_groups import CallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile
from rclpy.subscription import Subscription
from visualization_msgs.msg import MarkerArray

from slip_bringup.core.cell_markers import (
    FINGERS,
    CellMarkersParams,
    Sample,
    SlipDirection,
    Tracking,
    cell_markers,
)
from slip_cell_common.core import names
from slip_cell_common.core.frames import FrameParams
from slip_cell_common.marker_conv import marker_array_msg
from slip_cell_common.node_main import run_node
from slip_cell_common.param_binding import ParameterBinding
from slip_cell_common.qos import QUIET_SUB, SENSOR_SUB
from slip_cell_common.time_conv import stamp_to_seconds
from slip_msgs.msg import SlipTracking

#: Newest sample only, with SENSOR_SUB's reliability (matches every sensor publisher).
LATEST = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                    reliability=SENSOR_SUB.reliability, durability=SENSOR_SUB.durability)


class PolledGroup(CallbackGroup):
    """A callback group the executor never runs (nor waits on): read with `take_latest`."""

    def can_execute(self, entity: Any) -> bool:
        return False

    def beginning_execution(self, entity: Any) -> bool:
        return False

    def ending_execution(self, entity: Any) -> None:
        pass


def take_latest(sub: Subscription) -> Any | None:
    """The newest message waiting on ``sub`` (older ones are discarded), or None."""
    latest = None
    with sub.handle:
        while True:
            taken = sub.handle.take_message(sub.msg_type, sub.raw)
            if taken is None:
                return latest
            latest = taken[0]


class CellMarkersNode(Node):
    """The ``cell_markers`` node; see the module docstring.

    Args:
        node_name: Node name.
        **kwargs: Passed to `rclpy.node.Node` (``context``, ``parameter_overrides``, ...).
    """

    def __init__(self, node_name: str = 'cell_markers', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._binding = ParameterBinding(self, CellMarkersParams)
        self._frame_binding = ParameterBinding(self, FrameParams, prefix='frames.')
        self._params = self._binding.load()
        self._frames = self._frame_binding.load()
        self._binding.on_change(self._on_params)
        self._wrench: list[Sample | None] = [None, None]
        self._twist: list[Sample | None] = [None, None]
        self._tracking: Tracking | None = None
        self._direction = SlipDirection(self._frames, self._params.sliding_speed)
        self._newest = 0.0
        self._pub = self.create_publisher(MarkerArray, names.CELL_MARKERS, 10)
        polled = PolledGroup()

        def sub(kind: Any, topic: str) -> Subscription:
            return self.create_subscription(kind, topic, lambda _m: None, LATEST,
                                            callback_group=polled, event_callbacks=QUIET_SUB)
        self._inputs: list[tuple[Subscription, Callable[[int, Any], None], int]] = [
            (sub(WrenchStamped, names.ft_wrench(k)), self._on_wrench, k) for k in FINGERS]
        self._inputs += [(sub(TwistStamped, names.slip_twist(k)), self._on_twist, k)
                         for k in FINGERS]
        self._inputs.append((sub(SlipTracking, names.SLIP_TRACKING),
                             lambda _k, m: self._on_tracking(m), 0))
        self._drop_clock_subscription()
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = self.create_timer(1.0 / self._params.rate, self._draw, clock=self._steady)
        self.get_logger().info(f'drawing the cell on {names.CELL_MARKERS} at '
                               f'{self._params.rate:.0f} Hz')

    def _drop_clock_subscription(self) -> None:
        for sub in [s for s in self.subscriptions if s.topic_name == names.CLOCK]:
            self.destroy_subscription(sub)

    def _on_params(self, params: CellMarkersParams) -> None:
        if params.rate != self._params.rate:
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(1.0 / params.rate, self._draw, clock=self._steady)
        self._params = params

    def _stamp(self, msg: Any) -> float:
        t = stamp_to_seconds(msg.header.stamp)
        self._newest = max(self._newest, t)
        return t

    def _on_wrench(self, finger: int, msg: WrenchStamped) -> None:
        f, m = msg.wrench.force, msg.wrench.torque
        self._wrench[finger - 1] = Sample(self._stamp(msg), (f.x, f.y, f.z, m.x, m.y, m.z))

    def _on_twist(self, finger: int, msg: TwistStamped) -> None:
        v, w = msg.twist.linear, msg.twist.angular
        self._twist[finger - 1] = Sample(self._stamp(msg), (v.x, v.y, w.z))
        self._direction.update(finger, v.x, v.y, w.z)

    def _on_tracking(self, msg: SlipTracking) -> None:
        previous = self._tracking
        if previous is not None and previous.mode != msg.mode:
            self._direction.reset()
        self._tracking = Tracking(self._stamp(msg), int(msg.mode), float(msg.ref_pos),
                                  float(msg.meas_pos), bool(msg.done))

    def _draw(self) -> None:
        for sub, handle, finger in self._inputs:
            msg = take_latest(sub)
            if msg is not None:
                handle(finger, msg)
        specs = cell_markers(self._frames, self._params,
                             (self._wrench[0], self._wrench[1]),
                             (self._twist[0], self._twist[1]), self._tracking,
                             self._direction.direction, self._newest)
        self._pub.publish(marker_array_msg(specs))


def main(args: list[str] | None = None) -> int:
    """Console script ``cell_markers``."""
    return run_node(CellMarkersNode, args)


if __name__ == '__main__':
    sys.exit(main())
