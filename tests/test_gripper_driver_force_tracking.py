# SPDX-License-Identifier: Apache-2.0
"""force_tracking_test: the profile goes out at 500 Hz with SOURCE_TEST and is recorded; the
``analyze BAG`` subcommand recovers a known first-order response from a bag."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from slip_cell_common.core.force_profile import ForceTrackingProfile
from slip_cell_common.time_conv import (seconds_to_nanoseconds, split_nanoseconds,
                                        stamp_to_seconds)

TAU_S = 0.01  # first-order lag of the synthetic "gripper": f_-3dB = 1/(2π τ) ≈ 15.9 Hz


def _write_bag(path: Path, profile: ForceTrackingProfile, t0: float) -> None:
    from slip_cell_common.bag_io import BagWriter
    writer = BagWriter(path)
    store = writer.typestore
    Time = store.types['builtin_interfaces/msg/Time']
    Header = store.types['std_msgs/msg/Header']
    Vector3 = store.types['geometry_msgs/msg/Vector3']
    Wrench = store.types['geometry_msgs/msg/Wrench']
    WrenchStamped = store.types['geometry_msgs/msg/WrenchStamped']
    Command = store.types['slip_msgs/msg/GraspForceCommand']
    writer.add_topic('/gripper/grasp_force_cmd', 'slip_msgs/msg/GraspForceCommand')
    writer.add_topic('/finger_1/ft/wrench', 'geometry_msgs/msg/WrenchStamped')
    dt = 1.0 / profile.rate_hz
    t = np.arange(int((profile.duration + 0.5) / dt)) * dt
    target = profile.targets(t)
    alpha = 1.0 - math.exp(-dt / TAU_S)  # exact discretisation of the lag, zero-order hold
    y = np.empty_like(target)
    y[0] = target[0]
    for k in range(1, t.size):
        y[k] = y[k - 1] + alpha * (target[k - 1] - y[k - 1])

    def header(ts: float, frame: str = '') -> Any:
        sec, nanosec = split_nanoseconds(seconds_to_nanoseconds(ts))
        return Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame)
    with writer:
        for k in range(t.size):
            ts = t0 + t[k]
            ns = seconds_to_nanoseconds(ts)
            writer.write_message('/gripper/grasp_force_cmd', ns, Command(
                header=header(ts), force=float(target[k]), timeout=0.1, source=3))
            zero = Vector3(x=0.0, y=0.0, z=0.0)
            writer.write_message('/finger_1/ft/wrench', ns + 1000, WrenchStamped(
                header=header(ts, 'ft_sensor_1'),
                wrench=Wrench(force=Vector3(x=0.0, y=0.0, z=-float(y[k])), torque=zero)))


@pytest.mark.slow
def test_analyze_subcommand_recovers_a_first_order_lag(tmp_path: Path, capsys) -> None:
    from slip_gripper_driver.force_tracking_test import analyze_bag, main
    profile = ForceTrackingProfile()
    bag = tmp_path / 'sponge_1'
    _write_bag(bag, profile, t0=1000.0)
    report = analyze_bag(bag)
    assert report.step.rise_time == pytest.approx(2.197 * TAU_S, abs=0.004)
    assert abs(report.step.overshoot) < 0.1
    assert report.bandwidth_hz == pytest.approx(1.0 / (2.0 * math.pi * TAU_S), rel=0.15)
    assert main(['analyze', str(bag)]) == 0
    out = capsys.readouterr().out
    for piece in ('rise time', 'overshoot', 'settling', '-3 dB bandwidth'):
        assert piece in out
    assert main(['analyze', str(tmp_path / 'missing')]) == 1


@pytest.mark.ros
def test_run_publishes_the_profile_at_500_hz_with_source_test_and_records(
        ros_context: Any, tmp_path: Path) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile
    from slip_msgs.msg import GraspForceCommand

    from slip_cell_common.bag_io import read_messages
    from slip_gripper_driver.force_tracking_test import COMMAND_TOPIC, run_profile
    node = Node('force_tracking_test', context=ros_context)
    sink = Node('fake_driver', context=ros_context)  # stands in for gripper_driver
    received: list[GraspForceCommand] = []
    sink.create_subscription(GraspForceCommand, COMMAND_TOPIC, received.append,
                             QoSProfile(depth=1000))
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(sink)
    try:
        bag = run_profile(node, executor, ForceTrackingProfile(), bag=tmp_path / 'ft_bag',
                          duration_s=1.0, timeout_s=0.1, wait_s=10.0)
    finally:
        executor.shutdown()
        node.destroy_node()
        sink.destroy_node()
    assert received and all(m.source == GraspForceCommand.SOURCE_TEST for m in received)
    forces = [m.force for m in received]
    assert forces[:-1] == [5.0] * (len(forces) - 1) and forces[-1] == 0.0  # 5 N hold, then 0 N
    stamps = [stamp_to_seconds(m.header.stamp) for m in received]
    assert stamps == sorted(stamps) and stamps[-1] - stamps[0] >= 0.9
    assert len(received) > 100  # a 500 Hz timer (rclpy skips periods on a loaded host)
    recorded = read_messages(bag, ['/gripper/grasp_force_cmd'])['/gripper/grasp_force_cmd']
    assert len(recorded) >= 0.8 * len(received)
