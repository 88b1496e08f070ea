# SPDX-License-Identifier: Apache-2.0
"""End to end on a pseudo-terminal: pyserial ``serial_for_url`` + reader thread + bridge core
against the real-time firmware emulator (vanishing port, restarts, silence). Waits are bounded
and nothing asserts on timing."""
from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Callable, Iterator

import pytest

from slip_gripper_driver.core.bridge import BridgeParams, GripperDriverCore, LineResult, LinkState
from slip_gripper_driver.core.firmware_emulator import (FirmwareEmulator, GripperModelParams,
                                                        PtyFirmwareEmulator)
from slip_cell_common.core.serial_transport import LinkError, ReconnectParams

TIMEOUT_S = 5.0


def wait_until(predicate: Callable[[], bool], timeout_s: float = TIMEOUT_S,
               tick: Callable[[], None] | None = None) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if tick is not None:
            tick()
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()


class Recorder:
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.results: list[LineResult] = []
        self.events: list[tuple[str, str]] = []

    def on_result(self, result: LineResult) -> None:
        with self.lock:
            self.results.append(result)

    def on_event(self, t: float, kind: str, message: str) -> None:
        with self.lock:
            self.events.append((kind, message))

    def kinds(self) -> list[str]:
        with self.lock:
            return [k for k, _ in self.events]


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[tuple[PtyFirmwareEmulator, GripperDriverCore, Recorder]]:
    model = GripperModelParams(object_width=0.03, initial_opening=0.031)
    emu = PtyFirmwareEmulator(FirmwareEmulator(model), link_path=str(tmp_path / 'gripper'))
    emu.start()
    rec = Recorder()
    core = GripperDriverCore(emu.port, BridgeParams(), clock=time.monotonic,
                             reconnect=ReconnectParams(initial_delay=0.05, max_delay=0.2),
                             on_result=rec.on_result, on_event=rec.on_event)
    yield emu, core, rec
    core.shutdown(time.monotonic())
    emu.stop()


def last_command(emu: PtyFirmwareEmulator) -> bytes:
    with emu.lock:
        return emu.emulator.commands[-1] if emu.emulator.commands else b''


def test_missing_port_fails_configure_naming_it(tmp_path: Path) -> None:
    port = str(tmp_path / 'serial' / 'by-id' / 'usb-Espressif_USB_JTAG_serial-if00')
    core = GripperDriverCore(port, BridgeParams(), clock=time.monotonic)
    with pytest.raises(LinkError) as info:
        core.configure()
    assert port in str(info.value)
    with pytest.raises(LinkError):
        core.activate(time.monotonic())


def test_lines_in_commands_out_and_safe_stop_on_deactivate(rig) -> None:
    emu, core, rec = rig
    core.configure()
    assert wait_until(lambda: last_command(emu) == b'T0.00')  # safe voltage on connect
    core.activate(time.monotonic())
    assert wait_until(lambda: core.bridge.status(time.monotonic()).line_count > 100)
    assert wait_until(lambda: core.bridge.status(time.monotonic()).link_ok)
    status = core.bridge.status(time.monotonic())
    assert status.armed and not status.safe_state
    assert core.bridge.set_grasp_force(-4.0, time.monotonic()).accepted  # open: +1.02 V
    assert wait_until(lambda: last_command(emu) == b'T1.02')
    with rec.lock:
        telemetry = [r for r in rec.results if r.status is not None]
    assert all(r.written for r in telemetry) and len(telemetry) > 100
    stamps = [r.stamp for r in telemetry]
    assert stamps == sorted(stamps)
    core.deactivate(time.monotonic())
    assert wait_until(lambda: last_command(emu) == b'T0.00')
    with emu.lock:
        n = emu.emulator.commands_received
    time.sleep(0.05)
    with emu.lock:
        assert emu.emulator.commands_received == n  # nothing written after deactivation
    assert core.stats().callback_errors == 0


def test_garbage_and_restart_on_a_live_port(rig) -> None:
    emu, core, rec = rig
    core.configure()
    core.activate(time.monotonic())
    assert wait_until(lambda: core.bridge.status(time.monotonic()).line_count > 50)
    emu.inject(b'\x00\xff\xfe garbage\r\nnan\r\n' + b'9' * 500 + b'\r\n')
    assert wait_until(lambda: core.bridge.diagnostics(time.monotonic()).lines_too_long == 1)
    diag = core.bridge.diagnostics(time.monotonic())
    assert diag.lines_non_finite == 1 and diag.lines_bad >= 3 and diag.armed
    emu.restart(silence_s=0.005)
    assert wait_until(lambda: 'firmware_restart' in rec.kinds())
    status = core.bridge.status(time.monotonic())
    assert not status.armed and status.safe_state
    assert wait_until(lambda: last_command(emu) == b'T0.00')


def test_port_vanishes_reconnects_under_the_same_path_and_stays_disarmed(rig) -> None:
    emu, core, rec = rig
    core.configure()
    core.activate(time.monotonic())
    assert wait_until(lambda: core.bridge.status(time.monotonic()).line_count > 50)
    core.bridge.set_grasp_force(8.0, time.monotonic())
    assert wait_until(lambda: last_command(emu).startswith(b'T-'))
    emu.vanish()
    assert wait_until(lambda: 'lost' in rec.kinds())
    lost = next(m for k, m in rec.events if k == 'lost')
    assert emu.port in lost  # the failure names the port
    status = core.bridge.status(time.monotonic())
    assert not status.armed and not status.link_ok
    time.sleep(0.3)  # a few failed reopen attempts with back-off while the port is gone
    assert core.stats().connect_failures >= 1
    emu.reappear(reboot=False)
    assert wait_until(lambda: core.stats().reconnects == 1)
    assert wait_until(lambda: core.bridge.status(time.monotonic()).link_ok)
    status = core.bridge.status(time.monotonic())
    assert status.reconnect_count == 1 and status.link_ok and not status.armed
    assert last_command(emu) == b'T0.00'
    assert not core.bridge.set_grasp_force(8.0, time.monotonic()).accepted
    time.sleep(0.05)
    assert last_command(emu) == b'T0.00'  # no force after reconnect until re-armed
    assert core.bridge.arm(time.monotonic()).accepted
    assert core.bridge.set_grasp_force(-4.0, time.monotonic()).accepted
    assert wait_until(lambda: last_command(emu) == b'T1.02')


def test_silent_port_is_detected_by_the_watchdog_and_reopened(rig) -> None:
    emu, core, rec = rig
    core.configure()
    core.activate(time.monotonic())
    assert wait_until(lambda: core.bridge.status(time.monotonic()).line_count > 50)
    core.bridge.set_grasp_force(-4.0, time.monotonic())
    assert wait_until(lambda: last_command(emu) == b'T1.02')
    emu.silence(0.6)
    states: list[LinkState] = []
    assert wait_until(lambda: LinkState.FAULT in states,
                      tick=lambda: states.append(core.watchdog(time.monotonic()).state))
    assert LinkState.STALE in states
    assert last_command(emu) == b'T0.00'
    assert wait_until(lambda: core.stats().reconnects >= 1)
    assert wait_until(lambda: core.bridge.status(time.monotonic()).link_ok,
                      tick=lambda: core.watchdog(time.monotonic()))
    assert not core.bridge.status(time.monotonic()).armed
    assert 'stale' in rec.kinds() and 'fault' in rec.kinds()
