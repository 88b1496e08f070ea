"""TfBroadcaster and the robot_description latch, checked with real subscribers.

A late-joining /tf_static subscriber must get the whole static set (transient local, one
message holding every static transform); /tf carries the finger frames with the stamp given;
robot_description reaches a subscriber that joins after it was published.
"""
from __future__ import annotations

import pytest

pytestmark = pytest.mark.ros
rclpy = pytest.importorskip('rclpy')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

from slip_cell_common.calls import spin_until  # noqa: E402
from slip_cell_common.core.frames import (FrameParams, Transform, finger_transforms,  # noqa: E402
                                          static_transforms)
from slip_cell_common.core.gripper_urdf import gripper_urdf  # noqa: E402
from slip_cell_common.tf_publishing import (ROBOT_DESCRIPTION_QOS, TF_QOS,  # noqa: E402
                                            TF_STATIC_QOS, TfBroadcaster,
                                            publish_robot_description)

TIMEOUT_S = 10.0


@pytest.fixture
def graph(ros_context: object):
    """A publishing node and a listening node on one executor."""
    executor = SingleThreadedExecutor(context=ros_context)
    talker = rclpy.create_node('tf_talker', context=ros_context)
    listener = rclpy.create_node('tf_listener', context=ros_context)
    executor.add_node(talker)
    executor.add_node(listener)
    yield executor, talker, listener
    executor.shutdown()
    talker.destroy_node()
    listener.destroy_node()


def _edges(messages: list[TFMessage]) -> dict[str, str]:
    return {t.child_frame_id: t.header.frame_id for m in messages for t in m.transforms}


def test_profiles_are_the_tf2_ros_ones() -> None:
    assert (TF_STATIC_QOS.depth, TF_STATIC_QOS.durability, TF_STATIC_QOS.reliability) == (
        1, DurabilityPolicy.TRANSIENT_LOCAL, ReliabilityPolicy.RELIABLE)
    assert (TF_QOS.depth, TF_QOS.durability, TF_QOS.reliability) == (
        100, DurabilityPolicy.VOLATILE, ReliabilityPolicy.RELIABLE)
    assert ROBOT_DESCRIPTION_QOS.durability == DurabilityPolicy.TRANSIENT_LOCAL


def test_static_and_moving_frames_reach_a_late_subscriber(graph) -> None:
    executor, talker, listener = graph
    frames = FrameParams(tf_prefix='g_')
    tf = TfBroadcaster(talker)
    tf.send_static(static_transforms(frames), 5.0)

    static_rx: list[TFMessage] = []
    moving_rx: list[TFMessage] = []
    # joins after the static set was sent: only latching can deliver it
    listener.create_subscription(TFMessage, '/tf_static', static_rx.append, TF_STATIC_QOS)
    listener.create_subscription(TFMessage, '/tf', moving_rx.append, TF_QOS)
    assert spin_until(executor, lambda: bool(static_rx), TIMEOUT_S)
    assert _edges(static_rx) == {
        'g_gripper_base_link': 'tool0', 'g_gripper_middle': 'g_gripper_base_link',
        'g_vel_sensor_1': 'g_ft_sensor_1', 'g_vel_sensor_2': 'g_ft_sensor_2'}

    opening = 0.064
    spin_until(executor, lambda: talker.count_subscribers('/tf') > 0, TIMEOUT_S)
    for _ in range(200):  # /tf is volatile: resend until the matched reader has one
        tf.send(finger_transforms(frames, opening), 7.25)
        if spin_until(executor, lambda: bool(moving_rx), 0.05):
            break
    assert moving_rx
    msg = moving_rx[-1]
    assert _edges([msg]) == {'g_ft_sensor_1': 'g_gripper_middle',
                             'g_ft_sensor_2': 'g_gripper_middle'}
    assert {(t.header.stamp.sec, t.header.stamp.nanosec) for t in msg.transforms} == {
        (7, 250_000_000)}
    z = {t.child_frame_id: t.transform.translation.z for t in msg.transforms}
    # F/T origins sit pad_offset behind each pad surface
    assert z['g_ft_sensor_2'] - z['g_ft_sensor_1'] == pytest.approx(
        opening + 2 * frames.pad_offset, abs=1e-12)


def test_static_set_is_merged_and_relatched(graph) -> None:
    executor, talker, listener = graph
    tf = TfBroadcaster(talker)
    tf.send_static(static_transforms(FrameParams()), 1.0)
    moved_base = Transform('tool0', 'gripper_base_link', (0.0, 0.0, 0.01), (0.0, 0.0, 0.0, 1.0))
    extra = Transform('gripper_middle', 'camera', (0.1, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    tf.send_static([moved_base, extra], 2.0)
    assert tf.static_children == ('gripper_base_link', 'gripper_middle', 'vel_sensor_1',
                                  'vel_sensor_2', 'camera')

    received: list[TFMessage] = []
    listener.create_subscription(TFMessage, '/tf_static', received.append, TF_STATIC_QOS)
    assert spin_until(executor, lambda: bool(received), TIMEOUT_S)
    latched = received[-1]
    assert len(latched.transforms) == 5  # one message holds the whole set, no duplicates
    by_child = {t.child_frame_id: t for t in latched.transforms}
    assert by_child['gripper_base_link'].transform.translation.z == pytest.approx(0.01)
    assert by_child['camera'].header.frame_id == 'gripper_middle'


def test_robot_description_is_latched(graph) -> None:
    executor, talker, listener = graph
    urdf = gripper_urdf(FrameParams(tf_prefix='g_'))
    publisher = publish_robot_description(talker, urdf)
    received: list[String] = []
    listener.create_subscription(String, 'robot_description', received.append,
                                 ROBOT_DESCRIPTION_QOS)
    assert spin_until(executor, lambda: bool(received), TIMEOUT_S)
    assert received[0].data == urdf
    assert publisher.topic_name == '/robot_description'

