# SPDX-License-Identifier: Apache-2.0
"""Gripper and F/T messages ↔ host records (message types only, no ``rclpy.node``).

The one set of builders for everything a gripper driver publishes (``gripper/status``,
``gripper/motor_command``, ``gripper/joint_states``, the frame arrays, ``finger_k/ft/*``) and
for the grasp-force command it consumes. ``gripper_driver``, ``netft_driver`` and the
simulated cell (``sim_gripper``) all publish through these, from the same core records.

Times are float seconds on the node clock in the cores and ``builtin_interfaces/Time`` in
messages; every stamp passed here is an acquisition stamp (ros_interfaces §4.2).
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence

from geometry_msgs.msg import TransformStamped, WrenchStamped
from sensor_msgs.msg import JointState
from slip_msgs.msg import GraspForceCommand, GripperStatus, MotorCommand, TransformArray

from slip_gripper_driver.core.gripper_records import GripperStatusSnapshot, MotorCommandRecord
from slip_cell_common.core.frames import Transform
from slip_cell_common.time_conv import seconds_to_stamp, stamp_to_seconds


def _u32(value: int) -> int:
    return int(value) & 0xFFFFFFFF


def status_msg(s: GripperStatusSnapshot) -> GripperStatus:
    """``slip_msgs/GripperStatus`` from a bridge snapshot (stamp = line arrival)."""
    msg = GripperStatus(
        line_count=_u32(s.line_count), bad_line_count=_u32(s.bad_line_count),
        reconnect_count=_u32(s.reconnect_count), motor_angle=s.motor_angle, opening=s.opening,
        opening_rate=s.opening_rate, voltage_cmd=s.voltage_cmd, force_cmd=s.force_cmd,
        force_target=s.force_target, measured_grasp_force=s.measured_grasp_force,
        homed=s.homed, ft_biased=s.ft_biased, ft_fresh=s.ft_fresh, link_ok=s.link_ok,
        in_contact=s.in_contact, command_expired=s.command_expired, armed=s.armed,
        safe_state=s.safe_state)
    msg.header.stamp = seconds_to_stamp(s.stamp)
    return msg


def motor_msg(m: MotorCommandRecord) -> MotorCommand:
    """``slip_msgs/MotorCommand`` from one controller step."""
    msg = MotorCommand(
        force_target=m.force_target, force_cmd=m.force_cmd, voltage_cmd=m.voltage_cmd,
        measured_force=m.measured_force, error=m.error, integral=m.integral,
        gain_scale=m.gain_scale, closed_loop=m.closed_loop, bypass_reason=m.bypass_reason)
    msg.header.stamp = seconds_to_stamp(m.stamp)
    return msg


def joint_state_msg(stamp: float, names: Sequence[str], opening: float, opening_rate: float,
                    measured_force: float) -> JointState:
    """Both finger joints: position = opening/2 [m], velocity = rate/2 [m/s], effort =
    measured grasp force [N] (NaN when stale or unbiased; never the commanded force)."""
    msg = JointState(name=list(names), position=[0.5 * opening] * 2,
                     velocity=[0.5 * opening_rate] * 2, effort=[measured_force] * 2)
    msg.header.stamp = seconds_to_stamp(stamp)
    return msg


def wrench_msg(stamp: float, frame_id: str, wrench: Sequence[float]) -> WrenchStamped:
    """``geometry_msgs/WrenchStamped`` (N, N·m) in ``frame_id``."""
    msg = WrenchStamped()
    msg.header.stamp = seconds_to_stamp(stamp)
    msg.header.frame_id = frame_id
    f, m = msg.wrench.force, msg.wrench.torque
    f.x, f.y, f.z = float(wrench[0]), float(wrench[1]), float(wrench[2])
    m.x, m.y, m.z = float(wrench[3]), float(wrench[4]), float(wrench[5])
    return msg


def wrench_from_msg(msg: WrenchStamped) -> tuple[float, tuple[float, ...]]:
    """``(stamp [s], (Fx, Fy, Fz, Tx, Ty, Tz))`` of a wrench message."""
    f, m = msg.wrench.force, msg.wrench.torque
    return stamp_to_seconds(msg.header.stamp), (f.x, f.y, f.z, m.x, m.y, m.z)


def transforms_msg(stamp: float, transforms: Iterable[Transform]) -> TransformArray:
    """``slip_msgs/TransformArray`` (same layout as ``tf2_msgs/TFMessage``)."""
    out = TransformArray()
    time_msg = seconds_to_stamp(stamp)
    for tr in transforms:
        ts = TransformStamped()
        ts.header.stamp = time_msg
        ts.header.frame_id = tr.parent
        ts.child_frame_id = tr.child
        v, q = ts.transform.translation, ts.transform.rotation
        v.x, v.y, v.z = tr.translation
        q.x, q.y, q.z, q.w = tr.rotation
        out.transforms.append(ts)
    return out


def grasp_command(msg: GraspForceCommand) -> tuple[float, float, float, int]:
    """``(force [N], stamp [s] (0 = unstamped), timeout [s], source)`` of a command."""
    return (float(msg.force), stamp_to_seconds(msg.header.stamp), float(msg.timeout),
            int(msg.source))


def grasp_command_msg(stamp: float, force: float, timeout: float,
                      source: int = GraspForceCommand.SOURCE_MANUAL) -> GraspForceCommand:
    """A ``slip_msgs/GraspForceCommand`` (tools and tests)."""
    msg = GraspForceCommand(force=float(force), timeout=float(timeout), source=source)
    msg.header.stamp = seconds_to_stamp(stamp)
    return msg
