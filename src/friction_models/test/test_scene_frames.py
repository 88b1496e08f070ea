# SPDX-License-Identifier: Apache-2.0
"""The simulated scene as frames and markers (`friction_models.core.scene_frames`)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from friction_models.core.presets import reference_presets
from friction_models.core.scene_frames import object_markers, scene_transforms
from slip_cell_common.core.frames import FrameParams, static_transforms

FRAMES = FrameParams(tf_prefix='a/')


def _pose(tr) -> tuple[np.ndarray, Rotation]:
    return np.array(tr.translation), Rotation.from_quat(tr.rotation)


def test_arm_chain_puts_gripper_middle_at_the_plane_pose() -> None:
    xg, yg, phi = 0.03, 0.25, math.radians(30.0)
    tool, obj = scene_transforms(FRAMES, xg, yg, phi, 0.01, 0.2, 0.1)
    assert (tool.parent, tool.child) == ('world', 'tool0')
    assert (obj.parent, obj.child) == ('world', 'a/sim_object')
    t, r = _pose(tool)
    for tr in static_transforms(FRAMES)[:2]:       # tool0 → base → middle
        t, r = t + r.apply(tr.translation), r * Rotation.from_quat(tr.rotation)
    # Plane (X, Y up, Z grasp axis) → world: X → x, Y → z, Z → −y.
    assert t == pytest.approx([xg, 0.0, yg], abs=1e-12)
    assert r.apply([1.0, 0.0, 0.0]) == pytest.approx([math.cos(phi), 0.0, math.sin(phi)])
    assert r.apply([0.0, 0.0, 1.0]) == pytest.approx([0.0, -1.0, 0.0])   # grasp axis
    o_t, o_r = _pose(obj)
    assert o_t == pytest.approx([0.01, 0.0, 0.2])
    assert o_r.apply([0.0, 1.0, 0.0]) == pytest.approx([-math.sin(0.1), 0.0, math.cos(0.1)])


def test_object_box_is_centred_on_the_preset_geometry() -> None:
    preset = reference_presets()['cardboard']
    box, table = object_markers(FRAMES, preset, table_height=0.0)
    assert box.frame_id == 'a/sim_object' and box.frame_locked
    assert box.scale == pytest.approx((preset.width, preset.height_below + preset.height_above,
                                       preset.thickness))
    cx, cy = preset.com_offset
    # The box bottom lies height_below under the grasp point, which is −com_offset from the CoM.
    bottom = box.position[1] - box.scale[1] / 2.0
    assert bottom == pytest.approx(-cy - preset.height_below)
    assert box.position[0] == pytest.approx(-cx)
    assert table.frame_id == 'world' and table.position[2] + table.scale[2] / 2 == \
        pytest.approx(0.0)
    assert len(object_markers(FRAMES, preset, table_height=None)) == 1
