# SPDX-License-Identifier: Apache-2.0
"""The ``friction_models_cli`` console script."""
from __future__ import annotations

from pathlib import Path

import pytest

from friction_models.cli import main

PNG_MAGIC = b'\x89PNG\r\n\x1a\n'


def test_help_lists_the_commands(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(['--help'])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for word in ('surfaces', 'limit-surface', 'stick-slip', 'compare', 'Examples'):
        assert word in out
    with pytest.raises(SystemExit):
        main(['limit-surface', '--help'])
    assert '--n-ls' in capsys.readouterr().out


def test_surfaces_table(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['surfaces']) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith('line_grad '))
    assert '3.175' in row and '3.988' in row and '1.458' in row


def test_limit_surface_table_png_and_cache(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip('matplotlib')
    png = tmp_path / 'ls.png'
    args = ['limit-surface', '--surface', 'line_grad', '--n-ls', '8', '--png', str(png),
            '--cache-dir', str(tmp_path / 'cache')]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert 'r_a = 3.98' in out and png.read_bytes()[:8] == PNG_MAGIC
    assert len(list((tmp_path / 'cache').glob('*.npz'))) == 1
    rows = [line.split() for line in out.splitlines() if not line.startswith(('#', 'theta'))]
    first = [float(v) for v in rows[0]]
    assert first[:2] == [0.0, 0.0] and first[4] == pytest.approx(-1.0)


def test_stick_slip_series_and_png(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip('matplotlib')
    png = tmp_path / 'ss.png'
    assert main(['stick-slip', '--duration', '1.6', '--print-every', '0.4',
                 '--png', str(png)]) == 0
    out = capsys.readouterr().out
    assert 'stick-slip cycles' in out and png.read_bytes()[:8] == PNG_MAGIC
    assert int(out.strip().splitlines()[-2].split()[-1]) >= 1


def test_compare_prints_nrmse(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['compare', '--surface', 'square', '--n', '7', '--dt', '2e-3']) == 0
    row = next(line for line in capsys.readouterr().out.splitlines()
               if line.startswith('square'))
    ls_force, ls_torque, el_force, el_torque = (float(v) for v in row.split()[1:])
    assert ls_force < el_force and ls_torque < el_torque


def test_invalid_input_is_reported(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['stick-slip', '--mu-s', '0.5', '--mu-c', '1.0']) == 2
    assert 'mu_s' in capsys.readouterr().err
