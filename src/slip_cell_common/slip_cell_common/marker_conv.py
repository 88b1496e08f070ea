# SPDX-License-Identifier: Apache-2.0
"""Core `MarkerSpec` s → ``visualization_msgs/Marker`` and ``MarkerArray`` (no ``rclpy.node``).

See `slip_cell_common.core.markers` for the fields; stamps are float seconds on the node clock
(0 = "latest transform").
"""
from __future__ import annotations

from collections.abc import Iterable

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from slip_cell_common.core.markers import MarkerSpec
from slip_cell_common.time_conv import seconds_to_stamp


def _duration(seconds: float) -> Duration:
    if not seconds > 0.0:
        return Duration()
    ns = int(round(seconds * 1e9))
    return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def marker_msg(spec: MarkerSpec) -> Marker:
    """One ``visualization_msgs/Marker`` (action ADD, or DELETE for ``spec.delete``)."""
    msg = Marker(ns=spec.ns, id=int(spec.id), type=int(spec.shape),
                 action=Marker.DELETE if spec.delete else Marker.ADD,
                 frame_locked=bool(spec.frame_locked), text=spec.text,
                 lifetime=_duration(spec.lifetime))
    msg.header.frame_id = spec.frame_id
    msg.header.stamp = seconds_to_stamp(spec.stamp)
    p, q = msg.pose.position, msg.pose.orientation
    p.x, p.y, p.z = (float(v) for v in spec.position)
    q.x, q.y, q.z, q.w = (float(v) for v in spec.orientation)
    s = msg.scale
    s.x, s.y, s.z = (float(v) for v in spec.scale)
    r, g, b, a = (float(v) for v in spec.color)
    msg.color = ColorRGBA(r=r, g=g, b=b, a=a)
    msg.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in spec.points]
    return msg


def marker_array_msg(specs: Iterable[MarkerSpec]) -> MarkerArray:
    """``visualization_msgs/MarkerArray`` of ``specs`` in order."""
    return MarkerArray(markers=[marker_msg(s) for s in specs])
