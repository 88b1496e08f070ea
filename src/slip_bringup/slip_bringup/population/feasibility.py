# SPDX-License-Identifier: Apache-2.0
"""Which scenarios are physically possible for an object (stated criteria, from the truth).

Some requests cannot succeed whatever the controller does: an object too light to slide at
the smallest controllable grasp force, a hold that needs more force than the gripper has, a
rotation or a hinge whose centre-of-mass lever is short next to the torsional radius. The
population evaluation counts such objects apart, by the criteria below (all from the
simulator's true object and contacts; SI units; each reason reads ``'<category>: <details>'``).
Each pad carries half of the tangential load; the two pads together resist a tangential load
up to ``(μ₁ + μ₂)·F`` and a torque up to ``(μ₁r₁ + μ₂r₂)·F`` at grasp force ``F`` (ellipsoidal
limit surface, docs/control_and_estimation.md).

* HOLD (object as picked up, ``gripper_middle`` = object frame): each sustained load ``k`` is a
  force ``(fx, fy)`` and a torque ``τ`` at the CoM ``c``; with the weight the grasp carries
  ``L_k = (fx, fy − W)`` and ``M_k = τ + c × L_k`` (so a push on a long lever is a twist), and
  ``F_need = max_k √(|L_k|² + (M_k/r̄)²)/(μ₁ + μ₂)`` (the weight alone included) must stay
  below ``max_force/margin``. The other scenarios need the hold without loads (weight alone).
* LINEAR (gravity-driven slide from the hanging pose, CoM straight below the grasp point: in
  any other pose the weight's torque ``W·d·sin γ`` turns the object while the pads slide — on
  the limit surface a translating pad has no torque left — by about ``P·d·sin γ/r̄²`` rad over
  a slide ``P``, i.e. radians for millimetres of lever): the weight must overcome static
  friction at the smallest controllable force, ``W > (μs₁ + μs₂)·min_force·margin``, and a
  hold must be possible.
* ROTATIONAL (gravity-driven turn from the pose with the CoM lever ``d`` horizontal,
  `slip_bringup.core.evaluation.poses.lever_horizontal_turn`): holding that pose,
  ``√(W² + (W·d/r̄)²)/(μ₁ + μ₂)``, must be possible; the lever must satisfy
  ``d ≥ rotation_lever_ratio·r̄`` (translation per radian of turn ``≈ r̄²/d``); the weight's
  torque must overcome static torsional friction at the smallest force; and a hold must be
  possible.
* HINGE through ``turn`` from the pose ``turn`` from hanging (`poses.hinge_start_turn`):
  holding every pose on the way there must be possible (torque ``W·d·|sin γ|`` at the largest
  hanging angle ``γ`` passed); a hinge keeps the object where it is, ``γ₀ = turn`` from
  hanging, while the gripper turns around it: the weight and its torque are all that turns
  the pads, so the object turns relative to them about the centre of rotation at which the
  friction of both pads (their limit surfaces) balances that load (`grasp_geometry`: a gradient
  map, or two maps whose centres of pressure sit apart, move it off the grasp point; for one
  centred map it lies about ``r̄²/(d·sin γ₀)`` beside it). The grasp-point translation this
  gives over the turn (`grasp_geometry.hinge_translation`) must stay within
  ``hinge_translation_limit/margin``; static friction
  above kinetic must let the pads break loose in rotation at a force that still carries the
  weight, ``F* = max(min_force, W/(μ₁ + μ₂))``, where the static torque capacity left is
  ``r̄·√(((μs₁ + μs₂)·F*)² − W²)``: ``W·d·sin γ₀`` must exceed it by the margin (below it, the
  object stays stuck or every break-away is a slide of the grasp point); and a hold must be
  possible.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from friction_models.core.presets import ObjectPreset

from slip_bringup.core.evaluation.poses import hinge_start_turn, path_sin_max, rotated
from slip_bringup.population.grasp_geometry import hinge_translation


@dataclass(frozen=True)
class FeasibilityLimits:
    """The cell's capabilities and the criteria's margins (SI)."""

    gravity: float = 9.81                     # m/s²
    max_force: float = 40.0                   # N, largest grasp force the gripper delivers
    min_force: float = 0.6                    # N, smallest controllable grasp force
    margin: float = 1.2                       # -, safety factor on every criterion
    rotation_lever_ratio: float = 1.5         # -, d/r̄ below which a rotation drags the object
    hinge_turn: float = math.radians(60.0)    # rad
    hinge_translation_limit: float = 0.010    # m


@dataclass(frozen=True)
class Feasibility:
    """Per scenario: possible, and the reason when not."""

    hold: str
    linear: str
    rotational: str
    hinge: str
    hold_force_needed: float                  # N, F_need of the HOLD criterion

    def reason(self, scenario: str) -> str:
        """'' when feasible, else why not."""
        return str(getattr(self, scenario))


#: A sustained load at the CoM: ``(fx [N], fy [N], torque [N·m])`` in ``gripper_middle``.
Load = tuple[float, float, float]


def hold_force_needed(obj: ObjectPreset, loads: Sequence[Load], g: float = 9.81,
                      rotation: float = 0.0) -> float:
    """Grasp force that holds ``obj`` under its weight and each sustained load.

    ``loads``: ``(fx, fy, torque)`` at the CoM (``gripper_middle`` axes). ``rotation`` [rad]:
    the object's rotation in the pads (+z), 0 = as picked up; the CoM offset turns with it. The
    result is the largest ``√(|L|² + (M/r̄)²)/(μ₁ + μ₂)`` [N] over the weight alone and the
    weight with each load, ``M`` taken about the grasp point (module docstring).
    """
    mu = obj.finger_1.mu_c + obj.finger_2.mu_c
    r = 0.5 * (obj.finger_1.r + obj.finger_2.r)
    cx, cy = rotated(obj.com_offset, rotation)
    weight = obj.mass * g
    need = 0.0
    for fx, fy, torque in [(0.0, 0.0, 0.0), *loads]:
        lx, ly = fx, fy - weight
        moment = torque + cx * ly - cy * lx
        need = max(need, math.hypot(lx, ly, moment / r) / mu)
    return need


def hold_force_needed_held(obj: ObjectPreset, loads: Sequence[Load], rotation: float,
                           g: float = 9.81, steps: int = 30) -> float:
    """`hold_force_needed` for the pose the object is really held in (the HOLD judge).

    An object whose CoM is off to the side turns in the pads by ``rotation`` [rad] (truth)
    before the grasp holds it, and its lever then differs from the drawn one: the weight is
    counted at every pose from 0 to ``rotation``, and the loads at ``rotation``.
    """
    still = max(hold_force_needed(obj, (), g, rotation * k / steps) for k in range(steps + 1))
    return max(still, hold_force_needed(obj, loads, g, rotation))


def assess(obj: ObjectPreset, loads: Sequence[Load],
           limits: FeasibilityLimits = FeasibilityLimits()) -> Feasibility:
    """Apply the module's criteria to one object (``loads``: the HOLD's sustained loads)."""
    g, m = limits.gravity, limits.margin
    c1, c2 = obj.finger_1, obj.finger_2
    weight = obj.mass * g
    r = 0.5 * (c1.r + c2.r)
    lever = math.hypot(*obj.com_offset)
    need = hold_force_needed(obj, loads, g)
    hold = '' if need * m <= limits.max_force else (
        f'gripper too weak: holding needs {need:.1f} N x {m} margin, the gripper gives '
        f'{limits.max_force:.0f} N')
    still = hold_force_needed(obj, (), g)
    hold_ok = '' if still * m <= limits.max_force else (
        f'gripper too weak: holding it still needs {still:.1f} N x {m} margin, the gripper gives '
        f'{limits.max_force:.0f} N')
    static_slide = (c1.mu_s + c2.mu_s) * limits.min_force * m
    static_turn = (c1.mu_s * c1.r + c2.mu_s * c2.r) * limits.min_force * m
    mu = c1.mu_c + c2.mu_c

    def tilted(sin_gamma: float, what: str) -> str:
        need_tilt = math.hypot(weight, weight * lever * sin_gamma / r) / mu
        return '' if need_tilt * m <= limits.max_force else (
            f'gripper too weak: holding {what} needs {need_tilt:.1f} N x {m} margin, the '
            f'gripper gives {limits.max_force:.0f} N')

    linear = hold_ok or (
        '' if weight > static_slide else
        f'too light to slide: weight {weight:.2f} N cannot overcome static friction '
        f'{static_slide:.2f} N at the {limits.min_force} N minimum force')
    horizontal = tilted(1.0, 'the CoM lever horizontal')
    if hold_ok or horizontal:
        rotational = hold_ok or horizontal
    elif lever < limits.rotation_lever_ratio * r:
        rotational = (f'lever too short: CoM lever {lever * 1e3:.1f} mm < '
                      f'{limits.rotation_lever_ratio} x torsional radius {r * 1e3:.1f} mm')
    elif weight * lever <= static_turn:
        rotational = (f'too light to turn: weight torque {weight * lever * 1e3:.1f} mN·m cannot '
                      f'overcome static torsional friction {static_turn * 1e3:.1f} mN·m at the '
                      'minimum force')
    else:
        rotational = ''
    turn, sign = hinge_start_turn(obj.com_offset, limits.hinge_turn)
    on_the_way = tilted(path_sin_max(obj.com_offset, turn),
                        f'the poses on the way to {math.degrees(limits.hinge_turn):.0f} deg '
                        'from hanging')
    arm = lever * math.sin(limits.hinge_turn)        # d·sin γ₀ at the hinge pose
    drag = hinge_translation(obj, turn, sign * limits.hinge_turn) if arm > 0.0 else math.inf
    rho = (c1.mu_s + c2.mu_s) / mu
    carry = max(limits.min_force, weight / mu)       # least force that carries the weight
    stuck = r * math.sqrt(max(0.0, ((c1.mu_s + c2.mu_s) * carry) ** 2 - weight ** 2)) / weight
    if hold_ok or on_the_way:
        hinge = hold_ok or on_the_way
    elif drag * m > limits.hinge_translation_limit:
        hinge = (f'lever too short: a hinge through {math.degrees(limits.hinge_turn):.0f} deg '
                 f'drags the grasp point {drag * 1e3:.1f} mm on the limit surface (lever '
                 f'{lever * 1e3:.1f} mm, r {r * 1e3:.1f} mm, pressure map {obj.surface})')
    elif arm <= stuck * m:
        hinge = (f'static friction too high: at the hinge pose the weight\'s lever '
                 f'{arm * 1e3:.1f} mm cannot break the pads loose in rotation while they carry '
                 f'the weight (needs > {stuck * 1e3:.1f} mm x {m} margin at {carry:.2f} N, '
                 f'mu_s/mu_c {rho:.2f})')
    else:
        hinge = ''
    return Feasibility(hold=hold, linear=linear, rotational=rotational, hinge=hinge,
                       hold_force_needed=need)
