# SPDX-License-Identifier: Apache-2.0
"""Benchmark of the population evaluation (issue 15, "Scale"). Prints; never asserts.

Runs objects ``0 … N−1`` of a population (exploration + estimation, HOLD, LINEAR,
ROTATIONAL and HINGE with the thesis controllers, the same work as ``slip_evaluate
--population N``) on local worker processes (default: all cores) or a Dask scheduler, and
prints: objects, wall time, CPU seconds per object (measured in the workers), workers,
backend, the simulation core that ran, and the projection to 200 objects on 2 idle cores
(issue target: ≤ 5 min). Then the CPU cost of each scenario on one object, run inline.

The machine may be shared: the wall time is that of this run under the current load; the
CPU seconds per object are the steadier figure (projection = 200 × CPU-s / 2 cores).

Usage: ``python bench/bench_population.py [--quick] [--objects N] [--seed S] [--workers K]
[--scheduler tcp://host:port]`` (``--quick``: 10 objects; default 200).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

_ROOT = Path(__file__).resolve().parents[1]
for _pkg in ('friction_models', 'slip_gripper_driver', 'slip_velocity_sensor', 'slip_control',
             'slip_cell_common', 'slip_bringup'):
    _path = str(_ROOT / 'src' / _pkg)
    if _path not in sys.path:
        sys.path.insert(0, _path)

from friction_models.core import NATIVE_STATUS  # noqa: E402
from slip_bringup.population.progress import ProgressBar  # noqa: E402
from slip_bringup.population.results import SCENARIOS  # noqa: E402
from slip_bringup.population.run import run_population  # noqa: E402
from slip_bringup.population.runner import PopulationTask, evaluate_object  # noqa: E402

TARGET_OBJECTS = 200
TARGET_CORES = 2
TARGET_SECONDS = 300.0


def _scenario_costs(seed: int, index: int) -> dict[str, float]:
    """CPU seconds of each scenario on one object, inline (estimation runs in every one)."""
    def cpu(scenarios: tuple[str, ...]) -> float:
        return evaluate_object(PopulationTask(seed, index, scenarios=scenarios)).cpu_seconds

    base = cpu(('estimation',))
    costs = {'estimation': base}
    for s in SCENARIOS[1:]:
        costs[s] = cpu(('estimation', s)) - base
    return costs


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--quick', action='store_true', help='10 objects')
    p.add_argument('--objects', type=int, default=0, help='objects (default 200; 10 quick)')
    p.add_argument('--seed', type=int, default=11, help='population seed (default 11)')
    p.add_argument('--workers', type=int, default=0, help='local processes (0 = all cores)')
    p.add_argument('--scheduler', default='', help='Dask scheduler address (default: local)')
    ns = p.parse_args()
    count = ns.objects or (10 if ns.quick else TARGET_OBJECTS)
    print(f'population evaluation benchmark: simulation core {NATIVE_STATUS}; '
          f'{os.cpu_count()} CPUs visible', flush=True)
    run = run_population(ns.seed, count, workers=ns.workers, scheduler=ns.scheduler or None,
                         progress=ProgressBar(f'population {ns.seed}', sys.stderr))
    per_object = run.cpu_per_object
    projected = TARGET_OBJECTS * per_object / TARGET_CORES
    where = (f'dask ({run.scheduler})' if run.backend == 'dask'
             else f'local, {run.workers} worker process(es)')
    print(f'{"objects":<34} {count}')
    print(f'{"backend":<34} {where}')
    print(f'{"wall time":<34} {run.wall_seconds:.1f} s '
          f'({run.wall_seconds / count:.2f} s per object)')
    cpu = [r.cpu_seconds for r in run.results]
    print(f'{"CPU per object":<34} {per_object:.2f} s (min {min(cpu):.2f}, max {max(cpu):.2f})')
    print(f'{"CPU total":<34} {run.cpu_seconds:.1f} s')
    print(f'{"200 objects on 2 idle cores":<34} ≈ {projected:.0f} s '
          f'(target ≤ {TARGET_SECONDS:.0f} s; from CPU-s per object, start-up excluded)')
    print('CPU per scenario on one object (inline):', flush=True)
    for name, seconds in _scenario_costs(ns.seed, 0).items():
        print(f'  {name:<32} {seconds:.2f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
