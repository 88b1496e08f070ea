# SPDX-License-Identifier: Apache-2.0
"""Per-chip speed calibration: the correction law, upload commands and calibration files (SI).

The firmware corrects each chip axis as (hardware_protocols §3.4, §3.6)::

    v = v_raw / (b + a·term(v_raw))

with b the ratio of measured to true speed (0.70–0.93: raw chips read low) and a a small
speed-dependent term. ``term`` is the `SpeedTerm` (requirement HW-9):

* ``zero`` (default): a is uploaded as 0, the correction is the symmetric gain 1/b.
* ``signed_compat``: a uploaded as-is; the shipped firmware uses the signed v_raw, so the gain
  differs between directions (reproduces the reference).
* ``abs``: a uploaded as-is, for firmware fixed to use |v_raw| (symmetric).

SI everywhere: speeds in m/s, a in 1/(m/s) (the device's 1/(mm/s) value × 1000), radius in m.
The conversion to device units happens in `protocol` when the commands are built.

Calibration file (YAML, written by the fit tool, loaded by the node)::

    format: slip_velocity_sensor/calibration
    version: 1
    sensor: sensor_1          # the name the sensor answers to `n`
    radius: 0.0243            # [m]
    source: <free text: how the values were obtained>
    chips:
      chip_1: {x: {a: 0.0, b: 0.8847}, y: {a: 0.31, b: 0.9066}}   # a [1/(m/s)], b [-]
      chip_2: ...
      chip_3: ...
    fit: {...}                # optional report of the fit (ignored by the loader)
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any, TypeVar, overload
from collections.abc import Mapping

import numpy as np
import yaml
from numpy.typing import NDArray

from slip_velocity_sensor.core import protocol

FILE_FORMAT = 'slip_velocity_sensor/calibration'
FILE_VERSION = 1
AXES = ('x', 'y')

_Speed = TypeVar('_Speed', float, NDArray[np.float64])


class SpeedTerm(str, Enum):
    """How the a-term enters the correction law (requirement HW-9)."""

    ZERO = 'zero'
    SIGNED_COMPAT = 'signed_compat'
    ABS = 'abs'


#: Default ``calibration.file`` of the node: the installed file of the expected board (relative
#: paths refer to the package's share directory; the node substitutes and resolves it).
DEFAULT_FILE = 'config/calibration_{expected_name}.yaml'

#: Allowed values of the ``calibration.speed_term`` parameter.
SPEED_TERMS = tuple(term.value for term in SpeedTerm)


class CalibrationError(ValueError):
    """Raised for an invalid calibration file or values; the message names the file."""


@dataclass(frozen=True)
class AxisCalibration:
    """Correction of one chip axis.

    Attributes:
        a: Speed term [1/(m/s)].
        b: Ratio of measured to true speed [-], > 0.
    """

    a: float = field(default=0.0, metadata={
        'unit': '1/(m/s)', 'range': (-10.0, 10.0), 'description': 'speed term of the law'})
    b: float = field(default=1.0, metadata={
        'unit': '-', 'range': (0.05, 5.0), 'description': 'measured / true speed ratio'})

    def problems(self, where: str) -> list[str]:
        """Reasons this axis calibration is unusable (empty when valid)."""
        out = []
        if not math.isfinite(self.a) or abs(self.a) > 10.0:
            out.append(f'{where}.a = {self.a!r} must be finite with |a| <= 10 1/(m/s)')
        if not math.isfinite(self.b) or not 0.05 <= self.b <= 5.0:
            out.append(f'{where}.b = {self.b!r} must be finite in [0.05, 5]')
        return out


@dataclass(frozen=True)
class ChipCalibration:
    """Corrections of the tangential (x) and radial (y) axes of one chip."""

    x: AxisCalibration = field(default_factory=AxisCalibration)
    y: AxisCalibration = field(default_factory=AxisCalibration)


def _identity_chips() -> tuple[ChipCalibration, ...]:
    return (ChipCalibration(), ChipCalibration(), ChipCalibration())


@dataclass(frozen=True)
class SensorCalibration:
    """Calibration of one finger sensor (SI).

    Attributes:
        sensor: Name the sensor answers to ``n`` (``sensor_1``); '' when not bound to a sensor.
        radius: Chip distance from the sensor centre [m].
        chips: Corrections of chips 1..3.
        source: Where the values came from (file path, fit, parameters), for diagnostics.
    """

    sensor: str = ''
    radius: float = 0.0243
    chips: tuple[ChipCalibration, ...] = field(default_factory=_identity_chips)
    source: str = ''

    def axis(self, chip: int, axis: str) -> AxisCalibration:
        """Correction of chip ``chip`` (1..3), axis ``'x'`` or ``'y'``."""
        if axis not in AXES:
            raise ValueError(f"axis must be 'x' or 'y', got {axis!r}")
        correction: AxisCalibration = getattr(self.chips[chip - 1], axis)
        return correction

    def problems(self) -> list[str]:
        """Reasons the calibration is unusable (empty when valid)."""
        out = []
        if len(self.chips) != protocol.N_CHIPS:
            out.append(f'expected {protocol.N_CHIPS} chips, got {len(self.chips)}')
        if not (math.isfinite(self.radius) and 0.001 <= self.radius <= 0.5):
            out.append(f'radius = {self.radius!r} m outside [0.001, 0.5] m')
        for i, chip in enumerate(self.chips, start=1):
            for ax in AXES:
                out.extend(getattr(chip, ax).problems(f'chip_{i}.{ax}'))
        return out

    def validate(self) -> None:
        """Raise `CalibrationError` listing every problem."""
        problems = self.problems()
        if problems:
            raise CalibrationError('; '.join(problems))

    @property
    def is_identity(self) -> bool:
        """True when every axis has a = 0 and b = 1 (i.e. no calibration at all)."""
        return all(getattr(c, ax) == AxisCalibration() for c in self.chips for ax in AXES)


# --------------------------------------------------------------------------- the law


def _term(v_raw: _Speed, speed_term: SpeedTerm | str) -> _Speed:
    term = SpeedTerm(speed_term)
    if term is SpeedTerm.ZERO:
        return v_raw * 0.0
    if term is SpeedTerm.SIGNED_COMPAT:
        return v_raw
    return abs(v_raw)


@overload
def corrected_speed(v_raw: float, cal: AxisCalibration, speed_term: SpeedTerm | str) -> float:
    ...


@overload
def corrected_speed(v_raw: NDArray[np.float64], cal: AxisCalibration,
                    speed_term: SpeedTerm | str) -> NDArray[np.float64]:
    ...


def corrected_speed(v_raw: Any, cal: AxisCalibration, speed_term: SpeedTerm | str) -> Any:
    """Apply ``v = v_raw / (b + a·term(v_raw))``.

    Args:
        v_raw: Raw chip speed [m/s] (scalar or array).
        cal: Axis correction (a [1/(m/s)], b).
        speed_term: How the a-term enters (`SpeedTerm`).

    Returns:
        Corrected speed [m/s], same shape as ``v_raw``.
    """
    return v_raw / (cal.b + cal.a * _term(v_raw, speed_term))


def raw_speed(v_true: Any, cal: AxisCalibration, speed_term: SpeedTerm | str) -> Any:
    """Inverse of `corrected_speed`: the raw reading that corrects to ``v_true``.

    Used to model chips that read low (emulator, synthetic recordings). With the
    ``signed_compat`` and ``abs`` terms, ``v_raw = b·v / (1 − a·term(v))``.

    Args:
        v_true: True speed [m/s] (scalar or array); requires ``a·term(v_true) < 1``.
        cal: Axis correction that maps the raw reading back to ``v_true``.
        speed_term: How the a-term enters.
    """
    return cal.b * v_true / (1.0 - cal.a * _term(v_true, speed_term))


# --------------------------------------------------------------------------- upload


def upload_commands(cal: SensorCalibration, speed_term: SpeedTerm | str) -> list[bytes]:
    """The 13 device commands that upload a calibration: radius, then a/b of every chip axis.

    Args:
        cal: Calibration in SI (validated here).
        speed_term: ``zero`` uploads a = 0 (b only); the other modes upload a as-is.

    Raises:
        CalibrationError: When the calibration is invalid.
    """
    cal.validate()
    term = SpeedTerm(speed_term)
    commands = [protocol.radius_command(cal.radius)]
    for chip in range(1, protocol.N_CHIPS + 1):
        for ax in AXES:
            axis_cal = cal.axis(chip, ax)
            a = 0.0 if term is SpeedTerm.ZERO else axis_cal.a
            commands.append(protocol.calibration_command(chip, ax, 'a', a))
            commands.append(protocol.calibration_command(chip, ax, 'b', axis_cal.b))
    return commands


# --------------------------------------------------------------------------- files


def to_dict(cal: SensorCalibration, fit: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """YAML-ready mapping of a calibration (see the module docstring for the layout)."""
    chips = {}
    for i, chip in enumerate(cal.chips, start=1):
        chips[f'chip_{i}'] = {ax: {'a': float(getattr(chip, ax).a),
                                   'b': float(getattr(chip, ax).b)} for ax in AXES}
    out: dict[str, Any] = {'format': FILE_FORMAT, 'version': FILE_VERSION, 'sensor': cal.sensor,
                           'radius': float(cal.radius), 'source': cal.source, 'chips': chips}
    if fit:
        out['fit'] = dict(fit)
    return out


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CalibrationError(f'{where} must be a number, got {value!r}')
    return float(value)


def from_dict(data: Mapping[str, Any], source: str = '') -> SensorCalibration:
    """Build and validate a calibration from a mapping read from YAML.

    Args:
        data: Mapping with the file layout.
        source: Recorded as `SensorCalibration.source` when given (e.g. the file path).

    Raises:
        CalibrationError: Listing what is missing or invalid.
    """
    if not isinstance(data, Mapping):
        raise CalibrationError('calibration must be a mapping')
    if data.get('format') != FILE_FORMAT:
        raise CalibrationError(f"'format' must be {FILE_FORMAT!r}, got {data.get('format')!r}")
    if data.get('version') != FILE_VERSION:
        raise CalibrationError(f"unsupported version {data.get('version')!r}")
    chips_data = data.get('chips')
    if not isinstance(chips_data, Mapping):
        raise CalibrationError("'chips' must be a mapping chip_1..chip_3")
    chips = []
    for i in range(1, protocol.N_CHIPS + 1):
        chip = chips_data.get(f'chip_{i}')
        if not isinstance(chip, Mapping):
            raise CalibrationError(f'chips.chip_{i} missing')
        axes = {}
        for ax in AXES:
            entry = chip.get(ax)
            if not isinstance(entry, Mapping) or 'a' not in entry or 'b' not in entry:
                raise CalibrationError(f'chips.chip_{i}.{ax} needs a and b')
            axes[ax] = AxisCalibration(a=_number(entry['a'], f'chip_{i}.{ax}.a'),
                                       b=_number(entry['b'], f'chip_{i}.{ax}.b'))
        chips.append(ChipCalibration(**axes))
    sensor = data.get('sensor', '')
    if not isinstance(sensor, str):
        raise CalibrationError(f"'sensor' must be a string, got {sensor!r}")
    cal = SensorCalibration(sensor=sensor, radius=_number(data.get('radius'), 'radius'),
                            chips=tuple(chips), source=source or str(data.get('source', '')))
    cal.validate()
    return cal


def load_calibration(path: str | Path) -> SensorCalibration:
    """Load a calibration file; the source is recorded as ``file:<path>``.

    Raises:
        CalibrationError: When the file is missing, not YAML or invalid (message names it).
    """
    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text(encoding='utf-8'))
    except (OSError, yaml.YAMLError) as exc:
        raise CalibrationError(f'cannot read calibration file {p}: {exc}') from exc
    try:
        return from_dict(data, source=f'file:{p}')
    except CalibrationError as exc:
        raise CalibrationError(f'{p}: {exc}') from exc


def save_calibration(path: str | Path, cal: SensorCalibration,
                     fit: Mapping[str, Any] | None = None, header: str = '') -> None:
    """Write a calibration file (SI), optionally with a fit report and a comment header."""
    cal.validate()
    lines = [f'# {line}'.rstrip() for line in header.splitlines()] if header else []
    lines.append('# Velocity-sensor calibration (SI): v = v_raw / (b + a*term(v_raw)), '
                 'a [1/(m/s)], b [-], radius [m].')
    text = '\n'.join(lines) + '\n' + yaml.safe_dump(to_dict(cal, fit), sort_keys=False,
                                                  allow_unicode=True)
    Path(path).write_text(text, encoding='utf-8')


# --------------------------------------------------------------------------- parameters


@dataclass(frozen=True)
class AxisParams:
    """Inline calibration of one chip axis (node parameters ``calibration.chip_<i>.<x|y>``)."""

    a: float = field(default=0.0, metadata={
        'unit': '1/(m/s)', 'range': (-10.0, 10.0),
        'description': 'speed term a (uploaded / 1000 as 1/(mm/s))'})
    b: float = field(default=1.0, metadata={
        'unit': '-', 'range': (0.05, 5.0), 'description': 'measured / true speed ratio b'})


@dataclass(frozen=True)
class ChipParams:
    """Inline calibration of one chip."""

    x: AxisParams = field(default_factory=AxisParams)
    y: AxisParams = field(default_factory=AxisParams)


@dataclass(frozen=True)
class CalibrationParams:
    """Calibration parameters of the sensor node (``calibration.*``).

    ``file`` defaults to `DEFAULT_FILE` (the installed calibration of the expected board).
    Inline values default to the identity (a = 0, b = 1) so that no calibration is ever a
    literal in code; they apply only with ``file = ''``, and an identity calibration is
    reported as such in diagnostics.
    """

    file: str = field(default=DEFAULT_FILE, metadata={
        'read_only': True,
        'description': "calibration YAML from the fit tool ({expected_name} and {finger} are "
                       "substituted); overrides the inline values; '' = inline"})
    speed_term: str = field(default=SpeedTerm.ZERO.value, metadata={
        'choices': SPEED_TERMS, 'read_only': True,
        'description': 'zero (upload a = 0), signed_compat (reference), abs (fixed firmware)'})
    chip_1: ChipParams = field(default_factory=ChipParams)
    chip_2: ChipParams = field(default_factory=ChipParams)
    chip_3: ChipParams = field(default_factory=ChipParams)


def resolve_calibration(params: CalibrationParams, radius: float,
                        expected_name: str) -> SensorCalibration:
    """The calibration to upload: from ``params.file`` if set, else the inline values.

    Args:
        params: The ``calibration.*`` parameters.
        radius: Chip radius parameter [m] (used with inline values; a file carries its own).
        expected_name: Name of the sensor being configured; a file made for another sensor is
            refused (it would silently apply the wrong chip gains).

    Raises:
        CalibrationError: Unreadable/invalid file, or a file for another sensor.
    """
    if params.file:
        cal = load_calibration(params.file)
        if cal.sensor and cal.sensor != expected_name:
            raise CalibrationError(f'{params.file} is for {cal.sensor!r}, '
                                   f'but this node expects {expected_name!r}')
        return cal
    chips = tuple(ChipCalibration(x=AxisCalibration(c.x.a, c.x.b), y=AxisCalibration(c.y.a, c.y.b))
                  for c in (params.chip_1, params.chip_2, params.chip_3))
    cal = SensorCalibration(sensor=expected_name, radius=radius, chips=chips, source='parameters')
    if cal.is_identity:
        cal = SensorCalibration(sensor=expected_name, radius=radius, chips=chips,
                                source='parameters (identity: uncalibrated)')
    cal.validate()
    return cal
