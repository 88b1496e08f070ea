"""Core transforms → geometry_msgs/TransformStamped and tf2_msgs/TFMessage."""
from __future__ import annotations

import pytest

pytestmark = pytest.mark.ros
serialization = pytest.importorskip('rclpy.serialization')

from builtin_interfaces.msg import Time  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

from slip_cell_common.core.frames import (FrameParams, Transform, finger_transforms,  # noqa: E402
                                          static_transforms)
from slip_cell_common.tf_conv import (tf_message, transform_from_msg,  # noqa: E402
                                      transform_stamped_msg)


def test_transform_fields_and_stamp() -> None:
    tr = Transform('gripper_middle', 'ft_sensor_1', (0.0, 0.0, -0.0368),
                   (0.0, 0.0, 0.4027, 0.9153))
    msg = transform_stamped_msg(tr, 12.25)
    assert (msg.header.frame_id, msg.child_frame_id) == ('gripper_middle', 'ft_sensor_1')
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 250_000_000)
    t, q = msg.transform.translation, msg.transform.rotation
    assert (t.x, t.y, t.z) == (0.0, 0.0, -0.0368)
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.4027, 0.9153)
    assert transform_from_msg(msg) == tr


def test_a_time_stamp_is_used_as_is() -> None:
    tr = Transform('a', 'b', (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0))
    stamp = Time(sec=7, nanosec=5)
    assert transform_stamped_msg(tr, stamp).header.stamp == stamp


def test_frame_set_round_trips_through_a_serialized_tf_message() -> None:
    frames = FrameParams(tf_prefix='left_')
    transforms = static_transforms(frames) + finger_transforms(frames, 0.062)
    msg = tf_message(transforms, 3.5)
    decoded = serialization.deserialize_message(serialization.serialize_message(msg), TFMessage)
    assert [transform_from_msg(m) for m in decoded.transforms] == transforms
    assert {m.header.stamp.sec for m in decoded.transforms} == {3}
    assert [m.header.frame_id for m in decoded.transforms][:2] == ['tool0',
                                                                  'left_gripper_base_link']
