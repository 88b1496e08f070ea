# SPDX-License-Identifier: Apache-2.0
"""LINEAR and ROTATIONAL slip (§4.2–4.6, §4.9) on the toy plant and on scripted inputs.

The closed-loop cases validate the reference gains of §4.10 on a Coulomb–viscous object with
stiction, a 30 ms actuator lag, F/T noise and chip-quantised velocities (`toy_plant`), before
the cell simulator exists. Outcomes are the plant's true displacement/angle after settling.
"""
from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from slip_control.core.controllers import (ControlContact, ControlOutput, HoldController,
                                           LinearController, RotationalController, SlipMode)
from slip_control.core.params import ReversalParams, SlipControllerParams
from slip_control.core.signals import SensorSnapshot
from slip_control.core.toy_plant import ClosedLoop, ToyPlant, ToyPlantParams

DT = 1.0 / 120.0
Snap = Callable[..., SensorSnapshot]


def _held_loop(kind: str, seed: int, pp: ToyPlantParams,
               params: SlipControllerParams) -> tuple[ToyPlant, ClosedLoop, ControlContact]:
    plant = ToyPlant(pp, kind=kind, seed=seed)
    contact = ControlContact(mu_c=pp.mu_c, r=pp.r, r_valid=True)
    loop = ClosedLoop(plant)
    loop.run(HoldController(params, contact, initial_force=pp.initial_force), 1.0)
    return plant, loop, contact


class _Recorder:
    def __init__(self) -> None:
        self.outputs: list[tuple[float, ControlOutput]] = []

    def __call__(self, t: float, out: ControlOutput) -> None:
        self.outputs.append((t, out))

    def results(self) -> list[Any]:
        return [o.result for _, o in self.outputs if o.result is not None]


@pytest.mark.parametrize('distance, duration, seed, aware', [
    (0.02, 2.0, 0, True), (0.02, 2.0, 1, True), (0.04, 5.0, 2, True), (0.02, 2.0, 3, False)])
def test_linear_slip_reaches_the_distance(distance: float, duration: float, seed: int,
                                          aware: bool) -> None:
    params = SlipControllerParams(direction_aware=aware)
    pp = ToyPlantParams()
    plant, loop, contact = _held_loop('linear', seed, pp, params)
    x0, t0 = plant.state.pos, plant.state.t
    rec = _Recorder()
    ctrl = LinearController(params, contact, distance, duration, t0)
    final, _ = loop.run(ctrl, duration + 1.5, on_output=rec)
    results = rec.results()
    assert len(results) == 1 and results[0].success and results[0].message == 'done'
    assert isinstance(final, HoldController)
    slid = plant.state.pos - x0
    assert abs(distance - slid) <= 0.002                       # issue 7: ≤ 2 mm
    assert results[0].final_pos == pytest.approx(slid, abs=0.001)
    # It actually followed the trapezoid rather than dropping and catching the object.
    track = [o.tracking for _, o in rec.outputs if o.tracking is not None]
    err = np.array([tr.ref_pos - tr.meas_pos for tr in track])
    assert np.sqrt(np.mean(err ** 2)) < 0.25 * distance
    assert max(tr.meas_vel for tr in track) < 3.0 * 1.25 * distance / duration
    # The step that ends the trajectory publishes the HOLD force (§4.1).
    last = next(o for _, o in rec.outputs if o.result is not None)
    assert last.mode == SlipMode.HOLD and last.tracking is not None and last.tracking.done
    assert last.force == pytest.approx(last.tracking.force_cmd)
    assert last.force >= 2.0 * 2.0                             # HOLD: margin·floor at least


@pytest.mark.parametrize('angle_deg, duration, seed, tilt_deg', [
    (20.0, 2.0, 0, 45.0), (20.0, 2.0, 1, 45.0), (45.0, 5.0, 2, 75.0)])
def test_rotational_slip_reaches_the_angle(angle_deg: float, duration: float, seed: int,
                                           tilt_deg: float) -> None:
    params = SlipControllerParams()
    pp = ToyPlantParams(tilt0=math.radians(tilt_deg))
    plant, loop, contact = _held_loop('rotational', seed, pp, params)
    a0, t0 = plant.state.angle, plant.state.t
    rec = _Recorder()
    ctrl = RotationalController(params, contact, math.radians(angle_deg), duration, t0)
    final, _ = loop.run(ctrl, duration + 1.5, on_output=rec)
    results = rec.results()
    assert len(results) == 1 and results[0].success
    assert isinstance(final, HoldController)
    turned = plant.state.angle - a0
    assert abs(math.radians(angle_deg) - turned) <= math.radians(2.0)   # issue 7: ≤ 2°
    assert not plant.state.dropped          # the translation floor kept the object held


def test_velocity_stream_stops_mid_slip_safe_hold_within_100ms() -> None:
    params = SlipControllerParams()
    plant, loop, contact = _held_loop('linear', 0, ToyPlantParams(), params)
    t0 = plant.state.t
    drop = (t0 + 1.0, t0 + 1.6)
    rec = _Recorder()
    ctrl = LinearController(params, contact, 0.02, 2.0, t0)
    final, log = loop.run(ctrl, 2.0, velocity_dropout=drop, on_output=rec)
    safe = [(t, o) for t, o in rec.outputs if o.safe_hold]
    assert safe, 'no safe hold'
    t_safe = safe[0][0]
    assert drop[0] <= t_safe <= drop[0] + 0.100
    assert rec.results()[0].message == 'velocity stale' and not rec.results()[0].success
    # While stale the commanded force never decreases.
    forces = [o.force for t, o in rec.outputs if o.safe_hold and o.force is not None]
    assert all(b >= a - 1e-12 for a, b in itertools.pairwise(forces))
    # The object stops: at most 1 mm more slip from 0.2 s after the safe hold to the end of
    # the dropout, and HOLD resumes normally once velocity returns.
    i0 = next(i for i, t in enumerate(log.t) if t >= t_safe + 0.2)
    i1 = next(i for i, t in enumerate(log.t) if t >= drop[1])
    assert log.pos[i1] - log.pos[i0] < 0.001
    assert isinstance(final, HoldController)
    assert not rec.outputs[-1][1].safe_hold


def test_ft_stream_stops_mid_slip_holds_last_output() -> None:
    params = SlipControllerParams()
    pp = ToyPlantParams(tilt0=math.radians(45))
    plant, loop, contact = _held_loop('rotational', 1, pp, params)
    t0 = plant.state.t
    drop = (t0 + 0.8, t0 + 1.2)
    rec = _Recorder()
    loop.run(RotationalController(params, contact, math.radians(20), 2.0, t0), 1.5,
             ft_dropout=drop, on_output=rec)
    res = rec.results()
    assert res and res[0].message == 'F/T stale'
    t_safe = next(t for t, o in rec.outputs if o.safe_hold)
    assert drop[0] <= t_safe <= drop[0] + 0.100
    held = [o.force for t, o in rec.outputs if o.safe_hold]
    assert len(set(held)) == 1                                # the last output, unchanged


# --- scripted inputs ---------------------------------------------------------------------------

def test_linear_reversal_aborts_to_hold(params: SlipControllerParams, snap: Snap) -> None:
    contact = ControlContact(mu_c=0.4, r=0.005, r_valid=True)
    ctrl = LinearController(params, contact, 0.02, 2.0, 0.0, direction=(0.0, -1.0))
    t = 0.0
    out = None
    for i in range(1, 40):
        t = i * DT
        v = (0.0, -0.004) if i < 10 else (0.0, 0.005)       # reverses at i = 10
        out = ctrl.step(snap(t, f=(0.0, -1.0), v=v), t)
        if out.result is not None:
            break
    assert out is not None and out.result is not None
    assert out.result.message == 'slip reversed' and not out.result.success
    assert 0.1 < t - 10 * DT <= 0.1 + 2 * DT
    assert isinstance(out.next_controller, HoldController) and out.mode == SlipMode.HOLD


def test_reference_mode_counts_reversal_as_progress(snap: Snap) -> None:
    params = SlipControllerParams(direction_aware=False)
    ctrl = LinearController(params, ControlContact(mu_c=0.4), 0.02, 2.0, 0.0,
                            direction=(0.0, -1.0))
    for i in range(1, 40):
        out = ctrl.step(snap(i * DT, f=(0.0, -1.0), v=(0.0, 0.005)), i * DT)
        assert out.result is None
    assert ctrl.progress == pytest.approx(38 * DT * 0.005)


def test_latched_direction_then_reversal(params: SlipControllerParams, snap: Snap) -> None:
    ctrl = LinearController(params, ControlContact(mu_c=0.4), 0.02, 2.0, 0.0)
    ctrl.step(snap(DT, v=(0.001, 0.0)), DT)                   # below latch_speed
    assert ctrl.direction is None
    ctrl.step(snap(2 * DT, v=(0.003, 0.004)), 2 * DT)
    assert ctrl.direction == pytest.approx((0.6, 0.8))
    out = None
    for i in range(3, 30):
        out = ctrl.step(snap(i * DT, v=(-0.003, -0.004)), i * DT)
        if out.result is not None:
            break
    assert out is not None and out.result is not None
    assert out.result.message == 'slip reversed'


def test_rotational_sign_and_reversal(snap: Snap) -> None:
    params = SlipControllerParams(reversal=ReversalParams(time=0.05))
    c = ControlContact(mu_c=0.4, r=0.005, r_valid=True)
    ctrl = RotationalController(params, c, -0.3, 2.0, 0.0)
    ctrl.step(snap(DT, tz=-0.001, omega=-0.1), DT)
    ctrl.step(snap(2 * DT, tz=-0.001, omega=-0.1), 2 * DT)
    assert ctrl.progress == pytest.approx(0.1 * DT)            # negative ω is progress here
    out = None
    for i in range(3, 20):
        out = ctrl.step(snap(i * DT, tz=0.001, omega=0.05), i * DT)
        if out.result is not None:
            break
    assert out is not None and out.result is not None
    assert out.result.message == 'slip reversed'
    latched = RotationalController(params, c, 0.3, 2.0, 0.0, latch=True)
    latched.step(snap(DT, omega=-0.05), DT)
    assert latched.sign == -1.0


def test_linear_law_first_steps_hand_computed(params: SlipControllerParams,
                                              snap: Snap) -> None:
    c = ControlContact(mu_c=0.5)
    ctrl = LinearController(params, c, 0.02, 2.0, 0.0, direction=(0.0, -1.0))
    # First sample at t = 0.1 s, v = 0: f_slip = ft/μ_c = 1/0.5 = 2 N; no dt → E = 0.
    # x_d = a t²/2 = 0.03125·0.01/2, v_d = 0.003125; v_c = v_d + 2·x_d.
    out = ctrl.step(snap(0.1, f=(0.0, -1.0)), 0.1)
    xd, vd = 0.5 * 0.03125 * 0.01, 0.03125 * 0.1
    vc = vd + 2.0 * xd
    assert out.tracking is not None and out.tracking.f_slip == pytest.approx(2.0)
    assert out.force == pytest.approx(2.0 + 50.0 * 2.0 * (0.0 - vc))
    # Second sample 10 ms later, v = 0.002 along ê: x = 2e-5; acc = 0.2 m/s² > gate → f_slip
    # kept; E = (v_c2 − v)·dt.
    out = ctrl.step(snap(0.11, f=(0.0, -1.2), v=(0.0, -0.002)), 0.11)
    x = 0.002 * 0.01
    xd2, vd2 = 0.5 * 0.03125 * 0.11 ** 2, 0.03125 * 0.11
    vc2 = vd2 + 2.0 * (xd2 - x)
    E = (vc2 - 0.002) * 0.01
    acc = 0.2
    expected = 2.0 - 1000.0 * E + 0.1 * 2.0 * acc + 50.0 * 2.0 * (0.002 - vc2)
    assert out.tracking is not None and out.tracking.f_slip == pytest.approx(2.0)
    assert out.tracking.integral == pytest.approx(E)
    assert out.force == pytest.approx(max(expected, 0.6))


def test_dt_guard_skips_integration(params: SlipControllerParams, snap: Snap) -> None:
    ctrl = LinearController(params, ControlContact(mu_c=0.5), 0.02, 2.0, 0.0,
                            direction=(0.0, -1.0))
    ctrl.step(snap(0.1, f=(0.0, -1.0), v=(0.0, -0.005)), 0.1)
    # A 0.12 s gap (> dt_max) must not integrate position or the error integral.
    out = ctrl.step(snap(0.22, f=(0.0, -1.0), v=(0.0, -0.005)), 0.22)
    assert ctrl.progress == 0.0 and out.tracking is not None and out.tracking.integral == 0.0
    out = ctrl.step(snap(0.23, f=(0.0, -1.0), v=(0.0, -0.005)), 0.23)
    assert ctrl.progress == pytest.approx(0.005 * 0.01)


def test_timeout_and_settled_stops(params: SlipControllerParams, snap: Snap) -> None:
    c = ControlContact(mu_c=0.5, r=0.005, r_valid=True)
    # Never moves: after T + settle_timeout → "timeout" (it is slower than v < stop_speed?
    # no: v = 0.001 ≥ stop_speed, so only the timeout can end it).
    ctrl = LinearController(params, c, 0.02, 0.5, 0.0, direction=(1.0, 0.0))
    res = None
    for i in range(1, 400):
        out = ctrl.step(snap(i * DT, f=(1.0, 0.0), v=(0.001, 0.0)), i * DT)
        if out.result is not None:
            res = out.result
            break
    assert res is not None and not res.success
    assert res.message == 'timeout: 1.5 of 20.0 mm, still moving'
    assert res.elapsed == pytest.approx(1.5, abs=DT)
    # Stopped below stop_speed after T, far short of P: not "done" (issue 15) — the law keeps
    # acting until T + settle_timeout, then ends "stalled" with how far it got.
    ctrl = LinearController(params, c, 0.02, 0.5, 0.0, direction=(1.0, 0.0))
    for i in range(1, 400):
        out = ctrl.step(snap(i * DT, f=(1.0, 0.0), v=(0.0002, 0.0)), i * DT)
        if out.result is not None:
            res = out.result
            break
    assert not res.success and res.final_error > 0.019
    assert res.message.startswith('stalled') and res.message.endswith('0.3 of 20.0 mm')
    assert res.elapsed == pytest.approx(1.5, abs=DT)
    # Settled after T within position_tolerance of P: "done" at T.
    ctrl = LinearController(params, c, 0.02, 0.5, 0.0, direction=(1.0, 0.0))
    for i in range(1, 400):
        v = 0.0515 if i * DT < 0.4 else 0.0           # 19.7 mm, then at rest
        out = ctrl.step(snap(i * DT, f=(1.0, 0.0), v=(v, 0.0)), i * DT)
        if out.result is not None:
            res = out.result
            break
    assert res.message == 'done' and res.success
    assert 0.0 < res.final_error <= params.trajectory.position_tolerance
    assert res.elapsed == pytest.approx(0.5, abs=DT)


def test_preempt_abort_reports_progress(params: SlipControllerParams, snap: Snap) -> None:
    ctrl = LinearController(params, ControlContact(mu_c=0.5), 0.02, 2.0, 0.0,
                            direction=(1.0, 0.0))
    for i in range(1, 13):
        ctrl.step(snap(i * DT, f=(1.0, 0.0), v=(0.01, 0.0)), i * DT)
    res = ctrl.abort('preempted', 0.2)
    assert res is not None and res.message == 'preempted' and not ctrl.goal_active
    assert res.final_pos == pytest.approx(0.01 * 11 * DT)
    assert ctrl.abort('preempted', 0.3) is None


def test_rotational_translation_floor(snap: Snap) -> None:
    c = ControlContact(mu_c=0.5, r=0.005, r_valid=True)
    # The object does not turn: E grows and the slip law would drop the force to the 0.6 N
    # floor; the translation floor ft/μ_c = 1/0.5 = 2 N must hold it.
    ctrl = RotationalController(SlipControllerParams(), c, 0.5, 2.0, 0.0)
    for i in range(1, 150):
        out = ctrl.step(snap(i * DT, f=(0.6, 0.8), tz=0.0005), i * DT)
    assert out.tracking is not None and out.tracking.integral > 0.2
    assert out.force == pytest.approx(2.0)
    # kp_cop adds kp_cop·(‖c‖ − r) with ‖c‖ = ‖v̄‖/(|ω̄| + 1e-3) = 0.01/0.1 = 0.1 m.
    rot = replace(SlipControllerParams().rotational, kp_cop=20.0, translation_gain=0.0)
    ctrl = RotationalController(SlipControllerParams(rotational=rot), c, 0.5, 2.0, 0.0)
    for i in range(1, 150):
        out = ctrl.step(snap(i * DT, f=(0.6, 0.8), tz=0.0005, v=(0.01, 0.0), omega=0.099),
                        i * DT)
    assert out.force == pytest.approx(2.0 + 20.0 * (0.1 - 0.005))


def test_rotational_cop_term_is_gated_and_capped(snap: Snap) -> None:
    """Near ω = 0 the spec's ‖c‖ explodes (0.01/0.001 = 10 m): gated, and capped."""
    c = ControlContact(mu_c=0.5, r=0.005, r_valid=True)
    rot = replace(SlipControllerParams().rotational, kp_cop=20.0, translation_gain=0.0,
                  cop_min_rate=0.026, cop_max_force=1.5)
    ctrl = RotationalController(SlipControllerParams(rotational=rot), c, 0.5, 2.0, 0.0)
    for i in range(1, 150):
        out = ctrl.step(snap(i * DT, f=(0.6, 0.8), tz=0.0005, v=(0.01, 0.0), omega=0.0),
                        i * DT)
    assert out.force == pytest.approx(2.0)          # gated: ω below cop_min_rate
    ctrl = RotationalController(SlipControllerParams(rotational=rot), c, 0.5, 2.0, 0.0)
    for i in range(1, 150):
        out = ctrl.step(snap(i * DT, f=(0.6, 0.8), tz=0.0005, v=(0.01, 0.0), omega=0.03),
                        i * DT)
    assert out.force == pytest.approx(2.0 + 1.5)    # 20·(0.01/0.031 − 0.005) = 6.3 N → cap


@pytest.mark.parametrize('v, omega, expected_extra', [
    ((0.01, 0.0), 0.099, 300.0 * (0.01 - 0.005 * 0.099)),   # translation beyond c = r
    ((0.0003, 0.0004), 0.2, 0.0),                           # 0.5 mm/s < r·ω = 1 mm/s
    ((0.01, 0.0), 0.0, 300.0 * 0.01),                       # pure translation: no spike
])
def test_rotational_translation_speed_term(snap: Snap, v: tuple[float, float], omega: float,
                                           expected_extra: float) -> None:
    c = ControlContact(mu_c=0.5, r=0.005, r_valid=True)
    ctrl = RotationalController(SlipControllerParams(), c, 0.5, 2.0, 0.0)
    for i in range(1, 150):
        out = ctrl.step(snap(i * DT, f=(0.6, 0.8), tz=0.0005, v=v, omega=omega), i * DT)
    assert out.force == pytest.approx(2.0 + expected_extra)


def test_rotational_translation_margin_scales_the_floor(snap: Snap) -> None:
    c = ControlContact(mu_c=0.5, r=0.005, r_valid=True)
    rot = replace(SlipControllerParams().rotational, translation_margin=1.4)
    ctrl = RotationalController(SlipControllerParams(rotational=rot), c, 0.5, 2.0, 0.0)
    for i in range(1, 150):
        out = ctrl.step(snap(i * DT, f=(0.6, 0.8), tz=0.0005), i * DT)
    assert out.force == pytest.approx(1.4 * 2.0)


def test_clock_jump_reset_rebases_the_trajectory(params: SlipControllerParams,
                                                 snap: Snap) -> None:
    ctrl = LinearController(params, ControlContact(mu_c=0.5), 0.02, 2.0, 100.0,
                            direction=(1.0, 0.0))
    for i in range(1, 61):                                  # 0.5 s at 10 mm/s
        ctrl.step(snap(100.0 + i * DT, f=(1.0, 0.0), v=(0.01, 0.0)), 100.0 + i * DT)
    x = ctrl.progress
    # Replay restarts at t = 5 s: without a reset every sample would look old.
    assert ctrl.step(snap(5.0, f=(1.0, 0.0), v=(0.01, 0.0)), 5.0).force is None
    ctrl.reset(5.0)
    out = ctrl.step(snap(5.0 + DT, f=(1.0, 0.0), v=(0.01, 0.0)), 5.0 + DT)
    assert out.force is not None and out.tracking is not None
    assert out.tracking.ref_pos == pytest.approx(
        ctrl.trajectory.sample(60 * DT + DT)[0], abs=1e-9)
    # The travel re-based at the jump and then integrated the one sample after it.
    assert ctrl.progress == pytest.approx(x + 0.01 * DT)
    ctrl.step(snap(5.0 + 2 * DT, f=(1.0, 0.0), v=(0.01, 0.0)), 5.0 + 2 * DT)
    assert ctrl.progress == pytest.approx(x + 2 * 0.01 * DT)


@pytest.mark.parametrize('make', [
    lambda p, c: RotationalController(p, c, 0.3, 1.0, 0.0),
    lambda p, c: LinearController(p, c, 0.02, 1.0, 0.0, direction=(1.0, 0.0)),
])
def test_dropped_object_ends_the_trajectory_as_contact_lost(snap: Snap, make: Any) -> None:
    """A lost object reads as zero slip speed; without the normal-force check the trajectory
    would settle after T and report 'done'."""
    ctrl = make(SlipControllerParams(), ControlContact(mu_c=0.5, r=0.005, r_valid=True))
    for i in range(1, 13):                                   # turning/sliding, in contact
        out = ctrl.step(snap(i * DT, f=(0.0, 1.0), tz=0.001, v=(0.005, 0.0), omega=0.1), i * DT)
        assert out.result is None
    res = None
    for i in range(13, 13 + 240):                            # dropped: nothing measured
        out = ctrl.step(snap(i * DT, normal=0.0), i * DT)
        if out.result is not None:
            res = out.result
            break
    assert res is not None and not res.success and res.message == 'contact lost'
    # 0.1 s debounce at 120 Hz: ends on the 14th sample without contact, long before T.
    assert (i - 12) * DT == pytest.approx(0.1 + DT, abs=1.5 * DT)
    assert out.next_controller is not None and out.next_controller.mode == SlipMode.HOLD


def test_travel_integrates_each_finger_over_its_own_stamps() -> None:
    from slip_control.core.signals import MAX_TRAVEL_SPAN, Travel, TwistSample
    tr = Travel().advanced(TwistSample(1.0, 0.0, 0.5, 10.0))       # first: stamp only
    assert (tr.x, tr.theta, tr.stamp) == (0.0, 0.0, 10.0)
    tr = tr.advanced(TwistSample(0.01, -0.02, 0.5, 10.01))
    assert (tr.x, tr.y, tr.theta) == pytest.approx((1e-4, -2e-4, 5e-3))
    assert tr.advanced(TwistSample(9.0, 9.0, 9.0, 10.01)) is tr    # repeated stamp
    nan = tr.advanced(TwistSample(float('nan'), 0.0, 0.0, 10.02))   # unusable: re-base only
    assert (nan.x, nan.stamp) == (tr.x, 10.02)
    gap = tr.advanced(TwistSample(1.0, 1.0, 1.0, 10.01 + MAX_TRAVEL_SPAN + 0.01))
    assert (gap.x, gap.y, gap.theta) == (tr.x, tr.y, tr.theta)      # a gap is not bridged
    back = tr.advanced(TwistSample(1.0, 1.0, 1.0, 3.0))             # clock jumped back
    assert (back.x, back.stamp) == (tr.x, 3.0)


def test_progress_is_exact_when_steps_miss_samples(snap: Snap) -> None:
    """The node may step on only every third sample (executor backlog, DDS burst): progress
    comes from the travel, so it equals the sensors' integral; rate·dt would miss 2/3."""
    c = ControlContact(mu_c=0.5, r=0.005, r_valid=True)
    ctrl = RotationalController(SlipControllerParams(), c, 1.0, 2.0, 0.0)
    truth = 0.0
    for i in range(1, 121):
        omega = 0.2 + 0.5 * math.sin(i / 7.0)                      # a jerky rotation
        s = snap(i * DT, f=(0.0, 1.0), tz=0.001, omega=omega)
        if i > 1:
            truth += omega * DT
        if i % 3 == 1:
            ctrl.step(s, i * DT)
    assert ctrl.progress == pytest.approx(truth - sum(                # up to the last step
        (0.2 + 0.5 * math.sin(i / 7.0)) * DT for i in (119, 120)), rel=1e-9)
