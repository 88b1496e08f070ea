# SPDX-License-Identifier: Apache-2.0
"""Rotation centre, joint torsional radius and HINGE translation of two pads (no ROS)."""
from __future__ import annotations

import dataclasses
import math

import pytest

from friction_models.core.presets import ContactPreset, ObjectPreset

from slip_bringup.core.evaluation.poses import hinge_start_turn
from slip_bringup.population.grasp_geometry import (friction_wrench, hinge_translation,
                                                    joint_torsional_radius, pad_pressures,
                                                    rotation_centre, rotation_torque,
                                                    slip_centre)


def _object(surface: str, com: tuple[float, float], r: float = 0.006,
            mu: tuple[float, float] = (0.5, 0.5)) -> ObjectPreset:
    return ObjectPreset(name='geom', mass=0.2, inertia=1e-4, com_offset=com, width=0.05,
                        height_below=0.08, height_above=0.06, thickness=0.03, surface=surface,
                        finger_1=ContactPreset(mu_c=mu[0], mu_s=mu[0], mu_v=0.0, r=r),
                        finger_2=ContactPreset(mu_c=mu[1], mu_s=mu[1], mu_v=0.0, r=r))


def test_centred_maps_turn_about_the_grasp_point_with_their_own_radius() -> None:
    obj = _object('circle', (0.0, -0.03))
    pads = pad_pressures(obj)
    centre = rotation_centre(pads)
    assert math.hypot(*centre) < 1e-6
    # Each map is scaled so that its characteristic radius is r; the point-wise Coulomb
    # radius differs from the smoothed one by the discretisation only.
    assert joint_torsional_radius(pads, centre) == pytest.approx(0.006, rel=0.05)


def test_a_gradient_map_moves_the_rotation_centre_off_the_grasp_point() -> None:
    obj = _object('line_grad', (0.0, -0.03))
    pads = pad_pressures(obj)
    centre = rotation_centre(pads)
    assert math.hypot(*centre) > 0.002
    # The centre minimises the torque of pure rotation: any step away costs torque.
    best = rotation_torque(pads, centre)
    for dx, dy in ((5e-4, 0.0), (-5e-4, 0.0), (0.0, 5e-4), (0.0, -5e-4)):
        assert rotation_torque(pads, (centre[0] + dx, centre[1] + dy)) > best
    # The finger with more friction pulls the centre towards its own centre of pressure.
    lopsided = rotation_centre(pad_pressures(dataclasses.replace(
        obj, finger_1=dataclasses.replace(obj.finger_1, mu_c=1.0))))
    one = pads[0]
    cop_1 = (float((one.weight * one.x).sum()), float((one.weight * one.y).sum()))
    assert math.dist(lopsided, cop_1) < math.dist(centre, cop_1)


def test_slip_centre_balances_the_load_on_the_far_side_from_the_com() -> None:
    # Weight 1 N down with its CoM 20 mm to the right (+x): the friction must push up and
    # turn the object back. By symmetry the CoR of a centred circle lies on the x axis, on
    # the left; the friction there balances the load's direction.
    obj = _object('circle', (0.02, 0.0))
    pads = pad_pressures(obj)
    load = (0.0, 1.0, 0.02)                      # what the pads supply: up, and +τ
    cor = slip_centre(pads, load, 0.006, (-0.002, 0.0))
    assert cor is not None
    assert cor[0] < -1e-4 and abs(cor[1]) < 1e-6
    fx, fy, tz = friction_wrench(pads, cor, -1.0)
    scale = fy / load[1]
    assert scale > 0.0
    assert (fx, tz) == pytest.approx((0.0, scale * load[2]), abs=1e-9)


def test_hinge_translation_follows_the_slip_centre() -> None:
    # A small turn moves the grasp point by the turn times the CoR's distance.
    obj = _object('circle', (0.0, -0.02))
    start, sign = hinge_start_turn(obj.com_offset, math.radians(60.0))
    turn = 0.01
    moved = hinge_translation(obj, start, sign * turn, steps=4)
    pads = pad_pressures(obj)
    ca, sa = math.cos(start), math.sin(start)
    down = (-sa, -ca)
    w = obj.mass * 9.81
    com = obj.com_offset
    torque = (com[0] * down[1] - com[1] * down[0]) * w
    cor = slip_centre(pads, (-w * down[0], -w * down[1], -torque), 0.006, (0.0, 0.0))
    assert cor is not None
    assert moved == pytest.approx(turn * math.hypot(*cor), rel=0.02)
    # A longer lever turns the pads with more torque: the grasp point moves less.
    far = hinge_translation(_object('circle', (0.0, -0.04)), start, sign * math.radians(60.0))
    near = hinge_translation(obj, start, sign * math.radians(60.0))
    assert far < near
