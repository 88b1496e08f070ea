# SPDX-License-Identifier: Apache-2.0
"""Line protocol of the optical velocity sensor (hardware_protocols §3.3), ROS-free.

Device → host, ASCII lines ending in ``\\r\\n``; the field separator is the two characters
``/t`` (slash, letter t), **not** a TAB:

* ``v/t<vx>/t<vy>/t<omega>``: velocity of the surface relative to the pad, vx and vy in mm/s,
  omega in rad/s, 4 decimals (sensor frame in fused mode, chip frame in single-chip mode).
* ``n/t<name>``: reply to ``n``.
* ``n/tresynch`` (a bare ``resynch`` is accepted too): a chip did not answer its product-ID
  read. The firmware prints it, then one line with the three product IDs as signed decimals
  separated by single spaces (``0 49 49``: chip 1 reads 0, data line low; ``-1 49 49``: data
  line pulled high; 49 = 0x31 is a healthy chip), and only then re-syncs. It repeats the pair
  on every sensor pass (about every 6 ms) while a chip stays out and prints nothing when the
  re-sync worked: the end of a re-sync is the absence of notices (`resync.ResyncTracker`).
* Anything else is free text (command replies, start-up notices, ESP32 boot banner).

Host → device: ``n`` (identify), ``c<k>`` (chip mode), ``k<i><j><value>`` (calibration).

This module is the only place that knows device units: parsed values leave it in SI
(m/s, rad/s) and command builders take SI arguments (m, 1/(m/s)) and format device units
(mm, 1/(mm/s)). Variables holding device units carry the unit in their name.

Numbers of a velocity line are accepted only in the firmware's exact format (Arduino
``print(value, 4)``): optional minus, integer digits without leading zeros, a point and exactly
four decimals (``12.3456``, ``-0.0000``). The link has no checksum, so a number that lost or
gained a digit (``12.345``, ``1.23456``, ``12.``) is a corrupted line, never a value.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Union

#: Field separator of the device (two characters, not a TAB).
SEPARATOR = '/t'
#: Millimetres per metre (device speeds are mm/s, radius in mm).
MM_PER_M = 1000.0
#: Number of chips on one sensor ring.
N_CHIPS = 3
#: Largest chip-mode argument of the ``c<k>`` command (0 = fused, 1..3 = single chip).
MAX_CHIP_MODE = N_CHIPS
#: Product ID register value of a healthy chip (PAW3204-compatible register 0x00).
EXPECTED_PRODUCT_ID = 0x31

#: A velocity field as the firmware prints it: ``-?<int>.<4 decimals>``, no exponent or sign +.
_NUMBER = re.compile(r'-?(?:0|[1-9][0-9]*)\.[0-9]{4}')
_NAME = re.compile(r'[A-Za-z0-9_.\-]{1,32}')
_ID = r'(-?[0-9]{1,3})'
#: The product-ID line after a re-sync notice: three signed decimals, single spaces.
_PRODUCT_IDS = re.compile(rf'{_ID} {_ID} {_ID}')
_BOOT_BANNER = re.compile(r'(?:ESP-ROM:|rst:0x[0-9A-Fa-f]+ )')
_RESYNC_NAME = 'resynch'
_RESYNC_LINES = ('n/t' + _RESYNC_NAME, _RESYNC_NAME)


@dataclass(frozen=True)
class ProtocolLimits:
    """Plausibility limits applied to parsed lines (SI).

    The chips saturate at roughly 0.6 m/s raw (spec §3.2); values far beyond that are line
    corruption (the link has no checksum), not motion.
    """

    max_speed: float = field(default=2.0, metadata={
        'unit': 'm/s', 'range': (0.01, 100.0),
        'description': 'largest |vx|, |vy| accepted from a velocity line'})
    max_omega: float = field(default=100.0, metadata={
        'unit': 'rad/s', 'range': (0.1, 10000.0),
        'description': 'largest |omega| accepted from a velocity line'})
    max_line_bytes: int = field(default=128, metadata={
        'unit': 'B', 'range': (16, 4096),
        'description': 'longer lines are discarded as bad (the longest valid line is ~40 B)'})


# --------------------------------------------------------------------------- parsed lines


@dataclass(frozen=True, slots=True)
class VelocityLine:
    """A ``v`` line converted to SI.

    Attributes:
        vx: Surface velocity x [m/s] (sensor frame when fused, chip frame in single-chip mode).
        vy: Surface velocity y [m/s].
        omega: Angular rate [rad/s] (stale in single-chip mode).
    """

    vx: float
    vy: float
    omega: float


@dataclass(frozen=True, slots=True)
class NameLine:
    """Reply to ``n``: the sensor name compiled into the firmware (``sensor_1``, ...)."""

    name: str


@dataclass(frozen=True, slots=True)
class ResyncLine:
    """``n/tresynch``: a chip did not answer; the firmware re-syncs it after the ID line.

    Repeated on every sensor pass while the chip stays out; no line marks the end.
    """


@dataclass(frozen=True, slots=True)
class ProductIdLine:
    """The three product IDs that made the firmware re-sync, printed right after ``resynch``.

    Signed as the firmware prints them: 0x31 (49) is a healthy chip, 0 a chip holding its data
    line low (not answering), -1 a data line pulled high.
    """

    ids: tuple[int, int, int]


@dataclass(frozen=True, slots=True)
class BootLine:
    """An ESP32 ROM boot banner line: the board restarted (calibration and mode are lost)."""

    text: str


@dataclass(frozen=True, slots=True)
class TextLine:
    """Free text (command replies, debug or start-up notices); skipped by the host."""

    text: str


@dataclass(frozen=True, slots=True)
class BadLine:
    """A malformed line: undecodable, control characters, malformed record or implausible."""

    raw: bytes
    reason: str


ParsedLine = Union[VelocityLine, NameLine, ResyncLine, ProductIdLine, BootLine, TextLine, BadLine]


@dataclass(frozen=True)
class ParserCounters:
    """Line counts since the parser was created (every line lands in exactly one field).

    ``good`` = velocity + name + product-ID lines; ``unknown`` = free text and boot banners;
    ``resync`` = ``n/tresynch`` notices; ``total`` = good + bad + unknown + resync.
    """

    velocity: int = 0
    name: int = 0
    product_ids: int = 0
    resync: int = 0
    boot: int = 0
    text: int = 0
    bad: int = 0

    @property
    def good(self) -> int:
        """Well-formed records (velocity, name and product-ID lines)."""
        return self.velocity + self.name + self.product_ids

    @property
    def unknown(self) -> int:
        """Skipped free-text lines, including boot banners."""
        return self.text + self.boot

    @property
    def total(self) -> int:
        """Every line seen."""
        return self.good + self.bad + self.unknown + self.resync


# --------------------------------------------------------------------------- line splitting


class LineSplitter:
    """Split a byte stream into lines at ``\\n``, keeping partial lines between calls.

    For byte-level paths that do not go through ``slip_cell_common.core.serial_transport``
    (the emulator's command input, `session.SensorSession.feed`); it returns ``(line,
    overflow)`` pairs like that module's ``LineReader``. A run longer than ``max_line_bytes``
    without a newline is returned once, truncated, with ``overflow=True``; the rest up to the
    next newline is dropped, so garbage cannot grow the buffer without bound.

    Args:
        max_line_bytes: Longest line kept whole [bytes].
    """

    def __init__(self, max_line_bytes: int = 128) -> None:
        if max_line_bytes < 1:
            raise ValueError('max_line_bytes must be >= 1')
        self._max = max_line_bytes
        self._buf = bytearray()
        self._overflow = False

    @property
    def pending(self) -> bytes:
        """Bytes of the current partial line (not yet terminated)."""
        return bytes(self._buf)

    def clear(self) -> None:
        """Drop any partial line (after a reconnect the old tail is meaningless)."""
        self._buf.clear()
        self._overflow = False

    def feed(self, data: bytes) -> list[tuple[bytes, bool]]:
        """Add received bytes; return ``(line, overflow)`` pairs without ``\\n`` (``\\r`` kept).

        Args:
            data: Bytes as read from the port, any chunking.
        """
        lines: list[tuple[bytes, bool]] = []
        start = 0
        n = len(data)
        while start < n:
            end = data.find(b'\n', start)
            if end < 0:
                self._append(data[start:])
                break
            self._append(data[start:end])
            lines.append((bytes(self._buf), self._overflow))
            self._buf.clear()
            self._overflow = False
            start = end + 1
        return lines

    def _append(self, chunk: bytes) -> None:
        if self._overflow:
            return
        room = self._max - len(self._buf)
        if len(chunk) > room:
            self._buf += chunk[:room]
            self._overflow = True
        else:
            self._buf += chunk


# --------------------------------------------------------------------------- parsing


class LineParser:
    """Classify and convert device lines, counting every outcome.

    Args:
        limits: Plausibility limits; defaults of `ProtocolLimits` when omitted.
    """

    def __init__(self, limits: ProtocolLimits | None = None) -> None:
        self.limits = limits if limits is not None else ProtocolLimits()
        self._max_speed_mm_s = self.limits.max_speed * MM_PER_M
        self._max_omega = self.limits.max_omega
        self._c = {'velocity': 0, 'name': 0, 'product_ids': 0, 'resync': 0, 'boot': 0,
                   'text': 0, 'bad': 0}

    @property
    def counters(self) -> ParserCounters:
        """Snapshot of the line counters."""
        return ParserCounters(**self._c)

    def reset_counters(self) -> None:
        """Zero every counter."""
        for key in self._c:
            self._c[key] = 0

    def parse(self, line: bytes, overflow: bool = False) -> ParsedLine:
        """Parse one line (without ``\\n``; a trailing ``\\r`` is stripped).

        Never raises on any input; malformed input gives a `BadLine`.

        Args:
            line: The line bytes.
            overflow: The line splitter truncated it (longer than its limit).
        """
        if line.endswith(b'\r'):
            line = line[:-1]
        if overflow or len(line) > self.limits.max_line_bytes:
            return self._bad(line, 'overlong line')
        try:
            text = line.decode('ascii')
        except UnicodeDecodeError:
            return self._bad(line, 'non-ASCII bytes')
        if not text.isprintable():  # rejects TAB separators, NUL and other control bytes
            return self._bad(line, 'control characters')
        if text.startswith('v/t'):
            return self._velocity(line, text)
        if text in _RESYNC_LINES:
            self._c['resync'] += 1
            return ResyncLine()
        if text.startswith('n/t'):
            name = text[3:]
            if _NAME.fullmatch(name):
                self._c['name'] += 1
                return NameLine(name)
            return self._bad(line, 'malformed name reply')
        if len(text) >= 2 and text[0] in 'vn' and not text[1].isalpha():
            # 'v' or 'n' followed by a wrong separator ('v 1.0 ...', 'v/ t1.0', 'n:sensor_1').
            return self._bad(line, 'malformed record (separator must be "/t")')
        match = _PRODUCT_IDS.fullmatch(text)
        if match:
            self._c['product_ids'] += 1
            first, second, third = (int(g, 10) for g in match.groups())
            return ProductIdLine((first, second, third))
        if _BOOT_BANNER.match(text):
            self._c['boot'] += 1
            return BootLine(text)
        self._c['text'] += 1
        return TextLine(text)

    def _velocity(self, line: bytes, text: str) -> ParsedLine:
        fields = text[3:].split(SEPARATOR)
        if len(fields) != 3:
            return self._bad(line, f'velocity line with {len(fields)} fields, expected 3')
        for f in fields:
            if not _NUMBER.fullmatch(f):
                return self._bad(line, f'velocity field {f!r} is not a 4-decimal number')
        vx_mm_s, vy_mm_s, omega = float(fields[0]), float(fields[1]), float(fields[2])
        if not (math.isfinite(vx_mm_s) and math.isfinite(vy_mm_s) and math.isfinite(omega)):
            return self._bad(line, 'non-finite velocity')
        limit = self._max_speed_mm_s
        if abs(vx_mm_s) > limit or abs(vy_mm_s) > limit or abs(omega) > self._max_omega:
            return self._bad(line, 'implausible velocity')
        self._c['velocity'] += 1
        return VelocityLine(vx_mm_s / MM_PER_M, vy_mm_s / MM_PER_M, omega)

    def _bad(self, line: bytes, reason: str) -> BadLine:
        self._c['bad'] += 1
        return BadLine(bytes(line[:self.limits.max_line_bytes]), reason)


# --------------------------------------------------------------------------- formatting


def is_valid_name(name: str) -> bool:
    """True when ``name`` could be a sensor name in an ``n/t<name>`` reply."""
    return bool(_NAME.fullmatch(name)) and name != _RESYNC_NAME


def format_decimal(value: float, decimals: int = 10) -> str:
    """Fixed-point decimal text without exponent or trailing zeros (``0.00031``, ``24.3``).

    Raises:
        ValueError: When ``value`` is not finite.
    """
    if not math.isfinite(value):
        raise ValueError(f'cannot send non-finite value {value!r} to the sensor')
    text = f'{value:.{decimals}f}'.rstrip('0').rstrip('.')
    return '0' if text in ('', '-0', '+0') else text


def format_velocity_line(vx_mm_s: float, vy_mm_s: float, omega: float) -> bytes:
    """Device-side formatting of a ``v`` line (used by the emulator), 4 decimals, CRLF."""
    return f'v/t{vx_mm_s:.4f}/t{vy_mm_s:.4f}/t{omega:.4f}\r\n'.encode('ascii')


def identify_command() -> bytes:
    """The ``n`` (identify) command."""
    return b'n\n'


def chip_mode_command(mode: int) -> bytes:
    """The ``c<k>`` command: 0 fused output, 1..3 single-chip output of chip k.

    Raises:
        ValueError: When ``mode`` is not an int in 0..3.
    """
    if isinstance(mode, bool) or not isinstance(mode, int) or not 0 <= mode <= MAX_CHIP_MODE:
        raise ValueError(f'chip mode must be an int in 0..{MAX_CHIP_MODE}, got {mode!r}')
    return f'c{mode}\n'.encode('ascii')


def radius_command(radius: float) -> bytes:
    """The ``k00<mm>`` command setting the chip radius.

    Args:
        radius: Distance of the chips from the sensor centre [m], uploaded in mm.

    Raises:
        ValueError: When ``radius`` is not finite or not in (0, 1) m.
    """
    if not (math.isfinite(radius) and 0.0 < radius < 1.0):
        raise ValueError(f'radius must be in (0, 1) m, got {radius!r}')
    radius_mm = radius * MM_PER_M
    return f'k00{format_decimal(radius_mm)}\n'.encode('ascii')


#: ``j`` digit of the ``k<i><j>`` command per (axis, term).
_TERM_DIGIT = {('x', 'a'): 0, ('x', 'b'): 1, ('y', 'a'): 2, ('y', 'b'): 3}


def calibration_command(chip: int, axis: str, term: str, value: float) -> bytes:
    """A ``k<i><j><value>`` command for one chip calibration term.

    Args:
        chip: Chip number 1..3.
        axis: ``'x'`` (tangential) or ``'y'`` (radial) chip axis.
        term: ``'a'`` (speed term, value in SI 1/(m/s), uploaded as 1/(mm/s) = SI/1000) or
            ``'b'`` (dimensionless gain, must be > 0).
        value: The value in SI.

    Raises:
        ValueError: On an unknown chip/axis/term or a non-finite or non-positive ``b``.
    """
    if isinstance(chip, bool) or not isinstance(chip, int) or not 1 <= chip <= N_CHIPS:
        raise ValueError(f'chip must be an int in 1..{N_CHIPS}, got {chip!r}')
    digit = _TERM_DIGIT.get((axis, term))
    if digit is None:
        raise ValueError(f'axis must be x|y and term a|b, got {axis!r}, {term!r}')
    if term == 'a':
        a_per_mm_s = value / MM_PER_M
        text = format_decimal(a_per_mm_s, decimals=12)
    else:
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f'b must be finite and > 0, got {value!r}')
        text = format_decimal(value)
    return f'k{chip}{digit}{text}\n'.encode('ascii')
