# SPDX-License-Identifier: Apache-2.0
"""End to end on a pseudo-terminal: pyserial ``serial_for_url`` + reader thread + bridge core
against the real-time firmware emulator (vanishing port, restarts, silence). Waits are bounded
and nothing asserts on timing."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from collections.abc import Callable, Iterator

import pytest

from slip_gripper_driver.core.bridge_params import BridgeParams
from slip_gripper_driver.core.driver_core import GripperDriverCore
from slip_gripper_driver.core.gripper_records import LineResult, LinkState
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
    # Every line that stepped wrote; lines read together with a newer one (a backlog) only
    # update the state and write nothing.
    stepped = [r for r in telemetry if r.command is not None]
    assert all(r.written for r in stepped) and len(telemetry) > 100 and len(stepped) > 20
    assert all(not r.written for r in telemetry if r.command is None)
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
    armed_while_stale: list[bool] = []

    def tick() -> None:
        state = core.watchdog(time.monotonic()).state
        states.append(state)
        if state == LinkState.STALE:
            armed_while_stale.append(core.bridge.status(time.monotonic()).armed)
    assert wait_until(lambda: LinkState.FAULT in states, tick=tick)
    assert LinkState.STALE in states and all(armed_while_stale)
    assert wait_until(lambda: last_command(emu) == b'T0.00')  # written at the fault
    assert wait_until(lambda: core.stats().reconnects >= 1)
    assert wait_until(lambda: core.bridge.status(time.monotonic()).link_ok,
                      tick=lambda: core.watchdog(time.monotonic()))
    assert not core.bridge.status(time.monotonic()).armed
    assert 'stale' in rec.kinds() and 'fault' in rec.kinds()
    # The log says what was done (issue 17 item 7): stale holds the last command (the default
    # link.stale_action) and stays armed (as the status said meanwhile), only the fault
    # writes 0 V and disarms.
    stale = next(m for k, m in rec.events if k == 'stale')
    fault = next(m for k, m in rec.events if k == 'fault')
    assert 'last command held' in stale and 'still armed' in stale
    assert 'safe voltage' not in stale and 'disarmed' not in stale
    assert 'disarmed' in fault and 'reconnecting' in fault


# ---------------------------------------------------------------------------- host stalls
class EmulatorProcess:
    """The firmware emulator (and two Net F/T boxes measuring its pad force) in a child
    process: its 500 Hz timing does not depend on this process, like real firmware."""

    def __init__(self, link: str, *extra: str) -> None:
        cmd = [sys.executable, '-m', 'slip_gripper_driver.core.firmware_emulator', '--link',
               link, '--object-width', '0.03', '--initial-opening', '0.031', '--stats-json',
               '--netft', '127.0.0.1:0', '--netft', '127.0.0.1:0',
               # SCHED_FIFO when permitted (falls back with a warning): a real firmware's timing
               # does not depend on the host load, and a late emulator is a real link gap.
               '--priority', '5', *extra]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
        self.boxes: list[tuple[str, int]] = []
        assert self.proc.stdout is not None
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if line.startswith('Net F/T emulator'):
                host, port = line.rsplit(' ', 1)[1].strip().rsplit(':', 1)
                self.boxes.append((host, int(port)))
            if line.startswith('gripper firmware emulator on') or not line:
                break
        assert len(self.boxes) == 2, 'emulator did not start'

    def stop(self) -> dict:
        self.proc.send_signal(signal.SIGINT)
        out, _ = self.proc.communicate(timeout=10.0)
        return json.loads(out.strip().splitlines()[-1])


class StallingRecorder(Recorder):
    """Blocks the thread that delivers lines to the loop (the serial reader) once, on
    request: the executor stall of issue 16, while the firmware keeps sending."""

    def __init__(self) -> None:
        super().__init__()
        self.stall_s = 0.0
        self.stalled_at = -1  # index of the result after which the stall happened
        self.windows: list[tuple[float, float]] = []  # injected stalls [s, monotonic]
        self.times: list[tuple[float, str]] = []

    def on_event(self, t: float, kind: str, message: str) -> None:
        super().on_event(t, kind, message)
        with self.lock:
            self.times.append((t, kind))

    def on_result(self, result: LineResult) -> None:
        super().on_result(result)
        if self.stall_s > 0.0:
            stall, self.stall_s = self.stall_s, 0.0
            with self.lock:
                self.stalled_at = len(self.results)
            t0 = time.monotonic()
            time.sleep(stall)
            self.windows.append((t0, time.monotonic()))


def test_reader_stalls_of_60_and_300_ms_keep_the_grasp_without_dropout_disarm_or_burst(
        tmp_path: Path) -> None:
    """Issue 16 item 2, against the pty emulator in its own process with the loop closed
    through two Net F/T streams at 10 N."""
    from slip_gripper_driver.core.ft_scale import ForceTorqueScale
    from slip_gripper_driver.core.netft_client import NetFTClient

    emulator = EmulatorProcess(str(tmp_path / 'gripper'))
    rec = StallingRecorder()
    core = GripperDriverCore(str(tmp_path / 'gripper'), BridgeParams(), clock=time.monotonic,
                             on_result=rec.on_result, on_event=rec.on_event)
    scale = ForceTorqueScale(1e6, 1e6, 'N', 'N-m')
    clients = [NetFTClient(host, port=port, scale=scale, clock=time.monotonic,
                           on_sample=lambda s, k=k: core.bridge.on_ft_sample(
                               k, s.stamp, s.wrench[2], True))
               for k, (host, port) in enumerate(emulator.boxes, start=1)]
    try:
        core.configure()
        for client in clients:
            client.start()
        core.activate(time.monotonic())
        core.start_watchdog(0.005)
        assert core.bridge.set_grasp_force(10.0, time.monotonic()).accepted
        assert wait_until(lambda: abs(core.bridge.status(time.monotonic()).measured_grasp_force
                                      - 10.0) < 0.3)
        time.sleep(0.5)
        for stall in (0.06, 0.3):
            with rec.lock:
                n = len(rec.results)
            rec.stall_s = stall
            assert wait_until(lambda n=n: rec.stalled_at >= n)
            time.sleep(stall + 1.0)
            with rec.lock:
                after = rec.results[rec.stalled_at:]
            resumed = [r for r in after if r.status is not None]
            assert len(resumed) > 100  # telemetry kept flowing after the stall
            # The backlog of the stall was read at once: stepped once, no burst of commands.
            catch_up = [r for r in resumed[:200] if r.command is None]
            assert len(catch_up) >= 0.5 * stall / 0.002
            motors = [r.motor for r in after if r.motor is not None]
            assert max(m.force_cmd for m in motors) < 10.0 + 2.0  # no catch-up kick
            # During the injected stall (and the catch-up after it) the watchdog saw the
            # telemetry waiting: no safe voltage, no fault. (A stale event elsewhere would be
            # the emulator itself falling behind on a loaded host: a real gap.)
            start, end = rec.windows[-1]
            with rec.lock:
                inside = [k for t, k in rec.times if start <= t <= end + 0.02]
            assert 'stale' not in inside and 'fault' not in inside, rec.events
            first = next(m for m in motors if m.stamp >= end)
            assert first.voltage_cmd < -2.0  # the first command after the stall still squeezes
        diag = core.bridge.diagnostics(time.monotonic())
        assert diag.link_faults == 0 and diag.armed
        assert diag.host_stalls >= 2 and diag.max_host_stall_s >= 0.25
        assert 'fault' not in rec.kinds()
        stalls = [m for k, m in rec.events if k == 'host_stall']
        assert stalls and 'not disarmed' in stalls[-1] and 'nothing was written' in stalls[-1]
        assert abs(core.bridge.status(time.monotonic()).measured_grasp_force - 10.0) < 0.3
    finally:
        core.shutdown(time.monotonic())
        for client in clients:
            client.close()
        stats = emulator.stop()
    assert stats['malformed_commands'] == 0 and stats['nonfinite_commands'] == 0


def test_a_real_boot_silence_faults_reconnects_then_counts_the_firmware_restart(rig) -> None:
    """Issue 17 item 5: silent boot (longer than link.fault_after), only 'Voltage control',
    first angle not 0: the restart is still counted and reported as one."""
    emu, core, rec = rig
    core.configure()
    core.activate(time.monotonic())
    core.start_watchdog(0.005)
    assert wait_until(lambda: core.bridge.status(time.monotonic()).line_count > 50)
    emu.restart(silence_s=0.8)  # > fault_after 0.25 s: the link faults and reconnects first
    assert wait_until(lambda: 'firmware_restart' in rec.kinds())
    kinds = rec.kinds()
    assert kinds.index('fault') < kinds.index('firmware_restart')
    message = next(m for k, m in rec.events if k == 'firmware_restart')
    assert 'firmware restarted' in message and 'disarmed' in message
    diag = core.bridge.diagnostics(time.monotonic())
    assert diag.firmware_restarts == 1 and diag.reconnects >= 1 and not diag.armed
    assert wait_until(lambda: core.bridge.status(time.monotonic()).link_ok)
    status = core.bridge.status(time.monotonic())
    assert status.motor_angle != 0.0  # the alignment moved the rotor off the count origin
    with emu.lock:
        assert emu.emulator.malformed_commands == 0 and emu.emulator.nonfinite_commands == 0


def test_a_link_gap_is_logged_with_where_the_emulator_thread_was(tmp_path: Path) -> None:
    """A gap in the emulator's sends names its cause: here the thread waited (for the GIL,
    which one long C call in this process holds) instead of computing."""
    import random
    values = [random.random() for _ in range(3_000_000)]
    emu = PtyFirmwareEmulator(FirmwareEmulator(), link_path=str(tmp_path / 'gripper'))
    emu.start()
    try:
        time.sleep(0.2)
        values.sort()                       # one C call: the GIL is not released meanwhile
        time.sleep(0.2)
    finally:
        emu.stop()
    assert emu.long_gaps >= 1 and emu.gap_log, (emu.long_gaps, emu.max_send_gap_s)
    gap = emu.gap_log[0]
    assert gap.gap_s == pytest.approx(emu.max_send_gap_s)
    assert gap.cpu_s < 0.5 * gap.gap_s, gap          # not computing: waiting
    assert gap.voluntary_switches >= 1, gap
    # The record accounts for the time: the GIL wait ends in whichever call released the GIL
    # (the sleep until a tick, the pty write, a /proc read of the record itself).
    accounted = gap.overslept_s + gap.read_s + gap.tick_s + gap.write_s + gap.clock_s
    assert accounted > 0.8 * gap.gap_s, gap
