"""Frames of the gripper cell and planar transforms between pad frames and ``gripper_middle``.

Frame tree (hardware_protocols §5.1; rotations intrinsic, translations in m)::

    tool0 ─ gripper_base_link ─(0, 0, 0.173), Rx(+90°)─ gripper_middle
    gripper_middle ─(0, 0, −(opening/2 + pad_offset)), Rz(ft_1_yaw)─ ft_sensor_1
        ─(+z pad_offset)─ vel_sensor_1
    gripper_middle ─(0, 0, +(opening/2 + pad_offset)), Rx(180°)·Rz(ft_2_yaw)─ ft_sensor_2
        ─(+z pad_offset)─ vel_sensor_2

``gripper_middle`` z is the grasp axis (finger 1 → finger 2); its xy plane is the plane the
object slides in. ``vel_sensor_k`` has the axes of ``ft_sensor_k``. Because of the Rx(180°),
finger 2's z (and therefore its ω and Tz) is flipped relative to ``gripper_middle``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from slip_cell_common.core import names

Vector3 = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]  # (x, y, z, w)


@dataclass(frozen=True)
class FrameParams:
    """Shared frame constants (one YAML block read by every node that needs them)."""

    tf_prefix: str = field(default='', metadata={'description': 'prefix for all frame ids'})
    base_to_middle_z: float = field(default=0.173, metadata={
        'unit': 'm', 'range': (0.0, 1.0),
        'description': 'gripper_base_link -> gripper_middle offset along z'})
    pad_offset: float = field(default=0.0078, metadata={
        'unit': 'm', 'range': (0.0, 0.1),
        'description': 'F/T origin to pad surface along the sensor z'})
    ft_1_yaw: float = field(default=0.8290314, metadata={
        'unit': 'rad', 'range': (-math.pi, math.pi),
        'description': 'Rz of ft_sensor_1 in gripper_middle (47.5 deg)'})
    ft_2_yaw: float = field(default=-2.3125613, metadata={
        'unit': 'rad', 'range': (-math.pi, math.pi),
        'description': 'Rz of ft_sensor_2 after Rx(180 deg) in gripper_middle (-132.5 deg)'})

    def frame_id(self, name: str) -> str:
        """Frame id with the configured prefix (``tool0`` is the arm's and never prefixed)."""
        return name if name == names.TOOL0 else self.tf_prefix + name

    def yaw(self, finger: int) -> float:
        """Yaw [rad] of finger ``finger``'s sensor frame (before the flip for finger 2)."""
        if finger == 1:
            return self.ft_1_yaw
        if finger == 2:
            return self.ft_2_yaw
        raise ValueError(f'finger must be 1 or 2, got {finger!r}')


def _check_finger(finger: int) -> None:
    if finger not in (1, 2):
        raise ValueError(f'finger must be 1 or 2, got {finger!r}')


def planar_to_middle(frames: FrameParams, finger: int, vx: float, vy: float,
                     wz: float) -> Vector3:
    """Rotate a planar vector pair from ``vel_sensor_k`` / ``ft_sensor_k`` into ``gripper_middle``.

    Works for twists ``(vx, vy, ω)`` and for wrenches ``(Fx, Fy, Tz)`` alike (both are an xy
    vector plus a z component).

    Returns:
        ``(x, y, z)`` components in ``gripper_middle``.
    """
    _check_finger(finger)
    yaw = frames.yaw(finger)
    c, s = math.cos(yaw), math.sin(yaw)
    x = c * vx - s * vy
    y = s * vx + c * vy
    if finger == 2:  # Rx(180°): y and z flip
        return (x, -y, -wz)
    return (x, y, wz)


def planar_from_middle(frames: FrameParams, finger: int, x: float, y: float,
                       z: float) -> Vector3:
    """Inverse of `planar_to_middle`: ``gripper_middle`` components into the finger frame."""
    _check_finger(finger)
    if finger == 2:
        y, z = -y, -z
    yaw = frames.yaw(finger)
    c, s = math.cos(yaw), math.sin(yaw)
    return (c * x + s * y, -s * x + c * y, z)


def _quat_mul(a: Quaternion, b: Quaternion) -> Quaternion:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def quat_rz(angle: float) -> Quaternion:
    """Quaternion of a rotation about z [rad]."""
    return (0.0, 0.0, math.sin(angle / 2.0), math.cos(angle / 2.0))


def quat_rx(angle: float) -> Quaternion:
    """Quaternion of a rotation about x [rad]."""
    return (math.sin(angle / 2.0), 0.0, 0.0, math.cos(angle / 2.0))


@dataclass(frozen=True)
class Transform:
    """A parent → child transform: child origin and orientation expressed in the parent."""

    parent: str
    child: str
    translation: Vector3
    rotation: Quaternion


def static_transforms(frames: FrameParams) -> list[Transform]:
    """The transforms that never change: tool0 → base → middle, ft_sensor_k → vel_sensor_k."""
    p = frames.frame_id
    out = [
        Transform(names.TOOL0, p(names.GRIPPER_BASE_LINK), (0.0, 0.0, 0.0),
                  (0.0, 0.0, 0.0, 1.0)),
        Transform(p(names.GRIPPER_BASE_LINK), p(names.GRIPPER_MIDDLE),
                  (0.0, 0.0, frames.base_to_middle_z), quat_rx(math.pi / 2.0)),
    ]
    for k in (1, 2):
        out.append(Transform(p(names.ft_sensor_frame(k)), p(names.vel_sensor_frame(k)),
                             (0.0, 0.0, frames.pad_offset), (0.0, 0.0, 0.0, 1.0)))
    return out


def finger_transforms(frames: FrameParams, opening: float) -> list[Transform]:
    """``gripper_middle`` → ``ft_sensor_k`` for a finger separation ``opening`` [m]."""
    p = frames.frame_id
    half = opening / 2.0 + frames.pad_offset
    q1 = quat_rz(frames.ft_1_yaw)
    q2 = _quat_mul(quat_rx(math.pi), quat_rz(frames.ft_2_yaw))
    return [
        Transform(p(names.GRIPPER_MIDDLE), p(names.ft_sensor_frame(1)), (0.0, 0.0, -half), q1),
        Transform(p(names.GRIPPER_MIDDLE), p(names.ft_sensor_frame(2)), (0.0, 0.0, half), q2),
    ]
