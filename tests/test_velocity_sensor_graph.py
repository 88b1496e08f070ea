# SPDX-License-Identifier: Apache-2.0
"""The installed ``velocity_sensor`` console script in its own process against the firmware
emulator on a pseudo-terminal, seen from this process through real DDS; and the
``calibration_recorder`` running the (time-scaled) stop-to-stop procedure against it, with the
bag read back by the calibration fit's bag reader.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any
from collections.abc import Iterator

import numpy as np
import pytest

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / 'install' / 'slip_velocity_sensor' / 'lib' / 'slip_velocity_sensor'
PARAMS = ROOT / 'src' / 'slip_velocity_sensor' / 'config' / 'velocity_sensor_1.yaml'
TWIST = (0.015, 0.008, -0.2)


@pytest.fixture
def sensor_process(ros_env: dict[str, str], tmp_path: Path) -> Iterator[tuple[Any, Any]]:
    """A pty emulator and the installed node script configured for it (autostart)."""
    from slip_cell_common.testing import NodeProcess
    from slip_velocity_sensor.core import calibration as cal_mod
    from slip_velocity_sensor.core.emulator import (ConstantTwist, EmulatorParams,
                                                    FirmwareEmulator, PtyEmulator)

    truth = cal_mod.load_calibration(ROOT / 'src' / 'slip_velocity_sensor' / 'config'
                                     / 'calibration_sensor_1.yaml')
    pty = PtyEmulator(FirmwareEmulator(EmulatorParams(name='sensor_1', truth=truth),
                                       ConstantTwist(*TWIST))).start()
    script = SCRIPT / 'velocity_sensor'
    assert script.is_file(), 'run `make setup` first'
    proc = NodeProcess([str(script), '--ros-args', '-r', '__node:=velocity_sensor_1',
                        '--params-file', str(PARAMS), '-p', f'port:={pty.port}',
                        '-p', f'lock_dir:={tmp_path}'], tmp_path / 'velocity_sensor.log', ros_env)
    try:
        yield pty, proc
    finally:
        proc.stop()
        pty.stop()


def test_installed_console_script_publishes_the_twist(ros_context: Any,
                                                      sensor_process: tuple[Any, Any]) -> None:
    from geometry_msgs.msg import TwistStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_srvs.srv import Trigger

    from slip_cell_common.qos import SENSOR_SUB
    from slip_cell_common.testing import call_service, spin_until

    pty, proc = sensor_process
    node = Node('twist_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    twists: list[TwistStamped] = []
    node.create_subscription(TwistStamped, 'finger_1/slip/twist', twists.append, SENSOR_SUB)
    try:
        assert spin_until(executor, lambda: len(twists) >= 60, 15.0), proc.output()
        assert twists[-1].header.frame_id == 'vel_sensor_1'
        # The installed calibration of sensor_1 was uploaded, so the speeds are true speeds
        # (speed_term zero drops the small a-term: within 2 %).
        mean = [float(np.mean([m.twist.linear.x for m in twists[10:]])),
                float(np.mean([m.twist.linear.y for m in twists[10:]])),
                float(np.mean([m.twist.angular.z for m in twists[10:]]))]
        assert mean == pytest.approx(TWIST, rel=0.04)
        reset = call_service(executor, node.create_client(Trigger, 'finger_1/slip/reset_pose'),
                             Trigger.Request(), timeout_s=10.0)
        assert reset is not None and reset.success, proc.output()
    finally:
        executor.shutdown()
        node.destroy_node()
    assert proc.stop() == 0, proc.output()                  # SIGINT: clean lifecycle shutdown
    assert 'sensor_1 identified' in proc.output()
    from slip_cell_common.core.serial_transport import open_stream
    open_stream(pty.port, 115200, 0.05).close()              # the port was released


def test_calibration_recorder_records_a_single_chip_bag(sensor_process: tuple[Any, Any],
                                                        tmp_path: Path,
                                                        capsys: pytest.CaptureFixture) -> None:
    from slip_cell_common.bag_io import read_messages
    from slip_velocity_sensor import calibration_fit, calibration_recorder
    from slip_velocity_sensor.core import calibration as cal_mod
    from slip_velocity_sensor.core.fusion import DEFAULT_CHIP_ANGLES, model_matrix

    pty, proc = sensor_process
    out = tmp_path / 'recordings'
    code = calibration_recorder.main(['--finger', '1', '--chips', '2', '--axes', 'x',
                                      '--output-dir', str(out), '--time-scale', '0.02',
                                      '--warn-before', '0', '--yes', '--service-timeout', '15'])
    printed = capsys.readouterr().out
    assert code == 0, printed + proc.output()
    assert 'GO   traverse 12/12' in printed and 'procedure finished' in printed
    assert pty.emulator.chip_mode == 0                       # back to fused afterwards
    bag = out / 'Sensor1chip2x'
    data = read_messages(bag, ['/finger_1/slip/chips', '/finger_1/slip/state'])
    chips = [msg for _, msg in data['/finger_1/slip/chips']]
    assert len(chips) > 150 and {m.chip_mode for m in chips} == {2}   # ≈ 2.6 s at 120 Hz
    assert data['/finger_1/slip/state'][-1][1].chip_mode == 0         # fused at the end
    # The fit tool reads the bag: chip 2's raw tangential speed of the scripted motion.
    t, v = calibration_fit.read_bag_recording(bag, 2, 'x')
    assert len(t) == len(chips) and np.all(np.diff(t) >= 0.0)
    truth = cal_mod.load_calibration(ROOT / 'src' / 'slip_velocity_sensor' / 'config'
                                     / 'calibration_sensor_1.yaml')
    true_x = (model_matrix(truth.radius, DEFAULT_CHIP_ANGLES) @ np.array(TWIST))[2]
    expected = cal_mod.raw_speed(true_x, truth.axis(2, 'x'), 'abs')
    assert float(np.mean(v[10:])) == pytest.approx(expected, rel=0.05)
    assert all(math.isfinite(x) for x in v)
