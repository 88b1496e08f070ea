# SPDX-License-Identifier: Apache-2.0
"""Gripper actuator ASCII link: telemetry parser and voltage-command codec (ROS-free).

Link summary (hardware_protocols §2):

* Device → host: one line every 2 ms holding the SimpleFOC shaft angle [rad, multi-turn,
  relative to power-up] with exactly four decimals, e.g. ``3.1416\\r\\n``. The same stream
  carries debug text: ``Voltage control`` (once after ``initFOC``), ``Too long in read`` /
  ``Too long`` (the firmware rejected a command) and SimpleFOC initialisation messages.
  ``Voltage control`` and init text mean the firmware (re)started.
* Host → device: ``T<volts>\\n`` only; negative volts close the gripper. The firmware parses
  the value with C ``atof``, so any non-numeric text silently becomes **0 V** and releases
  the grasp, and ``nan``/``inf`` are accepted; the last accepted value is applied forever.
  The host therefore formats only finite, clipped values with the fixed ``T%.2f`` format
  (HW-3). The firmware appends bytes until ``\\n``, so a fragment would merge with the next
  command: every command leaves in one write, and each connection opens with a bare
  newline (`CONNECT_FLUSH`) in the same write as the first command (§2.2).

Force ↔ voltage at stall: ``F = -k_FV · V`` with ``k_FV`` = ``newton_per_volt`` (3.9166 N/V on
the reference cell); back-EMF lowers the force while the motor moves.

Device units live only here and carry their unit in the name (``voltage_v``, ``angle_rad``).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from enum import IntEnum
from typing import NamedTuple

from slip_cell_common.core.validation import validate_fields

#: The firmware drops its buffer after this many characters without a newline.
FIRMWARE_MAX_LINE_CHARS = 20

#: Nominal telemetry period of the firmware [s] (500 Hz, hardware_protocols §1.1).
TELEMETRY_PERIOD_S = 0.002

#: Sent before the first command of every connection, in the same write: ends whatever
#: fragment a previous host left in the firmware's buffer (§2.2).
CONNECT_FLUSH = b'\n'

#: Largest voltage magnitude the fixed command format may carry (keeps ``T-xx.xx``).
MAX_FORMAT_VOLTAGE_V = 99.99

#: A telemetry line: optional minus, up to five integer digits, exactly four decimals.
_ANGLE_RE = re.compile(rb'-?[0-9]{1,5}\.[0-9]{4}')

#: Every command this module emits matches this pattern (checked before returning).
_COMMAND_RE = re.compile(rb'T-?[0-9]{1,2}\.[0-9]{2}\n')

#: Line prefixes printed by the firmware while it boots (SimpleFOC init text, ESP32 ROM
#: banner and the sketch's own ``Voltage control``); seeing one means the firmware restarted.
RESTART_PREFIXES: tuple[str, ...] = (
    'Voltage control', 'MOT:', 'DRV:', 'ENC:', 'CS:', 'SimpleFOC', 'ESP-ROM:', 'rst:',
    'boot:', 'Build:')

#: Replies of the firmware's command parser when a host line exceeded its buffer.
TOO_LONG_PREFIX = 'Too long'

#: Printable ASCII plus tab: anything else in a line is line noise, not firmware text.
_PRINTABLE = frozenset(range(0x20, 0x7f)) | {0x09}


class LineKind(IntEnum):
    """Classification of one device → host line."""

    TELEMETRY = 0  #: a valid shaft angle
    BAD = 1  #: malformed: non-finite or wrongly formatted number, binary noise, over-long
    UNKNOWN = 2  #: text that is not telemetry (debug output, restart banner, firmware replies)


class ParsedLine(NamedTuple):
    """Result of parsing one line.

    Attributes:
        kind: Line classification.
        angle_rad: Shaft angle [rad] for telemetry lines, NaN otherwise.
        detail: Short machine-friendly reason (``'angle'``, ``'non_finite'``, ``'too_long'``,
            ``'malformed_number'``, ``'binary'``, ``'restart'``, ``'firmware_rejected'``,
            ``'text'``).
        restart: True when the line shows that the firmware (re)started.
    """

    kind: LineKind
    angle_rad: float
    detail: str
    restart: bool = False


_NAN = math.nan
_BAD_TOO_LONG = ParsedLine(LineKind.BAD, _NAN, 'too_long')
_BAD_BINARY = ParsedLine(LineKind.BAD, _NAN, 'binary')
_BAD_NON_FINITE = ParsedLine(LineKind.BAD, _NAN, 'non_finite')
_BAD_MALFORMED = ParsedLine(LineKind.BAD, _NAN, 'malformed_number')
_UNKNOWN_RESTART = ParsedLine(LineKind.UNKNOWN, _NAN, 'restart', True)
_UNKNOWN_REJECTED = ParsedLine(LineKind.UNKNOWN, _NAN, 'firmware_rejected')
_UNKNOWN_TEXT = ParsedLine(LineKind.UNKNOWN, _NAN, 'text')


class ParserCounters(NamedTuple):
    """Snapshot of a parser's counters (lines since the last reset; taken on every line).

    ``good + bad + unknown == total``; ``non_finite`` and ``too_long`` are subsets of ``bad``;
    ``restarts`` and ``firmware_rejects`` are subsets of ``unknown``.
    """

    good: int = 0
    bad: int = 0
    unknown: int = 0
    non_finite: int = 0
    too_long: int = 0
    restarts: int = 0
    firmware_rejects: int = 0

    @property
    def total(self) -> int:
        """All classified lines."""
        return self.good + self.bad + self.unknown


class TelemetryParser:
    """Classifies gripper telemetry lines and counts them (HW-6).

    Only lines of the exact firmware format (``-?d.dddd``) are telemetry: a number with another
    precision is a fragment of a corrupted line, not an angle, and NaN/inf are rejected.
    Lines are passed without their CR/LF terminator (see `transport.LineReader`).
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Zero every counter."""
        self._good = 0
        self._bad = 0
        self._unknown = 0
        self._non_finite = 0
        self._too_long = 0
        self._restarts = 0
        self._rejects = 0

    def counters(self) -> ParserCounters:
        """Counter snapshot."""
        return ParserCounters(self._good, self._bad, self._unknown, self._non_finite,
                              self._too_long, self._restarts, self._rejects)

    @property
    def good(self) -> int:
        """Telemetry lines (the status's ``line_count``, read per line without a snapshot)."""
        return self._good

    @property
    def not_telemetry(self) -> int:
        """Bad plus unknown lines."""
        return self._bad + self._unknown

    def parse(self, line: bytes, overflow: bool = False) -> ParsedLine:
        """Classify one line and update the counters; never raises on any input.

        Args:
            line: Line bytes without the terminator (may be truncated when ``overflow``).
            overflow: The line exceeded the reader's maximum length and was truncated.

        Returns:
            The classification; ``angle_rad`` is finite exactly for telemetry lines.
        """
        if overflow:
            self._bad += 1
            self._too_long += 1
            return _BAD_TOO_LONG
        body = line.strip(b' \t')
        if _ANGLE_RE.fullmatch(body) is not None:
            self._good += 1
            # The pattern admits only finite decimals, so float() cannot fail or overflow.
            return ParsedLine(LineKind.TELEMETRY, float(body), 'angle')
        result = self._classify_other(body)
        if result.kind == LineKind.BAD:
            self._bad += 1
            if result is _BAD_NON_FINITE:
                self._non_finite += 1
        else:
            self._unknown += 1
            if result.restart:
                self._restarts += 1
            elif result is _UNKNOWN_REJECTED:
                self._rejects += 1
        return result

    @staticmethod
    def _classify_other(body: bytes) -> ParsedLine:
        if any(b not in _PRINTABLE for b in body):
            return _BAD_BINARY
        text = body.decode('ascii')
        if text.startswith(RESTART_PREFIXES):
            return _UNKNOWN_RESTART
        if text.startswith(TOO_LONG_PREFIX):
            return _UNKNOWN_REJECTED
        try:
            value = float(text)
        except ValueError:
            return _UNKNOWN_TEXT
        return _BAD_MALFORMED if math.isfinite(value) else _BAD_NON_FINITE


class CommandError(ValueError):
    """A value that must never reach the firmware (non-finite, or a bad limit)."""


def format_voltage_command(voltage_v: float, voltage_limit_v: float) -> bytes:
    """Encode ``T<volts>\\n`` with exactly two decimals (HW-3).

    ``V = round(clip(V, -V_max, +V_max), 2)``; ``-0.00`` is written as ``0.00``. The result
    always matches ``T-?d{1,2}.dd\\n`` (≤ 8 bytes, below the firmware's 20-character buffer),
    so the firmware can never read it as anything but the intended value.

    Args:
        voltage_v: Requested q-axis voltage [V]; negative closes.
        voltage_limit_v: Symmetric clip limit [V], 0 < limit ≤ 99.99.

    Returns:
        The ASCII command bytes.

    Raises:
        CommandError: ``voltage_v`` or ``voltage_limit_v`` is not finite, or the limit is out
            of range.
    """
    if not math.isfinite(voltage_limit_v) or not 0.0 < voltage_limit_v <= MAX_FORMAT_VOLTAGE_V:
        raise CommandError(f'voltage limit {voltage_limit_v!r} V outside (0, '
                           f'{MAX_FORMAT_VOLTAGE_V}]')
    if not math.isfinite(voltage_v):
        raise CommandError(f'refusing to send non-finite voltage {voltage_v!r}')
    clipped = min(max(voltage_v, -voltage_limit_v), voltage_limit_v)
    text = f'{clipped:.2f}'
    if text == '-0.00':
        text = '0.00'
    # A finite value within ±99.99 formats as -?d{1,2}.dd: only a longer text could drift
    # from _COMMAND_RE (defensive; cheaper than matching the pattern on every line).
    if len(text) > 6:
        raise CommandError(f'internal error: malformed command {text!r}')
    return b'T' + text.encode('ascii') + b'\n'


def command_voltage(command: bytes) -> float:
    """Voltage [V] carried by a command produced by `format_voltage_command` (optionally
    preceded by `CONNECT_FLUSH`, as the first write of a connection is).

    Raises:
        CommandError: ``command`` is not in the host's fixed format.
    """
    if command[:1] == CONNECT_FLUSH:
        command = command[1:]
    if _COMMAND_RE.fullmatch(command) is None:
        raise CommandError(f'not a host voltage command: {command!r}')
    return float(command[1:-1])


def force_to_voltage(force_n: float, newton_per_volt: float) -> float:
    """Stall voltage [V] for a grasp-force command [N] (positive squeezes): ``V = -F / k_FV``."""
    return -force_n / newton_per_volt


def voltage_to_force(voltage_v: float, newton_per_volt: float) -> float:
    """Stall grasp force [N] of a voltage [V] (negative volts close): ``F = -k_FV · V``."""
    return -newton_per_volt * voltage_v


def encode_force_command(force_n: float, *, newton_per_volt: float, max_close_force_n: float,
                         max_open_force_n: float, voltage_limit_v: float) -> tuple[bytes, float]:
    """Clip a force command to the force ceiling, then to the voltage limit, and encode it.

    Order (HW-3): ``F ← clip(F, -max_open_force, max_close_force)``, ``V = -F / k_FV``,
    ``V ← clip(V, ±voltage_limit)``, rounded to 0.01 V.

    Args:
        force_n: Force command [N]; positive squeezes, negative opens.
        newton_per_volt: Stall force constant [N/V], > 0.
        max_close_force_n: Hard squeezing ceiling [N], ≥ 0.
        max_open_force_n: Hard opening ceiling [N] (magnitude), ≥ 0.
        voltage_limit_v: Symmetric voltage clip [V].

    Returns:
        ``(command_bytes, voltage_v)`` where ``voltage_v`` is exactly the encoded value.

    Raises:
        CommandError: A non-finite force or invalid constants (nothing must be sent then).
    """
    if not math.isfinite(force_n):
        raise CommandError(f'refusing to send non-finite force {force_n!r}')
    if not (math.isfinite(newton_per_volt) and newton_per_volt > 0.0):
        raise CommandError(f'newton_per_volt {newton_per_volt!r} must be finite and > 0')
    if not (max_close_force_n >= 0.0 and max_open_force_n >= 0.0):
        raise CommandError('force ceilings must be >= 0')
    clipped = min(max(force_n, -max_open_force_n), max_close_force_n)
    command = format_voltage_command(force_to_voltage(clipped, newton_per_volt), voltage_limit_v)
    return command, float(command[1:-1])


def _meta(unit: str, low: float, high: float, description: str,
          read_only: bool = False) -> dict[str, object]:
    return {'unit': unit, 'range': (low, high), 'description': description,
            'read_only': read_only}


@dataclass(frozen=True)
class ActuatorParams:
    """Actuator link constants (parameter group ``actuator``; SI except the link's volts)."""

    newton_per_volt: float = field(default=3.9166, metadata=_meta(
        'N/V', 0.1, 100.0, 'stall grasp force per volt (calibrated)', read_only=True))
    voltage_limit: float = field(default=20.0, metadata=_meta(
        'V', 0.5, 20.0, 'symmetric clip of the voltage command (firmware limit 20 V)'))
    opening_per_rad: float = field(default=0.0086751614, metadata=_meta(
        'm/rad', 1.0e-4, 0.1, 'finger separation per motor radian (calibrated)', read_only=True))
    safe_voltage: float = field(default=0.0, metadata=_meta(
        'V', -2.0, 2.0, 'voltage sent on deactivate, shutdown, faults and stop'))

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        extra = []
        if abs(self.safe_voltage) > self.voltage_limit:
            extra.append(f'safe_voltage {self.safe_voltage} V exceeds voltage_limit '
                         f'{self.voltage_limit} V')
        validate_fields(self, extra)
