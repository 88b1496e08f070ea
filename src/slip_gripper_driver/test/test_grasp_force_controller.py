# SPDX-License-Identifier: Apache-2.0
"""Grasp-force controller: the §2.3 law against hand-computed steps, and every §2.5 addition."""
from __future__ import annotations

import math

import pytest

from slip_gripper_driver.core.force_control import (BypassReason, ForceControlParams,
                                                    ForceLoopInput, GraspForceController)
from slip_cell_common.core.param_schema import ParameterError, flatten, from_flat

DT = 0.002


def contact(t: float, target: float, fm: float, **kw: object) -> ForceLoopInput:
    """Both fingers measuring grasp force ``fm`` [N], biased, fresh at ``t``."""
    base = dict(t=t, target=target, target_stamp=0.0, fz_1=-fm, fz_2=-fm, ft_stamp_1=t,
                ft_stamp_2=t, ft_biased=True)
    base.update(kw)
    return ForceLoopInput(**base)  # type: ignore[arg-type]


def test_law_hand_computed_three_steps() -> None:
    ctl = GraspForceController(ForceControlParams())  # kp 2, ki 100, gamma 5, i_max 10
    # step 1: first step, no dt → no integration; e = 6, s = 1 + 5·36 = 181
    out = ctl.step(contact(1.0, 10.0, 4.0))
    assert out.closed_loop and out.bypass_reason == BypassReason.NONE
    assert out.error == pytest.approx(6.0)
    assert out.gain_scale == pytest.approx(181.0)
    assert out.integral == pytest.approx(0.0)
    assert out.force_cmd == pytest.approx(10.0 + 2.0 / 181.0 * 6.0)
    # step 2: e = 5, s = 1 + 5·(5−6)² = 6, E = 0.01, I = 1.0 (< 10/6), u = 10 + 1 + 2/6·5
    out = ctl.step(contact(1.0 + DT, 10.0, 5.0))
    assert out.gain_scale == pytest.approx(6.0)
    assert out.integral == pytest.approx(1.0)
    assert out.force_cmd == pytest.approx(10.0 + 1.0 + 2.0 / 6.0 * 5.0)
    # step 3: e = 5, s = 1, E = 0.02, I = 2, u = 10 + 2 + 10 = 22
    out = ctl.step(contact(1.0 + 2 * DT, 10.0, 5.0))
    assert out.gain_scale == pytest.approx(1.0)
    assert out.integral == pytest.approx(2.0)
    assert out.force_cmd == pytest.approx(22.0)
    assert out.measured_force == pytest.approx(5.0)


def test_anti_windup_clamp_scheduled_by_s() -> None:
    ctl = GraspForceController(ForceControlParams(kp=0.0))
    t = 0.0
    for _ in range(200):  # constant e = 10 → I grows by 2 N per step until i_max / 1
        out = ctl.step(contact(t, 20.0, 10.0))
        t += DT
    assert out.integral == pytest.approx(10.0)
    assert out.force_cmd == pytest.approx(30.0)
    # a sudden error change of 2 N: s = 1 + 5·4 = 21 → |I| ≤ 10/21, E back-calculated
    out = ctl.step(contact(t, 20.0, 12.0))
    assert out.gain_scale == pytest.approx(21.0)
    assert out.integral == pytest.approx(10.0 / 21.0)
    # next step e unchanged (s = 1): E was reset to I/(ki+1e-6), then += e·dt
    out = ctl.step(contact(t + DT, 20.0, 12.0))
    assert out.integral == pytest.approx(100.0 * ((10.0 / 21.0) / (100.0 + 1e-6) + 8.0 * DT))


def test_no_derivative_term() -> None:
    """kd is not implemented: with ki = 0 and gamma = 0 the output is exactly F_d + kp·e."""
    ctl = GraspForceController(ForceControlParams(ki=0.0, gamma=0.0))
    for k, fm in enumerate([2.0, 8.0, 3.0, 9.5]):
        out = ctl.step(contact(k * DT, 10.0, fm))
        assert out.force_cmd == pytest.approx(10.0 + 2.0 * (10.0 - fm))


@pytest.mark.parametrize('dt', [0.0, -0.001, 0.2])
def test_bad_dt_skips_integral_update(dt: float) -> None:
    ctl = GraspForceController(ForceControlParams(gamma=0.0))
    ctl.step(contact(1.0, 10.0, 5.0))
    i1 = ctl.step(contact(1.0 + DT, 10.0, 5.0)).integral
    assert i1 == pytest.approx(1.0)
    out = ctl.step(contact(1.0 + DT + dt, 10.0, 5.0))
    assert out.integral == pytest.approx(i1)
    assert ctl.skipped_integrations == 1


@pytest.mark.parametrize('kw, reason', [
    (dict(fm=0.3), BypassReason.NO_CONTACT),
    (dict(ft_biased=False), BypassReason.NOT_BIASED),
    (dict(target=-5.0), BypassReason.OPEN_COMMAND),
])
def test_bypass_reasons_give_feed_forward_and_reset(kw: dict, reason: BypassReason) -> None:
    kw = dict(kw)
    ctl = GraspForceController(ForceControlParams())
    ctl.step(contact(1.0 - DT, 10.0, 5.0))
    assert ctl.step(contact(1.0 - DT / 2, 10.0, 5.0)).integral > 0.0
    target = kw.pop('target', 10.0)
    fm = kw.pop('fm', 5.0)
    out = ctl.step(contact(1.0, target, fm, **kw))
    assert out.bypass_reason == reason and not out.closed_loop
    assert out.force_cmd == pytest.approx(target)
    assert out.integral == 0.0 and out.error == 0.0 and out.gain_scale == 1.0
    # after a bypass the first in-contact step sees e − e_prev = e: heavily damped
    out = ctl.step(contact(1.0 + DT, 10.0, 8.0))
    assert out.gain_scale == pytest.approx(1.0 + 5.0 * 4.0)


@pytest.mark.parametrize('kw', [dict(ft_stamp_1=0.9), dict(fz_2=math.nan)])
def test_a_stale_or_invalid_sample_gives_feed_forward_with_the_integral_held(kw: dict) -> None:
    ctl = GraspForceController(ForceControlParams())
    ctl.step(contact(1.0 - DT, 10.0, 5.0))
    learnt = ctl.step(contact(1.0 - DT / 2, 10.0, 5.0)).integral
    assert learnt > 0.0
    out = ctl.step(contact(1.0, 10.0, 5.0, **kw))
    assert out.bypass_reason == BypassReason.FT_STALE and not out.closed_loop
    assert out.integral == learnt and out.force_cmd == pytest.approx(10.0 + learnt)
    assert out.error == 0.0 and out.gain_scale == 1.0
    # e_prev kept: the next fresh step with the same error is not damped
    out = ctl.step(contact(1.0 + DT, 10.0, 5.0))
    assert out.closed_loop and out.gain_scale == pytest.approx(1.0)


def test_measurement_selection() -> None:
    inp = contact(1.0, 10.0, 0.0, fz_1=-6.0, fz_2=-2.0, ft_stamp_2=math.nan)
    out1 = GraspForceController(ForceControlParams(measurement='finger_1')).step(inp)
    assert out1.closed_loop and out1.measured_force == pytest.approx(6.0)
    out_mean = GraspForceController(ForceControlParams(measurement='mean')).step(inp)
    assert out_mean.bypass_reason == BypassReason.FT_STALE
    inp2 = inp._replace(ft_stamp_2=1.0)
    assert GraspForceController(ForceControlParams()).step(inp2).measured_force == \
        pytest.approx(4.0)
    assert GraspForceController(ForceControlParams(measurement='finger_2')).step(
        inp2).measured_force == pytest.approx(2.0)


def test_target_limits_and_command_ceiling() -> None:
    p = ForceControlParams(max_grasp_force=30.0, max_open_force=8.0, max_command_force=35.0,
                           gamma=0.0)
    ctl = GraspForceController(p)
    out = ctl.step(ForceLoopInput(t=0.0, target=100.0))
    assert out.force_target == 30.0 and out.force_cmd == 30.0
    out = ctl.step(ForceLoopInput(t=DT, target=-50.0))
    assert out.force_target == -8.0 and out.force_cmd == -8.0
    # closed loop far from target: u = 30 + 0 + 2·29 = 88 N exceeds the ceiling
    out = ctl.step(contact(2 * DT, 30.0, 1.0))
    assert out.force_cmd == 35.0 and ctl.saturations == 1


def test_non_finite_target_is_zero_and_counted() -> None:
    ctl = GraspForceController()
    out = ctl.step(ForceLoopInput(t=0.0, target=math.nan))
    assert out.force_cmd == 0.0 and ctl.invalid_targets == 1


def test_target_rate_limit() -> None:
    ctl = GraspForceController(ForceControlParams(target_rate_limit=100.0))
    targets = [ctl.step(ForceLoopInput(t=k * DT, target=10.0)).force_target for k in range(6)]
    # starts from 0 N (state after reset), then 0.2 N per 2 ms step
    assert targets == pytest.approx([0.0, 0.2, 0.4, 0.6, 0.8, 1.0])
    # a long gap is capped at MAX_DT_S worth of slew
    assert ctl.step(ForceLoopInput(t=5.0, target=40.0)).force_target == pytest.approx(11.0)


def test_approach_speed_limit_only_in_free_air_closing_when_homed() -> None:
    p = ForceControlParams(approach_max_speed=0.02, approach_gain=100.0)
    ctl = GraspForceController(p)
    free = dict(t=0.0, target=10.0, homed=True, opening=0.05, opening_rate=-0.05, stroke=0.08)
    out = ctl.step(ForceLoopInput(**free))  # v_close 0.05 → u = 10 − 100·0.03 = 7
    assert out.bypass_reason == BypassReason.APPROACH_LIMIT
    assert out.force_cmd == pytest.approx(7.0) and out.force_target == 10.0
    out = ctl.step(ForceLoopInput(**{**free, 't': DT, 'opening_rate': -0.5}))
    assert out.force_cmd == 0.0  # clipped at 0, never pushes open
    out = ctl.step(ForceLoopInput(**{**free, 't': 2 * DT, 'opening_rate': -0.01}))
    assert out.bypass_reason == BypassReason.NOT_BIASED and out.force_cmd == 10.0
    out = ctl.step(ForceLoopInput(**{**free, 't': 3 * DT, 'homed': False}))
    assert out.force_cmd == 10.0
    off = GraspForceController(ForceControlParams()).step(ForceLoopInput(**free))
    assert off.force_cmd == 10.0


def test_ft_fault_limits_target_to_safe_hold_force_when_biased() -> None:
    p = ForceControlParams(safe_hold_force=5.0)
    ctl = GraspForceController(p)
    stale = contact(1.0, 20.0, 20.0, ft_stamp_1=0.95, ft_stamp_2=0.95)  # 50 ms: stale only
    out = ctl.step(stale)
    assert out.bypass_reason == BypassReason.FT_STALE and not out.ft_fault
    assert out.force_cmd == 20.0 and math.isnan(out.measured_force)
    fault = contact(1.0 + DT, 20.0, 20.0, ft_stamp_1=0.8, ft_stamp_2=0.8)  # 200 ms: fault
    out = ctl.step(fault)
    assert out.ft_fault and out.force_target == 5.0 and out.force_cmd == 5.0
    unbiased = fault._replace(t=1.0 + 2 * DT, ft_biased=False)
    out = ctl.step(unbiased)  # open loop by design: the F/T is not part of the loop
    assert out.ft_fault and out.force_cmd == 20.0
    assert ctl.step(ForceLoopInput(t=2.0, target=1.0)).ft_fault  # never any sample


def test_a_stale_sample_holds_the_learnt_integral_and_the_loop_resumes_bumplessly() -> None:
    """The plant needs 3 N more than the target: the integral learns it; a few stale samples
    (a late F/T reader) keep ``u = F_d + I`` instead of dropping the force by 3 N, and the
    first fresh sample continues from there. A faulted sample clears it (open loop)."""
    ctl = GraspForceController(ForceControlParams(kp=0.5, gamma=0.0))
    t, fm = 0.0, 0.0
    for _ in range(2000):  # first-order plant: grasp force = command − 3 N
        out = ctl.step(contact(t, 10.0, fm))
        fm += 0.2 * (out.force_cmd - 3.0 - fm)
        t += DT
    assert fm == pytest.approx(10.0, abs=0.01) and out.integral == pytest.approx(3.0, abs=0.02)
    learnt, settled = out.integral, out.force_cmd
    for _ in range(5):  # samples 20 ms old: stale, not faulted
        out = ctl.step(contact(t, 10.0, fm, ft_stamp_1=t - 0.02, ft_stamp_2=t - 0.02))
        assert out.bypass_reason == BypassReason.FT_STALE and not out.ft_fault
        assert out.integral == pytest.approx(learnt)
        assert out.force_cmd == pytest.approx(10.0 + learnt)
        t += DT
    out = ctl.step(contact(t, 10.0, fm))
    assert out.closed_loop and out.force_cmd == pytest.approx(settled, abs=0.02)
    out = ctl.step(contact(t + DT, 10.0, fm, ft_stamp_1=t - 0.2, ft_stamp_2=t - 0.2))
    assert out.ft_fault and out.integral == 0.0 and out.force_cmd == 5.0  # safe_hold_force
    stale = t + 2 * DT - 0.02
    out = ctl.step(contact(t + 2 * DT, 10.0, fm, ft_stamp_1=stale, ft_stamp_2=stale))
    assert out.bypass_reason == BypassReason.FT_STALE and out.force_cmd == 10.0  # cleared


@pytest.mark.parametrize('policy, expected', [
    ('hold', 20.0), ('safe_force', 5.0), ('open', -8.0), ('zero', 0.0)])
def test_command_expiry_policies(policy: str, expected: float) -> None:
    ctl = GraspForceController(ForceControlParams(on_command_timeout=policy))
    fresh = ForceLoopInput(t=1.04, target=20.0, target_stamp=1.0, target_timeout=0.05)
    out = ctl.step(fresh)
    assert not out.command_expired and out.force_target == 20.0
    out = ctl.step(fresh._replace(t=1.06))
    assert out.command_expired and out.force_target == expected
    no_timeout = fresh._replace(t=100.0, target_timeout=0.0)
    assert not ctl.step(no_timeout).command_expired


def test_end_stop_protection_until_next_target() -> None:
    ctl = GraspForceController(ForceControlParams())
    at_stop = ForceLoopInput(t=0.0, target=-8.0, target_stamp=0.0, homed=True,
                             opening=0.0795, opening_rate=0.0002, stroke=0.080)
    t = 0.0
    while t < 0.998:
        out = ctl.step(at_stop._replace(t=t))
        assert out.force_cmd == -8.0 and out.bypass_reason == BypassReason.OPEN_COMMAND
        t += DT
    t = 1.0
    out = ctl.step(at_stop._replace(t=t))
    assert out.bypass_reason == BypassReason.END_STOP and out.force_cmd == 0.0
    # still latched when the fingers drift away, as long as the target is the same
    out = ctl.step(at_stop._replace(t=t + DT, opening=0.07))
    assert out.bypass_reason == BypassReason.END_STOP
    # a new target (new stamp) releases the latch
    out = ctl.step(at_stop._replace(t=t + 2 * DT, target_stamp=1.001))
    assert out.bypass_reason == BypassReason.OPEN_COMMAND and out.force_cmd == -8.0
    # moving fingers never latch
    ctl.reset()
    for k in range(1000):
        out = ctl.step(at_stop._replace(t=k * DT, opening_rate=0.01))
    assert out.bypass_reason == BypassReason.OPEN_COMMAND


def test_safe_state_outputs_zero_and_clears_state() -> None:
    ctl = GraspForceController(ForceControlParams(target_rate_limit=100.0))
    for k in range(100):
        ctl.step(contact(k * DT, 10.0, 5.0))
    out = ctl.step(contact(100 * DT, 10.0, 5.0, safe_state=True))
    assert out.bypass_reason == BypassReason.SAFE_STATE and out.force_cmd == 0.0
    assert out.force_target == 0.0 and out.integral == 0.0
    out = ctl.step(contact(101 * DT, 10.0, 5.0))
    assert out.force_target == pytest.approx(0.2)  # ramps again from 0 N


def test_set_params_is_bumpless_for_ki() -> None:
    ctl = GraspForceController(ForceControlParams(gamma=0.0))
    for k in range(3):
        out = ctl.step(contact(k * DT, 10.0, 9.0))
    before = out.integral
    ctl.set_params(ForceControlParams(gamma=0.0, ki=400.0))
    out = ctl.step(contact(3 * DT, 10.0, 9.0))
    # I continues from its value: I = before + 400·1·dt
    assert out.integral == pytest.approx(before + 400.0 * 1.0 * DT, rel=1e-6)


def test_params_validate_and_schema_round_trip() -> None:
    p = ForceControlParams()
    p.validate()
    assert from_flat(ForceControlParams, flatten(p)) == p
    with pytest.raises(ParameterError, match='ft_fault_after'):
        ForceControlParams(ft_stale_after=0.2, ft_fault_after=0.1).validate()
    with pytest.raises(ParameterError, match='max_command_force'):
        ForceControlParams(max_command_force=30.0).validate()
    with pytest.raises(ParameterError, match='measurement'):
        ForceControlParams(measurement='both').validate()
    with pytest.raises(ParameterError, match='not finite'):
        ForceControlParams(kp=math.nan).validate()
    with pytest.raises(ParameterError):
        from_flat(ForceControlParams, {'on_command_timeout': 'explode'})


def test_bypass_enum_mirrors_motor_command_constants() -> None:
    from pathlib import Path
    msg = Path(__file__).resolve().parents[2] / 'slip_msgs' / 'msg' / 'MotorCommand.msg'
    constants = {}
    for line in msg.read_text().splitlines():
        if line.startswith('uint8 BYPASS_'):
            name, value = line.split()[1].split('=')
            constants[name.removeprefix('BYPASS_')] = int(value)
    assert constants == {r.name: r.value for r in BypassReason}
