# SPDX-License-Identifier: Apache-2.0
"""Gripper firmware emulator: firmware parser semantics and the finger/motor model."""
from __future__ import annotations

import math

import pytest

from slip_gripper_driver.core.firmware_emulator import (BOOT_BANNER, EmulatedFirmwareStream,
                                                        FirmwareEmulator, GripperModelParams,
                                                        atof)
from slip_gripper_driver.core.protocol import LineKind, TelemetryParser
from slip_cell_common.core.serial_transport import ByteStream, LineReader


@pytest.mark.parametrize('text, value', [
    ('-2.55', -2.55), ('  4', 4.0), ('1e1x', 10.0), ('.5', 0.5), ('abc', 0.0), ('', 0.0),
    ('-', 0.0), ('1e', 1.0), ('+3.', 3.0), ('inf', math.inf), ('0x10', 0.0)])
def test_atof_semantics(text: str, value: float) -> None:
    assert atof(text) == value


def lines_of(emu: FirmwareEmulator, n: int) -> list[bytes]:
    reader = LineReader(resync=False)
    out: list[bytes] = []
    for _ in range(n):
        out += [line for line, _ in reader.feed(emu.tick())]
    return out


def test_boot_banner_then_four_decimal_angle_lines() -> None:
    emu = FirmwareEmulator()
    lines = lines_of(emu, 5)
    assert [line.decode() for line in lines[:len(BOOT_BANNER)]] == list(BOOT_BANNER)
    parser = TelemetryParser()
    kinds = [parser.parse(line).kind for line in lines[len(BOOT_BANNER):]]
    assert kinds == [LineKind.TELEMETRY] * 5
    assert parser.counters().restarts == 0  # banner parsed separately above


def test_command_parser_rules() -> None:
    emu = FirmwareEmulator(boot=False)
    emu.receive(b'T-2.5')
    assert emu.target_voltage_v == 0.0  # not applied before the newline
    emu.receive(b'5\n')
    assert emu.target_voltage_v == -2.55
    emu.receive(b'X1.00\n')  # not a T line: ignored
    assert emu.target_voltage_v == -2.55 and emu.ignored_lines == 1
    emu.receive(b'Tgarbage\n')  # atof → 0 V: the firmware releases the grasp
    assert emu.target_voltage_v == 0.0
    emu.receive(b'T-30\n')
    assert emu.target_voltage_v == -20.0  # firmware voltage_limit
    emu.receive(b'T' + b'1' * 25 + b'\n')
    assert emu.too_long_replies == 1 and b'Too long in read\r\n' in emu.tick()
    emu.receive(b'Tnan\n')
    assert emu.target_voltage_v == 0.0 and emu.nonfinite_commands == 1


def test_stall_force_on_object_equals_newton_per_volt() -> None:
    params = GripperModelParams(object_width=0.03, friction=0.0)
    emu = FirmwareEmulator(params, boot=False)
    emu.receive(b'T-4.00\n')
    for _ in range(2000):
        emu.tick()
    assert emu.grasp_force == pytest.approx(4.0 * params.newton_per_volt, rel=1e-3)
    assert emu.opening < 0.03


def test_voltage_ceiling_of_svpwm() -> None:
    params = GripperModelParams(object_width=0.03, friction=0.0)
    emu = FirmwareEmulator(params, boot=False)
    emu.receive(b'T-20.00\n')
    for _ in range(2000):
        emu.tick()
    assert emu.grasp_force == pytest.approx(params.max_phase_voltage * params.newton_per_volt,
                                            rel=1e-3)


def test_back_emf_limits_free_speed_and_stops_hold() -> None:
    params = GripperModelParams(friction=0.0, damping=0.0)
    emu = FirmwareEmulator(params, boot=False)
    emu.receive(b'T4.00\n')
    emu.tick()
    emu.tick()
    speed = emu.plant.rate
    assert speed == pytest.approx(4.0 / params.back_emf * params.opening_per_rad, rel=1e-6)
    for _ in range(1000):
        emu.tick()
    assert emu.opening == params.stroke  # open end stop
    emu.receive(b'T-4.00\n')
    for _ in range(2000):
        emu.tick()
    assert -1e-4 < emu.opening < 0.0  # closed stop: pads pressed together
    assert emu.grasp_force == pytest.approx(4.0 * params.newton_per_volt, rel=1e-3)


def test_angle_is_relative_to_restart_and_quantised() -> None:
    params = GripperModelParams()
    emu = FirmwareEmulator(params, boot=False)
    emu.receive(b'T3.00\n')
    for _ in range(100):
        emu.tick()
    count = 2 * math.pi / params.counts_per_rev
    angle = emu.angle_rad()
    assert angle > 0.5 and abs(angle / count - round(angle / count)) < 1e-9
    emu.restart()
    assert emu.angle_rad() == 0.0 and emu.target_voltage_v == 0.0
    assert b'Voltage control' in emu.tick()


def test_emulated_stream_is_a_byte_stream() -> None:
    stream = EmulatedFirmwareStream(FirmwareEmulator(boot=False))
    assert isinstance(stream, ByteStream)
    data = stream.read(100)
    assert data.endswith(b'\r\n') and stream.now() == pytest.approx(0.002)
    stream.write(b'T1.00\n')
    assert stream.emulator.target_voltage_v == 1.0
    stream.close()
    with pytest.raises(OSError):
        stream.read(1)


def test_console_entry_points_run(tmp_path, capsys) -> None:
    import json

    from slip_gripper_driver.core import firmware_emulator, netft_emulator
    link = str(tmp_path / 'gripper')
    assert firmware_emulator.main(['--link', link, '--duration', '0.2', '--stats-json',
                                   '--netft', '127.0.0.1:0', '--garbage-every', '10']) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert f'gripper firmware emulator on {link}' in out
    assert any(line.startswith('Net F/T emulator (finger 1) on 127.0.0.1:') for line in out)
    stats = json.loads(out[-1])
    assert stats['lines_sent'] > 10
    assert netft_emulator.main(['--port', '0', '--duration', '0.1', '--http']) == 0
    assert 'Net F/T emulator on 127.0.0.1:' in capsys.readouterr().out
