# SPDX-License-Identifier: Apache-2.0
"""``slip_evaluate``: evaluate the contact estimator and the slip controllers in-process.

Runs `slip_bringup.core.evaluation.table.evaluate_all` on the simulated cell (no ROS, no DDS;
sim time, deterministic for a seed; the slip controller node's own host and the experiment
runner's own exploration) and prints the table of issue 7 item 4: per reference
object the μ_c and r estimation errors per finger, LINEAR 2 cm / 2 s and 4 cm / 5 s and
ROTATIONAL 20° / 2 s and 45° / 5 s final errors, peak slip under HOLD disturbances, and the
hinge through 60°, all measured from the simulator truth. Then, unless ``--quick`` or
``--no-online``, the ONLINE estimator (§3.6) is judged by `online_refinement`: started from the
true μ_c and r times 0.8 and 1.2, refined during a LINEAR and a ROTATIONAL slip (≈ 3 s wall per
preset and start).

With ``--population N`` it evaluates N objects drawn at random from the simulator's supported
ranges instead (`slip_bringup.population`): exploration + estimation, HOLD under loads scaled
to the object, LINEAR 20 mm / 2 s, ROTATIONAL 20° / 2 s and HINGE 60°, judged by the
simulator truth, on local worker processes (all cores by default) or a Dask distributed
cluster (``--scheduler``). A progress bar runs on stderr; the table goes to stdout, and JSON,
CSV and PNG plots to ``--out`` (default ``./population-<seed>-<N>`` in the current
directory). ``--object SEED:INDEX`` runs one object of a population and prints everything
measured on it (the worst cases of a table name theirs).

Examples::

    slip_evaluate                           # the four reference objects (~20-60 s)
    slip_evaluate --preset cardboard --quick
    slip_evaluate --preset wood,case --truth-properties
    slip_evaluate --no-online               # skip the online-refinement table
    slip_evaluate --population 200 --seed 11                 # local worker processes
    slip_evaluate --population 200 --seed 11 --scheduler tcp://10.0.0.5:8786
    slip_evaluate --object 11:42            # one object of population 11, verbose
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from friction_models.core.population import draw_object

from slip_bringup.core.evaluation.online import ONLINE_START_SCALES, online_refinement
from slip_bringup.core.evaluation.report import format_online_table, format_table
from slip_bringup.core.evaluation.settings import REFERENCE_PRESETS, EvalSettings, EvaluationError
from slip_bringup.core.evaluation.table import evaluate_all
from slip_bringup.population import report as population_report
from slip_bringup.population.backends import default_workers
from slip_bringup.population.progress import ProgressBar
from slip_bringup.population.results import ObjectResult
from slip_bringup.population.run import PopulationRun, make_tasks, run_tasks
from slip_cell_common.core.cli_args import (Parser, non_negative_int, plain_doc,
                                            positive_float, positive_int)
from slip_bringup.population.runner import (THESIS, PopulationTask, available_families,
                                            evaluate_object)


def _parser() -> Parser:
    p = Parser(prog='slip_evaluate', description=plain_doc(__doc__))
    p.add_argument('--preset', action='append', default=None, metavar='NAME[,NAME...]',
                   help='object preset(s); repeatable or comma-separated '
                        f'(default: {", ".join(REFERENCE_PRESETS)})')
    p.add_argument('--quick', action='store_true',
                   help='only the 2 s trajectories, no pick-up, no online refinement '
                        '(about half the time)')
    p.add_argument('--no-online', action='store_true',
                   help='skip the online-refinement table (ONLINE estimator from a start '
                        'off by 0.8x/1.2x)')
    p.add_argument('--truth-properties', action='store_true',
                   help='controllers use the simulator\'s true contact properties instead of '
                        'the estimate of the same run')
    p.add_argument('--physics-dt', type=positive_float, default=EvalSettings.physics_dt,
                   help='physics step [s] (default: %(default)s, as the sim_gripper node; '
                        '1e-4 for validation runs, about 8x slower)')
    p.add_argument('--seed', type=non_negative_int, default=0,
                   help='sensor-noise seed; with --population, the population seed (default 0)')
    p.add_argument('--presets-file', default='', metavar='YAML',
                   help='presets YAML adding objects to the reference ones (the format of '
                        'friction_models/config/sim_presets.yaml; then --preset NAME picks '
                        'one) (default: none, the reference objects only)')
    p.add_argument('--velocity-model', choices=('chips', 'ideal'), default='chips',
                   help='velocity-sensor model (default chips)')
    pop = p.add_argument_group(
        'population evaluation', 'random objects from the simulator\'s supported ranges; '
        '--seed is then the population seed')
    pop.add_argument('--population', type=positive_int, metavar='N',
                     help='evaluate N objects drawn with --seed instead of the presets')
    pop.add_argument('--workers', type=non_negative_int, default=0, metavar='K',
                     help='local worker processes (default: all cores, '
                          f'{default_workers()} here)')
    pop.add_argument('--scheduler', metavar='ADDRESS',
                     help='run on a Dask distributed scheduler (tcp://host:port) instead of '
                          'local processes; its workers need this workspace sourced')
    pop.add_argument('--controllers', default=THESIS, metavar='NAME[,NAME...]',
                     help='control-law families to compare (default thesis; available: '
                          f'{", ".join(available_families())})')
    pop.add_argument('--out', metavar='DIR',
                     help='output directory for JSON, CSV and plots '
                          '(default ./population-<seed>-<N>)')
    pop.add_argument('--object', metavar='SEED:INDEX',
                     help='run one object of a population and print everything measured')
    return p


def _presets(values: Sequence[str] | None) -> list[str]:
    if not values:
        return list(REFERENCE_PRESETS)
    out: list[str] = []
    for v in values:
        out.extend(name.strip() for name in v.split(',') if name.strip())
    return out


def _controllers(text: str) -> tuple[str, ...]:
    """``thesis,model`` → families; ValueError names an unknown one."""
    names = tuple(dict.fromkeys(n.strip() for n in text.split(',') if n.strip()))
    if not names:
        raise ValueError('--controllers needs at least one name')
    known = available_families()
    bad = [n for n in names if n not in known]
    if bad:
        raise ValueError(f'unknown controller {", ".join(bad)!s} (available: '
                         f'{", ".join(known)})')
    return names


def _scheduler_address(text: str) -> str:
    """Check the form of a Dask scheduler address (``[tcp://]host:port``)."""
    scheme, _, rest = text.rpartition('://')
    scheme = scheme or 'tcp'
    if scheme not in ('tcp', 'tls', 'ws', 'wss', 'ucx'):
        raise ValueError(f'bad scheduler address {text!r}: unknown protocol {scheme!r} '
                         '(expected tcp://host:port)')
    host, _, port = rest.rpartition(':')
    if not host or not port.isdigit() or not 0 < int(port) < 65536 or any(
            c.isspace() or c == '/' for c in host):
        raise ValueError(f'bad scheduler address {text!r} (expected tcp://host:port)')
    return text if '://' in text else f'tcp://{text}'


def _object_ref(text: str) -> tuple[int, int]:
    seed, sep, index = text.partition(':')
    if not sep or not seed.strip().isdigit() or not index.strip().isdigit():
        raise ValueError(f'--object expects SEED:INDEX with non-negative integers, got {text!r}')
    return int(seed), int(index)


def _usage_error(message: str) -> int:
    """One line on stderr; exit code 2 (as argparse's own errors)."""
    print(f'slip_evaluate: error: {message}', file=sys.stderr, flush=True)
    return 2


def _population_main(ns: argparse.Namespace) -> int:
    """``--population`` / ``--object``: the population evaluation."""
    try:
        controllers = _controllers(ns.controllers)
        scheduler = _scheduler_address(ns.scheduler) if ns.scheduler else None
        ref = _object_ref(ns.object) if ns.object else None
    except ValueError as exc:
        return _usage_error(str(exc))
    if ns.population is not None and ns.population < 1:
        return _usage_error(f'--population must be at least 1, got {ns.population}')
    if ns.workers < 0:
        return _usage_error(f'--workers must be >= 0 (0 = all cores), got {ns.workers}')
    if not ns.physics_dt > 0.0:
        return _usage_error(f'--physics-dt must be > 0, got {ns.physics_dt}')
    if ns.seed < 0:
        return _usage_error(f'--seed must be >= 0 for a population, got {ns.seed}')
    if ref is not None:
        return _one_object(ref, make_tasks(ref[0], [ref[1]], controllers=controllers,
                                           truth_properties=ns.truth_properties,
                                           physics_dt=ns.physics_dt,
                                           velocity_model=ns.velocity_model)[0])
    count = int(ns.population)
    out_dir = Path(ns.out) if ns.out else Path.cwd() / f'population-{ns.seed}-{count}'
    created = not out_dir.exists()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        print(f'slip_evaluate: error: cannot create {out_dir}: {exc}', file=sys.stderr)
        return 1
    where = (f'Dask scheduler {scheduler}' if scheduler else
             f'{ns.workers or default_workers()} local worker process(es)')
    print(f'population {ns.seed}: {count} objects, controllers {", ".join(controllers)}, on '
          f'{where}', file=sys.stderr, flush=True)
    tasks = make_tasks(ns.seed, range(count), controllers=controllers,
                       truth_properties=ns.truth_properties, physics_dt=ns.physics_dt,
                       velocity_model=ns.velocity_model)
    bar = ProgressBar(f'population {ns.seed}', sys.stderr)
    t0 = time.monotonic()
    try:
        results, backend, workers = run_tasks(tasks, workers=ns.workers, scheduler=scheduler,
                                              progress=bar, timeout=10.0)
    except (OSError, TimeoutError) as exc:
        why = ' '.join(str(exc).split()) or type(exc).__name__
        print(f'slip_evaluate: error: cannot run on the Dask scheduler {scheduler}: {why}',
              file=sys.stderr, flush=True)
        if created and not any(out_dir.iterdir()):
            out_dir.rmdir()
        return 1
    run = PopulationRun(seed=ns.seed, results=tuple(results), backend=backend,
                        workers=workers, wall_seconds=time.monotonic() - t0,
                        scheduler=scheduler or '')
    summaries = population_report.summarise(run.results)
    table = population_report.format_table(summaries, run.cpu_per_object, run.wall_seconds,
                                           count)
    print(table, flush=True)
    meta = {'seed': ns.seed, 'objects': count, 'controllers': list(controllers),
            'backend': backend, 'workers': workers, 'scheduler': scheduler or '',
            'truth_properties': bool(ns.truth_properties),
            'wall_seconds': run.wall_seconds, 'cpu_seconds': run.cpu_seconds,
            'cpu_per_object': run.cpu_per_object, 'native': _native_status()}
    try:
        population_report.write_json(out_dir / 'population.json', summaries, run.results, meta)
        population_report.write_csv(out_dir / 'population.csv', run.results)
        (out_dir / 'table.txt').write_text(table + '\n')
        plots = population_report.write_plots(out_dir, run.results, summaries)
    except OSError as exc:
        print(f'slip_evaluate: error: cannot write to {out_dir}: {exc}', file=sys.stderr)
        return 1
    print(f'\nwrote {out_dir}/: population.json, population.csv, table.txt and '
          f'{len(plots)} plots', flush=True)
    return 0


def _native_status() -> str:
    import friction_models.core as fm_core
    return str(getattr(fm_core, 'NATIVE_STATUS', 'unknown'))


def _one_object(ref: tuple[int, int], task: PopulationTask) -> int:
    """``--object SEED:INDEX``: every measurement of one object."""
    seed, index = ref
    obj = draw_object(seed, index)
    p = obj.preset
    print(f'object {p.name} (population {seed}, index {index})', flush=True)
    print(f'  mass {p.mass:.4f} kg, inertia {p.inertia:.3g} kg m^2, CoM offset '
          f'({1e3 * p.com_offset[0]:.1f}, {1e3 * p.com_offset[1]:.1f}) mm, box '
          f'{1e3 * p.width:.0f} x {1e3 * (p.height_below + p.height_above):.0f} x '
          f'{1e3 * p.thickness:.0f} mm, surface {p.surface}, table mu {p.table_mu:.2f}')
    for k, c in ((1, p.finger_1), (2, p.finger_2)):
        print(f'  finger {k}: mu_c {c.mu_c:.4f}, mu_s {c.mu_s:.4f} (x{c.mu_s / c.mu_c:.2f}), '
              f'mu_v {c.mu_v:.3f} s/m, r {1e3 * c.r:.3f} mm')
    sv = obj.sensors
    print(f'  F/T noise x{sv.noise_scale:.2f}; offsets 1 {_vec(sv.offset_1)}, '
          f'2 {_vec(sv.offset_2)}', flush=True)
    result = evaluate_object(task)
    _print_object(result)
    return 0


def _vec(values: Sequence[float]) -> str:
    return '(' + ', '.join(f'{v:+.3g}' for v in values) + ')'


def _print_object(result: ObjectResult) -> None:
    print('  parameters: ' + ', '.join(f'{k} {v:.4g}' for k, v in result.parameters.items()))
    for s in result.scenarios:
        verdict = 'success' if s.success else f'FAILURE ({s.failure})'
        feas = 'feasible' if s.feasible else f'INFEASIBLE ({s.infeasible_reason})'
        print(f'{s.scenario} [{s.controller}]: {verdict}; {feas}; reported: {s.reported}')
        for k, v in s.metrics.items():
            print(f'    {k:<32} {v:.6g}' if math.isfinite(v) else f'    {k:<32} n/a')
    print(f'({result.cpu_seconds:.2f} CPU-s)', flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the evaluation table; returns the process exit code."""
    parser = _parser()
    ns = parser.parse_args(argv)
    if ns.population is not None or ns.object:
        return _population_main(ns)
    presets = _presets(ns.preset)
    if not presets:
        parser.error('--preset needs at least one name')
    if not (ns.physics_dt > 0.0):
        parser.error(f'--physics-dt must be > 0, got {ns.physics_dt}')
    try:
        settings = EvalSettings(physics_dt=ns.physics_dt, seed=ns.seed,
                                velocity_model=ns.velocity_model,
                                presets_file=ns.presets_file)
        t0 = time.monotonic()

        def progress(text: str) -> None:
            print(f'[{time.monotonic() - t0:6.1f} s] {text}', file=sys.stderr, flush=True)

        rows = evaluate_all(presets, settings, quick=ns.quick,
                            use_truth=ns.truth_properties, progress=progress)
        online = []
        if not (ns.quick or ns.no_online):
            for name in presets:
                for scale in ONLINE_START_SCALES:
                    progress(f'{name}: online refinement from {scale:g}x')
                    online.append(online_refinement(name, scale, settings))
    except (KeyError, ValueError, EvaluationError) as exc:
        message = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f'slip_evaluate: error: {message}', file=sys.stderr)
        return 1
    print(format_table(rows))
    if online:
        print()
        print(format_online_table(online))
    print(f'\n(physics_dt {settings.physics_dt:g} s, seed {settings.seed}, velocity sensor '
          f'{settings.velocity_model}; {time.monotonic() - t0:.1f} s wall)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
