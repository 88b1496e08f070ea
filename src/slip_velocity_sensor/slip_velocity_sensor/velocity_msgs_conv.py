# SPDX-License-Identifier: Apache-2.0
"""Velocity-sensor samples ↔ ROS messages (message types only, no ``rclpy.node``).

Stamps are the samples' acquisition times (node clock when the serial line arrived); frames
are ``vel_sensor_k`` with the cell's ``tf_prefix``. SI throughout.
"""
from __future__ import annotations

import math

from geometry_msgs.msg import TwistStamped
from slip_msgs.msg import OpticalChipArray, PlanarSlip

from slip_velocity_sensor.core.protocol import N_CHIPS
from slip_velocity_sensor.core.session import Sample
from slip_cell_common.time_conv import seconds_to_stamp

NAN = math.nan


def twist_msg(sample: Sample, frame_id: str) -> TwistStamped:
    """A valid fused sample as TwistStamped: linear.x/y [m/s], angular.z [rad/s]."""
    msg = TwistStamped()
    msg.header.stamp = seconds_to_stamp(sample.stamp)
    msg.header.frame_id = frame_id
    msg.twist.linear.x = sample.vx
    msg.twist.linear.y = sample.vy
    msg.twist.angular.z = sample.omega
    return msg


def planar_slip_msg(sample: Sample, frame_id: str, chip_mode: int) -> PlanarSlip:
    """Any sample (valid or not) with the integrated pose as PlanarSlip.

    Args:
        sample: The sample.
        frame_id: Frame of the message.
        chip_mode: Mode reported when the sample's own mode is unknown (-1 while a switch
            settles): the mode being switched to.
    """
    msg = PlanarSlip(vx=sample.vx, vy=sample.vy, omega=sample.omega, x=sample.x, y=sample.y,
                     theta=sample.theta,
                     chip_mode=sample.chip_mode if sample.chip_mode >= 0 else chip_mode,
                     excluded_chip=sample.excluded_chip, residual_ratio=sample.residual_ratio,
                     valid=sample.valid)
    msg.header.stamp = seconds_to_stamp(sample.stamp)
    msg.header.frame_id = frame_id
    return msg


def chip_array_msg(sample: Sample, frame_id: str, dt: float) -> OpticalChipArray:
    """A single-chip-mode sample as OpticalChipArray.

    Only the chip under test is reported (raw chip-frame speeds, ``calibrated = False``); the
    other chips are NaN and not synced. The current firmware sends no counts (``dx``, ``dy``
    stay 0).

    Args:
        sample: Sample with ``chip_mode`` 1..3 and finite ``chip_vx``/``chip_vy``.
        frame_id: Frame of the message.
        dt: Time since the previous line [s] (NaN when unknown).
    """
    k = sample.chip_mode - 1
    vx = [NAN] * N_CHIPS
    vy = [NAN] * N_CHIPS
    synced = [False] * N_CHIPS
    vx[k], vy[k], synced[k] = sample.chip_vx, sample.chip_vy, True
    msg = OpticalChipArray(chip_mode=sample.chip_mode, dt=dt, vx=vx, vy=vy, calibrated=False,
                           synced=synced)
    msg.header.stamp = seconds_to_stamp(sample.stamp)
    msg.header.frame_id = frame_id
    return msg
