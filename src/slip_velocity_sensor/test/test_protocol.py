# SPDX-License-Identifier: Apache-2.0
"""Line parser, splitter and command formatting of the velocity-sensor protocol."""
from __future__ import annotations

import math

import numpy as np
import pytest

from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.protocol import (BadLine, BootLine, LineParser, LineSplitter,
                                                NameLine, ProductIdLine, ProtocolLimits,
                                                ResyncLine, TextLine, VelocityLine)


# --------------------------------------------------------------------------- golden lines

@pytest.mark.parametrize('line, expected', [
    (b'v/t12.3456/t-0.8000/t0.0131\r', (0.0123456, -0.0008, 0.0131)),  # spec example
    (b'v/t0.0000/t0.0000/t0.0000', (0.0, 0.0, 0.0)),
    (b'v/t-0.0000/t-0.9525/t-1.2500\r', (0.0, -0.0009525, -1.25)),
    (b'v/t550.0000/t-550.0000/t25.0000\r', (0.55, -0.55, 25.0)),
    (b'v/t1234.5678/t10.0000/t-99.9999\r', (1.2345678, 0.01, -99.9999)),
])
def test_golden_velocity_lines_convert_mm_s_to_si(line: bytes, expected: tuple) -> None:
    parser = LineParser()
    parsed = parser.parse(line)
    assert isinstance(parsed, VelocityLine)
    assert (parsed.vx, parsed.vy, parsed.omega) == pytest.approx(expected, abs=1e-12)
    assert parser.counters.velocity == 1 and parser.counters.good == 1


@pytest.mark.parametrize('line, kind', [
    (b'n/tsensor_1\r', NameLine),
    (b'n/tsensor_2', NameLine),
    (b'n/tresynch\r', ResyncLine),
    (b'resynch\r', ResyncLine),
    (b'0 49 49\r', ProductIdLine),
    (b'-1 49 49\r', ProductIdLine),
    (b'49 49 -1', ProductIdLine),
    (b'49/t49/t49', TextLine),            # not the firmware's format
    (b'0x31 0x31 0x00', TextLine),
    (b'radius is updated to: 24.30\r', TextLine),
    (b'a in filter updated to: 0.000310', TextLine),
    (b'Chip 2 prodid: 0', TextLine),
    (b'ESP-ROM:esp32s3-20210327\r', BootLine),
    (b'rst:0x1 (POWERON),boot:0x8 (SPI_FAST_FLASH_BOOT)', BootLine),
    (b'', TextLine),
])
def test_golden_other_lines(line: bytes, kind: type) -> None:
    assert isinstance(LineParser().parse(line), kind)


def test_name_and_product_id_values() -> None:
    parser = LineParser()
    assert parser.parse(b'n/tsensor_2\r') == NameLine('sensor_2')
    # Signed, as the firmware prints them: 0 = data line low, -1 = data line pulled high.
    assert parser.parse(b'0 49 49\r') == ProductIdLine((0, 0x31, 0x31))
    assert parser.parse(b'-1 49 49') == ProductIdLine((-1, 0x31, 0x31))
    assert parser.parse(b'49 -1 0') == ProductIdLine((0x31, -1, 0))
    assert parser.counters.product_ids == 3


# --------------------------------------------------------------------------- bad input

@pytest.mark.parametrize('line', [
    b'v\t12.3456\t-0.8000\t0.0131',      # TAB separator (the classic misreading of "/t")
    b'v/ t12.3456/ t-0.8000/ t0.0131',   # slash-space-t
    b'v 12.3456 -0.8000 0.0131',         # spaces
    b'v,12.3456,-0.8000,0.0131',
    b'v/t12.3456/t-0.8000',              # missing field
    b'v/t12.3456/t-0.8000/t0.0131/t1.0',  # extra field
    b'v/t12.3456/t/t0.0131',             # empty field
    b'v/t12.34.56/t-0.8000/t0.0131',
    b'v/t1e3/t0.0000/t0.0000',           # firmware never prints exponents
    b'v/t 1.0/t2.0/t3.0',
    b'v/t1.0/t2.0/t3.0 ',
    b'n\tsensor_1',
    b'n/t',
    b'n/tsensor 1',
    b'v/t12.3\xff/t0/t0',
    b'v/t1.0/t2.0/t3.0\x00',
])
def test_wrong_separators_and_malformed_records_are_bad(line: bytes) -> None:
    parser = LineParser()
    parsed = parser.parse(line)
    assert isinstance(parsed, BadLine), parsed
    assert parser.counters.bad == 1 and parser.counters.good == 0


@pytest.mark.parametrize('field', [b'nan', b'NaN', b'-nan', b'inf', b'-inf', b'ovf', b'Infinity'])
@pytest.mark.parametrize('position', [0, 1, 2])
def test_nan_inf_and_overflow_values_are_rejected(field: bytes, position: int) -> None:
    fields = [b'1.0000', b'2.0000', b'0.0100']
    fields[position] = field
    parsed = LineParser().parse(b'v/t' + b'/t'.join(fields) + b'\r')
    assert isinstance(parsed, BadLine)


def test_huge_digit_strings_and_implausible_speeds_are_rejected() -> None:
    parser = LineParser(ProtocolLimits(max_speed=2.0, max_omega=100.0))
    zeros = b'/t0.0000/t0.0000'
    overlong = parser.parse(b'v/t' + b'9' * 400 + b'.0000' + zeros)
    assert isinstance(overlong, BadLine) and overlong.reason == 'overlong line'
    for line in (b'v/t' + b'9' * 60 + b'.0000' + zeros, b'v/t2000.0001' + zeros,
                 b'v/t0.0000/t0.0000/t100.5000'):
        parsed = parser.parse(line)
        assert isinstance(parsed, BadLine) and parsed.reason == 'implausible velocity', line
    assert isinstance(parser.parse(b'v/t2000.0000/t-2000.0000/t100.0000'), VelocityLine)


#: Numbers a corrupted line can carry that are not in the firmware's format (Arduino
#: ``print(value, 4)``: ``-?<digits>.<4 digits>``). Accepting them gave values off by up to 10×.
MALFORMED_NUMBERS = [
    '12.345',       # a decimal lost
    '12.34567',     # a decimal gained
    '123.456',      # the point moved right (10× too large, 3 decimals)
    '1.23456',      # the point moved left (10× too small, 5 decimals)
    '123456',       # the point lost
    '12.3.456',     # a second point
    '12.',          # no decimals
    '.3456',        # no integer part
    '-.3456',
    '+12.3456',     # the firmware never prints a plus
    '012.3456',     # nor leading zeros
    '-00.1000',
    '00.0000',
    '1e3',          # nor exponents
    '1.2345e3',
    '12,3456',      # decimal comma
    '--1.0000',
    '-',
    '.',
    '',
    ' 1.0000',
    '1.0000 ',
    '1_0.0000',
    '0x1.0000',
    'nan', 'inf', 'ovf',
]


@pytest.mark.parametrize('number', MALFORMED_NUMBERS)
@pytest.mark.parametrize('position', [0, 1, 2])
def test_numbers_without_the_firmware_format_are_rejected(number: str, position: int) -> None:
    fields = ['12.3456', '-0.8000', '0.0131']
    fields[position] = number
    parser = LineParser()
    parsed = parser.parse(('v/t' + '/t'.join(fields) + '\r').encode())
    assert isinstance(parsed, BadLine), (number, parsed)
    assert parser.counters.velocity == 0 and parser.counters.bad == 1


def test_property_format_mutations_never_pass_as_values() -> None:
    """Seeded property check: for random firmware-formatted values, every single-character
    deletion at or after the point, digit insertion in the fraction and shift of the point is
    rejected, and the intact line parses to exactly the printed value."""
    rng = np.random.default_rng(16)
    parser = LineParser()
    for value in rng.normal(0.0, 300.0, 300):
        text = f'{value:.4f}'
        line = f'v/t{text}/t0.0000/t0.0000'.encode()
        parsed = parser.parse(line)
        assert isinstance(parsed, VelocityLine) and parsed.vx == float(text) / 1000.0
        point = text.index('.')
        lost = [text[:pos] + text[pos + 1:] for pos in range(point, len(text))]
        gained = [text[:pos] + d + text[pos:] for pos in range(point + 1, len(text) + 1)
                  for d in '059']
        moved = [text[:point] + text[point + 1:pos] + '.' + text[pos:]
                 for pos in range(point + 2, len(text) + 1)]     # the point shifted right
        for m in lost + gained + moved:
            bad = parser.parse(f'v/t{m}/t0.0000/t0.0000'.encode())
            assert isinstance(bad, BadLine), (text, m)


def test_overflowed_line_from_the_reader_is_bad() -> None:
    parser = LineParser()
    assert isinstance(parser.parse(b'v/t1.0/t2.0/t3.0', overflow=True), BadLine)


# --------------------------------------------------------------------------- splitting

def test_partial_lines_are_joined_across_reads() -> None:
    splitter = LineSplitter()
    stream = b'v/t12.3456/t-0.8000/t0.0131\r\nn/tsensor_1\r\nv/t1.0000/t2.0000/t3.0000\r\n'
    lines = []
    for i in range(len(stream)):  # one byte at a time: worst case
        lines += splitter.feed(stream[i:i + 1])
    assert [line for line, _ in lines] == [b'v/t12.3456/t-0.8000/t0.0131\r', b'n/tsensor_1\r',
                                           b'v/t1.0000/t2.0000/t3.0000\r']
    assert splitter.pending == b''
    assert splitter.feed(b'v/t1.0') == [] and splitter.pending == b'v/t1.0'
    assert splitter.feed(b'000/t2/t3\r\n') == [(b'v/t1.0000/t2/t3\r', False)]


def test_a_line_truncated_at_the_start_of_a_stream_is_not_a_velocity() -> None:
    parser = LineParser()
    lines = LineSplitter().feed(b'2.3456/t-0.8000/t0.0131\r\nv/t1.0000/t2.0000/t3.0000\r\n')
    parsed = [parser.parse(line, ov) for line, ov in lines]
    assert not isinstance(parsed[0], VelocityLine)
    assert isinstance(parsed[1], VelocityLine)


def test_overlong_garbage_is_cut_once_and_memory_stays_bounded() -> None:
    splitter = LineSplitter(max_line_bytes=32)
    assert splitter.feed(b'x' * 1000) == [] and len(splitter.pending) == 32
    assert splitter.feed(b'y' * 100_000) == [] and len(splitter.pending) == 32
    assert splitter.feed(b'tail\nv/t1/t2/t3\n') == [(b'x' * 32, True), (b'v/t1/t2/t3', False)]


# --------------------------------------------------------------------------- fuzz

def _fuzz_stream(rng: np.random.Generator, n_lines: int) -> bytes:
    """Valid, mutated and random lines, as one byte stream."""
    chunks = []
    for _ in range(n_lines):
        kind = rng.integers(0, 6)
        if kind <= 1:
            vals = rng.normal(0.0, 200.0, 3)
            line = f'v/t{vals[0]:.4f}/t{vals[1]:.4f}/t{vals[2] / 50:.4f}\r\n'.encode()
        elif kind == 2:
            line = rng.choice([b'n/tsensor_1\r\n', b'n/tresynch\r\n', b'0 49 49\r\n',
                               b'radius is updated to: 24.30\r\n', b'\r\n'])
        elif kind == 3:  # mutate a valid line: flip, drop or insert bytes
            line = bytearray(b'v/t12.3456/t-0.8000/t0.0131\r\n')
            for _ in range(rng.integers(1, 4)):
                pos = int(rng.integers(0, len(line)))
                op = rng.integers(0, 3)
                if op == 0:
                    line[pos] = int(rng.integers(0, 256))
                elif op == 1:
                    del line[pos]
                else:
                    line.insert(pos, int(rng.integers(0, 256)))
            line = bytes(line)
        elif kind == 4:
            line = bytes(rng.integers(32, 127, int(rng.integers(0, 60)), dtype=np.uint8)) + b'\n'
        else:
            line = bytes(rng.integers(0, 256, int(rng.integers(0, 300)), dtype=np.uint8))
        chunks.append(line)
    return b''.join(chunks)


def test_fuzz_1e5_lines_never_raise_and_counters_add_up() -> None:
    rng = np.random.default_rng(0)
    data = _fuzz_stream(rng, 120_000)
    limits = ProtocolLimits()
    splitter = LineSplitter(limits.max_line_bytes)
    parser = LineParser(limits)
    n_lines = 0
    kinds: dict[type, int] = {}
    pos = 0
    while pos < len(data):  # random chunking, like USB reads
        size = int(rng.integers(1, 200))
        for line, overflow in splitter.feed(data[pos:pos + size]):
            n_lines += 1
            parsed = parser.parse(line, overflow)
            kinds[type(parsed)] = kinds.get(type(parsed), 0) + 1
            if isinstance(parsed, VelocityLine):
                assert all(math.isfinite(v) for v in (parsed.vx, parsed.vy, parsed.omega))
                assert abs(parsed.vx) <= limits.max_speed and abs(parsed.vy) <= limits.max_speed
                assert abs(parsed.omega) <= limits.max_omega
                assert line.startswith(b'v/t') and b'\t' not in line
                fields = line.rstrip(b'\r')[3:].split(b'/t')
                assert all(len(f.split(b'.')[1]) == 4 for f in fields), line   # 4 decimals
        pos += size
    c = parser.counters
    assert n_lines >= 100_000
    assert c.total == n_lines
    assert c.good + c.bad + c.unknown + c.resync == n_lines
    assert c.velocity == kinds.get(VelocityLine, 0) and c.bad == kinds.get(BadLine, 0)
    assert c.resync == kinds.get(ResyncLine, 0) and c.name == kinds.get(NameLine, 0)
    # Every category was exercised, and most generated valid lines survived.
    assert min(c.velocity, c.bad, c.text, c.resync, c.name, c.product_ids) > 100
    assert c.velocity > 0.3 * n_lines


# --------------------------------------------------------------------------- commands

def test_command_formatting_in_device_units() -> None:
    assert protocol.identify_command() == b'n\n'
    assert [protocol.chip_mode_command(k) for k in range(4)] == [b'c0\n', b'c1\n', b'c2\n',
                                                                 b'c3\n']
    assert protocol.radius_command(0.0243) == b'k0024.3\n'           # spec example
    assert protocol.calibration_command(1, 'x', 'b', 0.8847) == b'k110.8847\n'  # spec example
    assert protocol.calibration_command(1, 'y', 'a', 0.31) == b'k120.00031\n'  # SI / 1000
    assert protocol.calibration_command(3, 'y', 'b', 0.9284) == b'k330.9284\n'
    assert protocol.calibration_command(2, 'x', 'a', 0.0) == b'k200\n'
    assert protocol.calibration_command(2, 'x', 'a', -0.5) == b'k20-0.0005\n'


@pytest.mark.parametrize('call', [
    lambda: protocol.chip_mode_command(4),
    lambda: protocol.chip_mode_command(-1),
    lambda: protocol.chip_mode_command(True),
    lambda: protocol.radius_command(0.0),
    lambda: protocol.radius_command(math.nan),
    lambda: protocol.calibration_command(0, 'x', 'a', 0.1),
    lambda: protocol.calibration_command(4, 'x', 'a', 0.1),
    lambda: protocol.calibration_command(1, 'z', 'a', 0.1),
    lambda: protocol.calibration_command(1, 'x', 'c', 0.1),
    lambda: protocol.calibration_command(1, 'x', 'b', 0.0),
    lambda: protocol.calibration_command(1, 'x', 'a', math.inf),
])
def test_invalid_commands_are_refused_before_reaching_the_device(call) -> None:
    with pytest.raises(ValueError):
        call()


def test_formatted_velocity_line_round_trips() -> None:
    line = protocol.format_velocity_line(12.34564, -0.8, 0.01314)
    assert line == b'v/t12.3456/t-0.8000/t0.0131\r\n'
    parsed = LineParser().parse(line.rstrip(b'\n'))
    assert parsed == VelocityLine(0.0123456, -0.0008, 0.0131)
