# SPDX-License-Identifier: Apache-2.0
"""The calibration fit reads recordings from bags as calibration_recorder writes them
(``finger_k/slip/chips`` OpticalChipArray samples with acquisition stamps), mixed with CSV.

Needs the workspace (slip_msgs definitions from the install prefix), not a running ROS graph.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip('rosbags')

from slip_velocity_sensor import calibration_fit as cli
from slip_velocity_sensor.core import calibration as cal_mod
from slip_velocity_sensor.core.calibration import AxisCalibration
from slip_velocity_sensor.core.calibration_fit import fit_axis
from slip_velocity_sensor.core.procedure import (ProcedureParams,
                                                 synthesize_recording)

TRUTH = AxisCalibration(0.31, 0.9066)
#: Three speed levels instead of six (a shorter bag, same fit).
SHORT = ProcedureParams(traverse_durations=(3.0, 1.0, 0.7), pauses=(3.0,) * 6, final_rest=3.0)


def test_bag_recording_round_trip_and_fit(tmp_path: Path) -> None:
    rec = synthesize_recording(TRUTH, SHORT)
    bag = tmp_path / 'Sensor1chip3y'
    cli.write_bag_recording(bag, rec.t, rec.v, chip=3, axis='y')
    t, v = cli.read_bag_recording(bag, 3, 'y')
    np.testing.assert_allclose(t, rec.t, atol=1e-9)       # stamps survive (ns resolution)
    np.testing.assert_array_equal(v, rec.v)
    fit = fit_axis(t, v)
    assert fit.calibration.b == pytest.approx(TRUTH.b, rel=2e-3)
    assert fit.calibration.a == pytest.approx(TRUTH.a, abs=0.05)
    with pytest.raises(ValueError, match='no single-chip samples of chip 1'):
        cli.read_bag_recording(bag, 1, 'y')
    with pytest.raises(ValueError, match='does not exist'):
        cli.read_bag_recording(tmp_path / 'missing', 3, 'y')


def test_fit_cli_accepts_bags_next_to_csv_files(tmp_path: Path) -> None:
    rec_dir = tmp_path / 'rec'
    rec_dir.mkdir()
    truths = {(c, a): AxisCalibration(0.2 if a == 'y' else 0.0, 0.80 + 0.05 * c)
              for c in (1, 2, 3) for a in ('x', 'y')}
    for (chip, axis), truth in truths.items():
        rec = synthesize_recording(truth)
        if (chip, axis) == (2, 'y'):
            cli.write_bag_recording(rec_dir / f'Sensor1chip{chip}{axis}', rec.t, rec.v, chip, axis)
        else:
            cli.write_recording(rec_dir / f'Sensor1chip{chip}{axis}.csv', rec.t, rec.v)
    out = tmp_path / 'out'
    assert cli.main(['fit', str(rec_dir), '--out-dir', str(out), '--no-plot']) == 0
    fitted = cal_mod.load_calibration(out / 'calibration_sensor_1.yaml')
    for (chip, axis), truth in truths.items():
        assert fitted.axis(chip, axis).b == pytest.approx(truth.b, rel=1e-3)
    # A bag and a CSV for the same recording are ambiguous: refused, not guessed.
    cli.write_recording(rec_dir / 'Sensor1chip2y.csv', [0.0], [0.0])
    assert cli.main(['fit', str(rec_dir), '--out-dir', str(out), '--no-plot']) == 2
