# SPDX-License-Identifier: Apache-2.0
"""Where the two pads let an object turn, and how far a hinge drags its grasp point (truth).

Both pads touch the same rigid object, so it can turn relative to them about one point only.
With the pressure maps placed in ``gripper_middle`` (finger frames from `FrameParams`, each
map scaled to its finger's torsional radius as the simulator scales it), pure rotation about
a point ``c`` needs the torque ``T(c) = F·Σ_k μ_k Σ_i p̂_ki ‖ρ_ki − c‖`` and leaves a net
tangential friction force unless ``c`` minimises ``T``: the **rotation centre** is that
friction-weighted geometric median of both maps (Weiszfeld iteration). A gradient map puts
it off the pad centre, and two maps whose centres of pressure sit on opposite sides of the
grasp point spread the contact, so the **joint torsional radius** ``r_j = T(c)/(F·Σμ_k)`` can
exceed either pad's own ``r``.

HINGE (the object keeps its place in the world while the gripper turns around it, slowly):
the pads carry the weight ``W`` and its torque, so the object turns relative to them about
the centre of rotation (CoR) at which the Coulomb friction of both pads balances exactly that
load (`slip_centre`; a slip, so this does not depend on the grasp force). Each pad's friction
for a twist comes from the simulator's own pre-computed limit surface of its map
(`friction_models.core.limit_surface`, looked up at the pad's centre of pressure in its own
frame), so the criterion uses the friction law the simulator integrates. On an ellipsoidal
limit surface the CoR would lie ``r_j²/x`` beside the rotation centre, horizontally, on the
far side from the CoM (``x`` the CoM's horizontal distance from the rotation centre; the
search starts there); a line contact's surface is far from an ellipsoid. `hinge_translation`
follows that CoR through the turn and returns how far the object point at the gripper centre
moves relative to the pads.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from friction_models.core.limit_surface import LimitSurface, LimitSurfaceCache
from friction_models.core.presets import ObjectPreset
from friction_models.core.surfaces import standard_surface
from slip_bringup.core.evaluation.poses import gravity_in_middle, rotated
from slip_cell_common.core.frames import FrameParams, planar_from_middle, planar_to_middle


@dataclass(frozen=True)
class PadPressure:
    """One pad's pressure map in ``gripper_middle`` (SI).

    Attributes:
        finger: 1 or 2.
        mu_c: Kinetic friction coefficient of the pad [-].
        radius: Characteristic radius of the pad about its centre of pressure [m].
        cop: Centre of pressure in ``gripper_middle`` [m].
        x: Cell centres x [m] (cells with pressure only).
        y: Cell centres y [m].
        weight: Normalised pressure of each cell [-] (sums to 1).
        table: The map's normalised limit surface (the simulator's).
        frames: Frame constants the pad was placed with.
    """

    finger: int
    mu_c: float
    radius: float
    cop: tuple[float, float]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    weight: NDArray[np.float64]
    table: LimitSurface
    frames: FrameParams


def pad_pressures(obj: ObjectPreset, frames: FrameParams = FrameParams(), grid_n: int = 21,
                  patch_size: float = 0.02, n_ls: int = 20,
                  cache: LimitSurfaceCache | None = None) -> tuple[PadPressure, PadPressure]:
    """Both pads' maps of ``obj`` in ``gripper_middle`` (the simulator's shape, scaling and
    limit-surface table; ``cache`` shares tables between calls)."""
    base = standard_surface(obj.surface, grid_n, patch_size)
    table = (cache if cache is not None else LimitSurfaceCache()).get(base, n_ls)
    p = np.asarray(base.pressure, dtype=np.float64)
    on = p > 0.0
    w = p[on] / float(np.sum(p[on]))
    pads = []
    for finger, contact in ((1, obj.finger_1), (2, obj.finger_2)):
        surface = base.scaled(contact.r / table.r_a)   # as `pad_contact.PadContact` scales it
        xs, ys = surface.cell_centres()
        ax, ay, _ = planar_to_middle(frames, finger, 1.0, 0.0, 0.0)
        bx, by, _ = planar_to_middle(frames, finger, 0.0, 1.0, 0.0)
        px, py = xs[on], ys[on]
        cx, cy = surface.cop
        pads.append(PadPressure(finger, contact.mu_c, contact.r,
                                (ax * cx + bx * cy, ay * cx + by * cy),
                                ax * px + bx * py, ay * px + by * py, w, table, frames))
    return pads[0], pads[1]


def rotation_torque(pads: Sequence[PadPressure], centre: Sequence[float]) -> float:
    """``T(c)/F`` [m]: Coulomb torque of pure rotation about ``centre`` per newton of grasp."""
    cx, cy = centre
    return float(sum(p.mu_c * np.sum(p.weight * np.hypot(p.x - cx, p.y - cy)) for p in pads))


def rotation_centre(pads: Sequence[PadPressure], iterations: int = 200,
                    tolerance: float = 1e-9) -> tuple[float, float]:
    """The point [m, ``gripper_middle``] the object turns about under pure torque."""
    c = np.zeros(2)
    for _ in range(iterations):
        num = np.zeros(2)
        den = 0.0
        for p in pads:
            d = np.maximum(np.hypot(p.x - c[0], p.y - c[1]), 1e-9)
            g = p.mu_c * p.weight / d
            num += (float(np.sum(g * p.x)), float(np.sum(g * p.y)))
            den += float(np.sum(g))
        nxt = num / den
        done = math.hypot(*(nxt - c)) < tolerance
        c = nxt
        if done:
            break
    return float(c[0]), float(c[1])


def joint_torsional_radius(pads: Sequence[PadPressure], centre: Sequence[float]) -> float:
    """``r_j`` [m]: torque capacity about ``centre`` over force capacity, both pads."""
    return rotation_torque(pads, centre) / sum(p.mu_c for p in pads)


def friction_wrench(pads: Sequence[PadPressure], cor: Sequence[float], omega: float
                    ) -> tuple[float, float, float]:
    """Friction on the object per newton of grasp ``(Fx, Fy, τ)`` [N/N, m] (torque about the
    gripper centre) while it turns relative to the pads about ``cor`` [m], in the sense of
    ``omega`` (sign only): each pad's limit surface at its centre of pressure."""
    fx = fy = tz = 0.0
    for p in pads:
        vx = -omega * (p.cop[1] - cor[1])                 # ω ẑ × (cop − c), gripper_middle
        vy = omega * (p.cop[0] - cor[0])
        px, py, pw = planar_from_middle(p.frames, p.finger, vx, vy, omega)
        hx, hy, ht = p.table.lookup(px, py, pw, p.radius)  # against the motion
        gx, gy, gt = planar_to_middle(p.frames, p.finger, p.mu_c * hx, p.mu_c * hy,
                                      p.mu_c * ht * p.radius)
        fx += gx
        fy += gy
        tz += gt + p.cop[0] * gy - p.cop[1] * gx
    return fx, fy, tz


def slip_centre(pads: Sequence[PadPressure], load: Sequence[float], scale: float,
                guess: Sequence[float], iterations: int = 60) -> tuple[float, float] | None:
    """The CoR [m] about which the friction balances ``load`` = ``(Fx, Fy, τ)`` the pads must
    supply (any positive multiple), or None if the search does not converge.

    Newton on the direction of ``(F, τ/scale)`` (``scale`` [m] a torsional radius) from
    ``guess``; the sense of turn is the one the torque asks for.
    """
    omega = -1.0 if load[2] > 0.0 else 1.0              # friction torque opposes the turn
    target = np.array([load[0], load[1], load[2] / scale])
    target /= float(np.linalg.norm(target))

    def residual(c: NDArray[np.float64]) -> NDArray[np.float64]:
        fx, fy, tz = friction_wrench(pads, (float(c[0]), float(c[1])), omega)
        a = np.array([fx, fy, tz / scale])
        a /= float(np.linalg.norm(a))
        return np.asarray(a - target, dtype=np.float64)

    c = np.array(guess, dtype=np.float64)
    h = 1e-6
    for _ in range(iterations):
        r0 = residual(c)
        if float(np.linalg.norm(r0)) < 1e-9:
            return float(c[0]), float(c[1])
        jac = np.column_stack([(residual(c + e) - r0) / h for e in (np.array([h, 0.0]),
                                                                     np.array([0.0, h]))])
        step = np.linalg.lstsq(jac, -r0, rcond=None)[0]
        n = float(np.linalg.norm(step))
        if n > 0.002:
            step *= 0.002 / n
        c = c + step
    return (float(c[0]), float(c[1])) if float(np.linalg.norm(residual(c))) < 1e-6 else None


def hinge_translation(obj: ObjectPreset, start_turn: float, turn: float, theta: float = 0.0,
                      frames: FrameParams = FrameParams(), steps: int = 60,
                      gravity: float = 9.81) -> float:
    """Quasi-static grasp-point translation [m] of a HINGE (module docstring).

    Args:
        obj: The object (truth).
        start_turn: Gripper turn from the pick-up pose at the hinge pose [rad].
        turn: Signed gripper turn of the hinge [rad].
        theta: Object rotation in the pads at the hinge pose [rad].
        frames: Frame constants (finger frames in ``gripper_middle``).
        steps: Integration steps over the turn.
        gravity: [m/s²].

    Returns:
        Distance from the gripper centre of the object point that was there at the start;
        inf when the weight has no lever to turn the pads with. Where the CoR search does not
        converge (a CoR far outside the pads: levers of a few millimetres) the ellipsoidal
        point is used for that step.
    """
    pads = pad_pressures(obj, frames)
    cx, cy = rotation_centre(pads)
    r_j = joint_torsional_radius(pads, (cx, cy))
    com = np.array(rotated(obj.com_offset, theta))           # CoM in gripper_middle
    point = np.zeros(2)                                       # the tracked object point
    centre = np.array([cx, cy])
    weight = obj.mass * gravity
    step = turn / steps
    # The gripper turns by +step, the object stays: it turns by −step in the pads.
    cs, sn = math.cos(-step), math.sin(-step)
    rot = np.array([[cs, -sn], [sn, cs]])
    arm = start_turn
    for _ in range(steps):
        ca, sa = math.cos(arm), math.sin(arm)
        down = np.array(gravity_in_middle(arm))
        rel = com - centre
        horizontal = ca * rel[0] - sa * rel[1]                # CoM's world x from the centre
        torque = float(com[0] * down[1] - com[1] * down[0]) * weight
        if abs(horizontal) < 1e-9 or torque == 0.0:
            return math.inf                                   # no torque: nothing turns it
        guess = centre - r_j * r_j / horizontal * np.array([ca, -sa])
        found = slip_centre(pads, (-weight * down[0], -weight * down[1], -torque), r_j,
                            guess)
        cor = np.array(found) if found is not None else guess
        point = cor + rot @ (point - cor)
        com = cor + rot @ (com - cor)
        arm += step
    return float(np.hypot(*point))
