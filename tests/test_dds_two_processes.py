"""Two processes exchange a custom message and a custom service call through real DDS."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros


def test_custom_message_and_service_across_processes(ros_context, ros_env, tmp_path: Path) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from slip_cell_common.qos import SENSOR_SUB
    from slip_cell_common.testing import NodeProcess, call_service, spin_until
    from slip_msgs.msg import GraspForceCommand
    from slip_msgs.srv import SetSlipMode

    peer = NodeProcess([sys.executable, str(Path(__file__).parent / 'peers' / 'interface_peer.py'),
                        '--force', '12.5'], tmp_path / 'peer.log', ros_env)
    node = Node('dds_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    received: list[GraspForceCommand] = []
    node.create_subscription(GraspForceCommand, 'peer/force_cmd', received.append, SENSOR_SUB)
    client = node.create_client(SetSlipMode, 'peer/set_mode')
    try:
        assert spin_until(executor, lambda: len(received) >= 3, timeout_s=15.0), peer.output()
        msg = received[-1]
        assert msg.force == pytest.approx(12.5)
        assert msg.source == GraspForceCommand.SOURCE_TEST
        assert msg.timeout == pytest.approx(0.1)

        ok = call_service(executor, client, SetSlipMode.Request(
            mode=SetSlipMode.Request.HOLD, duration=2.0), timeout_s=15.0)
        assert ok is not None, peer.output()
        assert ok.success and ok.message == 'mode=4 duration=2.000'
        refused = call_service(executor, client, SetSlipMode.Request(
            mode=SetSlipMode.Request.LINEAR, duration=0.5), timeout_s=5.0)
        assert refused is not None and not refused.success
        assert refused.message == 'mode=2 duration=0.500'
    finally:
        executor.shutdown()
        node.destroy_node()
        code = peer.stop()
    assert code == 0, peer.output()
