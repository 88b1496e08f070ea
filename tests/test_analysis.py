"""``slip_analyze`` on the committed bags: the documented metrics, and figures that show them.

Metrics: the force-tracking bag gives the step metrics, the frequency response from the sines
found in the command and a bandwidth; bags without the sines give no frequency response (and
say so); the hold bag gives hold metrics; the estimation bag gives the final r with its
uncertainty although the first published estimate has r = NaN; aborts are found. Figures are
checked by their content (lines, shaded phases, units in the axis labels, error bars, legend
placement), built through `analysis_plots.build_figures`.
"""
from __future__ import annotations

import functools
import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from slip_bringup import analysis_plots, analyze
from slip_bringup.core.phases import StateChange

pytestmark = pytest.mark.slow

BAGS = Path(__file__).resolve().parents[1] / 'bags'


def _bag(name: str) -> Path:
    path = BAGS / name
    if not path.is_dir():
        pytest.fail(f'bags/{name} is missing: run `make bags`')
    return path


@functools.cache
def _loaded(name: str) -> dict[str, Any]:
    return analyze.load(_bag(name))


def _analysed(name: str) -> tuple[dict[str, Any], dict[str, Any]]:
    data = _loaded(name)
    return data, analyze.jsonable(analyze.analyze_bag(data))


def _without(data: dict[str, Any], t_end: float) -> dict[str, Any]:
    """``data`` with every series cut at ``t_end`` [s]."""
    out = {k: (v.window(-math.inf, t_end) if isinstance(v, analyze.Series) else v)
           for k, v in data.items()}
    out['span'] = (data['span'][0], t_end)
    return out


# --- force ---------------------------------------------------------------------------------

def test_force_tracking_bag_gives_step_response_and_bandwidth_from_its_sines() -> None:
    _, m = _analysed('force_tracking')
    f = m['force']
    assert f['command_source'] == 'the experiment runner'
    assert f['excitation']['found'] and f['excitation']['sines_hz'] == [1, 2, 4, 8, 16, 32, 64]
    assert [p['frequency_hz'] for p in f['frequency_response']] == [1, 2, 4, 8, 16, 32, 64]
    low = f['frequency_response'][0]
    assert abs(low['magnitude_db']) < 1.0 and -20.0 < low['phase_deg'] <= 0.0
    assert 10.0 < f['bandwidth_hz'] < 60.0
    assert 0.0 < f['step']['rise_time'] < 0.3
    for key, value in f['step'].items():   # every missing step figure says why
        assert value is not None or key in f['step_notes'], key
    if f['step']['settling_time'] is None:
        assert 'not settled within the 1 s level' in f['step_notes']['settling_time']


def test_no_frequency_response_without_the_sines() -> None:
    """The profile's square wave alone (the bag cut before the first sine), and bags that
    never played the profile: a step at most, and "no excitation in this bag"."""
    data = _loaded('force_tracking')
    cut = _analysed('force_tracking')[1]['force']['step_t'] + 3.0
    partial = analyze.jsonable(analyze.analyze_bag(_without(data, cut)))['force']
    assert partial['step'] is not None
    for name, f in (('force_tracking cut', partial),
                    *((n, _analysed(n)[1]['force']) for n in
                      ('hold_disturbance', 'linear_slip', 'est_contact_cardboard'))):
        assert f['frequency_response'] is None, name
        assert f['bandwidth_hz'] is None, name
        assert not f['excitation']['found'] and f['excitation']['sines_hz'] == [], name
        assert f['excitation']['note'].startswith(analyze.NO_EXCITATION), name
    for name in ('hold_disturbance', 'linear_slip'):
        f = _analysed(name)[1]['force']
        assert f['step'] is None and 'no 5 → 25 N step' in f['step_note'], name


def test_force_peak_names_what_commanded_it() -> None:
    _, m = _analysed('hold_disturbance')
    peak = m['force']['peak']
    assert peak['phase'] == 'hold' and peak['source'] == 'the slip controller'
    assert peak['commanded'] and peak['force'] == pytest.approx(m['force']['measured']['max'])
    assert 'HOLD' in peak['explanation'] and 'slip controller' in peak['explanation']


# --- estimation ----------------------------------------------------------------------------

def test_final_estimate_keeps_r_although_the_first_estimate_has_none() -> None:
    _, m = _analysed('est_contact_cardboard')
    est = m['estimation']
    assert est['estimates'][0]['finger_1']['r'] is None      # the linear phase: r = NaN
    truth = est['truth']
    for key in ('finger_1', 'finger_2'):
        final = est['final'][key]
        assert final['r'] == pytest.approx(truth[key]['r'], rel=0.15), key
        assert final['mu_c'] == pytest.approx(truth[key]['mu_c'], rel=0.05), key
        assert 0.0 < final['r_std'] < 0.2 * final['r'] and final['mu_c_std'] > 0.0
        assert final['from_estimate']['r'] == len(est['estimates']) - 1
        assert est['spread'][key]['r']['mean'] == pytest.approx(final['r'])
    assert est['spread']['n_explorations'] == 1
    assert abs(est['error_final']['finger_1']['r']) < 0.15 * truth['finger_1']['r']


# --- phases, aborts, hold, slip ------------------------------------------------------------

def test_hold_bag_gives_hold_metrics() -> None:
    _, m = _analysed('hold_disturbance')
    assert [p['mode'] for p in m['phases']] == ['hold'] and m['aborts'] == []
    (hold,) = m['hold']
    assert hold['duration'] == pytest.approx(6.0, abs=0.1)
    assert 0.0 < hold['peak_slip_distance'] < 1e-3
    assert 0.0 < hold['peak_slip_angle'] < math.radians(1.0)
    # The sensors see the object's true slip (simulator truth), within 20 %.
    assert hold['peak_slip_distance'] == pytest.approx(hold['true_motion']['peak_distance'],
                                                       rel=0.2)
    # The pushes raise the force above the HOLD floor and it comes back.
    assert hold['force']['span'] > 3.0 and hold['force']['min'] < 4.5
    assert hold['command']['max'] > 8.0 and hold['force']['sd'] > 0.0


def test_linear_slip_bag_phases_and_outcome() -> None:
    _, m = _analysed('linear_slip')
    assert [p['mode'] for p in m['phases']] == ['linear', 'hold']
    assert m['ends'] == [{'mode': 'linear', 't': m['phases'][1]['t_start'], 'success': True,
                          'message': 'done'}]
    assert m['aborts'] == []
    (seg,) = m['slip']
    assert seg['outcome']['success'] and seg['target'] == pytest.approx(0.02, rel=0.02)
    assert len(m['hold']) == 1


def _aborted(data: dict[str, Any]) -> dict[str, Any]:
    """The linear-slip recording with its LINEAR ending "velocity stale" instead of done."""
    state = [replace(c, reason='LINEAR ended: velocity stale') if c.reason.endswith('done')
             else c for c in data['state']]
    assert state != data['state']
    return {**data, 'state': state}


def test_aborts_are_reported_with_their_message() -> None:
    m = analyze.jsonable(analyze.analyze_bag(_aborted(_loaded('linear_slip'))))
    assert m['aborts'] == [{'mode': 'linear', 't': m['phases'][1]['t_start'],
                            'success': False, 'message': 'velocity stale'}]
    assert m['slip'][0]['outcome']['success'] is False


# --- figures -------------------------------------------------------------------------------

def _figures(data: dict[str, Any]) -> dict[str, Any]:
    return analysis_plots.build_figures(data, analyze.analyze_bag(data))


def _gids(ax: Any, prefix: str) -> list[str]:
    artists = list(ax.patches) + list(ax.lines)
    return [a.get_gid() for a in artists if (a.get_gid() or '').startswith(prefix)]


def test_figures_of_a_linear_slip() -> None:
    data, m = _analysed('linear_slip')
    figs = _figures(data)
    assert set(figs) == {'force.png', 'slip.png', 'hold.png', 'twist.png', 'contact.png'}
    shaded = ['phase:linear', 'phase:hold']

    (ax,) = figs['force.png'].axes
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels[:3] == ['target F_d', 'measured F_m', 'finger 1 −Fz']
    assert _gids(ax, 'phase:') == shaded and _gids(ax, 'peak') == ['peak']
    assert ax.get_ylabel() == 'grasp force [N]'

    twist = figs['twist.png'].axes
    assert [a.get_ylabel() for a in twist] == [
        'finger 1 linear [mm/s]', 'finger 1 angular [rad/s]', 'finger 2 linear [mm/s]',
        'finger 2 angular [rad/s]']
    for a in twist:                     # one unit per axis: linear and angular never mixed
        names = [line.get_label() for line in a.get_lines()]
        assert names == (['v_x', 'v_y'] if '[mm/s]' in a.get_ylabel() else ['ω_z'])
        assert _gids(a, 'phase:') == shaded

    (ax,) = figs['slip.png'].axes
    assert ax.get_ylabel() == 'slip distance [mm]' and ax.get_title() == 'linear slip — done'
    assert [line.get_label() for line in ax.get_lines()][:2] == ['reference',
                                                                 'measured (controller)']
    assert _gids(ax, 'phase:') == shaded and _gids(ax, 'abort') == []
    final = ax.get_lines()[1].get_ydata()[-1]
    assert final == pytest.approx(m['slip'][0]['final_measured'] * 1e3)

    assert [a.get_ylabel() for a in figs['hold.png'].axes] == [
        'slip distance [mm]', 'slip angle [deg]', 'grasp force [N]']


def test_slip_figure_marks_an_abort() -> None:
    data = _aborted(_loaded('linear_slip'))
    figs = _figures(data)
    (ax,) = figs['slip.png'].axes
    assert ax.get_title() == 'linear slip — aborted: velocity stale'
    assert _gids(ax, 'abort') == ['abort']
    assert any('aborted: velocity stale' in t.get_text() for t in ax.texts)
    assert _gids(figs['force.png'].axes[0], 'abort') == ['abort']


def test_contact_figure_shows_the_final_estimate_with_error_bars() -> None:
    data, m = _analysed('est_contact_cardboard')
    fig = _figures(data)['contact.png']
    a_mu, a_r = fig.axes
    assert a_r.get_ylabel() == 'r [mm]' and a_mu.get_ylabel() == 'μ_c [-]'
    final, truth = m['estimation']['final'], m['estimation']['truth']
    from matplotlib.container import BarContainer
    bars = [c for c in a_r.containers if isinstance(c, BarContainer)]
    estimated, true = bars[0::2], bars[1::2]
    heights = [c.patches[0].get_height() for c in estimated]
    assert heights == pytest.approx([final[k]['r'] * 1e3 for k in ('finger_1', 'finger_2')])
    assert [c.patches[0].get_height() for c in true] == pytest.approx(
        [truth[k]['r'] * 1e3 for k in ('finger_1', 'finger_2')])
    assert all(c.errorbar is not None for c in estimated)
    assert _gids(a_r, 'not-estimated') == [] and not a_r.texts
    # The legend is the figure's, below the axes: it covers no bar.
    assert a_mu.get_legend() is None and a_r.get_legend() is None
    (legend,) = fig.legends
    fig.canvas.draw()
    box = legend.get_window_extent()
    for ax in fig.axes:
        assert not box.overlaps(ax.get_window_extent())


def test_force_tracking_figures_bode_and_step() -> None:
    data, m = _analysed('force_tracking')
    figs = _figures(data)
    assert {'force.png', 'force_step.png', 'force_bode.png'} <= set(figs)
    mag, phase = figs['force_bode.png'].axes
    assert mag.get_xscale() == 'log' and mag.get_ylabel() == 'magnitude [dB]'
    assert phase.get_ylabel() == 'phase [deg]' and phase.get_xlabel() == 'frequency [Hz]'
    def line(ax: Any, label: str) -> Any:
        return next(x for x in ax.get_lines() if x.get_label() == label)
    assert list(line(mag, '|F_m / F_d|').get_xdata()) == [1, 2, 4, 8, 16, 32, 64]
    assert list(line(phase, 'phase').get_ydata()) == [
        p['phase_deg'] for p in m['force']['frequency_response']]
    (ax,) = figs['force_step.png'].axes
    assert ax.get_xlabel() == 'time from the commanded step [s]'
    assert ax.get_ylabel() == 'grasp force [N]'
    assert any('not settled' in t.get_text() for t in figs['force_step.png'].texts) == (
        m['force']['step']['settling_time'] is None)


def test_no_bode_figure_without_excitation() -> None:
    data = _loaded('force_tracking')
    cut = _without(data, _analysed('force_tracking')[1]['force']['step_t'] + 3.0)
    figs = _figures(cut)
    assert 'force_bode.png' not in figs and 'force_step.png' in figs


# --- the command line ----------------------------------------------------------------------

def test_report_reads_the_bag_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls = []
    real = analyze.iter_raw

    def counting(*args: Any, **kwargs: Any) -> Any:
        calls.append(args)
        return real(*args, **kwargs)
    monkeypatch.setattr(analyze, 'iter_raw', counting)
    metrics, plots = analyze.report(_bag('hold_disturbance'), tmp_path)
    assert len(calls) == 1
    assert sorted(p.name for p in plots) == ['contact.png', 'force.png', 'hold.png', 'twist.png']
    assert json.loads((tmp_path / 'metrics.json').read_text()) == metrics


def test_main_prints_progress_and_the_metrics(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    assert analyze.main([str(_bag('linear_slip')), '--out', str(tmp_path), '--no-plots']) == 0
    out, err = capsys.readouterr()
    metrics = json.loads(out)
    assert {'force', 'estimation', 'slip', 'hold', 'phases', 'aborts'} <= set(metrics)
    lines = err.splitlines()
    assert all(line.startswith('slip_analyze: [') for line in lines), lines
    assert any('in one pass' in line for line in lines)
    assert any(line.endswith('metrics.json') for line in lines) and 'done' in lines[-1]
    assert not list(tmp_path.glob('*.png'))


def test_state_changes_before_the_recording_start_a_phase_at_its_start() -> None:
    data = _loaded('hold_disturbance')
    early = {**data, 'state': [StateChange(data['span'][0] - 5.0, 4, 'set_mode: HOLD')]}
    m = analyze.analyze_bag(early)
    assert m['phases'][0]['t_start'] == data['span'][0]
    assert np.isclose(m['hold'][0]['duration'], data['span'][1] - data['span'][0])
