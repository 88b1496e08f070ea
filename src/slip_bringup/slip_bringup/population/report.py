# SPDX-License-Identifier: Apache-2.0
"""Population report: summary per scenario and controller, text table, JSON, CSV, PNG plots."""
from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

from slip_bringup.population.results import SCENARIOS, ObjectResult, ScenarioResult
from slip_bringup.population.statistics import (Distribution, Rate, Split, best_split,
                                                distribution, wilson_interval)

#: Per scenario: the error metrics summarised in the table, with their display unit and scale.
ERROR_METRICS: dict[str, tuple[tuple[str, str, float], ...]] = {
    'estimation': (('mu_c_error', '-', 1.0), ('r_error_rel', '%', 100.0)),
    'hold': (('slip_peak', 'mm', 1e3), ('rotation_peak', 'deg', 180.0 / math.pi),
             ('force_peak_over_needed', '-', 1.0)),
    'linear': (('final_error', 'mm', 1e3), ('tracking_rms', 'mm', 1e3),
               ('duration_error_rel', '%', 100.0), ('off_axis', 'mm', 1e3)),
    'rotational': (('final_error', 'deg', 180.0 / math.pi),
                   ('tracking_rms', 'deg', 180.0 / math.pi),
                   ('duration_error_rel', '%', 100.0), ('translation', 'mm', 1e3)),
    'hinge': (('rotation_error', 'deg', 180.0 / math.pi), ('translation_turn', 'mm', 1e3)),
}
#: The metric that ranks the worst cases of a scenario.
WORST_BY = {'estimation': 'r_error_rel', 'hold': 'rotation_peak', 'linear': 'final_error',
            'rotational': 'final_error', 'hinge': 'rotation_error'}


@dataclass(frozen=True)
class ScenarioSummary:
    """One scenario under one controller family over the population.

    Attributes:
        scenario: Scenario name.
        controller: Control-law family ('-' for estimation).
        objects: Objects it ran on.
        infeasible: Objects on which it is physically impossible (`feasibility`).
        rate: Success on the feasible objects, with its 95 % interval.
        errors: Error distributions on the feasible objects (`ERROR_METRICS`).
        coverage: Estimation: share of fingers whose reported 95 % interval covers the truth.
        split: The parameter threshold that best separates failures (feasible objects).
        failures: Failure causes and their counts (feasible objects).
        worst: The worst feasible cases (failures first), with the seed and index that
            reproduce each.
        finger_rate: Estimation: fingers within tolerance over all fingers.
        infeasible_reasons: Infeasibility categories and their counts.
        infeasible_claimed: Infeasible objects on which the controller reported success.
    """

    scenario: str
    controller: str
    objects: int
    infeasible: int
    rate: Rate
    errors: dict[str, Distribution]
    coverage: dict[str, float]
    split: Split | None
    failures: dict[str, int]
    worst: list[dict[str, object]]
    finger_rate: Rate | None = None
    infeasible_reasons: dict[str, int] = field(default_factory=dict)
    infeasible_claimed: int = 0


def controllers_in(results: Sequence[ObjectResult]) -> list[str]:
    """Controller families present, thesis first."""
    found = {s.controller for r in results for s in r.scenarios if s.controller != '-'}
    return sorted(found, key=lambda c: (c != 'thesis', c))


def summarise(results: Sequence[ObjectResult]) -> list[ScenarioSummary]:
    """A `ScenarioSummary` per scenario and controller family (estimation once)."""
    out: list[ScenarioSummary] = []
    for scenario in SCENARIOS:
        families = ['-'] if scenario == 'estimation' else controllers_in(results)
        for controller in families:
            rows: list[tuple[ObjectResult, ScenarioResult]] = []
            for r in results:
                s = r.get(scenario, controller)
                if s is not None:
                    rows.append((r, s))
            if rows:
                out.append(_summary(scenario, controller, rows))
    return out


def _summary(scenario: str, controller: str,
             rows: list[tuple[ObjectResult, ScenarioResult]]) -> ScenarioSummary:
    feasible = [(r, s) for r, s in rows if s.feasible]
    ok = sum(1 for _, s in feasible if s.success)
    errors = {name: distribution([s.metric(name) for _, s in feasible])
              for name, _, _ in ERROR_METRICS.get(scenario, ())}
    coverage: dict[str, float] = {}
    for name in ('mu_c_covered', 'r_covered'):
        vals = [s.metric(name) for _, s in feasible if math.isfinite(s.metric(name))]
        if vals:
            coverage[name] = sum(vals) / len(vals)
    failed = [not s.success for _, s in feasible]
    params = {k: [r.parameters.get(k, math.nan) for r, _ in feasible]
              for k in (feasible[0][0].parameters if feasible else {})}
    failures: dict[str, int] = {}
    for _, s in feasible:
        if not s.success:
            key = s.failure.split(':')[0]
            failures[key] = failures.get(key, 0) + 1
    key = WORST_BY.get(scenario, '')

    def badness(rs: tuple[ObjectResult, ScenarioResult]) -> tuple[bool, float]:
        v = rs[1].metric(key)
        return rs[1].success, -abs(v) if math.isfinite(v) else -math.inf

    worst = [{'object': r.name, 'seed': r.seed, 'index': r.index, key: s.metric(key),
              'success': s.success, 'failure': s.failure}
             for r, s in sorted(feasible, key=badness)[:5]]
    finger_rate = None
    if scenario == 'estimation':
        fingers = [s.metric('fingers_ok') for _, s in feasible]
        good = [v for v in fingers if math.isfinite(v)]
        finger_rate = wilson_interval(int(round(2 * sum(good))), 2 * len(fingers))
    reasons: dict[str, int] = {}
    claimed = 0
    for _, s in rows:
        if not s.feasible:
            cat = s.infeasible_reason.split(':')[0]
            reasons[cat] = reasons.get(cat, 0) + 1
            claimed += int(s.metric('claimed_success') == 1.0)
    return ScenarioSummary(scenario=scenario, controller=controller, objects=len(rows),
                           infeasible=len(rows) - len(feasible),
                           rate=wilson_interval(ok, len(feasible)), errors=errors,
                           coverage=coverage, split=best_split(params, failed),
                           failures=failures, worst=worst, finger_rate=finger_rate,
                           infeasible_reasons=reasons, infeasible_claimed=claimed)


def format_table(summaries: Sequence[ScenarioSummary], cpu_per_object: float,
                 wall_seconds: float, count: int) -> str:
    """Plain-text report (success with 95 % CI on the feasible objects, then errors)."""
    lines = [f'{"scenario":<11} {"controller":<8} {"feasible":>8} {"success":>8} '
             f'{"95 % CI":>15}   errors on feasible objects: median / p90 / max']
    for s in summaries:
        ci = (f'{100 * s.rate.low:5.1f}-{100 * s.rate.high:5.1f} %'
              if s.rate.trials else '-')
        rate = f'{100 * s.rate.value:6.1f} %' if s.rate.trials else '-'
        errs = []
        for name, unit, scale in ERROR_METRICS.get(s.scenario, ()):
            d = s.errors.get(name)
            if d is not None and d.count:
                errs.append(f'{name} {d.median * scale:.3g}/{d.p90 * scale:.3g}/'
                            f'{d.max * scale:.3g} {unit}')
        lines.append(f'{s.scenario:<11} {s.controller:<8} {s.objects - s.infeasible:>4}/'
                     f'{s.objects:<3} {rate:>8} {ci:>15}   ' + '; '.join(errs))
        fr = s.finger_rate
        if fr is not None and fr.trials:
            lines.append(f'{"":<29}fingers within tolerance: {fr.successes}/{fr.trials} = '
                         f'{100 * fr.value:.1f} % (95 % CI {100 * fr.low:.1f}-'
                         f'{100 * fr.high:.1f} %)')
        for name, value in s.coverage.items():
            lines.append(f'{"":<29}coverage of the reported 95 % interval, '
                         f'{name.replace("_covered", "")}: {100 * value:.1f} %')
        if s.split is not None and s.rate.successes < s.rate.trials:
            sp = s.split
            side = '>' if sp.failures_above else '<='
            lines.append(f'{"":<29}failures separate by {sp.parameter} {side} '
                         f'{sp.threshold:.4g}: {100 * sp.failure_rate_inside:.0f} % fail there '
                         f'({sp.count_inside} objects), {100 * sp.failure_rate_outside:.0f} % '
                         f'elsewhere')
        if s.failures:
            causes = ', '.join(f'{k} x{v}' for k, v in sorted(s.failures.items(),
                                                              key=lambda kv: -kv[1]))
            lines.append(f'{"":<29}failures: {causes}')
        bad = [w for w in s.worst if not w['success']][:3]
        if bad:
            lines.append(f'{"":<29}worst: ' + '; '.join(
                f'{w["object"]} (--object {w["seed"]}:{w["index"]}) {w["failure"]}'
                for w in bad))
        if s.infeasible:
            why = ', '.join(f'{k} x{v}' for k, v in sorted(s.infeasible_reasons.items(),
                                                         key=lambda kv: -kv[1]))
            claim = (f'; the controller reported success on {s.infeasible_claimed} of them'
                     if s.infeasible_claimed else '')
            lines.append(f'{"":<29}infeasible: {why}{claim}')
    lines.append(f'{count} objects; {cpu_per_object:.2f} CPU-s per object; '
                 f'{wall_seconds:.0f} s wall')
    return '\n'.join(lines)


def _plain(value: object) -> object:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def write_json(path: Path, summaries: Sequence[ScenarioSummary],
               results: Sequence[ObjectResult], meta: dict[str, object]) -> None:
    """Summary and every object's results as JSON (NaN written as null)."""
    doc = {'meta': meta,
           'summary': [dict(asdict(s), success_rate=s.rate.value) for s in summaries],
           'objects': [asdict(r) for r in results]}
    path.write_text(json.dumps(_plain(doc), indent=1))


def write_csv(path: Path, results: Sequence[ObjectResult]) -> None:
    """One row per object, scenario and controller: parameters, outcome and metrics."""
    param_keys = sorted({k for r in results for k in r.parameters})
    metric_keys = sorted({k for r in results for s in r.scenarios for k in s.metrics})
    with path.open('w', newline='') as fh:
        w = csv.writer(fh)
        w.writerow(['seed', 'index', 'object', 'surface', 'scenario', 'controller', 'feasible',
                    'success', 'failure', 'infeasible_reason', 'reported']
                   + param_keys + metric_keys)
        for r in results:
            for s in r.scenarios:
                w.writerow([r.seed, r.index, r.name, r.surface, s.scenario, s.controller,
                            int(s.feasible), int(s.success), s.failure, s.infeasible_reason,
                            s.reported]
                           + [_fmt(r.parameters.get(k)) for k in param_keys]
                           + [_fmt(s.metrics.get(k)) for k in metric_keys])


def _fmt(v: float | None) -> str:
    return '' if v is None or not math.isfinite(v) else f'{v:.6g}'


#: Parameters each scenario's main error is plotted against (besides the best split's).
TELLING: dict[str, tuple[str, ...]] = {
    'estimation': ('static_ratio_max', 'gradient_map'),
    'hold': ('mass', 'com_lever_over_r'),
    'linear': ('mass', 'com_angle_from_down'),
    'rotational': ('com_lever_over_r', 'mass'),
    'hinge': ('com_lever_over_r', 'mass'),
}


def write_plots(out_dir: Path, results: Sequence[ObjectResult],
                summaries: Sequence[ScenarioSummary]) -> list[Path]:
    """One PNG per scenario and controller: its main error (signed) against the parameter
    that separates failures and the scenario's telling parameters (`TELLING`); successes,
    failures and infeasible objects marked apart."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    written: list[Path] = []
    for s in summaries:
        metric = WORST_BY.get(s.scenario, '')
        unit_scale = {n: (u, k) for n, u, k in ERROR_METRICS.get(s.scenario, ())}
        unit, scale = unit_scale.get(metric, ('', 1.0))
        params = list(TELLING.get(s.scenario, ('mass',)))
        if s.split is not None and s.split.parameter not in params:
            params.insert(0, s.split.parameter)
        fig, axes = plt.subplots(1, len(params), figsize=(4.2 * len(params), 3.8),
                                 squeeze=False, sharey=True)
        for ax, param in zip(axes[0], params):
            groups: dict[str, tuple[list[float], list[float]]] = {
                'success': ([], []), 'failure': ([], []), 'infeasible': ([], [])}
            for r in results:
                sr = r.get(s.scenario, s.controller)
                if sr is None:
                    continue
                kind = ('infeasible' if not sr.feasible else
                        'success' if sr.success else 'failure')
                groups[kind][0].append(r.parameters.get(param, math.nan))
                groups[kind][1].append(sr.metric(metric) * scale)
            for kind, style in (('infeasible', {'color': '0.7', 'marker': '.', 's': 16}),
                                ('success', {'color': 'tab:blue', 'marker': 'o', 's': 14}),
                                ('failure', {'color': 'tab:red', 'marker': 'x', 's': 20})):
                xs, ys = groups[kind]
                if xs:
                    ax.scatter(xs, ys, label=f'{kind} ({len(xs)})', **style)
            if s.split is not None and param == s.split.parameter:
                ax.axvline(s.split.threshold, color='tab:red', lw=0.8, ls='--')
            ax.set_xlabel(param)
            ax.grid(True, alpha=0.3)
        axes[0][0].set_ylabel(f'{metric} [{unit}]')
        axes[0][0].legend(loc='best', fontsize=7)
        rate = (f'{100 * s.rate.value:.1f} % of {s.rate.trials} feasible objects'
                if s.rate.trials else 'no feasible object')
        fig.suptitle(f'{s.scenario} ({s.controller}): {rate}', fontsize=10)
        fig.tight_layout()
        path = out_dir / f'{s.scenario}_{s.controller.strip("-") or "estimator"}.png'
        fig.savefig(path, dpi=100)
        plt.close(fig)
        written.append(path)
    return written
