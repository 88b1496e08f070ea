"""A fresh shell needs only ``source install/setup.bash`` to run an installed node.

The node runs under ``env -i`` (no inherited PYTHONPATH, LD_LIBRARY_PATH, AMENT_PREFIX_PATH or
venv) with just HOME, PATH=/usr/bin:/bin, the private domain and the loopback restriction; a
second process (this test) must receive its topic.
"""
from __future__ import annotations

import os
import shlex
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[1]


def test_installed_console_script_runs_from_a_fresh_shell(ros_context, tmp_path: Path) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from slip_cell_common.qos import SENSOR_SUB
    from slip_cell_common.testing import NodeProcess, spin_until
    from slip_msgs.msg import GripperStatus

    exe = ROOT / 'install' / 'friction_models' / 'lib' / 'friction_models' / 'sim_gripper'
    assert os.access(exe, os.X_OK)
    script = (f'source {shlex.quote(str(ROOT / "install" / "setup.bash"))} && '
              f'exec {shlex.quote(str(exe))} --ros-args -r __node:=fresh_shell_sim')
    env = {'HOME': os.environ.get('HOME', '/root'), 'PATH': '/usr/bin:/bin',
           'ROS_DOMAIN_ID': os.environ['ROS_DOMAIN_ID'],
           'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
           'ROS_LOG_DIR': os.environ.get('ROS_LOG_DIR', str(tmp_path))}
    proc = NodeProcess(['env', '-i', *[f'{k}={v}' for k, v in env.items()],
                        'bash', '-c', script], tmp_path / 'fresh.log')
    node = Node('fresh_shell_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    got: list[GripperStatus] = []
    node.create_subscription(GripperStatus, 'gripper/status', got.append, SENSOR_SUB)
    try:
        assert spin_until(executor, lambda: len(got) >= 20, 30.0), proc.output()
    finally:
        executor.shutdown()
        node.destroy_node()
        code = proc.stop()
    assert code == 0, proc.output()
    assert got[-1].link_ok
