# SPDX-License-Identifier: Apache-2.0
"""The ``velocity_sensor`` lifecycle node in-process on a private context, against the firmware
emulator on a pseudo-terminal (the device is faked only at the byte level; rclpy is real).

Covers: configure/activate, twist at the firmware's 125–167 Hz with SI values of a scripted
motion, PlanarSlip integration, chip-mode and reset services, diagnostics, configure failures
(unset, wrong-name and doubly claimed ports, bad calibration file), starts that fail first
(missing or silent port) and are retried with back-off until deactivated, and an unplugged port
that goes stale, reports ERROR and reconnects when it comes back.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any
from collections.abc import Callable, Iterator

import numpy as np
import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import TwistStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.lifecycle import TransitionCallbackReturn  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from slip_msgs.msg import OpticalChipArray, PlanarSlip  # noqa: E402
from slip_msgs.srv import SetChipMode  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from slip_cell_common.calls import call_service, spin_until  # noqa: E402
from slip_cell_common.qos import DIAGNOSTICS, SENSOR_SUB  # noqa: E402
from slip_cell_common.time_conv import clock_seconds, stamp_to_seconds  # noqa: E402
from slip_velocity_sensor.core import calibration as cal_mod  # noqa: E402
from slip_velocity_sensor.core.emulator import (ConstantTwist, EmulatorParams,  # noqa: E402
                                                FirmwareEmulator, PtyEmulator)
from slip_velocity_sensor.core.fusion import DEFAULT_CHIP_ANGLES, model_matrix  # noqa: E402
from slip_velocity_sensor.velocity_sensor_node import VelocitySensorNode  # noqa: E402

PACKAGE = Path(__file__).resolve().parents[1]
TRUTH = cal_mod.load_calibration(PACKAGE / 'config' / 'calibration_sensor_1.yaml')
TWIST = (0.020, -0.010, 0.30)
SUCCESS = TransitionCallbackReturn.SUCCESS
FAILURE = TransitionCallbackReturn.FAILURE
OK = b'\x00'
ERROR = b'\x02'


def _stamp(msg: Any) -> float:
    return stamp_to_seconds(msg.header.stamp)


class Harness:
    """Emulators, nodes under test and a probe node on one executor (private context)."""

    def __init__(self, context: Any, tmp_path: Path) -> None:
        self.context = context
        self.tmp_path = tmp_path
        self.executor = SingleThreadedExecutor(context=context)
        self.probe = Node('probe', context=context)
        self.executor.add_node(self.probe)
        self.nodes: list[VelocitySensorNode] = []
        self.ptys: list[PtyEmulator] = []

    def pty(self, name: str = 'sensor_1') -> PtyEmulator:
        params = EmulatorParams(name=name, truth=TRUTH, firmware_speed_term='abs',
                                boot_duration=0.05)
        pty = PtyEmulator(FirmwareEmulator(params, ConstantTwist(*TWIST))).start()
        self.ptys.append(pty)
        return pty

    def node(self, port: str, name: str = 'velocity_sensor_1', cli_args: list[str] | None = None,
             **params: Any) -> VelocitySensorNode:
        values = {'port': port, 'lock_dir': str(self.tmp_path), 'calibration.speed_term': 'abs',
                  'handshake.timeout': 0.3, 'handshake.retries': 2,
                  'reconnect.initial_delay': 0.1, 'reconnect.max_delay': 0.3, **params}
        overrides = [Parameter(k, value=v) for k, v in values.items() if v is not None]
        node = VelocitySensorNode(name, context=self.context, parameter_overrides=overrides,
                                  cli_args=cli_args)
        self.executor.add_node(node)
        self.nodes.append(node)
        return node

    def subscribe(self, msgtype: type, topic: str, qos: Any = SENSOR_SUB) -> list[Any]:
        received: list[Any] = []
        self.probe.create_subscription(msgtype, topic, received.append, qos)
        return received

    def spin_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        return spin_until(self.executor, predicate, timeout)

    def spin_for(self, duration: float) -> None:
        spin_until(self.executor, lambda: False, duration)

    def call(self, srv_type: type, name: str, request: Any) -> Any:
        client = self.probe.create_client(srv_type, name)
        response = call_service(self.executor, client, request, timeout_s=5.0)
        assert response is not None, f'no response from {name}'
        return response

    def close(self) -> None:
        for node in self.nodes:
            node.destroy_node()
        for pty in self.ptys:
            pty.stop()
        self.executor.shutdown()
        self.probe.destroy_node()


@pytest.fixture
def harness(ros_context: Any, tmp_path: Path) -> Iterator[Harness]:
    h = Harness(ros_context, tmp_path)
    yield h
    h.close()


def _statuses(diagnostics: list[Any], node_name: str) -> dict[str, Any]:
    """Latest status per task of ``node_name``."""
    out = {}
    for array in diagnostics:
        for status in array.status:
            if status.name.startswith(f'{node_name}: '):
                out[status.name.split(': ', 1)[1]] = status
    return out


def test_streams_twist_and_state_at_the_firmware_rate_with_si_values(harness: Harness) -> None:
    pty = harness.pty()
    node = harness.node(pty.port)
    twists = harness.subscribe(TwistStamped, 'finger_1/slip/twist')
    states = harness.subscribe(PlanarSlip, 'finger_1/slip/state')
    diagnostics = harness.subscribe(DiagnosticArray, '/diagnostics', DIAGNOSTICS)
    assert node.trigger_configure() == SUCCESS, node.last_error
    harness.spin_for(0.3)
    assert not twists and not states           # configured but inactive: nothing published
    assert node.trigger_activate() == SUCCESS
    assert harness.spin_until(lambda: len(twists) >= 200, 10.0)
    stamps = np.array([_stamp(m) for m in twists])
    assert np.all(np.diff(stamps) >= 0.0)                       # acquisition order
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    assert 125.0 <= rate <= 167.0                               # 6-8 ms firmware periods
    now = clock_seconds(node.get_clock())
    assert 0.0 <= now - stamps[-1] < 1.0                        # node clock, not a device clock
    assert {m.header.frame_id for m in twists} == {'vel_sensor_1'}
    mean = [float(np.mean([getattr(getattr(m.twist, part), axis) for m in twists[20:]]))
            for part, axis in (('linear', 'x'), ('linear', 'y'), ('angular', 'z'))]
    assert mean == pytest.approx(TWIST, rel=0.03)              # m/s, m/s, rad/s
    valid = [m for m in states if m.valid]
    assert len(valid) >= 190 and all(m.chip_mode == 0 and m.excluded_chip == -1 for m in valid)
    # Pose integration over every line's own period: lines a loaded host reads together share
    # the time since the previous read, so the object moved TWIST × the stamps' span.
    window = valid[10:]
    integrated = _stamp(window[-1]) - _stamp(window[0])
    assert integrated > 1.0
    for field, rate_si in zip(('x', 'y', 'theta'), TWIST):
        moved = getattr(window[-1], field) - getattr(window[0], field)
        assert moved == pytest.approx(rate_si * integrated, rel=0.05), field
    assert harness.spin_until(
        lambda: {k: s.level for k, s in _statuses(diagnostics, 'velocity_sensor_1').items()}
        == {'link': OK, 'rate': OK, 'chips': OK, 'calibration': OK}, 3.0), \
        {k: s.message for k, s in _statuses(diagnostics, 'velocity_sensor_1').items()}
    link = _statuses(diagnostics, 'velocity_sensor_1')['link']
    assert link.hardware_id == pty.port
    assert {kv.key for kv in link.values} >= {'lines_bad', 'reconnects', 'device_restarts'}
    assert node.trigger_deactivate() == SUCCESS
    harness.spin_for(0.1)
    count = len(twists)
    harness.spin_for(0.2)
    assert len(twists) == count                                  # inactive: silent again


def test_chip_mode_and_reset_pose_services(harness: Harness) -> None:
    pty = harness.pty()
    node = harness.node(pty.port)
    twists = harness.subscribe(TwistStamped, 'finger_1/slip/twist')
    states = harness.subscribe(PlanarSlip, 'finger_1/slip/state')
    chips = harness.subscribe(OpticalChipArray, 'finger_1/slip/chips')
    assert node.trigger_configure() == SUCCESS and node.trigger_activate() == SUCCESS
    assert harness.spin_until(lambda: len(twists) > 20, 10.0)

    bad = harness.call(SetChipMode, 'finger_1/slip/set_chip_mode', SetChipMode.Request(chip=4))
    assert not bad.success and '1..3' in bad.message
    ok = harness.call(SetChipMode, 'finger_1/slip/set_chip_mode', SetChipMode.Request(chip=2))
    assert ok.success and 'single-chip mode 2' in ok.message
    assert harness.spin_until(lambda: pty.emulator.chip_mode == 2, 1.0)   # next firmware loop
    assert harness.spin_until(lambda: len(chips) >= 60, 5.0)
    twist_count = len(twists)
    harness.spin_for(0.2)
    assert len(twists) - twist_count <= 1      # no twist from single-chip lines
    chip_states = [m for m in states if m.chip_mode == 2]
    assert chip_states and not any(m.valid for m in chip_states)
    assert all(math.isnan(m.omega) for m in chip_states)        # ω invalid (firmware: stale)
    msg = chips[-1]
    assert msg.chip_mode == 2 and not msg.calibrated and list(msg.synced) == [False, True, False]
    assert math.isnan(msg.vx[0]) and math.isnan(msg.vy[2])
    dts = [m.dt for m in chips[1:]]   # NaN when two lines arrived in one read (one stamp)
    assert all(math.isnan(dt) or dt > 0.0 for dt in dts) and any(dt > 0.0 for dt in dts)
    # Raw chip-frame speeds of chip 2: the rigid-body model with the chip reading low.
    true = model_matrix(TRUTH.radius, DEFAULT_CHIP_ANGLES) @ np.array(TWIST)
    expected = [cal_mod.raw_speed(true[2 + j], TRUTH.axis(2, ax), 'abs')
                for j, ax in enumerate(('x', 'y'))]
    measured = [float(np.mean([m.vx[1] for m in chips[10:]])),
                float(np.mean([m.vy[1] for m in chips[10:]]))]
    assert measured == pytest.approx(expected, rel=0.05, abs=2e-4)

    back = harness.call(SetChipMode, 'finger_1/slip/set_chip_mode', SetChipMode.Request(chip=0))
    assert back.success and harness.spin_until(lambda: pty.emulator.chip_mode == 0, 1.0)
    twist_count = len(twists)
    assert harness.spin_until(lambda: len(twists) > twist_count + 20, 5.0)

    x_before = [m.x for m in states if m.valid][-1]
    t_before = clock_seconds(node.get_clock())
    reset = harness.call(Trigger, 'finger_1/slip/reset_pose', Trigger.Request())
    assert reset.success
    t_after = clock_seconds(node.get_clock())
    n = len(states)
    assert harness.spin_until(lambda: len(states) > n + 10, 5.0)
    after = [m for m in states[n:] if m.valid and _stamp(m) > t_after]
    # Integration restarts from 0 somewhere between the call and its response.
    assert x_before > 0.005 and after
    assert 0.0 <= after[0].x <= 1.1 * TWIST[0] * (_stamp(after[0]) - t_before) + 2e-4


def test_configure_failures_are_clear_and_recoverable(harness: Harness, tmp_path: Path) -> None:
    # The shipped YAML leaves the port unset on purpose.
    yaml_file = PACKAGE / 'config' / 'velocity_sensor_1.yaml'
    unset = harness.node(None, name='velocity_sensor_1',
                         cli_args=['--ros-args', '--params-file', str(yaml_file)])
    assert unset.trigger_configure() == FAILURE
    assert 'port is required but not set' in unset.last_error

    # A start that can succeed later (missing port, silent sensor) configures without the
    # sensor, says why and retries while active (see the next test).
    missing = str(tmp_path / 'serial_by_id_missing')
    node = harness.node(missing, name='velocity_sensor_missing')
    diagnostics = harness.subscribe(DiagnosticArray, '/diagnostics', DIAGNOSTICS)
    assert node.trigger_configure() == SUCCESS and node.driver is None
    assert missing in node.last_error and 'cannot open serial port' in node.last_error
    assert harness.spin_until(
        lambda: 'link' in _statuses(diagnostics, 'velocity_sensor_missing'), 3.0)
    link = _statuses(diagnostics, 'velocity_sensor_missing')['link']
    assert link.level == ERROR and missing in link.message and link.hardware_id == missing
    assert 'not started' in link.message and 'when the node is activated' in link.message

    silent = harness.pty()
    silent.emulator.set_silent(True)
    node = harness.node(silent.port, name='velocity_sensor_silent')
    assert node.trigger_configure() == SUCCESS and node.driver is None
    assert silent.port in node.last_error and 'no answer to "n"' in node.last_error
    silent.emulator.set_silent(False)          # powered up: the retry started while active
    assert node.trigger_activate() == SUCCESS
    assert harness.spin_until(lambda: node.driver is not None, 5.0), node.last_error
    assert node.last_error == ''
    assert node.trigger_deactivate() == SUCCESS
    assert node.trigger_cleanup() == SUCCESS   # closes the port and releases sensor_1

    wrong = harness.pty(name='sensor_2')
    node = harness.node(wrong.port, name='velocity_sensor_wrong')
    assert node.trigger_configure() == FAILURE
    assert wrong.port in node.last_error and "answered 'sensor_2'" in node.last_error

    first, second = harness.pty(), harness.pty()   # two boards flashed as sensor_1
    node_1 = harness.node(first.port, name='velocity_sensor_1')
    node_2 = harness.node(second.port, name='velocity_sensor_2', finger=2,
                          frame_id='vel_sensor_2')
    assert node_1.trigger_configure() == SUCCESS
    assert node_2.trigger_configure() == FAILURE
    assert first.port in node_2.last_error and second.port in node_2.last_error
    assert 'same name' in node_2.last_error

    bad_file = tmp_path / 'calibration.yaml'
    bad_file.write_text('format: something_else\n')
    node = harness.node(second.port, name='velocity_sensor_badcal',
                        **{'calibration.file': str(bad_file)})
    assert node.trigger_configure() == FAILURE
    assert str(bad_file) in node.last_error and second.port in node.last_error


def test_a_failed_start_is_retried_until_the_port_appears_or_the_node_deactivates(
        harness: Harness, tmp_path: Path) -> None:
    link_path = tmp_path / 'usb-CP2102N-plugged-in-later'
    node = harness.node(str(link_path))
    twists = harness.subscribe(TwistStamped, 'finger_1/slip/twist')
    diagnostics = harness.subscribe(DiagnosticArray, '/diagnostics', DIAGNOSTICS)
    assert node.trigger_configure() == SUCCESS and node.trigger_activate() == SUCCESS

    def link_status() -> Any:
        return _statuses(diagnostics, 'velocity_sensor_1').get('link')
    assert harness.spin_until(
        lambda: link_status() is not None and 'retrying in' in link_status().message, 5.0)
    assert link_status().level == ERROR and str(link_path) in link_status().message
    attempts = {kv.key: kv.value for kv in link_status().values}['start_attempts']
    assert int(attempts) >= 2                        # configure's attempt plus retries
    pty = harness.pty()
    os.symlink(pty.port, link_path)                  # the adapter is plugged in
    assert harness.spin_until(lambda: len(twists) > 20, 10.0), node.last_error
    assert pty.emulator.device_calibration().axis(1, 'x').b == pytest.approx(
        TRUTH.axis(1, 'x').b)                        # a full start: calibration uploaded
    diagnostics.clear()
    assert harness.spin_until(lambda: link_status() is not None and link_status().level == OK,
                              3.0)

    # Deactivated, a node that never started stops retrying; activating resumes.
    idle_path = tmp_path / 'usb-CP2102N-never'
    idle = harness.node(str(idle_path), name='velocity_sensor_2', finger=2,
                        frame_id='vel_sensor_2', expected_name='sensor_2')
    assert idle.trigger_configure() == SUCCESS and idle.trigger_activate() == SUCCESS
    harness.spin_for(0.5)
    assert idle.trigger_deactivate() == SUCCESS
    diagnostics.clear()
    assert harness.spin_until(
        lambda: 'link' in _statuses(diagnostics, 'velocity_sensor_2'), 3.0)
    stopped = _statuses(diagnostics, 'velocity_sensor_2')['link']
    assert 'resume when the node is activated' in stopped.message
    count = {kv.key: kv.value for kv in stopped.values}['start_attempts']
    harness.spin_for(1.0)
    diagnostics.clear()
    assert harness.spin_until(
        lambda: 'link' in _statuses(diagnostics, 'velocity_sensor_2'), 3.0)
    later = _statuses(diagnostics, 'velocity_sensor_2')['link']
    assert {kv.key: kv.value for kv in later.values}['start_attempts'] == count


def test_unplugged_port_goes_stale_errors_and_reconnects(harness: Harness,
                                                         tmp_path: Path) -> None:
    link_path = tmp_path / 'usb-CP2102N-sensor_1'    # stands in for /dev/serial/by-id/...
    first = harness.pty()
    os.symlink(first.port, link_path)
    node = harness.node(str(link_path))
    twists = harness.subscribe(TwistStamped, 'finger_1/slip/twist')
    states = harness.subscribe(PlanarSlip, 'finger_1/slip/state')
    diagnostics = harness.subscribe(DiagnosticArray, '/diagnostics', DIAGNOSTICS)
    assert node.trigger_configure() == SUCCESS and node.trigger_activate() == SUCCESS
    assert harness.spin_until(lambda: len(twists) > 20, 10.0)

    first.vanish()                                    # unplugged mid-stream
    n_states = len(states)
    assert harness.spin_until(lambda: any(not m.valid for m in states[n_states:]), 3.0)
    marker = next(m for m in states[n_states:] if not m.valid)
    assert math.isnan(marker.vx) and math.isfinite(marker.x)     # stale: invalid, pose kept
    n_twists = len(twists)

    def link_status() -> Any:
        return _statuses(diagnostics, 'velocity_sensor_1').get('link')
    diagnostics.clear()
    assert harness.spin_until(lambda: link_status() is not None, 3.0)
    assert link_status().level == ERROR and str(link_path) in link_status().message
    assert len(twists) == n_twists                   # nothing old republished as new

    second = harness.pty()                           # plugged in again, same by-id path
    tmp_link = tmp_path / 'tmp_link'
    os.symlink(second.port, tmp_link)
    os.replace(tmp_link, link_path)
    assert harness.spin_until(lambda: len(twists) > n_twists + 20, 10.0)
    assert second.emulator.device_calibration().axis(2, 'y').b == pytest.approx(
        TRUTH.axis(2, 'y').b)                        # calibration re-uploaded
    diagnostics.clear()
    assert harness.spin_until(lambda: link_status() is not None and link_status().level == OK,
                              3.0)
    values = {kv.key: kv.value for kv in link_status().values}
    # Usually 1 and 1; a reopen can hit the dying pty once more (as a flaky USB hub does).
    assert int(values['reconnects']) >= 1 and int(values['losses']) >= 1
