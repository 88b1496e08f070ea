# SPDX-License-Identifier: Apache-2.0
"""The INSTALLED ``gripper_driver`` console script in its own process against the pty firmware
emulator: status received over DDS in the test process, commands applied, SIGINT → shutdown
transition → the safe voltage is the last thing written."""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from slip_cell_common.time_conv import clock_seconds

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_installed_gripper_driver_against_the_pty_emulator(ros_context: Any,
                                                           ros_env: dict[str, str],
                                                           tmp_path: Path) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile
    from slip_msgs.msg import GraspForceCommand, GripperStatus

    from slip_gripper_driver.gripper_msgs_conv import grasp_command_msg
    from slip_cell_common.qos import COMMAND
    from slip_gripper_driver.core.firmware_emulator import (FirmwareEmulator,
                                                            GripperModelParams,
                                                            PtyFirmwareEmulator)
    from slip_cell_common.testing import NodeProcess, spin_until, workspace_root

    root = workspace_root()
    exe = root / 'install' / 'slip_gripper_driver' / 'lib' / 'slip_gripper_driver' / \
        'gripper_driver'
    assert exe.is_file(), f'{exe} missing: run make setup'
    share = root / 'src' / 'slip_gripper_driver' / 'config'
    firmware = PtyFirmwareEmulator(FirmwareEmulator(GripperModelParams(initial_opening=0.04)),
                                   link_path=str(tmp_path / 'usb-gripper'))
    firmware.start()
    params = tmp_path / 'site.yaml'
    params.write_text(
        'gripper_driver:\n  ros__parameters:\n'
        f"    serial: {{port: '{firmware.port}'}}\n"
        "    ft: {mode: 'topic'}\n"  # no boxes here; the loop runs open (F/T stale)
        '    link: {stale_after: 0.5, fault_after: 1.0}\n')
    proc = NodeProcess([str(exe), '--ros-args', '--params-file', str(share / 'cell.yaml'),
                        '--params-file', str(share / 'gripper_driver.yaml'),
                        '--params-file', str(params)], tmp_path / 'gripper_driver.log', ros_env)
    probe = Node('probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(probe)
    statuses: list[GripperStatus] = []
    probe.create_subscription(GripperStatus, 'gripper/status', statuses.append,
                              QoSProfile(depth=100))
    pub = probe.create_publisher(GraspForceCommand, 'gripper/grasp_force_cmd', COMMAND)
    try:
        assert spin_until(executor, lambda: len(statuses) >= 100, 20.0), proc.output()
        last = statuses[-1]
        assert last.link_ok and last.armed and last.line_count >= 50 and not last.ft_fresh
        assert spin_until(executor, lambda: pub.get_subscription_count() > 0, 10.0)
        now = clock_seconds(probe.get_clock())
        pub.publish(grasp_command_msg(now, -4.0, 0.0, GraspForceCommand.SOURCE_TEST))
        assert spin_until(executor, lambda: statuses[-1].voltage_cmd > 1.0, 5.0), proc.output()
        assert firmware.wait_for(lambda: firmware.emulator.target_voltage_v > 1.0, 2.0)
    finally:
        code = proc.stop()
        executor.shutdown()
        probe.destroy_node()
        time.sleep(0.05)  # the emulator reads the pty in its own thread
        last_commands = list(firmware.emulator.commands)[-2:]
        firmware.stop()
    log = proc.output()
    assert code == 0, log
    assert last_commands[-1] == b'T0.00', (last_commands, log)  # SIGINT → safe voltage
    assert firmware.emulator.target_voltage_v == 0.0
    assert 'safe voltage written' in log
