# SPDX-License-Identifier: Apache-2.0
"""Homing state machine: unit behaviour and a full run against the firmware emulator."""
from __future__ import annotations

import math

import pytest

from slip_gripper_driver.core.bridge import GripperBridge
from slip_gripper_driver.core.bridge_params import BridgeParams
from slip_gripper_driver.core.firmware_emulator import FirmwareEmulator, GripperModelParams
from slip_gripper_driver.core.homing import (Homing, HomingParams, HomingPhase, HomingResult,
                                             homing_refusal)
from slip_cell_common.core.serial_transport import LineReader

K_OPEN = 0.0086751614
DT = 0.002


def run_phase(homing: Homing, t0: float, angles: list[float]) -> tuple[float, list]:
    steps = []
    t = t0
    for a in angles:
        steps.append(homing.step(t, a))
        t += DT
    return t, steps


def test_min_phase_time_prevents_an_early_stall_verdict() -> None:
    homing = Homing(HomingParams(min_phase_time=0.5), K_OPEN)
    homing.start(0.0)
    # the motor has not moved yet: constant angle would pass a zero-initialised average
    t, steps = run_phase(homing, 0.0, [0.0] * 200)
    assert all(s.phase == HomingPhase.CLOSING and s.voltage_v == -4.0 for s in steps)
    assert homing.active


def test_full_sequence_with_synthetic_angles() -> None:
    homing = Homing(HomingParams(), K_OPEN)
    homing.start(0.0)
    closing = [-0.02 * k for k in range(200)] + [-4.0] * 400
    t, steps = run_phase(homing, 0.0, closing)
    assert homing.phase == HomingPhase.OPENING and steps[-1].voltage_v == 4.0
    opening = [-4.0 + 0.02 * k for k in range(400)] + [4.0] * 400
    t, steps = run_phase(homing, t, opening)
    done = [s for s in steps if s.finished]
    assert len(done) == 1 and done[0].voltage_v is None
    assert homing.phase == HomingPhase.DONE and homing.homed
    assert homing.result.theta_closed == -4.0 and homing.result.theta_open == 4.0
    assert homing.result.stroke == pytest.approx(8.0 * K_OPEN)


def test_phase_timeout_fails() -> None:
    homing = Homing(HomingParams(timeout=1.0), K_OPEN)
    homing.start(0.0)
    _, steps = run_phase(homing, 0.0, [-0.01 * k for k in range(600)])  # never stalls
    assert homing.phase == HomingPhase.FAILED and 'timed out' in homing.message
    assert sum(s.finished for s in steps) == 1 and not homing.homed


@pytest.mark.parametrize('expected, message', [(0.05, 'differs'), (0.0, 'not positive')])
def test_stroke_checks(expected: float, message: str) -> None:
    homing = Homing(HomingParams(expected_stroke=expected), K_OPEN)
    homing.start(0.0)
    # a stall from the first line needs ln(1e3)/ln(1/0.98) ≈ 342 lines (average starts at 1 rad)
    t, _ = run_phase(homing, 0.0, [0.0] * 400)
    assert homing.phase == HomingPhase.OPENING
    # 'opening' ends below theta_closed when expected is 0 (direction error)
    end = 2.0 if expected else -1.0
    run_phase(homing, t, [end] * 400)
    assert homing.phase == HomingPhase.FAILED and message in homing.message
    assert not homing.homed


def test_invalidate_clears_result() -> None:
    homing = Homing(HomingParams(), K_OPEN)
    homing.start(0.0)
    t, _ = run_phase(homing, 0.0, [0.0] * 400)
    run_phase(homing, t, [5.0] * 400)
    assert homing.homed
    homing.invalidate('firmware restart')
    assert not homing.homed and homing.phase == HomingPhase.IDLE
    assert 'firmware restart' in homing.message


def test_refusals() -> None:
    ok = dict(link_ok=True, armed=True, busy=False, ft_checked=True, grasp_force=0.1,
              contact_threshold=0.5, target_force=0.0)
    assert homing_refusal(**ok) is None
    assert 'contact' in homing_refusal(**{**ok, 'grasp_force': 3.0})
    assert homing_refusal(**{**ok, 'grasp_force': 3.0, 'ft_checked': False}) is None
    assert 'release' in homing_refusal(**{**ok, 'target_force': 2.0})
    assert homing_refusal(**{**ok, 'target_force': -8.0}) is None
    assert 'armed' in homing_refusal(**{**ok, 'armed': False})
    assert 'telemetry' in homing_refusal(**{**ok, 'link_ok': False})
    assert 'already' in homing_refusal(**{**ok, 'busy': True})


def _run_bridge(bridge: GripperBridge, emu: FirmwareEmulator, seconds: float) -> list:
    reader = LineReader(resync=False)
    events = []
    for _ in range(int(round(seconds / emu.params.period))):
        for line, overflow in reader.feed(emu.tick()):
            result = bridge.on_line(line, overflow, emu.time_s)
            if result.event:
                events.append(result.event)
    return events


def _bridge(emu: FirmwareEmulator, params: BridgeParams) -> GripperBridge:
    def writer(data: bytes) -> bool:
        emu.receive(data)
        return True
    bridge = GripperBridge(params, writer)
    bridge.on_connected(0.0)
    bridge.activate(0.0)
    _run_bridge(bridge, emu, 0.05)
    return bridge


def test_homing_against_emulator_finds_the_stroke() -> None:
    model = GripperModelParams(stroke=0.085, initial_opening=0.03)
    emu = FirmwareEmulator(model)
    bridge = _bridge(emu, BridgeParams())
    assert bridge.start_homing(emu.time_s).accepted
    events = _run_bridge(bridge, emu, 8.0)
    assert events == ['homing_done']
    result = bridge.homing.result
    count = 2 * math.pi / 4096 * K_OPEN  # one encoder count of opening [m]
    # closed stop: pads pressed ≈ 16 µm into each other at 4 V, so the stroke reads a bit long
    assert result.stroke == pytest.approx(model.stroke, abs=2 * count + 3e-5)
    status = bridge.status(emu.time_s)
    assert status.homed and status.opening == pytest.approx(emu.opening, abs=2 * count + 3e-5)
    assert emu.target_voltage_v == 0.0  # safe voltage after homing


def test_homing_detects_an_object_by_the_stroke_check() -> None:
    model = GripperModelParams(stroke=0.085, object_width=0.04, object_stiffness=2.0e5)
    emu = FirmwareEmulator(model)
    params = BridgeParams(homing=HomingParams(expected_stroke=0.085, stroke_tolerance=0.002))
    bridge = _bridge(emu, params)
    assert bridge.start_homing(emu.time_s).accepted
    assert _run_bridge(bridge, emu, 8.0) == ['homing_failed']
    assert 'object' in bridge.homing.message and not bridge.status(emu.time_s).homed


def test_homing_refused_while_contact_or_squeeze_command() -> None:
    emu = FirmwareEmulator(GripperModelParams())
    bridge = _bridge(emu, BridgeParams())
    t = emu.time_s
    for finger in (1, 2):
        bridge.on_ft_sample(finger, t, -3.0, True)
    result = bridge.start_homing(t)
    assert not result.accepted and 'contact' in result.reason
    for finger in (1, 2):
        bridge.on_ft_sample(finger, t, 0.0, True)
    assert bridge.set_grasp_force(5.0, t).accepted
    result = bridge.start_homing(t)
    assert not result.accepted and 'release' in result.reason


def test_known_limits_are_adopted_under_the_same_refusals() -> None:
    emu = FirmwareEmulator(GripperModelParams())
    bridge = _bridge(emu, BridgeParams())
    t = emu.time_s
    wrench = (0.0, 0.0, -3.0, 0.0, 0.0, 0.0)     # bias-removed, squeezing: contact
    for finger in (1, 2):
        bridge.on_ft_wrench(finger, t, wrench)
    limits = HomingResult(theta_closed=-9.0, theta_open=-9.0 + 0.08 / K_OPEN, stroke=0.08)
    result = bridge.adopt_homing(t, limits)
    assert not result.accepted and 'contact' in result.reason and not bridge.homing.homed
    for finger in (1, 2):
        bridge.on_ft_wrench(finger, t, (0.0,) * 6)
    result = bridge.adopt_homing(t, limits)
    assert result.accepted and 'stroke 80.00 mm' in result.reason
    assert bridge.homing.homed and bridge.homing.result == limits
    status = bridge.status(t)
    assert status.homed and status.opening == pytest.approx((status.motor_angle + 9.0) * K_OPEN)
    # An unbiased sensor (None) leaves the grasp force unmeasured.
    bridge.on_ft_wrench(1, t, None)
    assert math.isnan(bridge.status(t).measured_grasp_force) and not bridge.status(t).ft_biased
