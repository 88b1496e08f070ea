"""Pad frame ↔ gripper_middle transforms agree with the quaternions of the frame tree."""
from __future__ import annotations

import math

import numpy as np
import pytest

from slip_cell_common.core.frames import (FrameParams, finger_transforms, planar_from_middle,
                                             planar_to_middle, static_transforms)


def _rot(q: tuple[float, float, float, float]) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


@pytest.mark.parametrize('finger', [1, 2])
def test_planar_transform_matches_the_frame_quaternion(finger: int) -> None:
    frames = FrameParams()
    rot = _rot(finger_transforms(frames, 0.03)[finger - 1].rotation)
    rng = np.random.default_rng(finger)
    for vx, vy, wz in rng.normal(size=(20, 3)):
        expected_xy = rot @ np.array([vx, vy, 0.0])
        expected_z = (rot @ np.array([0.0, 0.0, wz]))[2]
        got = planar_to_middle(frames, finger, vx, vy, wz)
        assert got == pytest.approx((expected_xy[0], expected_xy[1], expected_z), abs=1e-12)
        assert planar_from_middle(frames, finger, *got) == pytest.approx((vx, vy, wz), abs=1e-12)


def test_common_rotation_flips_for_finger_two() -> None:
    frames = FrameParams()
    # The same object rotation seen by both pads: raw rates have opposite signs.
    w1 = planar_from_middle(frames, 1, 0.0, 0.0, 0.5)[2]
    w2 = planar_from_middle(frames, 2, 0.0, 0.0, 0.5)[2]
    assert w1 == pytest.approx(0.5) and w2 == pytest.approx(-0.5)
    assert (w1 - w2) / 2 == pytest.approx(0.5)


def test_fingers_sit_on_either_side_of_the_grasp_centre() -> None:
    frames = FrameParams(tf_prefix='left_')
    t1, t2 = finger_transforms(frames, 0.04)
    assert t1.translation[2] == pytest.approx(-(0.02 + 0.0078))
    assert t2.translation[2] == pytest.approx(0.02 + 0.0078)
    assert t1.parent == 'left_gripper_middle' and t2.child == 'left_ft_sensor_2'
    names = {(t.parent, t.child) for t in static_transforms(frames)}
    assert ('tool0', 'left_gripper_base_link') in names
    assert math.isclose(np.linalg.det(_rot(t2.rotation)), 1.0)


def test_unknown_finger_is_rejected() -> None:
    with pytest.raises(ValueError, match='finger must be 1 or 2'):
        planar_to_middle(FrameParams(), 3, 0.0, 0.0, 0.0)
