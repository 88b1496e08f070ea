"""Peer process for test_dds_two_processes: publishes a custom message, serves a custom service.

It publishes ``peer/force_cmd`` (slip_msgs/GraspForceCommand, 20 Hz, force = --force) and serves
``peer/set_mode`` (slip_msgs/SetSlipMode): success only for HOLD, message echoing the request.
"""
from __future__ import annotations

import argparse
import sys

from rclpy.node import Node
from slip_cell_common.node_main import run_node
from slip_cell_common.qos import COMMAND
from slip_msgs.msg import GraspForceCommand
from slip_msgs.srv import SetSlipMode


class InterfacePeer(Node):
    """Publishes and serves slip_msgs types for the cross-process test."""

    def __init__(self, force: float) -> None:
        super().__init__('interface_peer')
        self._force = force
        self._pub = self.create_publisher(GraspForceCommand, 'peer/force_cmd', COMMAND)
        self.create_service(SetSlipMode, 'peer/set_mode', self._on_set_mode)
        self.create_timer(0.05, self._publish)

    def _publish(self) -> None:
        msg = GraspForceCommand(force=self._force, timeout=0.1,
                                source=GraspForceCommand.SOURCE_TEST)
        msg.header.stamp = self.get_clock().now().to_msg()
        self._pub.publish(msg)

    def _on_set_mode(self, req: SetSlipMode.Request,
                     res: SetSlipMode.Response) -> SetSlipMode.Response:
        res.success = req.mode == SetSlipMode.Request.HOLD
        res.message = f'mode={req.mode} duration={req.duration:.3f}'
        return res


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument('--force', type=float, required=True)
    ns, ros_args = parser.parse_known_args()
    return run_node(lambda: InterfacePeer(ns.force), [sys.argv[0], *ros_args])


if __name__ == '__main__':
    sys.exit(main())
