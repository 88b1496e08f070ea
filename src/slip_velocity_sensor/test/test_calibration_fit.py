# SPDX-License-Identifier: Apache-2.0
"""Calibration procedure schedule, synthetic recordings and the offline fit (spec §3.7)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from slip_velocity_sensor import calibration_fit as cli
from slip_velocity_sensor.core import calibration as cal_mod
from slip_velocity_sensor.core.calibration import AxisCalibration
from slip_velocity_sensor.core.calibration_fit import FitError, FitParams, fit_axis
from slip_velocity_sensor.core.chip_model import ChipModelParams
from slip_velocity_sensor.core.procedure import (ProcedureParams, StepKind, SynthesisParams,
                                                 schedule, step_at, synthesize_recording,
                                                 true_position)

PACKAGE = Path(__file__).resolve().parents[1]
TRUTHS = [AxisCalibration(0.31, 0.9066), AxisCalibration(0.48, 0.9284),
          AxisCalibration(0.27, 0.7029), AxisCalibration(0.0, 0.8847)]


def test_schedule_is_the_spec_procedure() -> None:
    steps = schedule()
    rests = [s for s in steps if s.kind is StepKind.REST]
    traverses = [s for s in steps if s.kind is StepKind.TRAVERSE]
    assert len(traverses) == 12 and len(rests) == 13
    assert [s.duration for s in rests[:12]] == [15, 15, 10, 10, 8, 8, 7, 7, 6, 6, 5, 5]
    assert [s.duration for s in traverses[0::2]] == [10, 5, 3, 2, 1, 0.7]
    assert [s.duration for s in traverses[1::2]] == [10, 5, 3, 2, 1, 0.7]
    assert [s.direction for s in traverses] == [1, -1] * 6
    assert all(a.end == pytest.approx(b.start) for a, b in zip(steps, steps[1:]))
    assert step_at(steps, 15.5).kind is StepKind.TRAVERSE and 'far stop in 10 s' in \
        step_at(steps, 15.5).prompt
    assert step_at(steps, steps[-1].end + 1.0) is None
    # The surface ends each traverse at a stop.
    t_end = np.array([s.end for s in traverses])
    assert true_position(t_end, steps, 0.1) == pytest.approx([0.1, 0.0] * 6, abs=1e-12)


def test_schedule_validation() -> None:
    with pytest.raises(ValueError, match='pause'):
        schedule(ProcedureParams(pauses=(1.0, 2.0)))


@pytest.mark.parametrize('truth', TRUTHS, ids=lambda c: f'a{c.a}_b{c.b}')
def test_fit_recovers_a_known_symmetric_calibration(truth: AxisCalibration) -> None:
    rec = synthesize_recording(truth, synthesis=SynthesisParams(profile='trapezoid'))
    fit = fit_axis(rec.t, rec.v, FitParams(model='abs'))
    assert len(fit.plateaus) == 13 and len(fit.accepted) == 12
    assert {tr.direction for tr in fit.accepted} == {1, -1}
    assert fit.calibration.b == pytest.approx(truth.b, rel=5e-4)
    assert fit.calibration.a == pytest.approx(truth.a, abs=0.02)
    # Both directions separately give the same line (the chip model is symmetric).
    for one_way in (fit.positive, fit.negative):
        assert one_way is not None and one_way.n == 6
        assert one_way.b == pytest.approx(truth.b, rel=1e-3)
        assert one_way.a == pytest.approx(truth.a, abs=0.03)
    # Re-integration with the fitted law gives ±100 mm to a few counts.
    assert np.max(np.abs(fit.check_errors)) < 0.05e-3


def test_constant_speed_traverses_recover_the_calibration_almost_exactly() -> None:
    truth = AxisCalibration(0.31, 0.9066)
    rec = synthesize_recording(truth, synthesis=SynthesisParams(profile='constant'))
    fit = fit_axis(rec.t, rec.v)
    assert fit.calibration.b == pytest.approx(truth.b, rel=2e-4)
    assert fit.calibration.a == pytest.approx(truth.a, rel=0.02)


def test_signed_fit_on_symmetric_chips_finds_no_slope_and_b_only_leaves_a_speed_error() -> None:
    truth = AxisCalibration(0.48, 0.9284)
    rec = synthesize_recording(truth)
    signed = fit_axis(rec.t, rec.v, FitParams(model='signed'))
    assert abs(signed.calibration.a) < 0.05 * truth.a   # the reference model cannot see it
    b_only = fit_axis(rec.t, rec.v, FitParams(model='none'))
    assert b_only.calibration.a == 0.0
    assert truth.b < b_only.calibration.b < truth.b * 1.05
    fitted = fit_axis(rec.t, rec.v)
    assert np.sqrt(np.mean(fitted.check_errors ** 2)) < \
        0.1 * np.sqrt(np.mean(b_only.check_errors ** 2))


def test_a_factor_only_applies_when_given() -> None:
    rec = synthesize_recording(AxisCalibration(0.3, 0.9))
    raw = fit_axis(rec.t, rec.v)
    scaled = fit_axis(rec.t, rec.v, FitParams(a_factor=0.88))
    assert scaled.calibration.a == pytest.approx(0.88 * raw.calibration.a)
    assert scaled.raw == raw.raw and scaled.calibration.b == raw.calibration.b


def test_noisy_rest_breaks_plateaus_with_a_clear_error() -> None:
    rng = np.random.default_rng(0)
    synthesis = SynthesisParams(chip=ChipModelParams(count_noise_std=0.5))
    rec = synthesize_recording(AxisCalibration(0.3, 0.9), synthesis=synthesis, rng=rng)
    with pytest.raises(FitError, match='plateau'):
        fit_axis(rec.t, rec.v)


def test_too_short_or_invalid_recordings_are_refused() -> None:
    t = np.arange(0.0, 5.0, 1 / 120)
    with pytest.raises(FitError, match='usable traverse'):
        fit_axis(t, np.zeros_like(t))
    with pytest.raises(FitError, match='non-finite'):
        fit_axis(t, np.full_like(t, np.nan))
    with pytest.raises(FitError, match='equal length'):
        fit_axis(t, np.zeros(3))


def test_operator_errors_are_rejected_not_fitted() -> None:
    """A half-way traverse (stopped 40 mm short) is reported and left out of the fit."""
    truth = AxisCalibration(0.3, 0.9)
    rec = synthesize_recording(truth)
    t, v = rec.t.copy(), rec.v.copy()
    steps = schedule()
    tr = [s for s in steps if s.kind is StepKind.TRAVERSE][2]
    start = 1.0 + tr.start   # lead-in of the synthesiser
    sel = (t > start) & (t <= start + tr.duration)
    v[sel] *= 0.6            # this traverse now covers only 60 % of the distance
    fit = fit_axis(t, v, FitParams(distance_tolerance=0.3))
    rejected = [x for x in fit.traverses if not x.accepted]
    assert rejected and 'not stop-to-stop' in rejected[0].reason
    assert fit.calibration.b == pytest.approx(truth.b, rel=2e-3)


def test_cli_synth_fit_and_from_table(tmp_path: Path) -> None:
    table = tmp_path / 'table.csv'
    table.write_text(
        'sensor,chip,axis,a_per_mm_s,b,radius_mm,applied_as,source\n'
        + ''.join(f'1,{c},{a},{0.0003 * c if a == "y" else 0.0},{0.80 + 0.05 * c},24.3,x,y\n'
                  for c in (1, 2, 3) for a in ('x', 'y')))
    recordings = tmp_path / 'rec'
    assert cli.main(['synth', str(recordings), '--truth-table', str(table)]) == 0
    assert len(list(recordings.glob('Sensor1chip*.csv'))) == 6
    out = tmp_path / 'out'
    assert cli.main(['fit', str(recordings), '--out-dir', str(out), '--no-plot']) == 0
    fitted = cal_mod.load_calibration(out / 'calibration_sensor_1.yaml')
    truth = cli.read_table(table)[1]
    assert fitted.sensor == 'sensor_1'
    for chip in (1, 2, 3):
        for axis in ('x', 'y'):
            assert fitted.axis(chip, axis).b == pytest.approx(truth.axis(chip, axis).b, rel=1e-3)
            assert fitted.axis(chip, axis).a == pytest.approx(truth.axis(chip, axis).a, abs=0.03)
    residuals = (out / 'calibration_sensor_1_residuals.csv').read_text().splitlines()
    assert len(residuals) == 1 + 6 * 12
    assert cli.main(['from-table', str(table), '--out-dir', str(tmp_path / 'cfg')]) == 0
    assert cal_mod.load_calibration(tmp_path / 'cfg' / 'calibration_sensor_1.yaml').chips == \
        truth.chips


@pytest.mark.slow
def test_cli_writes_the_png_report(tmp_path: Path) -> None:
    pytest.importorskip('matplotlib')
    rec = tmp_path / 'rec'
    rec.mkdir()
    for chip in (1, 2, 3):
        for axis in ('x', 'y'):
            r = synthesize_recording(AxisCalibration(0.2 if axis == 'y' else 0.0, 0.9))
            cli.write_recording(rec / f'Sensor2chip{chip}{axis}.csv', r.t, r.v)
    result = subprocess.run([sys.executable, '-m', 'slip_velocity_sensor.calibration_fit', 'fit',
                             str(rec), '--out-dir', str(tmp_path / 'out'), '--zero-x-a'],
                            capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stderr
    png = tmp_path / 'out' / 'calibration_sensor_2_report.png'
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert 'chip' in result.stdout and 'calibration_sensor_2.yaml' in result.stdout


def test_prompt_schedule_and_time_scaling() -> None:
    from slip_velocity_sensor.core.procedure import prompt_schedule, scaled
    steps = schedule()
    prompts = prompt_schedule(steps, warn_before=3.0)
    assert [p.t for p in prompts] == sorted(p.t for p in prompts)
    go = [p for p in prompts if p.text.startswith('GO')]
    ready = [p for p in prompts if p.text.startswith('get ready')]
    assert len(go) == 12 and len(ready) == 12          # every rest before a traverse is > 3 s
    assert go[0].t == 15.0 and ready[0].t == 12.0 and 'far stop in 10 s' in go[0].text
    assert prompts[-1].text == 'procedure finished' and prompts[-1].t == steps[-1].end
    fast = schedule(scaled(ProcedureParams(), 0.1))
    assert fast[-1].end == pytest.approx(0.1 * steps[-1].end)
    assert [p for p in prompt_schedule(fast, 0.0) if p.text.startswith('get ready')] == []
    with pytest.raises(ValueError):
        scaled(ProcedureParams(), 0.0)
