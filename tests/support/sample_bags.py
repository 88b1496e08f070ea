"""Small deterministic bags for tests (written with rclpy serialization)."""
from __future__ import annotations

import math
from pathlib import Path


def status_message(k: int):
    from slip_msgs.msg import GripperStatus
    msg = GripperStatus(line_count=k, motor_angle=0.01 * k, opening=math.nan, link_ok=True)
    msg.header.stamp.sec, msg.header.stamp.nanosec = 100, k * 1_000_000
    return msg


def write_sample_bag(path: Path, n: int = 50) -> None:
    from rclpy.serialization import serialize_message
    from slip_cell_common.bag_io import BagWriter
    from slip_msgs.msg import ContactProperties, GraspForceCommand
    with BagWriter(path) as bag:
        bag.add_topic('/gripper/status', 'slip_msgs/msg/GripperStatus')
        bag.add_topic('/gripper/grasp_force_cmd', 'slip_msgs/msg/GraspForceCommand')
        bag.add_topic('/contact/properties', 'slip_msgs/msg/ContactProperties', latched=True)
        props = ContactProperties(source=ContactProperties.SOURCE_PRESET, preset_name='wood')
        props.finger_1.mu_c = 0.46
        bag.write('/contact/properties', 1_000_000, serialize_message(props))
        for k in range(n):
            t = 2_000_000 + k * 2_000_000  # 500 Hz
            bag.write('/gripper/status', t, serialize_message(status_message(k)))
            if k % 10 == 0:
                bag.write('/gripper/grasp_force_cmd', t, serialize_message(
                    GraspForceCommand(force=5.0 + k, source=GraspForceCommand.SOURCE_TEST)))
