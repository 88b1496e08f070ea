# SPDX-License-Identifier: Apache-2.0
"""Core frame transforms ↔ ``geometry_msgs/TransformStamped`` and ``tf2_msgs/TFMessage``.

`slip_cell_common.core.frames.Transform` is a parent → child transform (translation [m] and
unit quaternion (x, y, z, w) of the child in the parent); the message form adds the stamp.
No ``rclpy.node`` here: publishing is in `slip_cell_common.tf_publishing`.
"""
from __future__ import annotations

from collections.abc import Iterable
from typing import TypeAlias

from builtin_interfaces.msg import Time
from geometry_msgs.msg import TransformStamped
from tf2_msgs.msg import TFMessage

from slip_cell_common.core.frames import Transform
from slip_cell_common.time_conv import seconds_to_stamp

#: Float seconds on the node clock, or a ``builtin_interfaces/Time``.
Stamp: TypeAlias = float | Time


def _stamp(stamp: Stamp) -> Time:
    return stamp if isinstance(stamp, Time) else seconds_to_stamp(stamp)


def transform_stamped_msg(tr: Transform, stamp: Stamp) -> TransformStamped:
    """One transform stamped with ``stamp`` (float seconds on the node clock, or a Time)."""
    msg = TransformStamped()
    msg.header.stamp = _stamp(stamp)
    msg.header.frame_id = tr.parent
    msg.child_frame_id = tr.child
    t, q = msg.transform.translation, msg.transform.rotation
    t.x, t.y, t.z = (float(v) for v in tr.translation)
    q.x, q.y, q.z, q.w = (float(v) for v in tr.rotation)
    return msg


def tf_message(transforms: Iterable[Transform], stamp: Stamp) -> TFMessage:
    """``tf2_msgs/TFMessage`` with every transform stamped alike."""
    return TFMessage(transforms=[transform_stamped_msg(tr, stamp) for tr in transforms])


def transform_from_msg(msg: TransformStamped) -> Transform:
    """Core transform of a message (the stamp is dropped)."""
    t, q = msg.transform.translation, msg.transform.rotation
    return Transform(msg.header.frame_id, msg.child_frame_id, (t.x, t.y, t.z),
                     (q.x, q.y, q.z, q.w))
