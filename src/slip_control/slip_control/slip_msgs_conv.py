# SPDX-License-Identifier: Apache-2.0
"""Message ↔ core conversions of the slip domain: sensor samples, contact properties, slip
controller requests, commands, tracking and state (may import messages, not rclpy.node).

Time: ``builtin_interfaces/Time`` ↔ float seconds on the same clock (node clock, sim time under
``use_sim_time``) through `slip_cell_common.time_conv`, the one time conversion. Every
conversion is SI in and SI out; nothing here invents values — fields the core leaves NaN stay
NaN in the message.
"""
from __future__ import annotations

import math
from typing import Any

from builtin_interfaces.msg import Time
from geometry_msgs.msg import TwistStamped, WrenchStamped
from slip_msgs.msg import ContactProperties as ContactPropertiesMsg
from slip_msgs.msg import FingerContact as FingerContactMsg
from slip_msgs.msg import GraspForceCommand, SlipControllerState, SlipTracking
from std_msgs.msg import Header

from slip_control.core.contact import ContactProperties, ContactSource, FingerContact
from slip_control.core.controllers import SlipResult, TrackingRecord
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.signals import TwistSample, WrenchSample
from slip_cell_common.time_conv import seconds_to_stamp, stamp_to_seconds


# --- sensors ----------------------------------------------------------------------------------

def wrench_from_msg(msg: WrenchStamped) -> WrenchSample:
    """Bias-removed wrench of one finger (frame ``ft_sensor_k``; N, N·m; acquisition stamp)."""
    f, tq = msg.wrench.force, msg.wrench.torque
    return WrenchSample(f.x, f.y, f.z, tq.z, stamp_to_seconds(msg.header.stamp), tq.x, tq.y)


def twist_from_msg(msg: TwistStamped) -> TwistSample:
    """Slip twist of one finger (frame ``vel_sensor_k``; m/s, rad/s; acquisition stamp).

    A NaN component (e.g. ω in single-chip mode) makes the sample unusable (`usable` false),
    so the controllers treat it as stale instead of computing with it.
    """
    v, w = msg.twist.linear, msg.twist.angular
    return TwistSample(v.x, v.y, w.z, stamp_to_seconds(msg.header.stamp))


def wrench_to_msg(sample: WrenchSample, frame_id: str) -> WrenchStamped:
    """A core wrench sample as ``WrenchStamped`` (tests, benchmarks, replays)."""
    msg = WrenchStamped()
    msg.header.stamp = seconds_to_stamp(sample.stamp)
    msg.header.frame_id = frame_id
    msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = sample.fx, sample.fy, sample.fz
    msg.wrench.torque.z = sample.tz
    return msg


def twist_to_msg(sample: TwistSample, frame_id: str) -> TwistStamped:
    """A core twist sample as ``TwistStamped`` (tests, benchmarks, replays)."""
    msg = TwistStamped()
    msg.header.stamp = seconds_to_stamp(sample.stamp)
    msg.header.frame_id = frame_id
    msg.twist.linear.x, msg.twist.linear.y = sample.vx, sample.vy
    msg.twist.angular.z = sample.omega
    return msg


# --- contact properties -----------------------------------------------------------------------

_FINGER_FIELDS = ('mu_c', 'mu_s', 'mu_v', 'r', 'u', 'mu_c_std', 'r_std', 'n_linear', 'n_static',
                  'n_rotational', 'linear_residual_rms', 'rotational_residual_rms',
                  'linear_valid', 'viscous_valid', 'static_valid', 'rotational_valid')


def finger_to_msg(f: FingerContact) -> FingerContactMsg:
    """Core finger properties → ``slip_msgs/FingerContact`` (field for field)."""
    msg = FingerContactMsg()
    for name in _FINGER_FIELDS:
        value = getattr(f, name)
        setattr(msg, name, int(value) if name.startswith('n_') else value)
    return msg


def finger_from_msg(msg: FingerContactMsg) -> FingerContact:
    """``slip_msgs/FingerContact`` → core finger properties."""
    return FingerContact(**{name: getattr(msg, name) for name in _FINGER_FIELDS})


def properties_to_msg(props: ContactProperties, stamp: Time) -> ContactPropertiesMsg:
    """Core property set → ``slip_msgs/ContactProperties``; ``valid`` is the derived flag."""
    msg = ContactPropertiesMsg()
    msg.header.stamp = stamp
    msg.finger_1 = finger_to_msg(props.finger_1)
    msg.finger_2 = finger_to_msg(props.finger_2)
    msg.source = int(props.source)
    msg.preset_name = props.preset_name
    msg.online_updated = props.online_updated
    msg.valid = props.valid
    return msg


def properties_from_msg(msg: ContactPropertiesMsg) -> ContactProperties:
    """``slip_msgs/ContactProperties`` → core property set.

    The message's ``valid`` is not copied: the core derives it from the flags and the source,
    so a message whose ``valid`` disagrees with its flags cannot unlock a slip mode.

    Raises:
        ValueError: unknown ``source`` value.
    """
    try:
        source = ContactSource(msg.source)
    except ValueError as exc:
        raise ValueError(f'contact properties with unknown source {msg.source}') from exc
    return ContactProperties(finger_from_msg(msg.finger_1), finger_from_msg(msg.finger_2),
                             source, preset_name=msg.preset_name,
                             online_updated=msg.online_updated)


# --- slip controller --------------------------------------------------------------------------

def mode_request(msg: Any) -> ModeRequest:
    """``SetSlipMode.Request`` or ``ExecuteSlip.Goal`` → `ModeRequest` (SI, unvalidated)."""
    d = msg.direction
    return ModeRequest(mode=int(msg.mode), duration=float(msg.duration),
                       distance=float(msg.distance), angle=float(msg.angle),
                       direction=(float(d.x), float(d.y), float(d.z)),
                       latch_direction=bool(msg.latch_direction),
                       control_law=str(msg.control_law))


def grasp_force_command(force: float, timeout: float, stamp: Time,
                        source: int) -> GraspForceCommand:
    """A ``GraspForceCommand`` [N] with expiry ``timeout`` [s] (0 = valid until replaced)."""
    if not math.isfinite(force):
        raise ValueError(f'refusing to command a non-finite grasp force {force!r}')
    msg = GraspForceCommand()
    msg.header.stamp = stamp
    msg.force = float(force)
    msg.timeout = float(timeout)
    msg.source = source
    return msg


def tracking_to_msg(rec: TrackingRecord) -> SlipTracking:
    """Core tracking row → ``slip_msgs/SlipTracking`` (stamp = triggering twist stamp)."""
    msg = SlipTracking()
    msg.header.stamp = seconds_to_stamp(rec.stamp)
    msg.mode = int(rec.mode)
    msg.ref_pos, msg.ref_vel = rec.ref_pos, rec.ref_vel
    msg.meas_pos, msg.meas_vel = rec.meas_pos, rec.meas_vel
    msg.force_cmd, msg.f_slip, msg.integral = rec.force_cmd, rec.f_slip, rec.integral
    msg.done = rec.done
    return msg


def fill_slip_result(result_msg: Any, res: SlipResult) -> Any:
    """Copy a core `SlipResult` into an ``ExecuteSlip.Result``; returns it."""
    result_msg.success = res.success
    result_msg.message = res.message
    result_msg.final_pos = res.final_pos
    result_msg.final_error = res.final_error
    result_msg.elapsed = res.elapsed
    return result_msg


def controller_state(stamp: Time, mode: int, goal_active: bool, contact_valid: bool,
                     velocity_fresh: bool, ft_fresh: bool, safe_hold: bool,
                     reason: str) -> SlipControllerState:
    """A ``SlipControllerState`` message."""
    return SlipControllerState(header=Header(stamp=stamp), mode=mode, goal_active=goal_active,
                               contact_valid=contact_valid, velocity_fresh=velocity_fresh,
                               ft_fresh=ft_fresh, safe_hold=safe_hold, reason=reason)
