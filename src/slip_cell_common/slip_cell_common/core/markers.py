# SPDX-License-Identifier: Apache-2.0
"""Display markers as plain data (ROS-free): what ``visualization_msgs/Marker`` carries.

Nodes build `MarkerSpec` s with the helpers below and convert them with
`slip_cell_common.marker_conv`. Units are SI (m, s); colours are RGBA in 0..1. A marker is
drawn in ``frame_id`` (with the prefix already applied); ``frame_locked`` markers follow their
frame as it moves (RViz and Foxglove re-transform them every frame), so a marker fixed to a
moving frame need not be re-sent.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from slip_cell_common.core.frames import Quaternion, Vector3

Rgba = tuple[float, float, float, float]

#: Colours used across the cell's pictures.
GREY: Rgba = (0.6, 0.6, 0.62, 0.8)
GREEN: Rgba = (0.1, 0.8, 0.2, 0.9)
RED: Rgba = (0.9, 0.15, 0.1, 0.9)
ORANGE: Rgba = (1.0, 0.55, 0.0, 0.9)
BLUE: Rgba = (0.15, 0.45, 0.95, 0.9)
WHITE: Rgba = (1.0, 1.0, 1.0, 1.0)
TAN: Rgba = (0.72, 0.58, 0.4, 0.85)

_IDENTITY: Quaternion = (0.0, 0.0, 0.0, 1.0)


class Shape(IntEnum):
    """Marker types (the values of ``visualization_msgs/Marker``)."""

    ARROW = 0
    CUBE = 1
    SPHERE = 2
    CYLINDER = 3
    LINE_STRIP = 4
    TEXT = 9  # TEXT_VIEW_FACING


@dataclass(frozen=True)
class MarkerSpec:
    """One marker (fields as in ``visualization_msgs/Marker``).

    Attributes:
        ns, id: Identity; a later marker with the same pair replaces it.
        shape: Marker type.
        frame_id: Frame the pose and points are in (prefixed).
        stamp: Time of the data [s, node clock]; 0 = draw with the latest transform.
        position, orientation: Pose of the marker in ``frame_id`` [m; unit quaternion xyzw].
        scale: Size [m]: box/sphere/cylinder extents; arrow with points: (shaft diameter,
            head diameter, head length); line strip: (width, -, -); text: (-, -, height).
        color: RGBA in 0..1.
        points: Arrow start and end, or the points of a line strip [m].
        text: Text of a TEXT marker.
        lifetime: Seconds until the viewer removes it unless re-sent; 0 = forever.
        frame_locked: Re-transform with the frame as it moves.
        delete: Remove the marker ``(ns, id)`` instead of drawing it.
    """

    ns: str
    id: int
    shape: Shape
    frame_id: str
    stamp: float = 0.0
    position: Vector3 = (0.0, 0.0, 0.0)
    orientation: Quaternion = _IDENTITY
    scale: Vector3 = (1.0, 1.0, 1.0)
    color: Rgba = WHITE
    points: tuple[Vector3, ...] = ()
    text: str = ''
    lifetime: float = 0.0
    frame_locked: bool = False
    delete: bool = False


def box(ns: str, id_: int, frame_id: str, size: Vector3, color: Rgba, *,
        position: Vector3 = (0.0, 0.0, 0.0), orientation: Quaternion = _IDENTITY,
        stamp: float = 0.0, lifetime: float = 0.0, frame_locked: bool = True) -> MarkerSpec:
    """A box of ``size`` [m] centred at ``position`` in ``frame_id``."""
    return MarkerSpec(ns, id_, Shape.CUBE, frame_id, stamp, position, orientation, size, color,
                      lifetime=lifetime, frame_locked=frame_locked)


def arrow(ns: str, id_: int, frame_id: str, start: Vector3, end: Vector3, color: Rgba, *,
          shaft: float = 0.002, stamp: float = 0.0, lifetime: float = 0.0) -> MarkerSpec:
    """An arrow from ``start`` to ``end`` [m] in ``frame_id``; the head scales with the shaft.

    A zero-length arrow is drawn as nothing (an empty arrow; viewers skip it).
    """
    length = math.dist(start, end)
    head = min(3.0 * shaft, 0.5 * length) if length > 0.0 else 0.0
    return MarkerSpec(ns, id_, Shape.ARROW, frame_id, stamp, scale=(shaft, 2.0 * shaft, head),
                      color=color, points=(start, end) if length > 0.0 else (),
                      lifetime=lifetime, frame_locked=True)


def line_strip(ns: str, id_: int, frame_id: str, points: tuple[Vector3, ...], color: Rgba, *,
               width: float = 0.002, stamp: float = 0.0, lifetime: float = 0.0) -> MarkerSpec:
    """A polyline through ``points`` [m] in ``frame_id``."""
    return MarkerSpec(ns, id_, Shape.LINE_STRIP, frame_id, stamp, scale=(width, 0.0, 0.0),
                      color=color, points=points, lifetime=lifetime, frame_locked=True)


def text(ns: str, id_: int, frame_id: str, position: Vector3, content: str, *,
         height: float = 0.008, color: Rgba = WHITE, stamp: float = 0.0,
         lifetime: float = 0.0) -> MarkerSpec:
    """Camera-facing text of ``height`` [m] at ``position`` in ``frame_id``."""
    return MarkerSpec(ns, id_, Shape.TEXT, frame_id, stamp, position, scale=(0.0, 0.0, height),
                      color=color, text=content, lifetime=lifetime, frame_locked=True)


def arc(centre: Vector3, radius: float, start: float, end: float,
        segments: int = 24) -> tuple[Vector3, ...]:
    """Points of a circular arc in the xy plane at ``centre`` from angle ``start`` to ``end``
    [rad] (counter-clockwise about +z for ``end > start``)."""
    n = max(2, segments)
    cx, cy, cz = centre
    return tuple((cx + radius * math.cos(start + (end - start) * i / (n - 1)),
                  cy + radius * math.sin(start + (end - start) * i / (n - 1)), cz)
                 for i in range(n))


def delete(ns: str, id_: int, frame_id: str) -> MarkerSpec:
    """Remove the marker ``(ns, id_)``."""
    return MarkerSpec(ns, id_, Shape.CUBE, frame_id, delete=True)
