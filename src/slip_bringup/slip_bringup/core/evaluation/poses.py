# SPDX-License-Identifier: Apache-2.0
"""Gripper set-up turns for an object whose centre of mass may lie in any direction (SI).

The reference presets carry their CoM just below the grasp point, so "turn the gripper 90°"
puts the lever horizontal and "turn 60°" puts the object 60° from hanging. A drawn object's
CoM sits anywhere around the grasp point; these functions give the turns that reproduce the
same set-ups for it.

Conventions: the object is held as picked up (object frame = ``gripper_middle`` axes, x
across, y up) at arm angle 0; ``com`` is the CoM offset from the grasp point in that frame
[m]; a gripper turn ``φ`` [rad] about the grasp axis is the ``rotation`` of
`SimCell.move_gripper` (gravity in ``gripper_middle`` becomes ``(−sin φ, −cos φ)``). The
*hanging angle* ``γ`` is the signed angle of the CoM lever from straight down, measured like
the object's rotation ``θ`` about ``gripper_middle`` +z: ``γ = α + θ + φ + π/2`` with
``α = atan2(com_y, com_x)``. Gravity's torque on the object about the grasp point is
``−W·d·sin γ`` (``d = |com|``), so it turns the object towards ``γ = 0``.
"""
from __future__ import annotations

import math
from collections.abc import Sequence


def rotated(point: Sequence[float], angle: float) -> tuple[float, float]:
    """``point`` (x, y) turned by ``angle`` [rad] about the origin (+z)."""
    c, s = math.cos(angle), math.sin(angle)
    return c * point[0] - s * point[1], s * point[0] + c * point[1]


def gravity_in_middle(arm_angle: float) -> tuple[float, float]:
    """Unit gravity direction in ``gripper_middle`` xy for a gripper turned ``arm_angle``."""
    return -math.sin(arm_angle), -math.cos(arm_angle)


def wrap(angle: float) -> float:
    """``angle`` [rad] wrapped to ``(−π, π]``."""
    a = math.remainder(angle, 2.0 * math.pi)
    return math.pi if a == -math.pi else a


def hanging_angle(com: Sequence[float], turn: float = 0.0, theta: float = 0.0) -> float:
    """Signed angle ``γ`` [rad] of the CoM lever from straight down (module docstring).

    Args:
        com: CoM offset from the grasp point, object frame [m] (x, y).
        turn: Gripper turn from the pick-up pose [rad].
        theta: Object rotation relative to the pads [rad].
    """
    return wrap(math.atan2(com[1], com[0]) + theta + turn + 0.5 * math.pi)


def turn_to_hanging_angle(com: Sequence[float], gamma: float, theta: float = 0.0) -> float:
    """Gripper turn [rad, in (−π, π]] from the pick-up pose that puts the lever at ``γ``."""
    return wrap(gamma - hanging_angle(com, 0.0, theta))


def _pick(com: Sequence[float], gammas: Sequence[float], theta: float) -> tuple[float, int]:
    """The smallest turn over ``±γ`` (ties: +), with the sign that chose it."""
    plus = turn_to_hanging_angle(com, gammas[0], theta)
    minus = turn_to_hanging_angle(com, gammas[1], theta)
    return (plus, 1) if abs(plus) <= abs(minus) + 1e-12 else (minus, -1)


def lever_horizontal_turn(com: Sequence[float], theta: float = 0.0) -> tuple[float, int]:
    """Set-up of a gravity-driven ROTATIONAL slip: lever horizontal (``γ = ∓90°``).

    Returns:
        ``(turn [rad], sign)``: the smaller gripper turn, and the sign of the slip angle
        gravity then drives (+1: the object turns about +z, i.e. ``γ = −90°``).
    """
    return _pick(com, (-0.5 * math.pi, 0.5 * math.pi), theta)


def hinge_start_turn(com: Sequence[float], swing: float = math.radians(60.0),
                     theta: float = 0.0) -> tuple[float, int]:
    """Set-up of a HINGE: the object ``swing`` [rad] from hanging (``γ = ±swing``).

    Returns:
        ``(turn [rad], sign)``: the smaller gripper turn to the hinge pose, and the sign of
        the turn that follows (the object hangs at ``γ = 0`` after its swing; the gripper
        then turns ``sign·turn`` on, as the reference set-up does with ``+60°`` twice).
    """
    return _pick(com, (swing, -swing), theta)


def path_sin_max(com: Sequence[float], turn: float, steps: int = 90) -> float:
    """Largest ``|sin γ|`` while the gripper turns from 0 to ``turn`` [rad] (the largest
    gravity torque on the way, as a fraction of ``W·d``)."""
    g0 = hanging_angle(com)
    return max(abs(math.sin(g0 + turn * k / steps)) for k in range(steps + 1))
