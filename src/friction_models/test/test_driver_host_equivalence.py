# SPDX-License-Identifier: Apache-2.0
"""The simulated cell and the real driver's host path agree on the same inputs (issue 14).

The driver side is assembled as ``gripper_driver`` assembles it: a `GripperBridge` whose
writer is the serial port, fed by two `FtChannel` bias paths (the Net F/T reader threads) and
by ``gripper/grasp_force_cmd``, ``gripper/home`` and ``gripper/stop``. The simulated cell runs
a scripted session (homing sequence, bias, valid and invalid commands, clock skew, an expiring
command, stop, a new command); every telemetry line it printed, every F/T record it measured
and every request it got are replayed into the driver side at the same stamps. Compared, line
by line: the command bytes written and the voltage the simulated motor applies, the gripper
status and motor-command records, the bias-removed wrenches, the outcome of every grasp-force
command, the bias result and the published ``gripper/status`` after a stop.
"""
from __future__ import annotations

import math
from typing import Any

import pytest

from slip_gripper_driver.core.bridge import GripperBridge
from slip_gripper_driver.core.bridge_params import BridgeParams
from slip_gripper_driver.core.ft_bias import BiasParams, BiasState
from slip_gripper_driver.core.gripper_records import LineResult
from slip_gripper_driver.core.grasp_command import MAX_COMMAND_CLOCK_SKEW_S
from slip_gripper_driver.core.netft_client import FtSample as RdtSample
from slip_gripper_driver.core.netft_params import FtStreamParams
from slip_gripper_driver.core.protocol import command_voltage
from slip_gripper_driver.ft_channel import FtChannel
from slip_gripper_driver.gripper_msgs_conv import status_msg

from friction_models.core.presets import reference_presets
from friction_models.core.sensors import FtSample, SimEvents
from friction_models.core.sim_cell import SimCell, SimParams

#: The simulator's defaults (homing by the real sequence); the driver side uses its own.
PARAMS = SimParams(homing_mode='sequence', seed=5)


class DriverHost:
    """The real driver's host path, wired like ``gripper_driver`` with its default parameters
    (no ROS, no hardware)."""

    def __init__(self) -> None:
        self.written: list[bytes] = []
        self.bridge = GripperBridge(BridgeParams(), self._write)
        self.wrenches: list[Any] = []
        self.channels = [FtChannel(k, f'box_{k}', FtStreamParams(), BiasParams(),
                                   clock=lambda: 0.0, sink=self._sink) for k in (1, 2)]
        self._seq = 0
        # Power-up: port opened, node activated, the firmware's first line (open stop: 0 rad).
        self.bridge.on_connected(0.0, 'pty')
        self.bridge.activate(0.0)
        self.bridge.on_line(b'0.0000', False, 0.0)

    def _write(self, command: bytes) -> bool:
        self.written.append(command)
        return True

    def _sink(self, finger: int, stamp: float, wrench: Any) -> None:
        self.wrenches.append(wrench)
        self.bridge.on_ft_wrench(finger, stamp, wrench)

    def ft_record(self, sample: FtSample) -> None:
        self._seq += 1
        self.channels[sample.finger - 1].on_sample(
            RdtSample(sample.stamp, self._seq, self._seq, 0, sample.raw))

    def telemetry(self, line: bytes, t: float) -> LineResult:
        return self.bridge.on_line(line, False, t)


def _line(result: LineResult) -> bytes:
    """The telemetry line the firmware printed (the angle with four decimals)."""
    assert result.status is not None
    return f'{result.status.motor_angle:.4f}'.encode('ascii')


class Session:
    """Runs the cell and replays everything into the driver host, comparing as it goes."""

    def __init__(self) -> None:
        self.cell = SimCell(PARAMS, reference_presets(), 'wood')
        self.driver = DriverHost()
        self.lines: list[tuple[LineResult, LineResult]] = []
        self.ft: list[tuple[Any, Any]] = []
        self.statuses: list[tuple[str, str]] = []    # between requests and after each chunk
        self.voltages: list[tuple[float, float]] = []
        self.commands: list[tuple[tuple[float, ...], Any, Any]] = []
        self.compare_status()

    def run_for(self, seconds: float) -> None:
        cell = self.cell
        t_end = cell.t + seconds
        while cell.t < t_end - 1e-9:
            self.replay(cell.advance(min(cell.t + 0.01, t_end)))

    def run_until(self, predicate: Any, timeout: float) -> bool:
        t_end = self.cell.t + timeout
        while not predicate():
            if self.cell.t >= t_end:
                return False
            self.run_for(0.01)
        return True

    def replay(self, events: SimEvents) -> None:
        driver = self.driver
        for event in events:
            if isinstance(event, FtSample):
                n = len(driver.wrenches)
                driver.ft_record(event)
                self.ft.append((event.biased, driver.wrenches[n]))
            elif isinstance(event, LineResult):
                self.lines.append((event, driver.telemetry(_line(event), event.stamp)))
        # The motor of the simulated firmware applies what the driver wrote last.
        self.voltages.append((self.cell.plant.voltage, command_voltage(driver.written[-1])))
        self.compare_status()

    def compare_status(self) -> None:
        t = self.cell.t
        self.statuses.append((repr(self.cell.status()), repr(self.driver.bridge.status(t))))

    def command(self, force: float, stamp: float = 0.0, timeout: float = 0.0) -> Any:
        t = self.cell.t
        sim = self.cell.command_grasp_force(force, stamp, timeout)
        real = self.driver.bridge.set_grasp_force(force, t, stamp=stamp, timeout=timeout)
        self.commands.append(((force, stamp, timeout), sim, real))
        self.compare_status()
        return sim


@pytest.fixture(scope='module')
def session() -> Session:
    s = Session()
    cell, driver = s.cell, s.driver
    # Home with the sequence, away from the object (as an operator would, gripper empty).
    assert cell.move_gripper(0.3, 0.0, 0.0, 0.5)[0]
    s.run_for(0.6)
    assert tuple(cell.home()) == tuple(driver.bridge.start_homing(cell.t))
    assert s.run_until(lambda: cell.homed, 20.0)
    assert cell.move_gripper(-0.3, 0.0, 0.0, 0.5)[0]
    s.run_for(0.6)
    # Bias (both boxes over the same window).
    assert cell.bias_ft()[0]
    for channel in driver.channels:
        channel.start_bias(cell.t)
    assert s.run_until(lambda: not cell.bias_in_progress, 1.0)
    s.bias = (cell.bias_result(), [c.accumulator.state for c in driver.channels],
              '; '.join(f'finger {c.finger}: {c.accumulator.message}' for c in driver.channels))
    # The grasp-command gate: invalid, skewed and valid commands at the same arrival time.
    t = s.gate_t = cell.t
    s.gate = [(args, s.command(*args)) for args in (
        (math.nan,), (math.inf,), (-math.inf,), (200.0,), (-79.0,), (5.0, 0.0, -0.1),
        (5.0, 0.0, math.nan), (5.0, 0.0, math.inf), (5.0, math.nan), (5.0, -math.inf),
        (5.0, t + MAX_COMMAND_CLOCK_SKEW_S + 0.01), (5.0, t + 10.0),
        (5.0, t + MAX_COMMAND_CLOCK_SKEW_S), (60.0,), (-12.0,), (10.0, t - 0.05))]
    s.run_for(0.5)
    # A command that expires (timeout 0.3 s) and the loop's policy afterwards.
    s.expiring = s.command(10.0, cell.t, 0.3)
    s.run_for(1.0)
    # Hold, then gripper/stop, then a new command.
    s.command(10.0)
    s.run_for(1.0)
    cell.stop()
    driver.bridge.stop(cell.t)
    s.compare_status()
    s.run_for(0.3)
    s.stopped = (cell.status(), driver.bridge.status(cell.t))
    s.command(6.0)
    s.run_for(0.5)
    return s


def test_every_line_writes_the_same_command_and_records(session: Session) -> None:
    assert len(session.lines) > 3000
    for sim, real in session.lines:
        assert sim.command == real.command and sim.written == real.written
        assert repr(sim.status) == repr(real.status)
        assert repr(sim.motor) == repr(real.motor)
        assert sim.event == real.event
    # The session exercised homing, closed and open loop, saturation-free holding and stop.
    events = {sim.event for sim, _ in session.lines}
    assert 'homing_done' in events
    motors = [sim.motor for sim, _ in session.lines if sim.motor is not None]
    assert any(m.closed_loop for m in motors) and any(not m.closed_loop for m in motors)
    assert len({sim.command for sim, _ in session.lines}) > 20


def test_status_between_lines_and_requests_is_the_same(session: Session) -> None:
    assert len(session.statuses) > 500
    for sim, real in session.statuses:
        assert sim == real


def test_voltage_encoding_is_the_drivers(session: Session) -> None:
    for applied, written in session.voltages:
        assert applied == written
    for sim, _ in session.lines:
        assert sim.status is not None and sim.command is not None
        assert sim.status.voltage_cmd == command_voltage(sim.command)
        if sim.motor is not None:
            assert sim.motor.voltage_cmd == sim.status.voltage_cmd
    voltages = {sim.status.voltage_cmd for sim, _ in session.lines}
    assert min(voltages) < -2.0 and max(voltages) > 2.0   # closing, and opening while homing


def test_bias_removes_the_same_offsets(session: Session) -> None:
    assert len(session.ft) > 6000
    for sim, real in session.ft:
        assert sim == real
    biased = [sim for sim, _ in session.ft if sim is not None]
    assert biased and len(biased) < len(session.ft)   # none before the bias, all after
    (ok, message), states, driver_message = session.bias
    assert ok and states == [BiasState.DONE, BiasState.DONE]
    assert message == driver_message and 'biased with' in message


def test_command_gate_and_clock_skew(session: Session) -> None:
    for args, sim, real in session.commands:
        assert tuple(sim) == tuple(real), args
    t = session.gate_t
    expected = ['not finite', 'not finite', 'not finite', 'actuator range', 'actuator range',
                'timeout', 'timeout', 'timeout', 'stamp nan', 'stamp -inf', 'in the future',
                'in the future', 'accepted', 'accepted', 'accepted', 'accepted']
    assert len(session.gate) == len(expected)
    for (args, result), text in zip(session.gate, expected):
        assert result.accepted == (text == 'accepted'), args
        assert text in result.reason, (args, result.reason)
    # Exactly at the allowed skew is accepted, a little beyond it is not.
    assert session.gate[12][0][1] == t + MAX_COMMAND_CLOCK_SKEW_S
    assert session.expiring.accepted


def test_command_timeout_expires_identically(session: Session) -> None:
    expired = [sim.status.command_expired for sim, _ in session.lines]
    assert any(expired) and not all(expired)


def test_stop_reports_the_safe_state(session: Session) -> None:
    sim, real = session.stopped
    assert repr(sim) == repr(real)
    assert sim.safe_state and sim.armed and sim.voltage_cmd == 0.0
    assert status_msg(sim).safe_state
    # The next command leaves the stop in both.
    assert not session.cell.status().safe_state
