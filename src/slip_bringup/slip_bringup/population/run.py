# SPDX-License-Identifier: Apache-2.0
"""A whole population run: tasks for objects ``0 … N−1``, on a backend, with its cost.

`run_population` builds one `runner.PopulationTask` per object and maps
`runner.evaluate_object` over them on local worker processes (`backends.run_local`) or a Dask
distributed cluster (`backends.run_dask`). The results come back in object order and do not
depend on the backend (each task carries all that determines its result).
"""
from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from friction_models.core.population import PopulationRanges

from slip_bringup.population.backends import ProgressHook, default_workers, run_dask, run_local
from slip_bringup.population.results import SCENARIOS, ObjectResult
from slip_bringup.population.runner import THESIS, PopulationTask, evaluate_object


@dataclass(frozen=True)
class PopulationRun:
    """Results of a population run and what it cost.

    Attributes:
        seed: Population seed.
        results: One `ObjectResult` per object, in index order.
        backend: ``'local'`` or ``'dask'``.
        workers: Local worker processes (0 for Dask: the cluster decides).
        wall_seconds: Wall time of the whole run [s] (a figure of cost, not control logic).
        scheduler: Dask scheduler address ('' for local).
    """

    seed: int
    results: tuple[ObjectResult, ...]
    backend: str
    workers: int
    wall_seconds: float
    scheduler: str = ''

    @property
    def cpu_seconds(self) -> float:
        """CPU time of all objects [s] (as measured in the workers)."""
        return sum(r.cpu_seconds for r in self.results)

    @property
    def cpu_per_object(self) -> float:
        """Mean CPU time per object [s]."""
        return self.cpu_seconds / len(self.results) if self.results else 0.0


def make_tasks(seed: int, indices: Sequence[int], *,
               controllers: Sequence[str] = (THESIS,),
               scenarios: Sequence[str] = SCENARIOS,
               ranges: PopulationRanges = PopulationRanges(),
               truth_properties: bool = False,
               physics_dt: float = PopulationTask.physics_dt,
               velocity_model: str = PopulationTask.velocity_model) -> list[PopulationTask]:
    """One task per object index."""
    return [PopulationTask(seed=seed, index=i, ranges=ranges, controllers=tuple(controllers),
                           scenarios=tuple(scenarios), truth_properties=truth_properties,
                           physics_dt=physics_dt, velocity_model=velocity_model)
            for i in indices]


def run_tasks(tasks: Sequence[PopulationTask], *, workers: int = 0, scheduler: Any = None,
              progress: ProgressHook | None = None, timeout: float = 20.0
              ) -> tuple[list[ObjectResult], str, int]:
    """``evaluate_object`` over ``tasks``: ``(results, backend, workers)``.

    ``scheduler`` (an address or a cluster object) selects Dask; otherwise ``workers`` local
    processes (0: all cores).
    """
    if scheduler is not None and scheduler != '':
        return run_dask(evaluate_object, tasks, scheduler, progress=progress,
                        timeout=timeout), 'dask', 0
    n = default_workers() if workers <= 0 else workers
    return run_local(evaluate_object, tasks, workers=n, progress=progress), 'local', n


def run_population(seed: int, count: int, *, controllers: Sequence[str] = (THESIS,),
                   scenarios: Sequence[str] = SCENARIOS, workers: int = 0,
                   scheduler: Any = None, progress: ProgressHook | None = None,
                   ranges: PopulationRanges = PopulationRanges(),
                   truth_properties: bool = False) -> PopulationRun:
    """Objects ``0 … count−1`` of population ``seed`` through every scenario.

    Raises:
        ValueError: ``count < 1``.
        OSError: The Dask scheduler cannot be reached.
    """
    if count < 1:
        raise ValueError(f'the population needs at least 1 object, got {count}')
    tasks = make_tasks(seed, range(count), controllers=controllers, scenarios=scenarios,
                       ranges=ranges, truth_properties=truth_properties)
    t0 = time.monotonic()
    results, backend, n = run_tasks(tasks, workers=workers, scheduler=scheduler,
                                    progress=progress)
    return PopulationRun(seed=seed, results=tuple(results), backend=backend, workers=n,
                         wall_seconds=time.monotonic() - t0,
                         scheduler=scheduler if isinstance(scheduler, str) else '')
