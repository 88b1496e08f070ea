# SPDX-License-Identifier: Apache-2.0
"""Gripper ASCII protocol: telemetry parser (golden lines, 1e5-line fuzz) and command codec."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from slip_gripper_driver.core.firmware_emulator import atof
from slip_cell_common.core.param_schema import ParameterError
from slip_gripper_driver.core.protocol import (ActuatorParams, CommandError, LineKind,
                                               TelemetryParser, command_voltage,
                                               encode_force_command, force_to_voltage,
                                               format_voltage_command, voltage_to_force)
from slip_cell_common.core.serial_transport import LineReader

NPV = 3.9166


@pytest.mark.parametrize('line, kind, angle, detail', [
    (b'3.1416', LineKind.TELEMETRY, 3.1416, 'angle'),
    (b'-12.0000', LineKind.TELEMETRY, -12.0, 'angle'),
    (b'0.0000', LineKind.TELEMETRY, 0.0, 'angle'),
    (b' 1.2345\t', LineKind.TELEMETRY, 1.2345, 'angle'),
    (b'99999.9999', LineKind.TELEMETRY, 99999.9999, 'angle'),
    (b'3.14', LineKind.BAD, math.nan, 'malformed_number'),
    (b'416', LineKind.BAD, math.nan, 'malformed_number'),
    (b'.1416', LineKind.BAD, math.nan, 'malformed_number'),
    (b'1e3', LineKind.BAD, math.nan, 'malformed_number'),
    (b'123456.0000', LineKind.BAD, math.nan, 'malformed_number'),
    (b'nan', LineKind.BAD, math.nan, 'non_finite'),
    (b'-inf', LineKind.BAD, math.nan, 'non_finite'),
    (b'Infinity', LineKind.BAD, math.nan, 'non_finite'),
    (b'NaN', LineKind.BAD, math.nan, 'non_finite'),
    (b'3.1\x0016', LineKind.BAD, math.nan, 'binary'),
    (b'\xff\xfe', LineKind.BAD, math.nan, 'binary'),
    (b'Voltage control', LineKind.UNKNOWN, math.nan, 'restart'),
    (b'MOT: Init', LineKind.UNKNOWN, math.nan, 'restart'),
    (b'Too long in read', LineKind.UNKNOWN, math.nan, 'firmware_rejected'),
    (b'Too long', LineKind.UNKNOWN, math.nan, 'firmware_rejected'),
    (b'hello', LineKind.UNKNOWN, math.nan, 'text'),
    (b'T-2.55', LineKind.UNKNOWN, math.nan, 'text'),
])
def test_golden_lines(line: bytes, kind: LineKind, angle: float, detail: str) -> None:
    parser = TelemetryParser()
    parsed = parser.parse(line)
    assert parsed.kind == kind
    assert parsed.detail == detail
    if kind == LineKind.TELEMETRY:
        assert parsed.angle_rad == pytest.approx(angle, abs=1e-9)
    else:
        assert math.isnan(parsed.angle_rad)
    c = parser.counters()
    assert c.total == 1
    assert (c.good, c.bad, c.unknown) == (kind == LineKind.TELEMETRY, kind == LineKind.BAD,
                                          kind == LineKind.UNKNOWN)


def test_overflow_line_is_bad_and_counted() -> None:
    parser = TelemetryParser()
    parsed = parser.parse(b'1.0000', overflow=True)
    assert parsed.kind == LineKind.BAD and parsed.detail == 'too_long'
    assert parser.counters().too_long == 1


_ORACLE = re.compile(r'-?[0-9]{1,5}\.[0-9]{4}')


def _fuzz_lines(rng: np.random.Generator, n: int, max_len: int) -> list[tuple[bytes, str]]:
    """Random lines with the category they were built as."""
    debug = [b'Voltage control', b'Too long in read', b'Too long', b'MOT: Align sensor.',
             b'ESP-ROM:esp32s3-20210327', b'random debug text']
    # no 'a'/'f': random text can then never spell nan or inf(inity)
    letters = np.frombuffer(b'bcdeghijklmnopqrstuvwxyzBCDEGHIJKLMNOPQRSTUVWXYZ :_-+/',
                            np.uint8)
    out: list[tuple[bytes, str]] = []
    for _ in range(n):
        cat = int(rng.integers(0, 8))
        if cat == 0:
            value = float(rng.uniform(-1000.0, 1000.0))
            out.append((f'{value:.4f}'.encode(), 'good'))
        elif cat == 1:
            raw = rng.integers(0, 256, size=int(rng.integers(1, 40)), dtype=np.uint8).tobytes()
            raw = raw.replace(b'\r', b'').replace(b'\n', b'')
            if raw:
                out.append((raw, 'random'))
        elif cat == 2:
            text = rng.choice(letters, size=int(rng.integers(1, 30))).tobytes()
            out.append((text, 'text'))
        elif cat == 3:
            digits = int(rng.choice([0, 1, 2, 3, 5, 6]))
            out.append((f'{float(rng.normal(0, 50)):.{digits}f}'.encode(), 'malformed'))
        elif cat == 4:
            word = [b'nan', b'NaN', b'inf', b'-inf', b'+inf', b'Infinity', b'-nan'][
                int(rng.integers(0, 7))]
            out.append((word, 'non_finite'))
        elif cat == 5:
            out.append((debug[int(rng.integers(0, len(debug)))], 'debug'))
        elif cat == 6:
            length = int(rng.integers(max_len + 1, 4 * max_len))
            out.append((b'7' * length, 'too_long'))
        else:
            # the tail of a cut angle line; the oracle decides ('-12.3456' → '12.3456' is valid)
            text = f'{float(rng.uniform(-100, 100)):.4f}'.encode()
            cut = int(rng.integers(1, len(text) - 1))
            out.append((text[cut:], 'fragment'))
    return out


def test_fuzz_1e5_lines_through_reader_and_parser() -> None:
    rng = np.random.default_rng(0)
    max_len = 48
    lines = _fuzz_lines(rng, 120_000, max_len)
    terminators = [b'\r\n', b'\n', b'\r', b'\r\n\r\n']
    stream = b''.join(line + terminators[int(rng.integers(0, 4))] for line, _ in lines)
    reader = LineReader(max_line_length=max_len, resync=False)
    parser = TelemetryParser()
    got = []
    pos = 0
    while pos < len(stream):  # random chunking, as a serial port delivers bytes
        step = int(rng.integers(1, 64))
        for raw, overflow in reader.feed(stream[pos:pos + step]):
            got.append(parser.parse(raw, overflow))
        pos += step

    assert len(got) == len(lines) >= 100_000
    c = parser.counters()
    assert c.total == c.good + c.bad + c.unknown == len(lines)
    expected_good = 0
    for (raw, cat), parsed in zip(lines, got):
        body = raw.strip(b' \t')
        is_angle = cat != 'too_long' and _ORACLE.fullmatch(body.decode('latin-1')) is not None
        assert (parsed.kind == LineKind.TELEMETRY) == is_angle, (raw, cat, parsed)
        if is_angle:
            expected_good += 1
            assert parsed.angle_rad == float(body)
        if cat == 'too_long':
            assert parsed.detail == 'too_long'
        if cat == 'non_finite':
            assert parsed.detail == 'non_finite'
        if cat == 'malformed':
            assert parsed.kind == LineKind.BAD
        if cat in ('text', 'debug'):
            assert parsed.kind == LineKind.UNKNOWN
    assert c.good == expected_good
    assert c.too_long == sum(cat == 'too_long' for _, cat in lines)
    assert c.non_finite == sum(cat == 'non_finite' for _, cat in lines)
    assert c.non_finite > 1000 and c.too_long > 1000 and c.good > 10_000


_CMD = re.compile(rb'T-?[0-9]{1,2}\.[0-9]{2}\n')


def test_command_format_examples() -> None:
    assert format_voltage_command(-2.55, 20.0) == b'T-2.55\n'
    assert format_voltage_command(0.0, 20.0) == b'T0.00\n'
    assert format_voltage_command(-0.0, 20.0) == b'T0.00\n'
    assert format_voltage_command(-0.004, 20.0) == b'T0.00\n'
    assert format_voltage_command(-25.0, 20.0) == b'T-20.00\n'
    assert format_voltage_command(1e300, 11.5) == b'T11.50\n'
    assert command_voltage(b'T-2.55\n') == -2.55


@pytest.mark.parametrize('bad', [math.nan, math.inf, -math.inf])
def test_command_rejects_non_finite(bad: float) -> None:
    with pytest.raises(CommandError):
        format_voltage_command(bad, 20.0)
    with pytest.raises(CommandError):
        encode_force_command(bad, newton_per_volt=NPV, max_close_force_n=45.0,
                             max_open_force_n=8.0, voltage_limit_v=20.0)


@pytest.mark.parametrize('limit', [0.0, -1.0, math.nan, 100.0])
def test_command_rejects_bad_limit(limit: float) -> None:
    with pytest.raises(CommandError):
        format_voltage_command(1.0, limit)


def test_random_commands_always_wellformed_and_read_back_exactly_by_firmware_atof() -> None:
    rng = np.random.default_rng(0)
    values = np.concatenate([rng.normal(0, 10, 20000), rng.uniform(-1e6, 1e6, 2000),
                             [5e-324, -5e-324, 1e-3, -1e-3, 0.005, -0.005, 19.999, -19.995]])
    for v in values:
        for limit in (20.0, 11.5):
            cmd = format_voltage_command(float(v), limit)
            assert _CMD.fullmatch(cmd) and len(cmd) <= 8
            sent = command_voltage(cmd)
            expected = round(min(max(float(v), -limit), limit), 2)
            assert sent == pytest.approx(expected, abs=0.0051)
            assert abs(sent) <= limit + 0.005
            # what the firmware applies equals what we meant: never an accidental 0 V
            assert atof(cmd[1:-1].decode()) == sent
            if abs(expected) >= 0.01:
                assert sent != 0.0


def test_force_command_clips_force_ceiling_before_voltage_limit() -> None:
    kw = dict(newton_per_volt=NPV, max_close_force_n=45.0, max_open_force_n=8.0)
    cmd, v = encode_force_command(100.0, voltage_limit_v=20.0, **kw)
    assert v == pytest.approx(-45.0 / NPV, abs=0.006) and cmd == b'T-11.49\n'
    cmd, v = encode_force_command(100.0, voltage_limit_v=5.0, **kw)
    assert cmd == b'T-5.00\n'
    cmd, v = encode_force_command(-20.0, voltage_limit_v=20.0, **kw)
    assert v == pytest.approx(8.0 / NPV, abs=0.006)
    cmd, v = encode_force_command(10.0, voltage_limit_v=20.0, **kw)
    assert cmd == b'T-2.55\n'


def test_force_voltage_conversion_round_trip() -> None:
    assert force_to_voltage(15.6664, NPV) == pytest.approx(-4.0)
    assert voltage_to_force(-4.0, NPV) == pytest.approx(15.6664)
    assert voltage_to_force(force_to_voltage(7.3, NPV), NPV) == pytest.approx(7.3)


def test_actuator_params_validate() -> None:
    ActuatorParams().validate()
    with pytest.raises(ParameterError, match='voltage_limit'):
        ActuatorParams(voltage_limit=30.0).validate()
    with pytest.raises(ParameterError, match='safe_voltage'):
        ActuatorParams(voltage_limit=1.0, safe_voltage=1.5).validate()
