# SPDX-License-Identifier: Apache-2.0
"""Identify handshake and calibration upload, against the firmware emulator in virtual time."""
from __future__ import annotations

from pathlib import Path

import pytest

from slip_velocity_sensor.core import calibration as cal_mod
from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.emulator import EmulatorParams, FirmwareEmulator
from slip_velocity_sensor.core.handshake import (Handshake, HandshakeFailure, HandshakeParams,
                                                 HandshakeState)
from slip_velocity_sensor.core.protocol import (BootLine, NameLine, ProductIdLine, ResyncLine,
                                                VelocityLine)

CONFIG = Path(__file__).resolve().parents[1] / 'config'
PORT = '/dev/serial/by-id/usb-Silicon_Labs_CP2102N-if00-port0'


def _init_commands(term: str = 'signed_compat') -> list[bytes]:
    cal = cal_mod.load_calibration(CONFIG / 'calibration_sensor_1.yaml')
    return cal_mod.upload_commands(cal, term) + [protocol.chip_mode_command(0)]


def test_identify_upload_with_spacing(clock, virtual_stream, drive_handshake) -> None:
    emulator = FirmwareEmulator(EmulatorParams(name='sensor_1'))
    commands = _init_commands()
    hs = Handshake('sensor_1', HandshakeParams(timeout=2.0, retries=3), init_commands=commands,
                   command_spacing=0.010, port=PORT)
    written = drive_handshake(hs, virtual_stream(emulator))
    assert hs.state is HandshakeState.DONE and hs.error is None
    assert [c for _, c in written] == [b'n\n'] + commands
    gaps = [b[0] - a[0] for a, b in zip(written, written[1:])]
    assert min(gaps) >= 0.010 - 1e-12
    result = hs.result
    assert result is not None and result.name == 'sensor_1' and result.attempts == 1
    assert result.init_commands == 14 and result.commands_sent == 15
    assert result.finished - result.started < 1.0
    # Every command reached the device (at most one per 8.3 ms loop, none lost).
    assert [c for _, c in emulator.received] == [c.rstrip(b'\n') for _, c in written]
    device = emulator.device_calibration()
    expected = cal_mod.load_calibration(CONFIG / 'calibration_sensor_1.yaml')
    assert device.radius == pytest.approx(0.0243)
    for chip in (1, 2, 3):
        for axis in ('x', 'y'):
            assert device.axis(chip, axis).a == pytest.approx(expected.axis(chip, axis).a)
            assert device.axis(chip, axis).b == pytest.approx(expected.axis(chip, axis).b)


def test_resynch_reply_waits_for_the_resync_and_asks_again(clock, virtual_stream,
                                                           drive_handshake) -> None:
    emulator = FirmwareEmulator(EmulatorParams(resync_on_identify=1, resync_duration=0.05))
    hs = Handshake('sensor_1', HandshakeParams(timeout=1.0, retries=3),
                   init_commands=_init_commands('zero'), port=PORT)
    written = drive_handshake(hs, virtual_stream(emulator))
    assert hs.state is HandshakeState.DONE, hs.error
    assert hs.result is not None and hs.result.resyncs == 1 and hs.result.attempts == 2
    n_times = [t for t, c in written if c == b'n\n']
    assert len(n_times) == 2
    # Asked again right after the re-sync finished, not after a full timeout.
    assert 0.05 <= n_times[1] - n_times[0] < 0.2


def test_a_sensor_that_keeps_resyncing_fails_with_a_clear_error(clock, virtual_stream,
                                                                drive_handshake) -> None:
    emulator = FirmwareEmulator(EmulatorParams(resync_on_identify=100))
    hs = Handshake('sensor_1', HandshakeParams(timeout=1.0, retries=3), port=PORT)
    start = clock()
    drive_handshake(hs, virtual_stream(emulator))
    assert hs.state is HandshakeState.FAILED and hs.error is not None
    assert hs.error.reason is HandshakeFailure.RESYNC_LOOP
    assert PORT in str(hs.error) and 're-sync' in str(hs.error)
    assert clock() - start < 3.0


def test_silent_port_times_out_after_the_retries_with_a_clear_error(clock, virtual_stream,
                                                                    drive_handshake) -> None:
    emulator = FirmwareEmulator(EmulatorParams())
    emulator.set_silent(True)
    hs = Handshake('sensor_1', HandshakeParams(timeout=2.0, retries=3), port=PORT)
    start = clock()
    written = drive_handshake(hs, virtual_stream(emulator), max_time=60.0)
    elapsed = clock() - start
    assert hs.state is HandshakeState.FAILED
    assert hs.error is not None and hs.error.reason is HandshakeFailure.NO_ANSWER
    message = str(hs.error)
    assert PORT in message and 'no answer' in message and '3 attempt' in message
    assert [c for _, c in written] == [b'n\n'] * 3
    assert 6.0 <= elapsed < 6.1  # 3 attempts × 2 s, then stop: never hangs


def test_data_without_a_name_reply_is_reported_as_such() -> None:
    hs = Handshake('sensor_1', HandshakeParams(timeout=0.5, retries=2), port=PORT)
    hs.start(0.0)
    t = 0.0
    while not hs.done and t < 5.0:
        hs.step(t, [VelocityLine(0.0, 0.0, 0.0)])
        t += 0.01
    assert hs.error is not None and hs.error.reason is HandshakeFailure.NO_NAME
    assert 'velocity' in str(hs.error) and 'baud' in str(hs.error)
    assert 0.99 <= t <= 1.02


def test_another_name_fails_at_once(clock, virtual_stream, drive_handshake) -> None:
    emulator = FirmwareEmulator(EmulatorParams(name='sensor_2'))
    hs = Handshake('sensor_1', HandshakeParams(timeout=2.0, retries=3), port=PORT)
    start = clock()
    drive_handshake(hs, virtual_stream(emulator))
    assert hs.error is not None and hs.error.reason is HandshakeFailure.WRONG_NAME
    assert hs.error.name == 'sensor_2' and "'sensor_2'" in str(hs.error) and PORT in str(hs.error)
    assert clock() - start < 0.1


def test_any_name_mode_reports_the_answered_name(clock, virtual_stream, drive_handshake) -> None:
    hs = Handshake('', port=PORT)
    drive_handshake(hs, virtual_stream(FirmwareEmulator(EmulatorParams(name='sensor_2'))))
    assert hs.result is not None and hs.result.name == 'sensor_2'


def test_board_restart_during_the_upload_restarts_the_handshake() -> None:
    commands = _init_commands()
    hs = Handshake('sensor_1', HandshakeParams(timeout=1.0, retries=3), init_commands=commands)
    hs.start(0.0)
    sent = hs.poll(0.0)
    hs.on_line(0.005, NameLine('sensor_1'))
    t = 0.005
    while len(sent) < 5:
        t += 0.011
        sent += hs.poll(t)
    hs.on_line(t, BootLine('ESP-ROM:esp32s3'))
    assert hs.state is HandshakeState.WAITING_BOOT and hs.poll(t + 0.5) == []
    hs.on_line(t + 0.6, VelocityLine(0.0, 0.0, 0.0))   # the firmware runs again
    assert hs.poll(t + 0.6) == [b'n\n'] and hs.attempt == 2
    hs.on_line(t + 0.61, NameLine('sensor_1'))
    resent = []
    t += 0.61
    while not hs.done:
        t += 0.011
        resent += hs.poll(t)
    assert resent == commands  # the whole upload again, from the radius on


def test_resync_state_machine_details() -> None:
    """The firmware prints notice + IDs before every re-sync pass and no end line: the
    handshake asks again only after a velocity line that followed a period free of notices;
    the ID line is not an end marker."""
    zero = VelocityLine(0.0, 0.0, 0.0)
    hs = Handshake('sensor_1', HandshakeParams(timeout=1.0, retries=2))
    hs.start(0.0)
    assert hs.poll(0.0) == [b'n\n']
    hs.on_line(0.01, ResyncLine())
    hs.on_line(0.01, ProductIdLine((0, 0x31, 0x31)))
    assert hs.state is HandshakeState.WAITING_RESYNC and hs.poll(0.5) == []
    for k in range(5):                                # still out: notices every pass
        hs.on_line(0.014 + 0.007 * k, zero)
        hs.on_line(0.016 + 0.007 * k, ResyncLine())
        hs.on_line(0.016 + 0.007 * k, ProductIdLine((0, 0x31, 0x31)))
        assert hs.state is HandshakeState.WAITING_RESYNC and hs.attempt == 1
    hs.on_line(0.06, zero)                            # covers the last re-sync
    hs.on_line(0.067, zero)                           # a clean period ...
    assert hs.state is HandshakeState.WAITING_RESYNC
    hs.on_line(0.074, zero)                           # ... followed by a line: ask again
    assert hs.poll(0.074) == [b'n\n'] and hs.attempt == 2
    hs.on_line(0.08, ResyncLine())
    for k in range(3):
        hs.on_line(0.085 + 0.007 * k, zero)           # no attempt left
    assert hs.error is not None and hs.error.reason is HandshakeFailure.RESYNC_LOOP


def test_a_name_reply_during_a_resync_is_accepted() -> None:
    """The serial task answers "n" while the sensor task re-syncs a chip."""
    hs = Handshake('sensor_1', HandshakeParams(timeout=1.0, retries=1),
                   init_commands=[b'c0\n'])
    hs.start(0.0)
    assert hs.poll(0.0) == [b'n\n']
    hs.on_line(0.002, ResyncLine())
    hs.on_line(0.002, ProductIdLine((-1, 0x31, 0x31)))
    hs.on_line(0.007, NameLine('sensor_1'))
    assert hs.state is HandshakeState.UPLOADING and hs.poll(0.02) == [b'c0\n']
    hs.on_line(0.03, ResyncLine())                    # the chip stays out: upload goes on
    hs.poll(0.04)
    assert hs.state is HandshakeState.DONE and hs.result is not None
    assert hs.result.resyncs == 1


def test_link_failure_and_wait_hint() -> None:
    hs = Handshake('sensor_1', HandshakeParams(timeout=2.0, retries=1), command_spacing=0.01)
    assert hs.wait_hint(0.0) == 0.0
    hs.start(10.0)
    assert hs.wait_hint(10.0) == 0.0          # the identify command is due now
    hs.poll(10.0)
    assert hs.wait_hint(10.5) == pytest.approx(1.5)
    hs.link_failed('/dev/ttyUSB0: device disconnected')
    assert hs.error is not None and hs.error.reason is HandshakeFailure.LINK_ERROR
    assert '/dev/ttyUSB0' in str(hs.error) and hs.poll(11.0) == []
