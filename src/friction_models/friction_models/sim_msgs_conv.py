# SPDX-License-Identifier: Apache-2.0
"""Ground-truth messages of the simulated cell (``sim/*``; message types only, no rclpy.node).

What the simulator publishes in place of the drivers (gripper status, motor command, joint
states, frames, wrenches, twists) goes through the drivers' own builders
(`slip_gripper_driver.gripper_msgs_conv`, `slip_velocity_sensor.velocity_msgs_conv`); only the
simulator's own topics are built here.
"""
from __future__ import annotations

import math

from geometry_msgs.msg import PoseStamped, TwistStamped
from slip_msgs.msg import ContactProperties, FingerContact, SimState

from friction_models.core.presets import ContactPreset
from friction_models.core.sim_cell import SimState as CoreSimState
from slip_cell_common.time_conv import seconds_to_stamp


def sim_state_msg(state: CoreSimState, frame_id: str, realtime_factor: float) -> SimState:
    """Ground truth of the scene."""
    msg = SimState(x=state.x, y=state.y, theta=state.theta, vx=state.vx, vy=state.vy,
                   omega=state.omega, normal_force_1=state.normal_force_1,
                   normal_force_2=state.normal_force_2, opening=state.opening,
                   arm_height=state.arm_height, arm_angle=state.arm_angle,
                   realtime_factor=float(realtime_factor), object_in_grasp=state.in_grasp,
                   object_on_table=state.on_table, object_dropped=state.dropped,
                   arm_moving=state.arm_moving, preset=state.preset)
    msg.header.stamp = seconds_to_stamp(state.stamp)
    msg.header.frame_id = frame_id
    return msg


def object_pose_msg(state: CoreSimState, frame_id: str) -> PoseStamped:
    """Grasp-relative object pose in ``gripper_middle`` (planar: z rotation only)."""
    msg = PoseStamped()
    msg.header.stamp = seconds_to_stamp(state.stamp)
    msg.header.frame_id = frame_id
    msg.pose.position.x, msg.pose.position.y = state.x, state.y
    msg.pose.orientation.z = math.sin(state.theta / 2.0)
    msg.pose.orientation.w = math.cos(state.theta / 2.0)
    return msg


def object_twist_msg(state: CoreSimState, frame_id: str) -> TwistStamped:
    """Object twist relative to the gripper, ``gripper_middle`` axes."""
    msg = TwistStamped()
    msg.header.stamp = seconds_to_stamp(state.stamp)
    msg.header.frame_id = frame_id
    msg.twist.linear.x, msg.twist.linear.y = state.vx, state.vy
    msg.twist.angular.z = state.omega
    return msg


def _finger_truth(c: ContactPreset) -> FingerContact:
    return FingerContact(mu_c=c.mu_c, mu_s=c.mu_s, mu_v=c.mu_v, r=c.r, u=c.r * c.r,
                         mu_c_std=0.0, r_std=0.0, linear_valid=True, viscous_valid=True,
                         static_valid=True, rotational_valid=True)


def true_contact_msg(contacts: tuple[ContactPreset, ContactPreset], preset: str,
                     t: float) -> ContactProperties:
    """The simulator's true contact parameters (source GROUND_TRUTH)."""
    msg = ContactProperties(finger_1=_finger_truth(contacts[0]),
                            finger_2=_finger_truth(contacts[1]),
                            source=ContactProperties.SOURCE_GROUND_TRUTH, preset_name=preset,
                            valid=True)
    msg.header.stamp = seconds_to_stamp(t)
    return msg
