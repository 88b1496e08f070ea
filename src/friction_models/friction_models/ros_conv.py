"""Conversions between the simulated cell's core records and ROS messages (no rclpy.node)."""
from __future__ import annotations

import math

from geometry_msgs.msg import PoseStamped, TransformStamped, TwistStamped, WrenchStamped
from sensor_msgs.msg import JointState
from slip_msgs.msg import (ContactProperties, FingerContact, GripperStatus, MotorCommand,
                           PlanarSlip, SimState, TransformArray)

from friction_models.core.presets import ContactPreset
from friction_models.core.sensors import FtSample, TelemetrySample
from friction_models.core.sim_cell import SimState as CoreSimState
from friction_models.core.sim_cell import SimStatus
from slip_cell_common.core.frames import Transform
from slip_cell_common.time_conv import seconds_to_stamp
from slip_velocity_sensor.core.session import Sample


def wrench_msg(sample: FtSample, values: tuple[float, ...], frame_id: str) -> WrenchStamped:
    """An F/T record (6 values, sensor frame) as WrenchStamped stamped at acquisition."""
    msg = WrenchStamped()
    msg.header.stamp = seconds_to_stamp(sample.stamp)
    msg.header.frame_id = frame_id
    f, tq = msg.wrench.force, msg.wrench.torque
    f.x, f.y, f.z, tq.x, tq.y, tq.z = (float(v) for v in values)
    return msg


def twist_msg(sample: Sample, frame_id: str) -> TwistStamped:
    """A velocity-sensor sample (pad frame, SI) as TwistStamped."""
    msg = TwistStamped()
    msg.header.stamp = seconds_to_stamp(sample.stamp)
    msg.header.frame_id = frame_id
    msg.twist.linear.x, msg.twist.linear.y = float(sample.vx), float(sample.vy)
    msg.twist.angular.z = float(sample.omega)
    return msg


def planar_slip_msg(sample: Sample, frame_id: str) -> PlanarSlip:
    """A velocity-sensor sample with its integrated displacement as PlanarSlip."""
    msg = PlanarSlip(vx=float(sample.vx), vy=float(sample.vy), omega=float(sample.omega),
                     x=float(sample.x), y=float(sample.y), theta=float(sample.theta),
                     chip_mode=max(0, int(sample.chip_mode)),
                     excluded_chip=int(sample.excluded_chip),
                     residual_ratio=float(sample.residual_ratio), valid=bool(sample.valid))
    msg.header.stamp = seconds_to_stamp(sample.stamp)
    msg.header.frame_id = frame_id
    return msg


def motor_command_msg(tel: TelemetrySample) -> MotorCommand:
    """One inner-loop step (logging) from a telemetry tick."""
    msg = MotorCommand(force_target=float(tel.force_target), force_cmd=float(tel.force_cmd),
                       voltage_cmd=float(tel.voltage_cmd), measured_force=float(tel.measured_force),
                       error=float(tel.error), integral=float(tel.integral),
                       gain_scale=float(tel.gain_scale), closed_loop=bool(tel.closed_loop),
                       bypass_reason=int(tel.bypass_reason))
    msg.header.stamp = seconds_to_stamp(tel.stamp)
    return msg


def gripper_status_msg(tel: TelemetrySample, status: SimStatus, line_count: int,
                       ft_fresh: bool) -> GripperStatus:
    """Gripper status of a telemetry tick (the simulated link never drops)."""
    msg = GripperStatus(
        line_count=line_count & 0xFFFFFFFF, bad_line_count=0, reconnect_count=0,
        motor_angle=float(tel.motor_angle_rad), opening=float(status.opening),
        opening_rate=float(status.opening_rate), voltage_cmd=float(tel.voltage_cmd),
        force_cmd=float(tel.force_cmd), force_target=float(tel.force_target),
        measured_grasp_force=float(tel.measured_force), homed=bool(status.homed),
        ft_biased=bool(status.ft_biased), ft_fresh=ft_fresh, link_ok=True,
        in_contact=bool(status.in_contact), command_expired=bool(status.command_expired),
        armed=True, safe_state=False)
    msg.header.stamp = seconds_to_stamp(tel.stamp)
    return msg


def joint_state_msg(tel: TelemetrySample, status: SimStatus, prefix: str) -> JointState:
    """Finger joints (position = opening/2 each) with the measured force as effort."""
    half = status.opening / 2.0
    rate = status.opening_rate / 2.0
    msg = JointState(name=[f'{prefix}finger_1_joint', f'{prefix}finger_2_joint'],
                     position=[half, half], velocity=[rate, rate],
                     effort=[float(tel.measured_force)] * 2)
    msg.header.stamp = seconds_to_stamp(tel.stamp)
    return msg


def transform_array_msg(transforms: list[Transform], t: float) -> TransformArray:
    """Core transforms as TransformArray (same layout as tf2_msgs/TFMessage)."""
    out = TransformArray()
    for tr in transforms:
        msg = TransformStamped()
        msg.header.stamp = seconds_to_stamp(t)
        msg.header.frame_id = tr.parent
        msg.child_frame_id = tr.child
        v, q = msg.transform.translation, msg.transform.rotation
        v.x, v.y, v.z = tr.translation
        q.x, q.y, q.z, q.w = tr.rotation
        out.transforms.append(msg)
    return out


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
