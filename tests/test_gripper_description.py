"""The gripper URDF: a valid tree with the documented joints, and the frames.py frame tree.

Forward kinematics of the URDF at a given opening must give exactly the transforms the nodes
publish (`slip_cell_common.core.frames`), so robot_state_publisher and our own TF agree.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from slip_cell_common.core.frames import FrameParams, finger_transforms, static_transforms
from slip_cell_common.core.gripper_urdf import (GripperGeometry, finger_joint_names,
                                                gripper_urdf, main)

ROOT = Path(__file__).resolve().parents[1]
SHIPPED_URDF = ROOT / 'src' / 'slip_gripper_description' / 'urdf' / 'slip_gripper.urdf'
FRAME_NAMES = {'gripper_base_link', 'gripper_middle', 'ft_sensor_1', 'ft_sensor_2',
               'vel_sensor_1', 'vel_sensor_2'}


def _parse(urdf: str) -> ET.Element:
    return ET.fromstring(urdf)


def _joints(robot: ET.Element) -> dict[str, ET.Element]:
    return {j.get('name'): j for j in robot.findall('joint')}


def _frames_py_names(frames: FrameParams) -> set[str]:
    names: set[str] = set()
    for tr in static_transforms(frames) + finger_transforms(frames, 0.05):
        names |= {tr.parent, tr.child}
    return names


def _floats(text: str) -> np.ndarray:
    return np.array([float(v) for v in text.split()])


def _child_pose(joint: ET.Element, q: float) -> tuple[np.ndarray, Rotation]:
    """Pose of the joint's child in its parent at joint position ``q`` (URDF semantics)."""
    origin = joint.find('origin')
    rotation = Rotation.from_euler('xyz', _floats(origin.get('rpy')))
    translation = _floats(origin.get('xyz'))
    if joint.get('type') == 'prismatic':
        translation = translation + rotation.apply(q * _floats(joint.find('axis').get('xyz')))
    return translation, rotation


def test_links_and_joints_are_the_documented_ones() -> None:
    robot = _parse(gripper_urdf())
    links = {link.get('name') for link in robot.findall('link')}
    assert links == FRAME_NAMES | {'tool0'}
    joints = _joints(robot)
    kinds = {name: j.get('type') for name, j in joints.items()}
    assert kinds['finger_1_joint'] == kinds['finger_2_joint'] == 'prismatic'
    assert sorted(k for k in kinds.values() if k != 'fixed') == ['prismatic', 'prismatic']
    assert (joints['finger_1_joint'].find('child').get('link'),
            joints['finger_2_joint'].find('child').get('link')) == ('ft_sensor_1', 'ft_sensor_2')
    assert joints['finger_2_joint'].find('mimic').get('joint') == 'finger_1_joint'
    assert joints['finger_1_joint'].find('mimic') is None


def test_the_urdf_is_a_tree_rooted_at_the_flange() -> None:
    robot = _parse(gripper_urdf())
    children = [j.find('child').get('link') for j in robot.findall('joint')]
    parents = {j.find('parent').get('link') for j in robot.findall('joint')}
    links = {link.get('name') for link in robot.findall('link')}
    assert len(children) == len(set(children)) == len(links) - 1
    assert links - set(children) == {'tool0'}
    assert parents <= links


def test_prismatic_limits_follow_the_stroke() -> None:
    geometry = GripperGeometry(stroke=0.09, max_finger_force=40.0, max_finger_speed=0.2)
    joints = _joints(_parse(gripper_urdf(geometry=geometry)))
    for name in finger_joint_names(FrameParams()):
        limit = joints[name].find('limit')
        assert float(limit.get('lower')) == 0.0
        assert float(limit.get('upper')) == pytest.approx(0.045)
        assert float(limit.get('effort')) == pytest.approx(40.0)
        assert float(limit.get('velocity')) == pytest.approx(0.2)


def test_frame_names_equal_those_of_frames_py() -> None:
    for prefix in ('', 'left_'):
        frames = FrameParams(tf_prefix=prefix)
        links = {link.get('name') for link in _parse(gripper_urdf(frames)).findall('link')}
        assert links == _frames_py_names(frames)


def test_prefix_applies_to_every_name_but_the_flange() -> None:
    frames = FrameParams(tf_prefix='left_')
    robot = _parse(gripper_urdf(frames))
    links = {link.get('name') for link in robot.findall('link')}
    assert links == {'tool0'} | {'left_' + n for n in FRAME_NAMES}
    assert all(name.startswith('left_') for name in _joints(robot))
    assert finger_joint_names(frames) == ('left_finger_1_joint', 'left_finger_2_joint')
    assert {'left_finger_1_joint', 'left_finger_2_joint'} <= set(_joints(robot))


@pytest.mark.parametrize('opening', [0.0, 0.031, 0.077])
def test_forward_kinematics_equals_the_published_frames(opening: float) -> None:
    """Joint position opening/2 reproduces every transform of frames.py."""
    frames = FrameParams(tf_prefix='g_')
    joints = _joints(_parse(gripper_urdf(frames)))
    by_child = {j.find('child').get('link'): j for j in joints.values()}
    expected = static_transforms(frames) + finger_transforms(frames, opening)
    for tr in expected:
        joint = by_child[tr.child]
        assert joint.find('parent').get('link') == tr.parent
        q = opening / 2.0 if joint.get('type') == 'prismatic' else 0.0
        translation, rotation = _child_pose(joint, q)
        np.testing.assert_allclose(translation, tr.translation, atol=1e-9)
        assert (rotation.inv() * Rotation.from_quat(tr.rotation)).magnitude() < 1e-8


def test_finger_separation_is_the_opening() -> None:
    joints = _joints(_parse(gripper_urdf()))
    opening = 0.058
    pads = []
    for k in (1, 2):
        p_ft, r_ft = _child_pose(joints[f'finger_{k}_joint'], opening / 2.0)
        p_pad, _ = _child_pose(joints[f'vel_sensor_{k}_joint'], 0.0)
        pads.append(p_ft + r_ft.apply(p_pad))  # pad surface in gripper_middle
    assert np.linalg.norm(pads[1] - pads[0]) == pytest.approx(opening, abs=1e-12)


def test_pads_have_collision_boxes() -> None:
    robot = _parse(gripper_urdf(geometry=GripperGeometry(pad_size=0.025)))
    for k in (1, 2):
        link = robot.find(f"link[@name='vel_sensor_{k}']")
        box = link.find('collision/geometry/box')
        assert _floats(box.get('size'))[:2].tolist() == [0.025, 0.025]


def test_without_parent_the_base_link_is_the_root() -> None:
    robot = _parse(gripper_urdf(parent_link=None))
    links = {link.get('name') for link in robot.findall('link')}
    children = {j.find('child').get('link') for j in robot.findall('joint')}
    assert links - children == {'gripper_base_link'}
    assert 'tool0' not in links


def test_shipped_urdf_is_the_generated_one(capsys: pytest.CaptureFixture[str]) -> None:
    """src/slip_gripper_description/urdf/slip_gripper.urdf is the generator's default output."""
    main([])
    printed = capsys.readouterr().out
    assert printed == gripper_urdf()
    assert SHIPPED_URDF.read_text() == printed, (
        'regenerate: python -m slip_cell_common.core.gripper_urdf > ' + str(SHIPPED_URDF))


@pytest.mark.ros
def test_description_package_installs_the_urdf() -> None:
    packages = pytest.importorskip('ament_index_python.packages')
    share = Path(packages.get_package_share_directory('slip_gripper_description'))
    installed = share / 'urdf' / 'slip_gripper.urdf'
    assert installed.read_text() == gripper_urdf()


def test_rpy_of_flipped_finger_is_consistent() -> None:
    """Finger 2 is Rx(180°) then Rz(ft_2_yaw): its sensor z is gripper_middle −z."""
    joints = _joints(_parse(gripper_urdf()))
    _, rotation = _child_pose(joints['finger_2_joint'], 0.0)
    np.testing.assert_allclose(rotation.apply([0.0, 0.0, 1.0]), [0.0, 0.0, -1.0], atol=1e-9)
    assert math.isclose(float(joints['finger_2_joint'].find('origin').get('xyz').split()[2]),
                        FrameParams().pad_offset)
