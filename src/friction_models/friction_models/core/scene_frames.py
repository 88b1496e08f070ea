# SPDX-License-Identifier: Apache-2.0
"""The simulated scene as frames and markers for ``/tf`` and ``sim/markers`` (ROS-free).

The plant works in a vertical plane (`friction_models.core.plant`: X horizontal, Y up, Z the
grasp axis). For viewers it is placed in a z-up ``world`` frame (REP-103) by Rx(+90°): plane
X → world x, plane Y (up) → world z, plane Z (grasp axis) → world −y. Frames:

* ``world → tool0``: the simulated arm, from the gripper pose ``(X_g, Y_g, φ)`` and the fixed
  ``tool0 → gripper_middle`` chain of `slip_cell_common.core.frames.static_transforms`, so the
  gripper's own frames (published by the same node) hang below it;
* ``world → <prefix>sim_object``: the object's centre of mass and angle (truth).

`object_markers` draws the object as a box locked to ``sim_object`` and the table as a slab in
``world``.
"""
from __future__ import annotations

import math

from scipy.spatial.transform import Rotation

from slip_cell_common.core import names
from slip_cell_common.core.frames import FrameParams, Transform, static_transforms
from slip_cell_common.core.markers import GREY, TAN, MarkerSpec, box

from .presets import ObjectPreset

#: Plane (X right, Y up, Z grasp axis) → z-up world.
_PLANE_TO_WORLD = Rotation.from_euler('x', math.pi / 2.0)

#: Table slab drawn under the object: length along world x, depth along world y, thickness [m].
TABLE_SIZE = (0.6, 0.4, 0.02)


def _plane_point(x: float, y: float) -> tuple[float, float, float]:
    v = _PLANE_TO_WORLD.apply((x, y, 0.0))
    return (float(v[0]), float(v[1]), float(v[2]))


def _plane_pose(x: float, y: float, angle: float) -> tuple[tuple[float, float, float],
                                                              Rotation]:
    """World pose of a plane pose ``(x, y)`` [m] turned ``angle`` [rad] about the grasp axis."""
    return _plane_point(x, y), _PLANE_TO_WORLD * Rotation.from_euler('z', angle)


def _quat(r: Rotation) -> tuple[float, float, float, float]:
    x, y, z, w = (float(v) for v in r.as_quat())
    return (x, y, z, w)


def scene_transforms(frames: FrameParams, arm_lateral: float, arm_height: float,
                     arm_angle: float, object_x: float, object_y: float,
                     object_theta: float) -> list[Transform]:
    """``world → tool0`` and ``world → sim_object`` for the current truth.

    Args:
        frames: Frame constants (prefix, ``base_to_middle_z``).
        arm_lateral, arm_height, arm_angle: Gripper pose ``X_g, Y_g`` [m] and ``φ`` [rad].
        object_x, object_y, object_theta: Object CoM ``X, Y`` [m] and angle ``θ`` [rad].
    """
    mid_t, mid_r = _plane_pose(arm_lateral, arm_height, arm_angle)
    # tool0 → gripper_middle from the shared static chain (tool0 → base → middle).
    tool_to_base, base_to_mid = static_transforms(frames)[:2]
    r_tb = Rotation.from_quat(tool_to_base.rotation)
    r_bm = Rotation.from_quat(base_to_mid.rotation)
    t_tm = r_tb.apply(base_to_mid.translation) + tool_to_base.translation
    r_tm = r_tb * r_bm
    # world → tool0 = (world → middle) · (tool0 → middle)⁻¹
    r_wt = mid_r * r_tm.inv()
    t_wt = mid_t - r_wt.apply(t_tm)
    obj_t, obj_r = _plane_pose(object_x, object_y, object_theta)
    return [
        Transform(names.WORLD, names.TOOL0, (float(t_wt[0]), float(t_wt[1]), float(t_wt[2])),
                  _quat(r_wt)),
        Transform(names.WORLD, frames.frame_id(names.SIM_OBJECT), obj_t, _quat(obj_r)),
    ]


def object_markers(frames: FrameParams, preset: ObjectPreset, table_height: float | None,
                   ns: str = 'sim') -> list[MarkerSpec]:
    """The object as a box fixed to ``sim_object`` and, if given, the table surface.

    Args:
        frames: Frame constants (prefix).
        preset: Object geometry (grasp-point frame; the CoM is at ``com_offset`` from it).
        table_height: Plane Y of the table surface [m], or None without a table.
        ns: Marker namespace.
    """
    cx, cy = preset.com_offset
    # Box centre relative to the CoM (object axes): the grasp point is at −com_offset.
    centre = (-cx, 0.5 * (preset.height_above - preset.height_below) - cy, 0.0)
    size = (preset.width, preset.height_below + preset.height_above, preset.thickness)
    out = [box(ns, 0, frames.frame_id(names.SIM_OBJECT), size, TAN, position=centre)]
    if table_height is not None:
        top = _plane_point(0.0, table_height)
        centre_t = (top[0], top[1], top[2] - 0.5 * TABLE_SIZE[2])
        out.append(box(ns, 1, names.WORLD, TABLE_SIZE, GREY, position=centre_t))
    return out

