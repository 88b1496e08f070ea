"""URDF of the parallel gripper, generated from the cell's frame parameters.

The kinematic tree is the frame tree of `slip_cell_common.core.frames` (hardware_protocols
spec §5.1), so ``robot_state_publisher`` fed with ``joint_states`` reproduces exactly the
transforms our nodes publish::

    tool0 ─fixed─ gripper_base_link ─fixed─ gripper_middle
    gripper_middle ─finger_1_joint (prismatic)─ ft_sensor_1 ─fixed─ vel_sensor_1
    gripper_middle ─finger_2_joint (prismatic, mimic)─ ft_sensor_2 ─fixed─ vel_sensor_2

Each finger joint's position is half the opening [m]; both axes are −z of their sensor frame,
i.e. away from the object, so a growing position opens the gripper symmetrically. Joint
origins are the finger transforms at opening 0. Link geometry is a visual aid: the pad stack
(contact pad and sensor ring between the F/T origin and the pad surface) as a box, the F/T
sensor as a cylinder, the housing as a box envelope.

Run as a module to print the URDF for the default parameters
(``python -m slip_cell_common.core.gripper_urdf [--tf-prefix P]``).
"""
from __future__ import annotations

import argparse
import dataclasses
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field

from scipy.spatial.transform import Rotation

from slip_cell_common.core import names
from slip_cell_common.core.frames import (FrameParams, Transform, finger_transforms,
                                          static_transforms)


@dataclass(frozen=True)
class GripperGeometry:
    """Joint limits and visual dimensions of the gripper (SI)."""

    stroke: float = field(default=0.08, metadata={
        'unit': 'm', 'range': (0.005, 0.5),
        'description': 'largest opening; each finger joint travels 0 .. stroke/2'})
    max_finger_force: float = field(default=78.3, metadata={
        'unit': 'N', 'range': (0.0, 1000.0),
        'description': 'joint effort limit (the +-20 V command clip at 3.9166 N/V)'})
    max_finger_speed: float = field(default=0.1, metadata={
        'unit': 'm/s', 'range': (0.0, 10.0),
        'description': 'joint velocity limit (nominal: the firmware enforces none)'})
    pad_size: float = field(default=0.02, metadata={
        'unit': 'm', 'range': (0.001, 0.2),
        'description': 'side of the square contact pad (the simulated pad patch)'})
    ft_diameter: float = field(default=0.04, metadata={
        'unit': 'm', 'range': (0.001, 0.5), 'description': 'F/T sensor body diameter'})
    ft_height: float = field(default=0.0122, metadata={
        'unit': 'm', 'range': (0.001, 0.5), 'description': 'F/T sensor body height'})
    finger_width: float = field(default=0.03, metadata={
        'unit': 'm', 'range': (0.001, 0.5), 'description': 'finger plate width'})
    finger_thickness: float = field(default=0.008, metadata={
        'unit': 'm', 'range': (0.001, 0.5),
        'description': 'finger plate thickness (behind the F/T sensor)'})
    housing_size: tuple[float, ...] = field(default=(0.08, 0.16, 0.13), metadata={
        'unit': 'm', 'description': 'housing box (x, y, z) in gripper_base_link, from z = 0'})


def finger_joint_names(frames: FrameParams) -> tuple[str, str]:
    """The two finger joint names with the frame prefix (as published on ``joint_states``)."""
    return (frames.tf_prefix + names.finger_joint(1), frames.tf_prefix + names.finger_joint(2))


def _fmt(values: Sequence[float]) -> str:
    return ' '.join(f'{v:.15g}' if abs(v) > 1e-12 else '0' for v in values)


def _origin(parent: ET.Element, tr: Transform) -> None:
    rpy = Rotation.from_quat(tr.rotation).as_euler('xyz')  # fixed axes x, y, z = URDF rpy
    ET.SubElement(parent, 'origin', xyz=_fmt(tr.translation), rpy=_fmt(rpy))


def _visual(link: ET.Element, shape: str, attrs: dict[str, str], xyz: Sequence[float],
            material: str, collision: bool = False,
            rpy: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
    for tag in ('visual', 'collision') if collision else ('visual',):
        item = ET.SubElement(link, tag)
        ET.SubElement(item, 'origin', xyz=_fmt(xyz), rpy=_fmt(rpy))
        ET.SubElement(ET.SubElement(item, 'geometry'), shape, attrs)
        if tag == 'visual':
            ET.SubElement(item, 'material', name=material)


def _finger_plate(link: ET.Element, finger: Transform, frames: FrameParams,
                  geometry: GripperGeometry) -> None:
    """Plate behind the F/T sensor reaching from the pad down to the housing top.

    The plate is laid out in ``gripper_middle`` axes (its length along −y of gripper_middle,
    towards the housing) and expressed in the sensor frame of ``finger``.
    """
    reach = frames.base_to_middle_z - geometry.housing_size[2]  # housing top to grasp centre
    if reach <= 0.0:
        return
    to_sensor = Rotation.from_quat(finger.rotation).inv()  # gripper_middle axes -> sensor axes
    top = geometry.pad_size / 2.0
    centre_in_middle_axes = (0.0, (top - reach) / 2.0, 0.0)
    behind = (0.0, 0.0, -(geometry.ft_height + geometry.finger_thickness / 2.0))
    centre = to_sensor.apply(centre_in_middle_axes) + behind
    size = (geometry.finger_width, reach + top, geometry.finger_thickness)
    # the plate's thickness must lie along the sensor z: gripper_middle z is ±sensor z
    _visual(link, 'box', {'size': _fmt(size)}, centre, 'housing',
            rpy=to_sensor.as_euler('xyz'))


def _joint(robot: ET.Element, name: str, kind: str, tr: Transform) -> ET.Element:
    joint = ET.SubElement(robot, 'joint', name=name, type=kind)
    ET.SubElement(joint, 'parent', link=tr.parent)
    ET.SubElement(joint, 'child', link=tr.child)
    _origin(joint, tr)
    return joint


def gripper_urdf(frames: FrameParams = FrameParams(),
                 geometry: GripperGeometry = GripperGeometry(),
                 parent_link: str | None = names.TOOL0, name: str = 'slip_gripper') -> str:
    """URDF XML of the gripper with ``frames.tf_prefix`` on every link and joint name.

    Args:
        frames: Frame constants (prefix, offsets, sensor yaws).
        geometry: Joint limits and visual dimensions.
        parent_link: Root link the gripper hangs from (the arm's flange, never prefixed);
            ``None`` makes ``gripper_base_link`` the root.
        name: Robot name.
    """
    p = frames.frame_id
    robot = ET.Element('robot', name=name)
    robot.append(ET.Comment(' generated by slip_cell_common.core.gripper_urdf; do not edit '))
    for material, rgba in (('housing', '0.25 0.25 0.28 1'), ('ft_sensor', '0.7 0.7 0.72 1'),
                           ('pad', '0.1 0.45 0.85 1')):
        ET.SubElement(ET.SubElement(robot, 'material', name=material), 'color', rgba=rgba)

    base_to_parent, base_to_middle, *pads = static_transforms(frames)
    if parent_link is not None:
        ET.SubElement(robot, 'link', name=parent_link)
        _joint(robot, p('gripper_base_joint'), 'fixed',
               dataclasses.replace(base_to_parent, parent=parent_link))
    base = ET.SubElement(robot, 'link', name=p(names.GRIPPER_BASE_LINK))
    hx, hy, hz = geometry.housing_size
    _visual(base, 'box', {'size': _fmt((hx, hy, hz))}, (0.0, 0.0, hz / 2.0), 'housing')
    ET.SubElement(robot, 'link', name=p(names.GRIPPER_MIDDLE))
    _joint(robot, p('gripper_middle_joint'), 'fixed', base_to_middle)

    joint_names = finger_joint_names(frames)
    fingers = finger_transforms(frames, 0.0)  # joint origins: the fingers at opening 0
    for k, (joint_name, finger) in enumerate(zip(joint_names, fingers, strict=True)):
        sensor = ET.SubElement(robot, 'link', name=finger.child)
        _visual(sensor, 'cylinder', {'radius': _fmt((geometry.ft_diameter / 2.0,)),
                                     'length': _fmt((geometry.ft_height,))},
                (0.0, 0.0, -geometry.ft_height / 2.0), 'ft_sensor')
        _finger_plate(sensor, finger, frames, geometry)
        joint = _joint(robot, joint_name, 'prismatic', finger)
        ET.SubElement(joint, 'axis', xyz='0 0 -1')
        ET.SubElement(joint, 'limit', lower='0', upper=_fmt((geometry.stroke / 2.0,)),
                      effort=_fmt((geometry.max_finger_force,)),
                      velocity=_fmt((geometry.max_finger_speed,)))
        if k == 1:
            ET.SubElement(joint, 'mimic', joint=joint_names[0], multiplier='1', offset='0')

    for k, pad in enumerate(pads, start=1):
        link = ET.SubElement(robot, 'link', name=pad.child)
        size = (geometry.pad_size, geometry.pad_size, frames.pad_offset)
        _visual(link, 'box', {'size': _fmt(size)}, (0.0, 0.0, -frames.pad_offset / 2.0), 'pad',
                collision=True)
        _joint(robot, p(f'vel_sensor_{k}_joint'), 'fixed', pad)

    ET.indent(robot, space='  ')
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding='unicode') + '\n'


def main(argv: Sequence[str] | None = None) -> None:
    """Print the URDF for the default geometry (``--tf-prefix`` to prefix the names)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--tf-prefix', default='', help='prefix of every link and joint name')
    parser.add_argument('--no-parent', action='store_true',
                        help='make gripper_base_link the root (no tool0 link)')
    args = parser.parse_args(argv)
    print(gripper_urdf(FrameParams(tf_prefix=args.tf_prefix),
                       parent_link=None if args.no_parent else names.TOOL0), end='')


if __name__ == '__main__':
    main()
