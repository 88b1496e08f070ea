# SPDX-License-Identifier: Apache-2.0
"""The cell picture (`slip_bringup.core.cell_markers`): ROS-free, then the node through DDS."""
from __future__ import annotations

import math
from typing import Any

import pytest

from slip_bringup.core.cell_markers import (
    CellMarkersParams,
    Sample,
    SlipDirection,
    Tracking,
    cell_markers,
    target_markers,
)
from slip_cell_common.core.frames import FrameParams, planar_from_middle
from slip_cell_common.core.markers import GREEN, GREY, RED, Shape
from slip_control.core.controllers import SlipMode

FRAMES = FrameParams(tf_prefix='cell_a/')
P = CellMarkersParams()


def _by_id(specs: list[Any]) -> dict[tuple[str, int], Any]:
    return {(s.ns, s.id): s for s in specs}


def test_pads_wrenches_and_slip_arrows() -> None:
    wrench = (Sample(10.0, (1.0, -2.0, -8.0, 0.0, 0.0, 0.01)), None)
    twist = (Sample(10.0, (0.01, 0.0, 0.0)), Sample(9.0, (0.02, 0.0, 0.0)))
    m = _by_id(cell_markers(FRAMES, P, wrench, twist, None, None, now=10.1))
    pad_1, pad_2 = m[('pads', 1)], m[('pads', 2)]
    assert pad_1.frame_id == 'cell_a/vel_sensor_1' and pad_1.shape == Shape.CUBE
    assert pad_1.color == RED                     # loaded and slipping at 10 mm/s
    assert pad_2.color == GREY                    # no wrench: not in contact
    arrow = m[('wrench', 1)]
    assert arrow.frame_id == 'cell_a/ft_sensor_1' and arrow.shape == Shape.ARROW
    start, end = arrow.points
    assert start == (0.0, 0.0, FRAMES.pad_offset)
    assert end == pytest.approx((0.004, -0.008, FRAMES.pad_offset - 0.032))
    assert arrow.stamp == 10.0 and arrow.lifetime == P.stale_after
    assert m[('wrench', 2)].delete                # no data: removed, not frozen
    assert m[('slip', 1)].points[1] == pytest.approx((0.01, 0.0, 0.0))
    assert m[('slip', 2)].delete                  # 1.1 s old: stale
    assert all(m[('slip_target', i)].delete for i in range(3))   # no tracking


def test_contact_without_slip_is_green() -> None:
    wrench = (Sample(1.0, (0.0, 0.0, -5.0, 0, 0, 0)),) * 2
    twist = (Sample(1.0, (0.0005, 0.0, 0.0)),) * 2
    m = _by_id(cell_markers(FRAMES, P, wrench, twist, None, None, now=1.0))
    assert m[('pads', 1)].color == GREEN and m[('pads', 2)].color == GREEN


def test_slip_direction_follows_the_object_in_gripper_middle() -> None:
    direction = SlipDirection(FRAMES, min_speed=0.002, alpha=1.0)
    vx, vy = 0.0, -0.01                          # sliding down along gripper_middle −y
    for k in (1, 2):
        fx, fy, fw = planar_from_middle(FRAMES, k, vx, vy, 0.0)
        direction.update(k, fx, fy, fw)
    assert direction.direction == pytest.approx((0.0, -1.0), abs=1e-9)
    direction.update(1, 0.0, 0.0, 0.0)            # both stop: keeps the last direction
    direction.update(2, 0.0, 0.0, 0.0)
    assert direction.direction == pytest.approx((0.0, -1.0), abs=1e-9)


def test_linear_and_rotational_targets() -> None:
    lin = Tracking(5.0, int(SlipMode.LINEAR), ref_pos=0.012, meas_pos=0.010)
    m = _by_id(target_markers(FRAMES, P, lin, (0.6, -0.8), now=5.1))
    assert m[('slip_target', 0)].frame_id == 'cell_a/gripper_middle'
    assert m[('slip_target', 0)].points[1] == pytest.approx((0.0072, -0.0096, 0.0))
    assert m[('slip_target', 1)].points[1] == pytest.approx((0.006, -0.008, 0.0))
    assert '12.0 mm' in m[('slip_target', 2)].text and '10.0 mm' in m[('slip_target', 2)].text
    rot = Tracking(5.0, int(SlipMode.ROTATIONAL), ref_pos=math.radians(20.0),
                   meas_pos=math.radians(15.0))
    m = _by_id(target_markers(FRAMES, P, rot, None, now=5.0))
    arc = m[('slip_target', 0)].points
    assert m[('slip_target', 0)].shape == Shape.LINE_STRIP
    assert arc[0] == pytest.approx((0.0, -P.target_radius, 0.0), abs=1e-12)
    end_angle = math.atan2(arc[-1][1], arc[-1][0])
    assert end_angle == pytest.approx(-math.pi / 2 + math.radians(20.0))
    assert '20.0°' in m[('slip_target', 2)].text
    hold = Tracking(5.0, int(SlipMode.HOLD), 0.0, 0.0)
    assert all(s.delete for s in target_markers(FRAMES, P, hold, None, now=5.0))


@pytest.mark.ros
def test_node_publishes_the_picture(ros_context: Any) -> None:
    from geometry_msgs.msg import TwistStamped, WrenchStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from visualization_msgs.msg import Marker, MarkerArray

    from slip_bringup.cell_markers_node import CellMarkersNode
    from slip_cell_common.qos import SENSOR_PUB
    from slip_cell_common.testing import spin_until
    from slip_cell_common.time_conv import seconds_to_stamp
    from slip_msgs.msg import SlipTracking
    node = CellMarkersNode(context=ros_context)
    probe = Node('markers_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(probe)
    got: list[MarkerArray] = []
    probe.create_subscription(MarkerArray, 'cell/markers', got.append, 10)
    wrench = probe.create_publisher(WrenchStamped, 'finger_1/ft/wrench', SENSOR_PUB)
    twist = probe.create_publisher(TwistStamped, 'finger_1/slip/twist', SENSOR_PUB)
    track = probe.create_publisher(SlipTracking, 'slip_control/tracking', SENSOR_PUB)
    try:
        assert spin_until(executor, lambda: wrench.get_subscription_count() > 0 and
                          track.get_subscription_count() > 0 and len(got) > 1, 10.0)
        stamp = 100.0
        for i in range(30):                       # older samples are dropped, newest drawn
            w = WrenchStamped()
            w.header.stamp = seconds_to_stamp(stamp + 0.002 * i)
            w.wrench.force.z = -5.0 - 0.1 * i
            wrench.publish(w)
        t = TwistStamped()
        t.header.stamp = seconds_to_stamp(stamp)
        t.twist.linear.x = 0.01
        twist.publish(t)
        tr = SlipTracking(mode=2, ref_pos=0.012, meas_pos=0.01)   # LINEAR
        tr.header.stamp = seconds_to_stamp(stamp)
        track.publish(tr)

        def drawn() -> bool:
            if not got:
                return False
            ms = {(x.ns, x.id): x for x in got[-1].markers}
            arrow = ms.get(('wrench', 1))
            return arrow is not None and arrow.action == Marker.ADD and \
                ms[('slip_target', 2)].action == Marker.ADD
        assert spin_until(executor, drawn, 10.0)
        ms = {(x.ns, x.id): x for x in got[-1].markers}
        arrow = ms[('wrench', 1)]
        assert arrow.header.frame_id == 'ft_sensor_1' and arrow.type == Marker.ARROW
        assert arrow.points[1].z == pytest.approx(0.0078 + 0.004 * (-5.0 - 2.9))
        assert ms[('pads', 1)].color.r > 0.8      # loaded and slipping: red
        assert ms[('slip', 1)].points[1].x == pytest.approx(0.01)
        assert 'LINEAR' in ms[('slip_target', 2)].text
    finally:
        executor.shutdown()
        node.destroy_node()
        probe.destroy_node()
