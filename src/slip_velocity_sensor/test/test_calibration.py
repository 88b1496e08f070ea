# SPDX-License-Identifier: Apache-2.0
"""Calibration law, speed-term modes, upload commands and calibration files."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from slip_velocity_sensor.core import calibration as cal_mod
from slip_velocity_sensor.core.calibration import (AxisCalibration, AxisParams, CalibrationError,
                                                   CalibrationParams, ChipCalibration, ChipParams,
                                                   SensorCalibration, SpeedTerm)

PACKAGE = Path(__file__).resolve().parents[1]
DATA_TABLE = (Path(__file__).resolve().parents[3] / 'docs' / 'data'
              / 'velocity_sensor_calibration.csv')


def test_law_divides_raw_speed_by_b_plus_a_term() -> None:
    cal = AxisCalibration(a=0.31, b=0.9066)
    v_raw = 0.025
    assert cal_mod.corrected_speed(v_raw, cal, 'zero') == pytest.approx(v_raw / 0.9066)
    assert cal_mod.corrected_speed(v_raw, cal, 'abs') == pytest.approx(
        v_raw / (0.9066 + 0.31 * 0.025))
    assert cal_mod.corrected_speed(-v_raw, cal, 'signed_compat') == pytest.approx(
        -v_raw / (0.9066 - 0.31 * 0.025))


def test_signed_term_is_direction_asymmetric_abs_and_zero_are_not() -> None:
    cal = AxisCalibration(a=0.48, b=0.9284)
    v = np.array([0.025, -0.025])
    signed = cal_mod.corrected_speed(v, cal, SpeedTerm.SIGNED_COMPAT)
    assert abs(signed[0]) != pytest.approx(abs(signed[1]), rel=1e-3)
    # Spec HW-9: at most ≈ 1.3 % at 25 mm/s with the table values.
    assert abs(abs(signed[1]) / abs(signed[0]) - 1.0) < 0.03
    for term in ('abs', 'zero'):
        sym = cal_mod.corrected_speed(v, cal, term)
        assert sym[0] == pytest.approx(-sym[1])


@pytest.mark.parametrize('term', ['zero', 'signed_compat', 'abs'])
def test_raw_speed_inverts_the_law(term: str) -> None:
    cal = AxisCalibration(a=0.3, b=0.8)
    v = np.linspace(-0.5, 0.5, 101)
    assert cal_mod.corrected_speed(cal_mod.raw_speed(v, cal, term), cal, term) == \
        pytest.approx(v, abs=1e-14)


def _sensor() -> SensorCalibration:
    return SensorCalibration(
        sensor='sensor_1', radius=0.0243, source='test',
        chips=(ChipCalibration(AxisCalibration(0.0, 0.8847), AxisCalibration(0.31, 0.9066)),
               ChipCalibration(AxisCalibration(0.0, 0.8852), AxisCalibration(0.29, 0.8831)),
               ChipCalibration(AxisCalibration(0.0, 0.9313), AxisCalibration(0.48, 0.9284))))


def test_upload_commands_convert_si_to_device_units() -> None:
    commands = cal_mod.upload_commands(_sensor(), 'signed_compat')
    assert len(commands) == 13
    assert commands[0] == b'k0024.3\n'
    assert commands[1:5] == [b'k100\n', b'k110.8847\n', b'k120.00031\n', b'k130.9066\n']
    assert commands[-2:] == [b'k320.00048\n', b'k330.9284\n']


def test_zero_mode_uploads_a_as_zero_and_keeps_b() -> None:
    commands = cal_mod.upload_commands(_sensor(), 'zero')
    a_commands = [c for c in commands[1:] if c[2:3] in (b'0', b'2')]
    b_commands = [c for c in commands[1:] if c[2:3] in (b'1', b'3')]
    assert len(a_commands) == 6 and all(c[3:] == b'0\n' for c in a_commands)
    assert b'k130.9066\n' in b_commands


def test_invalid_calibration_is_refused_with_every_problem() -> None:
    bad = SensorCalibration(radius=0.0, chips=(
        ChipCalibration(AxisCalibration(math.nan, 1.0), AxisCalibration(0.0, -1.0)),
        ChipCalibration(), ChipCalibration()))
    with pytest.raises(CalibrationError) as err:
        cal_mod.upload_commands(bad, 'zero')
    text = str(err.value)
    assert 'radius' in text and 'chip_1.x.a' in text and 'chip_1.y.b' in text


def test_yaml_round_trip(tmp_path: Path) -> None:
    path = tmp_path / 'cal.yaml'
    cal_mod.save_calibration(path, _sensor(), fit={'note': 'x'}, header='hello')
    loaded = cal_mod.load_calibration(path)
    assert loaded.chips == _sensor().chips
    assert loaded.radius == 0.0243 and loaded.sensor == 'sensor_1'
    assert loaded.source == f'file:{path}'
    assert path.read_text().startswith('# hello\n')


@pytest.mark.parametrize('mutate, message', [
    (lambda d: d.pop('chips'), 'chips'),
    (lambda d: d['chips'].pop('chip_2'), 'chip_2'),
    (lambda d: d['chips']['chip_1']['x'].pop('b'), 'chip_1.x'),
    (lambda d: d['chips']['chip_3']['y'].update(a='0.3'), 'number'),
    (lambda d: d.update(format='other'), 'format'),
    (lambda d: d.update(version=2), 'version'),
    (lambda d: d['chips']['chip_1']['x'].update(b=0.0), 'chip_1.x.b'),
])
def test_invalid_files_name_the_problem(tmp_path: Path, mutate,
                                        message: str) -> None:
    import yaml
    data = cal_mod.to_dict(_sensor())
    mutate(data)
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(CalibrationError, match=message) as err:
        cal_mod.load_calibration(path)
    assert str(path) in str(err.value)


def test_missing_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(CalibrationError, match='cannot read calibration file'):
        cal_mod.load_calibration(tmp_path / 'nope.yaml')


def _table() -> dict[tuple[int, int, str], tuple[float, float]]:
    with DATA_TABLE.open(newline='') as handle:
        return {(int(r['sensor']), int(r['chip']), r['axis']):
                (float(r['a_per_mm_s']) * 1000.0, float(r['b'])) for r in csv.DictReader(handle)}


@pytest.mark.parametrize('sensor', [1, 2])
def test_config_calibration_files_match_the_reference_table(sensor: int) -> None:
    cal = cal_mod.load_calibration(PACKAGE / 'config' / f'calibration_sensor_{sensor}.yaml')
    assert cal.sensor == f'sensor_{sensor}' and cal.radius == pytest.approx(0.0243)
    table = _table()
    for chip in (1, 2, 3):
        for axis in ('x', 'y'):
            a, b = table[(sensor, chip, axis)]
            assert cal.axis(chip, axis).a == pytest.approx(a, abs=1e-12)
            assert cal.axis(chip, axis).b == pytest.approx(b, abs=1e-12)


def test_resolve_prefers_the_file_and_refuses_another_sensors_file() -> None:
    file_1 = str(PACKAGE / 'config' / 'calibration_sensor_1.yaml')
    cal = cal_mod.resolve_calibration(CalibrationParams(file=file_1), 0.02, 'sensor_1')
    assert cal.source.startswith('file:') and cal.radius == pytest.approx(0.0243)
    with pytest.raises(CalibrationError, match="for 'sensor_1'"):
        cal_mod.resolve_calibration(CalibrationParams(file=file_1), 0.0243, 'sensor_2')


def test_resolve_inline_parameters_and_flag_identity() -> None:
    identity = cal_mod.resolve_calibration(CalibrationParams(file=''), 0.0243, 'sensor_1')
    assert identity.is_identity and 'identity' in identity.source
    params = CalibrationParams(file='', chip_2=ChipParams(y=AxisParams(a=0.29, b=0.8831)))
    cal = cal_mod.resolve_calibration(params, 0.0243, 'sensor_1')
    assert cal.axis(2, 'y') == AxisCalibration(0.29, 0.8831) and cal.source == 'parameters'
