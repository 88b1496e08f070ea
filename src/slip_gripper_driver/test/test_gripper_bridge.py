# SPDX-License-Identifier: Apache-2.0
"""Gripper bridge core: command validation, ceilings and fail-safe sequences.

Deterministic: the firmware emulator runs in simulated time in-process; F/T samples are the
emulated pad force (``Fz = −F``, both fingers) stamped with the telemetry time.
"""
from __future__ import annotations

import dataclasses
import math
import re

import pytest

from slip_gripper_driver.core.bridge import GripperBridge
from slip_gripper_driver.core.bridge_params import BridgeParams, CommandParams
from slip_gripper_driver.core.gripper_records import LineResult, LinkState
from slip_gripper_driver.core.firmware_emulator import FirmwareEmulator, GripperModelParams
from slip_gripper_driver.core.force_control import BypassReason, ForceControlParams
from slip_cell_common.core.param_schema import ParameterError, flatten, from_flat
from slip_gripper_driver.core.protocol import command_voltage
from slip_cell_common.core.serial_transport import LineReader

NPV = 3.9166
OBJECT = GripperModelParams(object_width=0.03, object_stiffness=20000.0, initial_opening=0.031)


class Rig:
    """Bridge + in-process firmware emulator + emulated F/T."""

    def __init__(self, params: BridgeParams = BridgeParams(),
                 model: GripperModelParams = OBJECT) -> None:
        self.emu = FirmwareEmulator(model)
        self.writes: list[bytes] = []
        self.port_up = True
        self.ft_on = True
        self.bridge = GripperBridge(params, self._write)
        self.reader = LineReader(resync=False)
        self.bridge.on_connected(0.0, 'emulated')
        self.bridge.activate(0.0)

    def _write(self, data: bytes) -> bool:
        self.writes.append(data)
        if self.port_up:
            self.emu.receive(data)
        return self.port_up

    @property
    def t(self) -> float:
        return self.emu.time_s

    def run(self, seconds: float) -> list[LineResult]:
        out = []
        for _ in range(int(round(seconds / self.emu.params.period))):
            if self.ft_on:
                for finger in (1, 2):
                    self.bridge.on_ft_sample(finger, self.t, -self.emu.grasp_force, True)
            for line, overflow in self.reader.feed(self.emu.tick()):
                out.append(self.bridge.on_line(line, overflow, self.t))
        return out

    def voltages(self) -> list[float]:
        return [command_voltage(w) for w in self.writes]


def telemetry(results: list[LineResult]) -> list[LineResult]:
    return [r for r in results if r.status is not None]


#: The conservative stale policy: a telemetry gap writes the safe voltage once.
SAFE_ON_STALE = dataclasses.replace(
    BridgeParams(), link=dataclasses.replace(BridgeParams().link, stale_action='safe_voltage'))


def test_invalid_commands_are_rejected_counted_and_never_written() -> None:
    rig = Rig()
    rig.run(0.1)
    n = len(rig.writes)
    t = rig.t
    bad = [dict(force=math.nan), dict(force=math.inf), dict(force=-math.inf),
           dict(force=79.0), dict(force=-1e6), dict(force=5.0, timeout=math.nan),
           dict(force=5.0, timeout=-0.1), dict(force=5.0, stamp=math.inf),
           dict(force=5.0, stamp=t + 10.0)]
    for kw in bad:
        force = kw.pop('force')
        assert not rig.bridge.set_grasp_force(force, t, **kw).accepted
    rig.run(0.1)
    assert set(rig.writes[n:]) == {b'T0.00\n'}  # the zero target never changed
    diag = rig.bridge.diagnostics(rig.t)
    assert diag.commands_rejected == len(bad) and diag.commands_accepted == 0
    assert dict(diag.rejected_by_reason) == {'non_finite': 3, 'out_of_range': 2,
                                             'bad_timeout': 2, 'bad_stamp': 1,
                                             'future_stamp': 1}


def test_hard_ceiling_whatever_the_command() -> None:
    rig = Rig()
    rig.run(0.05)
    assert rig.bridge.set_grasp_force(70.0, rig.t).accepted  # expressible, beyond limits
    results = rig.run(1.0)
    assert rig.bridge.diagnostics(rig.t).targets_clipped == 1
    ceiling_v = -45.0 / NPV
    assert min(rig.voltages()) >= round(ceiling_v, 2) - 1e-9
    motors = [r.motor for r in results if r.motor is not None]
    assert max(m.force_target for m in motors) == 40.0
    assert max(m.force_cmd for m in motors) <= 45.0


def test_closed_loop_reaches_the_commanded_force_on_an_object() -> None:
    rig = Rig()
    rig.run(0.05)
    assert rig.bridge.set_grasp_force(10.0, rig.t).accepted
    results = telemetry(rig.run(1.5))
    assert rig.emu.grasp_force == pytest.approx(10.0, abs=0.3)
    last = results[-1]
    assert last.motor.closed_loop and last.motor.bypass_reason == BypassReason.NONE
    assert last.status.in_contact and last.status.measured_grasp_force == pytest.approx(
        rig.emu.grasp_force, abs=0.05)
    assert last.status.voltage_cmd == command_voltage(last.command)


def test_stale_command_goes_to_safe_force() -> None:
    params = BridgeParams(force_control=ForceControlParams(on_command_timeout='safe_force'))
    rig = Rig(params)
    rig.run(0.05)
    assert rig.bridge.set_grasp_force(15.0, rig.t, stamp=rig.t, timeout=0.5).accepted
    rig.run(0.45)
    assert not rig.bridge.status(rig.t).command_expired
    results = telemetry(rig.run(1.5))
    assert results[-1].status.command_expired and results[-1].motor.force_target == 5.0
    assert rig.emu.grasp_force == pytest.approx(5.0, abs=0.3)


def test_default_timeout_applies_to_commands_without_one() -> None:
    params = BridgeParams(force_control=ForceControlParams(on_command_timeout='zero'),
                          command=CommandParams(default_timeout=0.2))
    rig = Rig(params)
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    results = telemetry(rig.run(1.0))
    assert results[-1].status.command_expired and results[-1].motor.force_target == 0.0


def test_stale_ft_bypasses_then_fault_limits_to_safe_force() -> None:
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(15.0, rig.t)
    rig.run(1.0)
    rig.ft_on = False
    results = telemetry(rig.run(0.05))
    reasons = [r.motor.bypass_reason for r in results]
    assert reasons[0] == BypassReason.NONE and reasons[-1] == BypassReason.FT_STALE
    assert not results[-1].status.ft_fresh and math.isnan(results[-1].status.measured_grasp_force)
    results = telemetry(rig.run(0.1))
    assert results[-1].motor.force_target == 5.0  # ft_fault: safe_hold_force
    assert results[-1].command == b'T-1.28\n'  # open loop 5 N = −1.2766 V


def test_ft_records_waiting_unread_keep_an_old_sample_stale_not_a_fault() -> None:
    """A busy host: the F/T reader is behind while the boxes keep sending (records wait in
    its socket). Past ft_fault_after that is the host's delay, not a silent box: the loop
    stays open loop at the target instead of dropping a 40 N grasp to safe_hold_force."""
    rig = Rig()
    waiting = {1: True, 2: True}
    rig.bridge.set_ft_backlog_probe(lambda finger: waiting[finger])
    rig.run(0.05)
    rig.bridge.set_grasp_force(40.0, rig.t)
    rig.run(1.5)
    rig.ft_on = False  # the readers fall behind; records pile up unread
    results = telemetry(rig.run(0.3))
    assert results[-1].motor.bypass_reason == BypassReason.FT_STALE
    assert min(r.motor.force_target for r in results) == 40.0
    assert rig.emu.grasp_force > 35.0
    lagged = rig.bridge.diagnostics(rig.t).ft_host_lag_steps
    assert lagged > 50
    waiting[2] = False  # finger 2's box really went silent: an F/T fault after all
    results = telemetry(rig.run(0.05))
    assert results[-1].motor.force_target == 5.0
    # ... and the exemption ends at link.host_stall_limit even with records waiting.
    waiting[2] = True
    rig.ft_on = True
    rig.run(0.5)
    rig.ft_on = False
    rig.run(rig.bridge.params.link.host_stall_limit + 0.05)
    assert telemetry(rig.run(0.01))[-1].motor.force_target == 5.0


def test_short_stale_gap_holds_the_last_command_and_the_grasp_by_default() -> None:
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.0)
    held = rig.writes[-1]
    assert command_voltage(held) < -2.0
    t_last = rig.t
    rig.emu.silence(0.1)  # longer than link.stale_after (20 ms), shorter than the fault
    n = len(rig.writes)
    result = rig.bridge.check_watchdog(t_last + 0.025)
    assert result.state == LinkState.STALE and result.held and not result.reconnect
    assert rig.writes[n:] == [] and rig.emu.target_voltage_v == command_voltage(held)
    status = rig.bridge.status(t_last + 0.025)
    assert status.armed and not status.safe_state and not status.link_ok
    assert rig.bridge.check_watchdog(t_last + 0.08).held and rig.writes[n:] == []
    forces = []
    for _ in range(200):  # the gap, then telemetry resumes: the loop is clocked by it
        rig.run(0.005)
        forces.append(rig.emu.grasp_force)
    assert max(abs(f - 10.0) for f in forces) < 1.0
    assert rig.bridge.diagnostics(rig.t).stale_events == 1
    assert not rig.bridge.status(rig.t).safe_state and rig.bridge.status(rig.t).link_ok


def test_short_stale_gap_writes_safe_voltage_then_resumes_armed_when_so_configured() -> None:
    rig = Rig(SAFE_ON_STALE)
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.0)
    t_last = rig.t
    rig.emu.silence(0.1)  # longer than link.stale_after (20 ms), shorter than the fault
    n = len(rig.writes)
    result = rig.bridge.check_watchdog(t_last + 0.025)
    assert result.state == LinkState.STALE and not result.reconnect
    assert rig.writes[n:] == [b'T0.00\n'] and rig.emu.target_voltage_v == 0.0
    status = rig.bridge.status(t_last + 0.025)
    assert status.armed and status.safe_state and not status.link_ok
    rig.run(1.0)  # telemetry resumes: the loop is clocked by it and squeezes again
    assert rig.voltages()[-1] < -2.0
    assert not rig.bridge.status(rig.t).safe_state


def test_link_fault_disarms_writes_safe_voltage_and_needs_explicit_rearm() -> None:
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.0)
    assert rig.voltages()[-1] < -2.0
    t_last = rig.t
    assert rig.bridge.check_watchdog(t_last + 0.01).state == LinkState.OK
    rig.emu.silence(0.5)
    n = len(rig.writes)
    result = rig.bridge.check_watchdog(t_last + 0.025)
    assert result.state == LinkState.STALE and not result.reconnect and result.held
    assert rig.writes[n:] == []  # stale: the firmware keeps the last command
    status = rig.bridge.status(t_last + 0.025)
    assert status.armed and not status.safe_state and not status.link_ok
    fault = rig.bridge.check_watchdog(t_last + 0.3)
    assert rig.writes[n:] == [b'T0.00\n'] and rig.emu.target_voltage_v == 0.0
    assert not rig.bridge.status(t_last + 0.3).armed
    assert fault.state == LinkState.FAULT and fault.reconnect
    assert not rig.bridge.check_watchdog(t_last + 0.31).reconnect  # once per fault
    rig.run(1.0)  # telemetry resumes: the safe voltage is written on every line
    assert set(rig.writes[n:]) == {b'T0.00\n'}
    refused = rig.bridge.set_grasp_force(10.0, rig.t)
    assert not refused.accepted and 'armed' in refused.reason
    rig.run(0.1)
    assert set(rig.writes[n:]) == {b'T0.00\n'}
    assert rig.bridge.arm(rig.t).accepted
    rig.run(0.1)
    assert set(rig.writes[n:]) == {b'T0.00\n'}  # arming cleared the old 10 N target
    assert rig.bridge.set_grasp_force(10.0, rig.t).accepted
    rig.run(0.5)
    assert rig.voltages()[-1] < -2.0


def test_reconnect_writes_safe_voltage_invalidates_homing_and_stays_disarmed() -> None:
    rig = Rig(model=GripperModelParams())
    rig.run(0.05)
    rig.bridge.start_homing(rig.t)
    rig.run(6.0)
    assert rig.bridge.status(rig.t).homed
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(0.2)
    rig.port_up = False
    rig.bridge.on_link_lost(rig.t, '/dev/ttyACM0: device disconnected')
    status = rig.bridge.status(rig.t)
    assert not status.armed and not status.link_ok and not status.homed
    assert rig.bridge.check_watchdog(rig.t).state == LinkState.DOWN
    rig.port_up = True
    n = len(rig.writes)
    rig.bridge.on_connected(rig.t + 0.5, '/dev/ttyACM0')
    assert rig.writes[n:] == [b'\nT0.00\n']  # one write: a newline ends any fragment first
    rig.run(0.2)
    status = rig.bridge.status(rig.t)
    assert status.reconnect_count == 1 and status.link_ok and not status.armed
    assert not status.homed and math.isnan(status.opening)
    assert set(rig.writes[n:]) == {b'\nT0.00\n', b'T0.00\n'}
    assert not rig.bridge.set_grasp_force(10.0, rig.t).accepted


def test_firmware_restart_after_telemetry_disarms_but_boot_banner_does_not() -> None:
    rig = Rig()
    rig.run(0.05)  # includes the boot banner before the first angle line
    assert rig.bridge.status(rig.t).armed
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(0.5)
    rig.emu.restart(silence_s=0.004)
    events = [r.event for r in rig.run(0.1) if r.event]
    assert events == ['firmware_restart']
    status = rig.bridge.status(rig.t)
    assert not status.armed and status.safe_state and rig.emu.target_voltage_v == 0.0
    assert rig.bridge.diagnostics(rig.t).firmware_restarts == 1


def test_deactivate_writes_safe_voltage_first_then_nothing() -> None:
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(0.5)
    n = len(rig.writes)
    assert rig.bridge.deactivate(rig.t)
    assert rig.writes[n:] == [b'T0.00\n']
    rig.run(0.1)
    assert len(rig.writes) == n + 1 and rig.emu.target_voltage_v == 0.0
    assert rig.bridge.check_watchdog(rig.t + 1.0).state == LinkState.INACTIVE


def test_stop_writes_safe_voltage_now_until_next_command() -> None:
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(0.5)
    n = len(rig.writes)
    assert rig.bridge.stop(rig.t)
    assert rig.writes[n:] == [b'T0.00\n']
    rig.run(0.1)
    assert set(rig.writes[n:]) == {b'T0.00\n'}
    status = rig.bridge.status(rig.t)
    assert status.armed and status.safe_state
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(0.5)
    assert rig.voltages()[-1] < -2.0


def test_write_failures_are_counted() -> None:
    rig = Rig()
    rig.run(0.05)
    rig.port_up = False
    rig.run(0.02)
    assert rig.bridge.diagnostics(rig.t).write_failures >= 9


def test_live_parameter_swap_between_lines() -> None:
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.0)
    new = dataclasses.replace(rig.bridge.params, force_control=ForceControlParams(
        max_grasp_force=6.0, safe_hold_force=5.0))
    new.validate()
    rig.bridge.set_params(new)
    results = telemetry(rig.run(1.0))
    assert results[-1].motor.force_target == 6.0
    assert rig.emu.grasp_force == pytest.approx(6.0, abs=0.3)


def test_bridge_params_validation_and_flat_round_trip() -> None:
    p = BridgeParams()
    p.validate()
    flat = flatten(p)
    assert flat['force_control.kp'] == 2.0 and flat['link.stale_after'] == 0.020
    assert flat['actuator.newton_per_volt'] == NPV and 'observer.ki' in flat
    assert from_flat(BridgeParams, flat) == p
    with pytest.raises(ParameterError, match='homing.voltage'):
        from_flat(BridgeParams, {'homing.voltage': 12.0})
    with pytest.raises(ParameterError, match='fault_after'):
        from_flat(BridgeParams, {'link.fault_after': 0.01})


def test_every_reconnection_disarms_even_after_activation_while_down() -> None:
    rig = Rig()
    rig.run(0.05)
    rig.bridge.on_link_lost(rig.t, 'port gone')
    rig.bridge.deactivate(rig.t)
    rig.bridge.activate(rig.t)  # operator re-activates while the port is still gone
    rig.bridge.on_connected(rig.t + 0.5, 'emulated')
    rig.run(0.1)
    status = rig.bridge.status(rig.t)
    assert status.link_ok and not status.armed and status.safe_state


def test_reset_after_a_backwards_clock_jump_keeps_arming_and_homing() -> None:
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.0)
    jumped = 0.0  # e.g. a replay or simulation restarted /clock
    rig.bridge.reset(jumped)
    assert rig.bridge.check_watchdog(jumped + 0.01).state == LinkState.OK
    status = rig.bridge.status(jumped)
    assert status.armed and not status.safe_state
    assert rig.bridge.diagnostics(jumped).command_age_s >= 0.0


# ---------------------------------------------------------------------------- F/T bias
def test_bias_is_refused_while_the_pads_may_be_loaded() -> None:
    """Issue 16 item 1: a bias under load absorbs the load (10 N then read as 0 N)."""
    rig = Rig()
    rig.run(0.05)
    assert rig.bridge.bias_refusal(rig.t) is None  # open, 1 mm from the object: free
    assert rig.bridge.set_grasp_force(10.0, rig.t).accepted
    rig.run(1.0)
    refusal = rig.bridge.bias_refusal(rig.t)
    assert refusal is not None
    for reason in ('a squeezing grasp-force target of 10.0 N is active',
                   'the motor is commanded to squeeze', 'finger 1 F/T measures',
                   'finger 2 F/T measures', 'touched something'):
        assert reason in refusal, refusal
    rig.bridge.stop(rig.t)  # 0 V, target cleared: the pads relax but still touch the object
    rig.run(0.5)
    assert rig.emu.grasp_force < 0.1
    refusal = rig.bridge.bias_refusal(rig.t)
    assert refusal is not None and 'touched something' in refusal and 'active' not in refusal
    assert rig.bridge.set_grasp_force(-4.0, rig.t).accepted  # open the gripper
    rig.run(0.5)
    assert rig.emu.opening > 0.035 and rig.bridge.bias_refusal(rig.t) is None


def test_bias_refusal_sees_a_squeezing_stall_without_a_biased_ft() -> None:
    rig = Rig()
    rig.ft_on = False  # no F/T yet (the first bias of the day): the opening must tell
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(0.1)  # still closing: not a contact yet
    assert math.isnan(rig.bridge.diagnostics(rig.t).contact_angle)
    rig.run(0.5)
    rig.bridge.stop(rig.t)
    rig.run(0.3)
    refusal = rig.bridge.bias_refusal(rig.t)
    assert refusal is not None and 'touched something' in refusal
    assert math.isfinite(rig.bridge.diagnostics(rig.t).contact_angle)
    rig.bridge.set_grasp_force(-4.0, rig.t)
    rig.run(0.5)
    assert rig.bridge.bias_refusal(rig.t) is None
    assert math.isnan(rig.bridge.diagnostics(rig.t).contact_angle)


# ---------------------------------------------------------------------------- host stalls
def _backlog(rig: Rig, seconds: float) -> list[tuple[bytes, bool]]:
    """The firmware keeps printing while the host does not read: the lines pile up."""
    data = b''.join(rig.emu.tick() for _ in range(int(round(seconds / rig.emu.params.period))))
    return rig.reader.feed(data)


def test_a_host_stall_with_telemetry_waiting_writes_nothing_and_resumes_without_a_burst(
        ) -> None:
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.5)
    before = rig.voltages()[-1]
    assert before < -2.0 and rig.emu.grasp_force == pytest.approx(10.0, abs=0.3)
    t_last = rig.t
    n = len(rig.writes)
    for stall in (0.06, 0.3):
        lines = _backlog(rig, stall)
        # The watchdog runs meanwhile: the lines wait at the port, so the device is fine.
        for dt in (0.025, 0.1, stall - 0.001):
            result = rig.bridge.check_watchdog(t_last + dt, input_pending=lambda: 7 * 50)
            assert result.state == LinkState.LAGGING and not result.disarmed
        assert rig.writes[n:] == []  # no safe voltage: the last command stays applied
        assert rig.bridge.status(t_last + stall).link_ok
        assert rig.bridge.diagnostics(t_last + stall).link_state == LinkState.LAGGING
        results = rig.bridge.on_lines(lines, rig.t)
        commands = [r.command for r in results if r.command is not None]
        assert len(commands) == 1 and len(results) == len(lines) > 25  # no catch-up burst
        assert [r.event for r in results if r.event] == ['host_stall']
        stamps = [r.stamp for r in results]
        assert stamps == sorted(stamps) and stamps[-1] == rig.t  # one period apart, newest now
        assert stamps[-1] - stamps[0] == pytest.approx(stall - 0.002, abs=1e-9)
        assert command_voltage(commands[0]) == pytest.approx(before, abs=0.02)  # from applied
        rig.run(0.5)
        motors = [r.motor for r in telemetry(rig.run(0.5)) if r.motor is not None]
        assert max(m.force_cmd for m in motors) < 10.0 + 1.0  # no catch-up kick
        assert rig.emu.grasp_force == pytest.approx(10.0, abs=0.3)
        t_last = rig.t
        n = len(rig.writes)
    diag = rig.bridge.diagnostics(rig.t)
    assert diag.host_stalls == 2 and diag.max_host_stall_s == pytest.approx(0.3, abs=0.01)
    assert diag.stale_events == 0 and diag.link_faults == 0 and diag.armed
    assert set(rig.writes) <= {w for w in rig.writes if command_voltage(w) != 0.0} | {
        b'\nT0.00\n', b'T0.00\n'}


def test_a_silent_device_holds_then_resumes_without_a_command_burst() -> None:
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.5)
    held = command_voltage(rig.writes[-1])
    held_force = -held * NPV
    t_last = rig.t
    rig.emu.silence(0.15)  # the device itself stops: nothing waits at the port
    n = len(rig.writes)
    result = rig.bridge.check_watchdog(t_last + 0.025, input_pending=lambda: 0)
    assert result.state == LinkState.STALE and result.held and not result.disarmed
    # Meanwhile the target rises: on resumption the command may not jump to it.
    assert rig.bridge.set_grasp_force(30.0, t_last + 0.03).accepted
    assert rig.bridge.check_watchdog(t_last + 0.1, input_pending=lambda: 0).held
    assert rig.writes[n:] == []
    results = telemetry(rig.run(0.4))
    motors = [r.motor for r in results if r.motor is not None]
    assert motors[0].stamp - t_last > 0.15
    rate = rig.bridge.params.link.resume_rate
    t0 = motors[0].stamp
    for m in motors:  # from the held value, at most resume_rate N/s
        assert abs(m.force_cmd - held_force) <= rate * (m.stamp - t0) + 0.01
    assert rig.bridge.diagnostics(rig.t).resume_ramps == 1
    rig.run(1.5)
    assert rig.emu.grasp_force == pytest.approx(30.0, abs=0.5)


def test_a_silent_device_goes_stale_then_resumes_rate_limited_from_the_applied_value() -> None:
    rig = Rig(SAFE_ON_STALE)
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.5)
    t_last = rig.t
    rig.emu.silence(0.1)  # the device itself stops: nothing waits at the port
    n = len(rig.writes)
    result = rig.bridge.check_watchdog(t_last + 0.025, input_pending=lambda: 0)
    assert result.state == LinkState.STALE and not result.disarmed
    assert rig.writes[n:] == [b'T0.00\n'] and rig.bridge.status(rig.t).armed
    results = telemetry(rig.run(0.4))  # the pads relax at 0 V until telemetry resumes
    motors = [r.motor for r in results if r.motor is not None]
    assert motors[0].stamp - t_last > 0.1
    rate = rig.bridge.params.link.resume_rate
    t0 = motors[0].stamp
    assert motors[0].force_cmd == 0.0  # resumes from the value applied (the safe voltage)
    for m in motors:  # ... at most resume_rate N/s
        assert m.force_cmd <= rate * (m.stamp - t0) + 1e-9
    # No kick: the command follows the ramp, then the loop's own correction stays close to
    # the target (11.3 N here; 12.7 N with the ramp off).
    assert max(m.force_cmd for m in motors) < 10.0 + 2.0
    rig.run(1.0)
    assert rig.emu.grasp_force == pytest.approx(10.0, abs=0.3)
    assert rig.bridge.diagnostics(rig.t).resume_ramps == 1


def _watch_on_time(rig: Rig, t_from: float, t_to: float, pending: int) -> list:
    """The watchdog checks every 5 ms from ``t_from`` to ``t_to`` while the reader is stuck
    (``pending`` bytes wait); returns the results."""
    out = []
    t = t_from
    while t <= t_to + 1e-9:
        out.append(rig.bridge.check_watchdog(t, input_pending=lambda: pending))
        t += 0.005
    return out


def test_a_loop_stuck_beyond_the_limit_while_the_watchdog_runs_disarms() -> None:
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.0)
    t_last = rig.t
    limit = rig.bridge.params.link.host_stall_limit
    n = len(rig.writes)
    results = _watch_on_time(rig, t_last + 0.005, t_last + limit + 0.01, 4000)
    assert all(r.state == LinkState.LAGGING for r in results[4:])
    assert not any(r.disarmed for r in results[:-3])
    assert results[-1].disarmed and 'stuck' in results[-1].reason, results[-1]
    assert rig.writes[n:] == [b'T0.00\n'] and not rig.bridge.status(rig.t).armed
    assert not rig.bridge.check_watchdog(t_last + limit + 0.02, lambda: 4000).disarmed  # once


def test_a_pause_of_the_whole_driver_process_is_reported_and_does_not_disarm() -> None:
    """The reader and the watchdog were both held up for 5.6 s (seen beside CPU burners
    without real-time priority): the firmware kept the last command meanwhile, so the loop
    resumes rate-limited from it, still armed, instead of dropping the object afterwards."""
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.0)
    t_last = rig.t
    assert rig.bridge.check_watchdog(t_last + 0.004, lambda: 0).state == LinkState.OK
    n = len(rig.writes)
    paused = rig.bridge.check_watchdog(t_last + 5.6, input_pending=lambda: 280 * 9)
    assert paused.state == LinkState.LAGGING and not paused.disarmed, paused
    assert 'did not run for 5.6' in paused.reason, paused.reason
    later = _watch_on_time(rig, t_last + 5.605, t_last + 5.7, 280 * 9)  # loop still behind
    assert not any(r.disarmed for r in later)
    assert rig.writes[n:] == [] and rig.bridge.status(rig.t).armed
    # ... but a loop that then stays stuck while the watchdog runs on time does disarm.
    stuck = _watch_on_time(rig, t_last + 5.705, t_last + 5.6 + 1.1, 280 * 9)
    assert any(r.disarmed for r in stuck) and not rig.bridge.status(rig.t).armed


def test_telemetry_the_kernel_still_holds_is_a_host_stall_not_a_link_fault() -> None:
    """The reader waits for the kernel's tty worker (seen beside CPU burners: beyond 1 s)
    while the firmware keeps sending: no safe voltage, no disarm, the log names the kernel;
    not even beyond host_stall_limit (the loop is not stuck), only beyond kernel_hold_limit,
    once. The same gap with nothing held is a link fault at fault_after."""
    for held in (True, False):
        rig = Rig()
        rig.run(0.05)
        rig.bridge.set_grasp_force(10.0, rig.t)
        rig.run(1.0)
        t_last = rig.t
        n = len(rig.writes)
        limit = rig.bridge.params.link.kernel_hold_limit
        assert limit > rig.bridge.params.link.host_stall_limit
        results = []
        t = t_last + 0.005
        while t <= t_last + rig.bridge.params.link.host_stall_limit + 0.1:
            results.append(rig.bridge.check_watchdog(t, lambda: 0, lambda h=held: h))
            t += 0.005
        if not held:
            assert any(r.state == LinkState.FAULT and r.disarmed for r in results)
            assert not rig.bridge.status(rig.t).armed
            continue
        assert {r.state for r in results[4:]} == {LinkState.LAGGING}, results[4]
        assert not any(r.disarmed for r in results)
        assert 'waits in the kernel' in results[-1].reason, results[-1].reason
        assert rig.writes[n:] == [] and rig.bridge.status(t).armed
        while t <= t_last + limit + 0.02:
            results.append(rig.bridge.check_watchdog(t, lambda: 0, lambda h=held: h))
            t += 0.005
        disarmed = [r for r in results if r.disarmed]
        assert len(disarmed) == 1 and 'overloaded' in disarmed[0].reason, disarmed
        assert rig.writes[n:] == [b'T0.00\n'] and not rig.bridge.status(t).armed


def test_bytes_at_the_port_behind_a_reader_waiting_for_the_kernel_are_the_kernels_stall(
        ) -> None:
    """Some bytes reached the port, but the reader still waits in the kernel's flush (seen in
    a 10-minute hold: 1.3 s): the kernel is the cause, so kernel_hold_limit bounds it, not
    host_stall_limit (which stays for a reader that is free and does not read)."""
    for held in (True, False):
        rig = Rig()
        rig.run(0.05)
        rig.bridge.set_grasp_force(10.0, rig.t)
        rig.run(1.0)
        t_last = rig.t
        host_limit = rig.bridge.params.link.host_stall_limit
        results = []
        t = t_last + 0.005
        while t <= t_last + host_limit + 0.1:
            results.append(rig.bridge.check_watchdog(t, lambda: 350, lambda h=held: h))
            t += 0.005
        assert {r.state for r in results[4:]} == {LinkState.LAGGING}
        assert any(r.disarmed for r in results) is (not held), held
        assert rig.bridge.status(t).armed is held


def test_a_reader_seen_waiting_for_the_kernel_once_counts_for_stale_after_only() -> None:
    """The reader alternates between the kernel's flush and its own poll while the worker is
    starved: a sighting counts for ``link.stale_after``, after which a silent port is a
    silent device again (the fault is only delayed by that much)."""
    rig = Rig()
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.0)
    t_last = rig.t
    stale_after = rig.bridge.params.link.stale_after
    fault_after = rig.bridge.params.link.fault_after
    seen = rig.bridge.check_watchdog(t_last + 0.1, lambda: 0, lambda: True)
    assert seen.state == LinkState.LAGGING
    within = rig.bridge.check_watchdog(t_last + 0.1 + 0.5 * stale_after, lambda: 0,
                                       lambda: False)
    assert within.state == LinkState.LAGGING
    after = rig.bridge.check_watchdog(t_last + 0.1 + 2.0 * stale_after, lambda: 0,
                                      lambda: False)
    assert after.state == LinkState.STALE
    fault = rig.bridge.check_watchdog(t_last + fault_after + 0.01, lambda: 0, lambda: False)
    assert fault.state == LinkState.FAULT and fault.disarmed


def test_a_device_that_resumes_after_a_long_gap_is_not_taken_for_a_stalled_host() -> None:
    """The watchdog found the port empty during a gap: bytes it sees waiting when the device
    resumes arrived after that, so the host is not stalled (no disarm, no host-stall event
    with the length of the gap). Seen with fault_after above host_stall_limit."""
    link = dataclasses.replace(BridgeParams().link, fault_after=4.0, host_stall_limit=1.0)
    rig = Rig(dataclasses.replace(BridgeParams(), link=link))
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.0)
    t_last = rig.t
    n = len(rig.writes)
    rig.emu.silence(1.5)
    states = set()
    while rig.t < t_last + 1.49:  # the device is silent; the watchdog checks every 5 ms
        rig.run(0.005)
        states.add(rig.bridge.check_watchdog(rig.t, lambda: 0).state)
    assert states == {LinkState.OK, LinkState.STALE}
    # Its first line waits at the port when the watchdog looks, before the reader takes it.
    resumed = rig.bridge.check_watchdog(rig.t + 0.004, input_pending=lambda: 12)
    assert resumed.state == LinkState.LAGGING and not resumed.disarmed
    assert resumed.age_s < 0.01, resumed
    assert rig.writes[n:] == [] and rig.bridge.status(rig.t).armed
    results = rig.run(0.1)
    assert 'host_stall' not in [r.event for r in results]
    assert rig.bridge.diagnostics(rig.t).host_stalls == 0
    # A host that really stalled (the watchdog never saw the port empty) is still one.
    rig.run(0.5)
    t_last = rig.t
    stalled = _watch_on_time(rig, t_last + 0.005, t_last + 1.2, 6000)
    assert stalled[-1].state == LinkState.LAGGING and any(r.disarmed for r in stalled)


# ---------------------------------------------------------------------------- firmware
def test_a_real_firmware_reset_is_counted_as_a_restart_after_the_link_reconnected() -> None:
    """Issue 17 item 5: ~5.7 s of silence (the link faults and reconnects first), then only
    'Voltage control' and angles from a non-zero first angle."""
    rig = Rig(model=GripperModelParams())
    rig.run(0.05)
    rig.bridge.start_homing(rig.t)
    rig.run(6.0)
    assert rig.bridge.status(rig.t).homed
    rig.emu.restart()  # the real boot time
    t_reset = rig.t
    rig.run(0.3)
    fault = rig.bridge.check_watchdog(rig.t, input_pending=lambda: 0)
    assert fault.state == LinkState.FAULT and fault.reconnect
    rig.bridge.on_link_lost(rig.t, 'dropped for reconnection')
    rig.bridge.on_connected(rig.t + 0.5, 'emulated')  # reopened while the firmware boots
    results = rig.run(6.0)
    events = [r.event for r in results if r.event]
    assert events == ['firmware_restart']
    first = next(r for r in results if r.status is not None)
    assert first.stamp - t_reset == pytest.approx(rig.emu.params.boot_time, abs=0.01)
    assert first.status.motor_angle != 0.0
    diag = rig.bridge.diagnostics(rig.t)
    assert diag.firmware_restarts == 1 and diag.reconnects == 1
    assert diag.safe_reason == 'firmware restart detected'
    status = rig.bridge.status(rig.t)
    assert not status.armed and not status.homed and status.link_ok


def test_every_write_is_one_complete_command_and_a_connection_flushes_a_fragment() -> None:
    rig = Rig()
    rig.emu.receive(b'T-2.')  # a previous host died in the middle of a command
    rig.bridge.on_connected(0.0, 'emulated')  # reconnection: newline + safe voltage, one write
    assert rig.writes[-1] == b'\nT0.00\n' and rig.emu.target_voltage_v == 0.0
    rig.run(0.05)
    rig.bridge.set_grasp_force(10.0, rig.t)
    rig.run(1.0)
    rig.bridge.set_grasp_force(-8.0, rig.t)
    rig.run(0.5)
    command = re.compile(rb'\n?T-?[0-9]{1,2}\.[0-9]{2}\n')
    assert all(command.fullmatch(w) for w in rig.writes) and len(rig.writes) > 500
    # Only the stale fragment of the previous host ever reached the firmware malformed.
    assert rig.emu.malformed_commands == 1 and rig.emu.nonfinite_commands == 0


def test_the_longest_watchdog_gap_is_reported_and_inactivity_is_not_one() -> None:
    rig = Rig()
    rig.run(0.05)
    _watch_on_time(rig, rig.t, rig.t + 0.05, 0)
    assert rig.bridge.diagnostics(rig.t).max_watchdog_gap_s == 0.0  # every 5 ms: no gap
    rig.bridge.check_watchdog(rig.t + 0.4, lambda: 0)
    assert rig.bridge.diagnostics(rig.t).max_watchdog_gap_s == pytest.approx(0.35, abs=0.006)
    rig.bridge.deactivate(rig.t + 0.5)
    rig.bridge.activate(rig.t + 30.0)
    rig.bridge.check_watchdog(rig.t + 30.0, lambda: 0)
    assert rig.bridge.diagnostics(rig.t).max_watchdog_gap_s == pytest.approx(0.35, abs=0.006)
