# SPDX-License-Identifier: Apache-2.0
"""Gripper firmware emulator: firmware parser semantics, the real firmware's boot and buffer
behaviour (hardware_protocols §2.2, §2.3, §8) and the finger/motor model."""
from __future__ import annotations

import math

import pytest

from slip_gripper_driver.core.firmware_emulator import (BOOT_LINE, EmulatedFirmwareStream,
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


def test_only_voltage_control_then_four_decimal_angle_lines_from_a_nonzero_angle() -> None:
    emu = FirmwareEmulator()
    lines = lines_of(emu, 5)
    assert lines[0].decode() == BOOT_LINE == 'Voltage control'  # no SimpleFOC init text
    parser = TelemetryParser()
    parsed = [parser.parse(line) for line in lines[1:]]
    assert [p.kind for p in parsed] == [LineKind.TELEMETRY] * 5
    assert parsed[0].angle_rad != 0.0  # the alignment left the rotor off the count origin
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
    emu.receive(b'Tnan\n')  # not rejected: the target becomes NaN
    assert math.isnan(emu.target_voltage_v) and emu.nonfinite_commands == 1
    emu.receive(b'Tinf\n')  # not rejected either: SimpleFOC's constrain clips it
    assert emu.target_voltage_v == 20.0 and emu.nonfinite_commands == 2
    assert emu.malformed_commands == 4  # garbage, T-30, Tnan, Tinf: not the host's T%.2f


def test_a_fragment_merges_with_the_next_command() -> None:
    emu = FirmwareEmulator(boot=False)
    emu.receive(b'T-2.')  # a host wrote half a command
    emu.receive(b'T0.00\n')
    assert emu.target_voltage_v == -2.0  # atof('-2.T0.00'): the 0 V command never applied
    assert emu.malformed_commands == 1
    emu.receive(b'\nT0.00\n')  # what the driver sends on connecting: flush, then command
    assert emu.target_voltage_v == 0.0 and emu.malformed_commands == 1


def test_too_long_at_exactly_20_characters_and_a_bare_newline_reruns_the_stale_buffer() -> None:
    emu = FirmwareEmulator(boot=False)
    emu.receive(b'T-3.0' + b'0' * 14)  # 19 characters: nothing yet
    assert emu.too_long_replies == 0
    emu.receive(b'0')  # the 20th
    assert emu.too_long_replies == 1 and b'Too long\r\n' in emu.tick()
    assert emu.target_voltage_v == 0.0
    emu.receive(b'\n')  # a bare newline acts on the stale 20 characters
    assert emu.target_voltage_v == -3.0 and emu.stale_reruns == 1
    emu.receive(b'T0.0' + b'0' * 16)
    emu.receive(b'T1.00\n')  # any other byte starts a new buffer: the stale one is gone
    assert emu.target_voltage_v == 1.0 and emu.stale_reruns == 1


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
    emu.restart(silence_s=0.01)
    assert emu.target_voltage_v == 0.0
    assert b'Voltage control' in b''.join(emu.tick() for _ in range(6))
    assert emu.angle_rad() != 0.0  # counted from the reset; the alignment moved the rotor


def test_reset_is_silent_for_the_boot_time_while_the_alignment_moves_the_fingers() -> None:
    params = GripperModelParams()
    emu = FirmwareEmulator(params, boot=False)
    emu.tick()
    x0 = emu.opening
    emu.restart()  # the real boot: 5.7 s
    emu.receive(b'\nT-1.00\n')  # written during the boot: parsed after it
    out = b''
    openings = []
    while emu.time_s < params.boot_time - 0.01:
        out += emu.tick()
        openings.append(emu.opening)
    assert out == b'' and emu.booting and emu.target_voltage_v == 0.0
    assert max(openings) - x0 == pytest.approx(params.align_amplitude, abs=1.5e-3)
    assert x0 - min(openings) == pytest.approx(params.align_amplitude, abs=1.5e-3)
    lines = lines_of(emu, 10)
    assert lines[0] == b'Voltage control' and not emu.booting
    assert emu.target_voltage_v == -1.0  # the queued command ran after the boot
    first = float(lines[1])
    assert first == pytest.approx(params.align_end_offset / params.opening_per_rad, abs=0.02)


def test_period_jitter_makes_lines_late_never_early() -> None:
    params = GripperModelParams(period_jitter=50e-6)
    emu = FirmwareEmulator(params, seed=3, boot=False)
    periods = []
    for _ in range(500):
        emu.tick()
        periods.append(emu.last_period_s)
    assert min(periods) >= params.period and max(periods) <= params.period + 50e-6
    assert max(periods) - min(periods) > 40e-6  # it varies


def test_emulated_stream_is_a_byte_stream() -> None:
    stream = EmulatedFirmwareStream(FirmwareEmulator(boot=False))
    assert isinstance(stream, ByteStream)
    data = stream.read(100)
    period = stream.emulator.params
    assert data.endswith(b'\r\n')
    assert period.period <= stream.now() <= period.period + period.period_jitter
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
