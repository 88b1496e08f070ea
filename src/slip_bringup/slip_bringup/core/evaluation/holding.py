# SPDX-License-Identifier: Apache-2.0
"""HOLD on the simulated cell: pick-up and hold under disturbance, judged by the truth.

* `pick_up` — grasp 10 N on the table, HOLD, lift 0.20 m (§5.3 ``pick_up_object``);
* `hold_under_disturbance` — object held in the air under HOLD, external pushes on its CoM.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from slip_bringup.core.evaluation.scene import controlled_scene
from slip_bringup.core.evaluation.settings import EvalSettings
from slip_bringup.core.evaluation.truth import centre_point_displacement
from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import SlipMode
from slip_control.core.mode_switch import ModeRequest

_NAN = math.nan


@dataclass(frozen=True)
class PickUpOutcome:
    """Outcome of `pick_up` (truth unless noted).

    Attributes:
        preset: Object preset.
        lift: Rise of the object's CoM [m] (≈ the commanded 0.20 m when held).
        slip_peak: Largest grasp-point displacement relative to the pads from HOLD on [m].
        rotation_peak: Largest relative rotation from HOLD on [rad].
        force_min: Smallest commanded force under HOLD [N].
        force_max: Largest commanded force under HOLD [N].
        normal_force_final: True normal force at the end [N].
        dropped: The object fell.
    """

    preset: str
    lift: float
    slip_peak: float
    rotation_peak: float
    force_min: float
    force_max: float
    normal_force_final: float
    dropped: bool


def pick_up(preset: str, settings: EvalSettings = EvalSettings(),
            properties: ContactProperties | None = None, lift: float = 0.20,
            hold: float = 1.0) -> PickUpOutcome:
    """§5.3 ``grasp`` then ``pick_up_object``: 10 N for 2 s, HOLD on, lift, hold."""
    h, ctl, probe = controlled_scene(preset, settings, properties, on_table=True)
    h.command_force(10.0)
    h.run_for(2.0)
    y0 = h.state().object_y
    ctl.require_mode(h, ModeRequest(int(SlipMode.HOLD)))
    t0 = h.t
    s0 = h.state()
    h.move(lift=lift)
    h.run_for(hold)
    s = h.state()
    forces = ctl.forces_between(t0, h.t) or [_NAN]
    return PickUpOutcome(preset=preset, lift=s.object_y - y0,
                         slip_peak=probe.peak_displacement(t0, h.t, s0.x, s0.y, s0.theta),
                         rotation_peak=probe.peak_rotation(t0, h.t, s0.theta),
                         force_min=min(forces), force_max=max(forces),
                         normal_force_final=s.normal_force_1, dropped=s.dropped)


@dataclass(frozen=True)
class Push:
    """One external load on the object's CoM (``gripper_middle`` axes, SI).

    Attributes:
        fx: Force x [N].
        fy: Force y [N] (−: pulls down at the pick-up pose).
        torque: Torque about +z [N·m].
        duration: How long it acts [s].
        pause: Time after it before the next one [s].
    """

    fx: float = 0.0
    fy: float = 0.0
    torque: float = 0.0
    duration: float = 0.5
    pause: float = 0.5


#: Sustained pulls, pushes and twists, then escalating taps (the hold protocol of §5.5 in
#: simulation). Forces act on the CoM; the reference objects weigh 0.8–2.0 N.
DEFAULT_PUSHES: tuple[Push, ...] = (
    Push(fy=-1.0),                                 # pull down 1 N
    Push(fy=-3.0),                                 # pull down 3 N
    Push(fx=2.0),                                  # push sideways 2 N
    Push(torque=0.02),                             # twist 0.02 N·m
    Push(fy=-2.0, duration=0.02),                  # taps down: 2, 4, 6 N for 20 ms
    Push(fy=-4.0, duration=0.02),
    Push(fy=-6.0, duration=0.02),
    Push(fx=-4.0, duration=0.02),                  # tap sideways 4 N
)

#: Pushes shorter than this count as taps [s].
TAP_MAX_DURATION = 0.1

#: Lever of the twist in `scaled_pushes` [m]: the torque is that of half the weight there.
SCALED_TWIST_LEVER = 0.010


def scaled_pushes(weight: float) -> tuple[Push, ...]:
    """The hold protocol scaled to an object of ``weight`` [N] (population evaluation).

    A fixed-size push is a gentle nudge on a heavy object and a blow on a light one, and on a
    long centre-of-mass lever it becomes a large twist; these loads are fractions of the
    object's own weight ``W``: sustained pulls down of 0.25 W and 0.5 W, a push sideways of
    0.5 W, a twist of 0.5 W × 10 mm (0.5 s each, 0.5 s apart); then 20 ms taps down of 0.5 W,
    1 W and 1.5 W and a tap sideways of 1 W. Forces act on the CoM (``gripper_middle`` axes).

    Raises:
        ValueError: ``weight`` is not finite and > 0.
    """
    if not (math.isfinite(weight) and weight > 0.0):
        raise ValueError(f'weight must be finite and > 0 N, got {weight!r}')
    w = weight
    return (
        Push(fy=-0.25 * w),
        Push(fy=-0.5 * w),
        Push(fx=0.5 * w),
        Push(torque=0.5 * w * SCALED_TWIST_LEVER),
        Push(fy=-0.5 * w, duration=0.02),
        Push(fy=-1.0 * w, duration=0.02),
        Push(fy=-1.5 * w, duration=0.02),
        Push(fx=-1.0 * w, duration=0.02),
    )


def sustained(pushes: Sequence[Push]) -> tuple[Push, ...]:
    """The pushes that last at least `TAP_MAX_DURATION` (the loads a hold must carry)."""
    return tuple(p for p in pushes if p.duration >= TAP_MAX_DURATION)


@dataclass(frozen=True)
class HoldOutcome:
    """Outcome of `hold_under_disturbance` (truth unless noted).

    Attributes:
        preset: Object preset.
        pushes: The loads applied.
        slip_peak: Largest grasp-point displacement from the pose before the first push [m].
        rotation_peak: Largest relative rotation from that pose [rad].
        slip_final: Displacement at the end [m].
        push_slip: Per push, the largest displacement during it and its pause, from the pose
            at its start [m].
        sustained_slip: Largest `push_slip` of the sustained pushes [m] (0 if none).
        tap_slip: Largest `push_slip` of the taps (shorter than `TAP_MAX_DURATION`) [m].
        force_min: Smallest commanded force during the window [N].
        force_max: Largest commanded force during the window [N].
        dropped: The object fell.
        force_max_settle: Largest commanded force from HOLD on to the first push [N] (the
            HOLD law taking up the object's weight).
        rotation_held: The object's rotation in the pads before the first push [rad] (+z; 0 =
            as placed between the pads): the pose the loads act in.
    """

    preset: str
    pushes: tuple[Push, ...]
    slip_peak: float
    rotation_peak: float
    slip_final: float
    push_slip: tuple[float, ...]
    sustained_slip: float
    tap_slip: float
    force_min: float
    force_max: float
    dropped: bool
    force_max_settle: float = _NAN
    rotation_held: float = 0.0


def hold_under_disturbance(preset: str, pushes: Sequence[Push] = DEFAULT_PUSHES,
                           settings: EvalSettings = EvalSettings(),
                           properties: ContactProperties | None = None) -> HoldOutcome:
    """HOLD on an object held in the air while ``pushes`` act on it one after the other."""
    h, ctl, probe = controlled_scene(preset, settings, properties)
    t0 = h.t
    s0 = h.state()
    settle_forces = ctl.forces_between(-math.inf, t0) or [_NAN]
    per_push = []
    for p in pushes:
        ts = h.t
        sp = h.state()
        h.disturb(p.fx, p.fy, p.torque, p.duration)
        h.run_for(p.duration + p.pause)
        per_push.append(probe.peak_displacement(ts, h.t, sp.x, sp.y, sp.theta))
    s = h.state()
    forces = ctl.forces_between(t0, h.t) or [_NAN]
    taps = [d for p, d in zip(pushes, per_push) if p.duration < TAP_MAX_DURATION]
    sustained = [d for p, d in zip(pushes, per_push) if p.duration >= TAP_MAX_DURATION]
    return HoldOutcome(preset=preset, pushes=tuple(pushes),
                       slip_peak=probe.peak_displacement(t0, h.t, s0.x, s0.y, s0.theta),
                       rotation_peak=probe.peak_rotation(t0, h.t, s0.theta),
                       slip_final=math.hypot(*centre_point_displacement(
                           s0.x, s0.y, s0.theta, s.x, s.y, s.theta)), push_slip=tuple(per_push),
                       sustained_slip=max(sustained, default=0.0),
                       tap_slip=max(taps, default=0.0), force_min=min(forces),
                       force_max=max(forces), dropped=s.dropped,
                       force_max_settle=max(settle_forces), rotation_held=s0.theta)
