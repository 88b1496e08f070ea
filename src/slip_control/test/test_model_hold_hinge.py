# SPDX-License-Identifier: Apache-2.0
"""The ``model`` HOLD and HINGE laws (model_hold, model_hinge) and their slip-twist observer
(twist_observer): hand-computed forces, the observer on quantised samples, the online
adaptation, the stale rules and the refusals with their reasons."""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import pytest

from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import ControlContact, SlipMode
from slip_control.core.mode_switch import ModeRequest, build_controller, with_params
from slip_control.core.model_hinge import (ModelHingeController, limit_surface_force,
                                           torque_capacity, translation_per_radian)
from slip_control.core.model_hold import ModelHoldController
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import MiddleTwist, SensorSnapshot
from slip_control.core.twist_observer import TwistObserver, TwistObserverConfig

CONTACT = ControlContact(mu_c=0.4, r=0.005, r_valid=True)
DT = 1.0 / 120.0
COUNT = 0.001                      # one velocity-sensor count at 120 Hz [m/s] (§6.8)
Snap = Callable[..., SensorSnapshot]
MakeProps = Callable[..., ContactProperties]


def _need(f: tuple[float, float], tz: float, contact: ControlContact = CONTACT) -> float:
    """Limit-surface force D/μ_c [N] of a two-finger mean load."""
    return math.sqrt(f[0] ** 2 + f[1] ** 2 + (tz / contact.r) ** 2) / contact.mu_c


# -- observer -----------------------------------------------------------------------------

def test_observer_ignores_a_lone_count_and_sees_a_sustained_slip() -> None:
    obs = TwistObserver(TwistObserverConfig(), r=0.005)
    t = 0.0
    for _ in range(20):
        t += DT
        assert not obs.update(MiddleTwist(0.0, 0.0, 0.0), t).slipping
    t += DT
    est = obs.update(MiddleTwist(COUNT, 0.0, 0.0), t)       # one count of noise
    assert not est.slipping and 0.0 < est.translation_speed < COUNT
    for _ in range(5):
        t += DT
        assert not obs.update(MiddleTwist(0.0, 0.0, 0.0), t).slipping
    seen = None
    for k in range(120):                                     # 3 counts for 1 s
        t += DT
        est = obs.update(MiddleTwist(0.0, -3 * COUNT, 0.0), t)
        if seen is None and est.slipping:
            seen = k
    assert seen is not None and seen <= 2                    # within three samples
    assert est.velocity[1] == pytest.approx(-3 * COUNT, rel=0.02)
    assert est.displacement[1] == pytest.approx(-3 * COUNT * 1.0, rel=0.1)


def test_observer_detects_a_slow_turn_of_a_small_pad() -> None:
    # 0.1 rad/s on r = 3 mm moves the rim 0.3 mm/s: far below a count, but a turn.
    obs = TwistObserver(TwistObserverConfig(), r=0.003)
    t, est = 0.0, None
    for _ in range(60):
        t += DT
        est = obs.update(MiddleTwist(0.0, 0.0, 0.1), t)
    assert est is not None and est.slipping
    assert est.rotation_rate == pytest.approx(0.1, rel=0.02)
    assert est.translation_speed == pytest.approx(0.0, abs=1e-9)


def test_observer_repeated_stamp_and_bad_config() -> None:
    obs = TwistObserver(TwistObserverConfig(), r=0.005)
    obs.update(MiddleTwist(0.002, 0.0, 0.0), 1.0)
    before = obs.estimate.displacement
    obs.update(MiddleTwist(0.002, 0.0, 0.0), 1.0)            # same stamp: no prediction
    assert obs.estimate.displacement == before
    with pytest.raises(ValueError, match='detect_speed'):
        TwistObserverConfig(detect_speed=0.0)
    with pytest.raises(ValueError, match='r must be'):
        TwistObserver(TwistObserverConfig(), r=float('nan'))


# -- model HOLD ---------------------------------------------------------------------------

def _hold(params: SlipControllerParams, snap: Snap, loads: list[tuple[float, float]],
          t0: float = 1.0, tz: float = 0.0, **kw: object
          ) -> tuple[ModelHoldController, list[float]]:
    """Run a model HOLD over ``loads`` (F̄ per step, 120 Hz); returns it and its outputs."""
    h = ModelHoldController(params, CONTACT)
    out = []
    for k, f in enumerate(loads):
        t = t0 + k * DT
        o = h.step(snap(t, f=f, tz=tz, **kw), t)
        assert o.force is not None
        out.append(o.force)
    return h, out


def test_model_hold_law_hand_computed(params: SlipControllerParams, snap: Snap) -> None:
    h = ModelHoldController(params, CONTACT)
    hm = params.hold_model
    # F̄ = (0.3, −0.4) → 0.5 N; τ̄/r = 0.002/0.005 = 0.4 N → D = √0.41 = 0.6403 N;
    # need = D/0.4 = 1.6008 N; margin·need + extra_force (below the bound
    # max_margin·need + max_extra_force).
    out = h.step(snap(1.0, f=(0.3, -0.4), tz=0.002), 1.0)
    assert out.mode == SlipMode.HOLD and not out.safe_hold
    assert out.force == pytest.approx(hm.margin * math.sqrt(0.41) / 0.4 + hm.extra_force,
                                      rel=1e-9)
    assert h.needed_force == pytest.approx(math.sqrt(0.41) / 0.4, rel=1e-9)


def test_model_hold_clamps_to_the_gripper_range(params: SlipControllerParams,
                                                snap: Snap) -> None:
    hm = params.hold_model
    _, light = _hold(params, snap, [(0.0, -0.01)] * 3)
    assert light[-1] == pytest.approx(max(hm.margin * 0.01 / 0.4 + hm.extra_force,
                                          params.model.min_force))
    low = replace(params, hold_model=replace(params.hold_model, extra_force=0.0))
    _, tiny = _hold(low, snap, [(0.0, -0.01)] * 3)
    assert tiny[-1] == pytest.approx(params.model.min_force)
    _, heavy = _hold(params, snap, [(0.0, -20.0)] * 3)
    assert heavy[-1] == pytest.approx(params.model.max_force)


def test_model_hold_ignores_a_tap_but_follows_a_sustained_load(params: SlipControllerParams,
                                                               snap: Snap) -> None:
    rest, high = (0.0, -1.0), (0.0, -3.0)
    need_rest, need_high = _need(rest, 0.0), _need(high, 0.0)
    hm = params.hold_model
    bound_rest = hm.max_margin * need_rest + hm.max_extra_force
    # A 17 ms tap (two samples) of three times the load: the force stays within the bound
    # set by the sustained load, far below what the tap's load would ask for.
    _, tap = _hold(params, snap, [rest] * 30 + [high] * 2 + [rest] * 30)
    assert max(tap) <= bound_rest + 1e-9
    assert max(tap) < hm.margin * need_high
    # The same load sustained: after sustain_time the force is the law's for it.
    _, step = _hold(params, snap, [rest] * 30 + [high] * 30)
    assert step[-1] == pytest.approx(hm.margin * need_high + hm.extra_force, rel=1e-6)
    k_bound = next(k for k, f in enumerate(step) if f > bound_rest + 1e-9)
    assert (k_bound - 30) * DT <= params.hold_model.sustain_time + 2 * DT


def test_model_hold_remembers_the_recent_load(params: SlipControllerParams,
                                              snap: Snap) -> None:
    high, rest = (0.0, -3.0), (0.0, -1.0)
    _, out = _hold(params, snap, [high] * 30 + [rest] * 60)     # 0.5 s after the load fell
    hm = params.hold_model
    f_high = hm.margin * _need(high, 0.0) + hm.extra_force
    mem = hm.memory_time
    # The remembered need decays with memory_time (seconds), not with fall_time (0.3 s).
    assert out[29] == pytest.approx(f_high, rel=1e-6)
    assert out[-1] > hm.margin * (_need(rest, 0.0) + (_need(high, 0.0) - _need(rest, 0.0))
                                  * math.exp(-0.6 / mem)) + hm.extra_force - 0.05
    assert out[-1] < f_high


def test_model_hold_reacts_to_observed_slip_and_learns(params: SlipControllerParams,
                                                       snap: Snap) -> None:
    load = (0.0, -1.0)
    h, quiet = _hold(params, snap, [load] * 30)
    f0 = quiet[-1]
    outs = []
    for k in range(30, 90):                  # 4 mm/s of slip for 0.5 s (2 mm of path)
        t = 1.0 + k * DT
        o = h.step(snap(t, f=load, v=(0.0, -0.004)), t)
        assert o.force is not None
        outs.append(o.force)
    assert outs[2] > f0 + 0.05                # incipient slip: more force within 3 samples
    assert h.learned_margin > 0.0             # beyond the 1 mm dead zone: the margin grows
    need = _need(load, 0.0)
    hm = params.hold_model
    assert outs[-1] > hm.max_margin * need + hm.max_extra_force        # ... and lifts the bound
    assert outs[-1] <= (hm.max_margin + h.learned_margin) * need + hm.max_extra_force + 1e-9


def test_model_hold_stale_rules(params: SlipControllerParams, snap: Snap) -> None:
    h, out = _hold(params, snap, [(0.0, -2.0)] * 5)
    last = out[-1]
    # Velocity stops; F/T continues with a smaller load: no decrease, safe hold.
    for k in range(1, 20):
        t = 1.0 + 4 * DT + 0.06 + k * 0.01
        o = h.step(snap(1.0 + 4 * DT, f=(0.0, -0.5), ft_stamp=t), t)
        assert o.safe_hold and o.force == pytest.approx(last)
    # A larger load while the velocity is stale: the force rises at once.
    t = 2.0
    o = h.step(snap(1.0 + 4 * DT, f=(0.0, -6.0), ft_stamp=t), t)
    hm = params.hold_model
    assert o.safe_hold and o.force == pytest.approx(hm.margin * _need((0.0, -6.0), 0.0)
                                                    + hm.extra_force)
    # F/T stale: hold the last output.
    o = h.step(snap(3.0, f=(0.0, -0.1), ft_stamp=2.5), 3.0)
    assert o.safe_hold and o.reason.startswith('F/T stale')


# -- model HINGE --------------------------------------------------------------------------

def test_limit_surface_relations_are_consistent() -> None:
    mu, r, ft, c = 0.5, 0.006, 0.8, 0.004
    f = limit_surface_force(ft, mu, r, c)
    assert translation_per_radian(f, ft, mu, r) == pytest.approx(c, rel=1e-12)
    # At that force a torque r²·ft/c is exactly the capacity (CoR at c).
    assert torque_capacity(f, ft, mu, r) == pytest.approx(r * r * ft / c, rel=1e-12)
    assert torque_capacity(ft / mu, ft, mu, r) == 0.0      # sliding already: no torque left
    assert translation_per_radian(ft / mu, ft, mu, r) == math.inf


def test_model_hinge_law_hand_computed(params: SlipControllerParams, snap: Snap) -> None:
    g = params.hinge_model
    assert (g.orientation_gain, g.static_ratio, g.max_cor) == pytest.approx((2.0, 1.3, 0.008))
    # At the request the pads may carry the torque they carry now (20 mN·m) with the weight
    # (0.5 N); stuck, static friction (μ_s = 1.3·μ_c) holds: F = ‖(0.5, 0.02/0.005)‖/(1.3·0.4).
    h = ModelHingeController(params, CONTACT)
    out = h.step(snap(1.0, f=(0.0, -0.5), tz=0.02), 1.0)
    assert out.mode == SlipMode.HINGE
    assert h.reference_torque == pytest.approx(0.02)
    assert out.force == pytest.approx(math.hypot(0.5, 4.0) / (1.3 * 0.4), rel=1e-9)
    # A nearly hanging object (0.1 mN·m): the reference torque is raised to r²·ft/max_cor
    # (CoR within 8 mm), and the force never falls below the weight's ft/(μ_c·max_load_ratio).
    h = ModelHingeController(params, CONTACT)
    out = h.step(snap(1.0, f=(0.0, -0.5), tz=0.0001), 1.0)
    floor_torque = 0.005 ** 2 * 0.5 / 0.008
    expected = max(math.hypot(0.5, floor_torque / 0.005) / (1.3 * 0.4),
                   0.5 / (0.4 * g.max_load_ratio))
    assert out.force == pytest.approx(expected, rel=1e-9)
    assert 'no torque' in out.reason


def _turned_load(turn: float) -> tuple[float, float]:
    """Mean load of a 0.5 N weight on a gripper turned ``turn`` [rad] (load direction)."""
    return 0.5 * math.sin(turn), -0.5 * math.cos(turn)


def _hinge_steps(params: SlipControllerParams, snap: Snap, gripper_turn: float,
                 pad_turn_rate: float, n: int = 60) -> tuple[ModelHingeController, list[float]]:
    """Gripper turning ``gripper_turn`` [rad] over ``n`` samples from the start pose, the
    object turning in the pads at ``pad_turn_rate`` [rad/s]; torque 20 mN·m throughout."""
    h = ModelHingeController(params, CONTACT)
    forces = []
    for k in range(n):
        t = 1.0 + k * DT
        o = h.step(snap(t, f=_turned_load(gripper_turn * k / (n - 1)), tz=0.02,
                        omega=pad_turn_rate if k else 0.0), t)
        assert o.force is not None
        forces.append(o.force)
    return h, forces


def test_model_hinge_releases_an_object_the_gripper_drags_along(
        params: SlipControllerParams, snap: Snap) -> None:
    # The gripper turns 0.2 rad with the object stuck to the pads: with τ₀ > 0 the uphill
    # sense is −1 and a load direction turning by +a reads as a gripper turn of −a.
    h, forces = _hinge_steps(params, snap, 0.2, 0.0)
    assert h.world_turn == pytest.approx(-0.2, abs=0.01)
    assert forces[-1] < 0.7 * forces[0]
    # Never below the force that carries the weight.
    assert min(forces) >= 0.5 / (0.4 * params.hinge_model.max_load_ratio) - 1e-9
    # Swinging down instead (the other way): more force, to catch it.
    h, forces = _hinge_steps(params, snap, -0.2, 0.0)
    assert h.world_turn == pytest.approx(0.2, abs=0.01)
    assert forces[-1] > 1.2 * forces[0]


def test_model_hinge_keeps_the_force_while_the_object_keeps_its_place(
        params: SlipControllerParams, snap: Snap) -> None:
    # The pads turn under the object exactly as the gripper turns (the object keeps its
    # orientation in the world): nothing to correct.
    n = 60
    rate = 0.2 / ((n - 1) * DT)
    h, forces = _hinge_steps(params, snap, 0.2, rate, n)
    assert h.world_turn == pytest.approx(0.0, abs=0.01)
    no_damping = replace(params, hinge_model=replace(params.hinge_model, rotation_damping=0.0))
    h2, forces2 = _hinge_steps(no_damping, snap, 0.2, rate, n)
    assert h2.world_turn == pytest.approx(0.0, abs=0.01)
    # Slipping, so kinetic friction: the pads carry the reference torque at μ_c.
    assert h2.observer.estimate.slipping
    assert forces2[-1] == pytest.approx(math.hypot(0.5, 4.0) / 0.4, rel=0.02)


def test_model_hinge_stale_inputs_hand_over_to_model_hold(params: SlipControllerParams,
                                                          snap: Snap) -> None:
    h = ModelHingeController(params, CONTACT)
    h.step(snap(1.0, f=(0.0, -0.5), tz=0.004), 1.0)
    out = h.step(snap(1.0, f=(0.0, -0.5), tz=0.004, ft_stamp=1.0), 1.2)
    assert isinstance(out.next_controller, ModelHoldController)
    assert out.reason.startswith('HINGE ended')


# -- requests -----------------------------------------------------------------------------

def test_model_requests_build_the_model_controllers(make_props: MakeProps,
                                                    params: SlipControllerParams,
                                                    snap: Snap) -> None:
    inputs = snap(1.0, f=(0.0, -0.5), tz=0.004)
    hold = build_controller(ModeRequest(int(SlipMode.HOLD), control_law='model'),
                            make_props(), params, 1.0, inputs=inputs)
    assert hold.ok and isinstance(hold.controller, ModelHoldController)
    hinge = build_controller(ModeRequest(int(SlipMode.HINGE), control_law='model'),
                             make_props(), params, 1.0, inputs=inputs)
    assert hinge.ok and isinstance(hinge.controller, ModelHingeController)
    # μ_s/μ_c from the properties (the test fingers have μ_s = μ_c), not the 1.3 default.
    assert hinge.controller.mu_s_ratio == pytest.approx(1.0)
    # Live parameter updates keep the law (and what it took from the properties).
    rebuilt = with_params(hinge.controller, params)
    assert isinstance(rebuilt, ModelHingeController) and rebuilt.mu_s_ratio == pytest.approx(1.0)
    assert isinstance(with_params(hold.controller, params), ModelHoldController)


def test_model_hinge_refusals_state_the_reason(make_props: MakeProps,
                                               params: SlipControllerParams,
                                               snap: Snap) -> None:
    req = ModeRequest(int(SlipMode.HINGE), control_law='model')
    torque = snap(1.0, f=(0.0, -0.5), tz=0.004)
    no_r = build_controller(req, make_props(rotational_valid=False), params, 1.0,
                            inputs=torque)
    assert not no_r.ok and no_r.controller is None and 'r is not valid' in no_r.message
    no_inputs = build_controller(req, make_props(), params, 1.0, inputs=None)
    assert not no_inputs.ok and 'no wrench measured' in no_inputs.message
    flat = build_controller(req, make_props(), params, 1.0,
                            inputs=snap(1.1, f=(0.0, -0.5), tz=0.0001))
    assert not flat.ok and 'no torque measured' in flat.message
    assert 'nothing would turn the pads' in flat.message
    # The thesis HINGE needs none of it.
    thesis = build_controller(ModeRequest(int(SlipMode.HINGE)), make_props(
        rotational_valid=False), params, 1.0, inputs=None)
    assert thesis.ok
