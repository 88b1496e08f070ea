"""The figures of ``slip_analyze`` (matplotlib, no pyplot state: each is a `Figure` object).

`build_figures` returns the figures of a loaded bag and its metrics (`slip_bringup.analyze`)
so that tests can look at what they show; `save_figures` writes them as PNG. Every timeline
shades the slip controller's phases (one colour per mode; OFF unshaded) and marks aborted
trajectories with a red dashed line and their message. Each axis carries one unit.

Artists that tests look for carry a ``gid``: ``phase:<mode>`` (shaded phase), ``abort``
(abort marker), ``peak`` (the force peak), ``not-estimated`` (an estimate that is missing).
"""
from __future__ import annotations

import math
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from slip_bringup.core.phases import Phase
from slip_cell_common.core.frames import FrameParams

#: Shading per controller mode (OFF is not shaded).
PHASE_COLORS = {'hold': '#cfe2f3', 'linear': '#fce5cd', 'rotational': '#d9ead3',
                'hinge': '#e4d7f1'}
DEG = 180.0 / math.pi


def _runs(metrics: dict[str, Any]) -> list[Phase]:
    return [Phase(**p) for p in metrics.get('phases', [])]


def shade_phases(ax: Axes, runs: list[Phase], t_ref: float,
                 window: tuple[float, float] | None = None) -> int:
    """Shade every non-OFF phase (clipped to ``window`` [s, absolute]); returns how many."""
    n = 0
    for p in runs:
        color = PHASE_COLORS.get(p.mode)
        if color is None:
            continue
        a, b = p.t_start, p.t_end
        if window is not None:
            a, b = max(a, window[0]), min(b, window[1])
        if b <= a:
            continue
        ax.axvspan(a - t_ref, b - t_ref, color=color, lw=0, zorder=0, gid=f'phase:{p.mode}')
        n += 1
    return n


def mark_aborts(ax: Axes, aborts: list[dict[str, Any]], t_ref: float, label: bool = True,
                window: tuple[float, float] | None = None) -> int:
    """A red dashed line (and the message) at every aborted trajectory; returns how many."""
    n = 0
    for a in aborts:
        if window is not None and not window[0] <= a['t'] <= window[1]:
            continue
        x = a['t'] - t_ref
        ax.axvline(x, color='red', ls='--', lw=1.0, zorder=3, gid='abort')
        if label:
            ax.annotate(f'{a["mode"].upper()} aborted: {a["message"]}', xy=(x, 1.0),
                        xycoords=('data', 'axes fraction'), xytext=(3, -3),
                        textcoords='offset points', ha='left', va='top', fontsize=7,
                        color='red', rotation=90)
        n += 1
    return n


def _phase_handles(runs: list[Phase], aborts: list[dict[str, Any]]) -> list[Any]:
    present = [m for m in PHASE_COLORS if any(p.mode == m for p in runs)]
    handles: list[Any] = [Patch(color=PHASE_COLORS[m], label=m.upper()) for m in present]
    if aborts:
        from matplotlib.lines import Line2D
        handles.append(Line2D([], [], color='red', ls='--', lw=1.0, label='abort'))
    return handles


def _legend(ax: Axes, extra: list[Any] | None = None) -> None:
    """Legend outside the axes, on the right: it never covers data."""
    handles, _ = ax.get_legend_handles_labels()
    ax.legend(handles=handles + (extra or []), loc='upper left', bbox_to_anchor=(1.01, 1.0),
              fontsize=8, borderaxespad=0.0)


def _time_label(t_ref: float) -> str:
    return f'time [s] from the first stamp ({t_ref:.3f} s)'


def force_figure(data: dict[str, Any], metrics: dict[str, Any]) -> Figure:
    """Target, measured and finger-1 force over the recording; phases, aborts, the peak."""
    t_ref = data['span'][0]
    runs = _runs(metrics)
    aborts = metrics.get('aborts', [])
    fig = Figure(figsize=(10, 4.2))
    ax = fig.subplots()
    m = data['motor']
    ax.plot(m.t - t_ref, m.cols['target'], lw=1.0, label='target F_d')
    ax.plot(m.t - t_ref, m.cols['measured'], lw=1.0, label='measured F_m')
    if 'ft1' in data:
        ax.plot(data['ft1'].t - t_ref, -data['ft1'].cols['fz'], lw=0.5, alpha=0.6,
                label='finger 1 −Fz')
    shade_phases(ax, runs, t_ref)
    mark_aborts(ax, aborts, t_ref)
    peak = metrics['force'].get('peak')
    if peak is not None:
        ax.plot([peak['t'] - t_ref], [peak['force']], 'v', color='k', ms=7, gid='peak',
                label='peak')
        fig.text(0.01, 0.01, '\n'.join(textwrap.wrap(peak['explanation'], 140)),
                 fontsize=8, va='bottom')
    ax.set(xlabel=_time_label(t_ref), ylabel='grasp force [N]', title='Grasp force')
    _legend(ax, _phase_handles(runs, aborts))
    fig.subplots_adjust(bottom=0.22, right=0.82)
    return fig


def step_figure(data: dict[str, Any], metrics: dict[str, Any]) -> Figure | None:
    """The 5 → 25 N step of the force-tracking profile (§6.1), time from the step."""
    f = metrics['force']
    if not f.get('step') or 'ft1' not in data:
        return None
    t_step, step = f['step_t'], f['step']
    lo, hi = t_step - 0.3, t_step + 1.0
    fig = Figure(figsize=(8, 4.2))
    ax = fig.subplots()
    cmd = data['cmd'].window(lo, hi)
    mine = cmd.cols['source'] == f.get('command_source_id', -1)
    ft = data['ft1'].window(lo, hi)
    ax.step(cmd.t[mine] - t_step, cmd.cols['force'][mine], where='post', lw=1.2,
            label=f'command ({f.get("command_source", "?")})')
    motor = data['motor'].window(lo, hi)
    ax.plot(motor.t - t_step, motor.cols['target'], lw=0.8, color='C2', alpha=0.8,
            label='loop target F_d (all sources)')
    ax.plot(ft.t - t_step, -ft.cols['fz'], lw=1.0, color='C1', label='measured (finger 1 −Fz)')
    ax.axhspan(25.0 - 0.4, 25.0 + 0.4, color='0.85', lw=0, zorder=0, label='±0.4 N band')
    for key, style in (('t50', ':'), ('settling_time', '--')):
        value = step.get(key)
        if value is not None and math.isfinite(value):
            ax.axvline(value, color='k', ls=style, lw=0.8, label=key.replace('_', ' '))
    lines = [f'{k.replace("_", " ")}: ' + (f'{v * 1e3:.1f} ms' if k != 'overshoot' and
                                          k != 'peak' else f'{v:.2f} N')
             if v is not None and math.isfinite(v) else f'{k.replace("_", " ")}: —'
             for k, v in step.items()]
    notes = [f'{k.replace("_", " ")}: {v}' for k, v in f.get('step_notes', {}).items()]
    fig.text(0.01, 0.01, '; '.join(lines) + ('\n' + '\n'.join(notes) if notes else ''),
             fontsize=8, va='bottom')
    ax.set(xlabel='time from the commanded step [s]', ylabel='grasp force [N]',
           title='Force step response 5 → 25 N')
    _legend(ax)
    fig.subplots_adjust(bottom=0.25, right=0.74)
    return fig


def bode_figure(metrics: dict[str, Any]) -> Figure | None:
    """Magnitude and phase of the force loop at the excited sine frequencies (§6.2)."""
    f = metrics['force']
    points = f.get('frequency_response')
    if not points:
        return None
    freq = np.array([p['frequency_hz'] for p in points], dtype=float)
    mag = np.array([np.nan if p['magnitude_db'] is None else p['magnitude_db'] for p in points],
                   dtype=float)
    phase = np.array([p['phase_deg'] for p in points], dtype=float)
    fig = Figure(figsize=(7, 5.5))
    a1, a2 = fig.subplots(2, 1, sharex=True)
    a1.semilogx(freq, mag, 'o-', label='|F_m / F_d|')
    a1.axhline(-3.0, color='k', ls=':', lw=0.8, label='−3 dB')
    bw = f.get('bandwidth_hz')
    if bw is not None and math.isfinite(bw):
        for ax in (a1, a2):
            ax.axvline(bw, color='C3', ls='--', lw=0.8)
        a1.plot([], [], color='C3', ls='--', label=f'bandwidth {bw:.1f} Hz')
    a2.semilogx(freq, phase, 'o-', color='C1', label='phase')
    a1.set(ylabel='magnitude [dB]', title='Force-loop frequency response')
    a2.set(xlabel='frequency [Hz]', ylabel='phase [deg]')
    a1.legend(loc='lower left', fontsize=8)
    fig.text(0.01, 0.01, f'{f["excitation"]["note"]}; bandwidth: {f.get("bandwidth_note")}',
             fontsize=8, va='bottom')
    fig.subplots_adjust(bottom=0.13)
    return fig


def slip_figure(data: dict[str, Any], metrics: dict[str, Any]) -> Figure | None:
    """Reference and measured slip per LINEAR / ROTATIONAL segment, with the phases and the
    outcome (abort marked)."""
    segs = metrics.get('slip', [])
    if not segs or 'tracking' not in data:
        return None
    runs = _runs(metrics)
    aborts = metrics.get('aborts', [])
    fig = Figure(figsize=(10, 3.0 * len(segs)))
    axes = fig.subplots(len(segs), 1, squeeze=False)[:, 0]
    for ax, seg in zip(axes, segs):
        t0, t1 = seg['t_start'], seg['t_end']
        window = (t0 - 0.3, t1 + 1.0)
        track = data['tracking'].window(t0, t1)
        linear = seg['mode'] == 'linear'
        scale, unit = (1e3, 'mm') if linear else (DEG, 'deg')
        ax.plot(track.t - t0, track.cols['ref_pos'] * scale, label='reference')
        ax.plot(track.t - t0, track.cols['meas_pos'] * scale, label='measured (controller)')
        ax.axhline(seg['target'] * scale, color='k', ls=':', lw=0.8, label='target')
        shade_phases(ax, runs, t0, window)
        mark_aborts(ax, aborts, t0, window=window)
        outcome = seg.get('outcome')
        verdict = ('' if outcome is None else ' — done' if outcome['success'] else
                   f' — aborted: {outcome["message"]}')
        ax.set(xlabel=f'time [s] from the start of the {seg["mode"]} slip',
               ylabel=f'slip {"distance" if linear else "angle"} [{unit}]',
               title=f'{seg["mode"]} slip{verdict}', xlim=(window[0] - t0, window[1] - t0))
        _legend(ax, _phase_handles([p for p in runs if p.t_end >= window[0]
                                    and p.t_start <= window[1]],
                                   [a for a in aborts if window[0] <= a['t'] <= window[1]]))
    fig.subplots_adjust(right=0.78, hspace=0.55)
    return fig


def hold_figure(data: dict[str, Any], metrics: dict[str, Any],
                frames: FrameParams) -> Figure | None:
    """Accumulated slip distance and angle in every HOLD phase, and the grasp force (§6.7)."""
    from slip_bringup.analyze import hold_series
    holds = [h for h in metrics.get('hold', []) if 'peak_slip_distance' in h]
    if not holds:
        return None
    t_ref = data['span'][0]
    runs = _runs(metrics)
    aborts = metrics.get('aborts', [])
    fig = Figure(figsize=(10, 7))
    a_d, a_a, a_f = fig.subplots(3, 1, sharex=True)
    for i, h in enumerate(holds):
        phase = Phase('hold', h['t_start'], h['t_end'], '')
        series = hold_series(data, phase, frames)
        if series is None:
            continue
        t, dist, ang = series
        a_d.plot(t - t_ref, dist * 1e3, color='C0', label='slip distance' if i == 0 else None)
        a_a.plot(t - t_ref, ang * DEG, color='C1', label='slip angle' if i == 0 else None)
    m = data['motor']
    a_f.plot(m.t - t_ref, m.cols['measured'], lw=1.0, label='measured F_m')
    if 'cmd' in data:
        a_f.step(data['cmd'].t - t_ref, data['cmd'].cols['force'], where='post', lw=0.8,
                 label='command')
    for ax in (a_d, a_a, a_f):
        shade_phases(ax, runs, t_ref)
        mark_aborts(ax, aborts, t_ref, label=ax is a_d)
    a_d.set(ylabel='slip distance [mm]',
            title='Slip accumulated in each HOLD phase (velocity sensors)')
    a_a.set(ylabel='slip angle [deg]')
    a_f.set(ylabel='grasp force [N]', xlabel=_time_label(t_ref))
    _legend(a_d, _phase_handles(runs, aborts))
    _legend(a_a)
    _legend(a_f)
    fig.subplots_adjust(right=0.8)
    return fig


def twist_figure(data: dict[str, Any], metrics: dict[str, Any]) -> Figure | None:
    """Each finger's slip twist: linear [mm/s] and angular [rad/s] on separate axes."""
    fingers = [k for k in (1, 2) if f'tw{k}' in data]
    if not fingers:
        return None
    t_ref = data['span'][0]
    runs = _runs(metrics)
    aborts = metrics.get('aborts', [])
    fig = Figure(figsize=(10, 2.2 * 2 * len(fingers)))
    axes = fig.subplots(2 * len(fingers), 1, sharex=True)
    for j, k in enumerate(fingers):
        s = data[f'tw{k}']
        lin, rot = axes[2 * j], axes[2 * j + 1]
        lin.plot(s.t - t_ref, s.cols['vx'] * 1e3, lw=0.8, label='v_x')
        lin.plot(s.t - t_ref, s.cols['vy'] * 1e3, lw=0.8, label='v_y')
        rot.plot(s.t - t_ref, s.cols['wz'], lw=0.8, color='C2', label='ω_z')
        lin.set(ylabel=f'finger {k} linear [mm/s]')
        rot.set(ylabel=f'finger {k} angular [rad/s]')
        for ax in (lin, rot):
            shade_phases(ax, runs, t_ref)
            mark_aborts(ax, aborts, t_ref, label=False)
            _legend(ax)
    _legend(axes[0], _phase_handles(runs, aborts))
    axes[-1].set(xlabel=_time_label(t_ref))
    fig.suptitle('Slip twist per finger (pad frames)')
    fig.subplots_adjust(right=0.82, hspace=0.35)
    return fig


def contact_figure(metrics: dict[str, Any]) -> Figure | None:
    """The final estimate (±1σ error bars) and the simulator's truth, per finger."""
    est = metrics.get('estimation', {})
    final, truth = est.get('final'), est.get('truth')
    if not final and not truth:
        return None
    fig = Figure(figsize=(9, 3.8))
    a_mu, a_r = fig.subplots(1, 2)
    width = 0.35
    for ax, name, scale, unit in ((a_mu, 'mu_c', 1.0, '[-]'), (a_r, 'r', 1e3, '[mm]')):
        for k, key in enumerate(('finger_1', 'finger_2')):
            for offset, label, source, color in ((0, 'final estimate (±1σ)', final, 'C0'),
                                                 (1, 'simulator truth', truth, 'C1')):
                if not source:
                    continue
                value = source[key].get(name)
                std = source[key].get(f'{name}_std') if offset == 0 else None
                x = k + (offset - 0.5) * width
                show = label if k == 0 else None
                if value is None or not math.isfinite(value):
                    ax.bar(x, 0.0, width, color=color, label=show)
                    ax.text(x, 0.0, 'not\nestimated', ha='center', va='bottom', fontsize=7,
                            gid='not-estimated')
                    continue
                err = None if std is None or not math.isfinite(std) else std * scale
                ax.bar(x, value * scale, width, color=color, label=show, yerr=err,
                       capsize=4 if err is not None else 0)
        ax.set_xticks([0, 1], ['finger 1', 'finger 2'])
        ax.set(ylabel=f'{"μ_c" if name == "mu_c" else "r"} {unit}',
               title='Coulomb coefficient μ_c' if name == 'mu_c' else 'torsional radius r')
    handles, labels = a_mu.get_legend_handles_labels()
    fig.legend(handles, labels, loc='lower center', ncol=2, fontsize=8, frameon=False)
    fig.subplots_adjust(bottom=0.22, wspace=0.3)
    return fig


def build_figures(data: dict[str, Any], metrics: dict[str, Any],
                  frames: FrameParams | None = None) -> dict[str, Figure]:
    """Every figure the bag supports, by file name (``force.png``, ...).

    ``data`` is what `slip_bringup.analyze.load` returns, ``metrics`` what
    `slip_bringup.analyze.analyze_bag` returns for it (NaN or None for absent values).
    """
    from slip_bringup.analyze import jsonable
    frames = frames or FrameParams()
    metrics = jsonable(metrics)
    makers: dict[str, Callable[[], Figure | None]] = {
        'force.png': lambda: force_figure(data, metrics),
        'force_step.png': lambda: step_figure(data, metrics),
        'force_bode.png': lambda: bode_figure(metrics),
        'slip.png': lambda: slip_figure(data, metrics),
        'hold.png': lambda: hold_figure(data, metrics, frames),
        'twist.png': lambda: twist_figure(data, metrics),
        'contact.png': lambda: contact_figure(metrics),
    }
    out = {}
    for name, make in makers.items():
        fig = make()
        if fig is not None:
            out[name] = fig
    return out


def save_figures(data: dict[str, Any], metrics: dict[str, Any], out_dir: Path,
                 progress: Callable[[str], None] | None = None) -> list[Path]:
    """Write `build_figures` as PNG files in ``out_dir``; returns their paths."""
    say = progress or (lambda text: None)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    say('plotting')
    for name, fig in build_figures(data, metrics).items():
        path = out_dir / name
        fig.savefig(path, dpi=110, bbox_inches='tight')
        written.append(path)
        say(f'wrote {path}')
    return written
