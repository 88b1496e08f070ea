# SPDX-License-Identifier: Apache-2.0
"""Run one function over many items on local worker processes or a Dask distributed cluster.

Both backends return the results in item order, so a population run gives the same table
whatever ran it: each item carries everything that determines its result (the object's seed
and index), and no worker keeps state between items.

Dask: ``address`` is a scheduler address (``tcp://host:8786``) or a ``distributed.Client``'s
cluster (e.g. ``LocalCluster``, or a ``dask_jobqueue.SLURMCluster``); its workers must run in
the same workspace environment (``source install/setup.bash``) so that they import the
project's packages.
"""
from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, TypeVar

_I = TypeVar('_I')
_R = TypeVar('_R')

#: ``progress(done, total)`` after each finished item.
ProgressHook = Callable[[int, int], None]


def default_workers() -> int:
    """Worker processes of the local backend: every core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


def run_local(function: Callable[[_I], _R], items: Sequence[_I], *, workers: int = 0,
              progress: ProgressHook | None = None) -> list[_R]:
    """``[function(i) for i in items]`` on ``workers`` processes (0 = all cores, 1 = inline)."""
    n = len(items)
    workers = default_workers() if workers <= 0 else workers
    results: list[Any] = [None] * n
    if workers == 1 or n <= 1:
        for k, item in enumerate(items):
            results[k] = function(item)
            if progress is not None:
                progress(k + 1, n)
        return results
    # spawn: workers start clean (no inherited threads, locks or DDS participants).
    context = multiprocessing.get_context('spawn')
    with ProcessPoolExecutor(max_workers=min(workers, n), mp_context=context) as pool:
        futures = {pool.submit(function, item): k for k, item in enumerate(items)}
        for done, future in enumerate(as_completed(futures), start=1):
            results[futures[future]] = future.result()
            if progress is not None:
                progress(done, n)
    return results


def run_dask(function: Callable[[_I], _R], items: Sequence[_I], address: Any, *,
             progress: ProgressHook | None = None, timeout: float = 20.0) -> list[_R]:
    """``[function(i) for i in items]`` on a Dask distributed cluster.

    Args:
        function: A picklable top-level function.
        items: Picklable items.
        address: Scheduler address string or a cluster object (``LocalCluster`` …).
        progress: Called after each finished item.
        timeout: Longest wait for the scheduler [s].

    Raises:
        ImportError: ``distributed`` is not installed (the message says so).
        OSError: The scheduler cannot be reached within ``timeout``.
    """
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError as exc:  # pragma: no cover - distributed is a declared dependency
        raise ImportError('the Dask backend needs the "distributed" package') from exc
    n = len(items)
    results: list[Any] = [None] * n
    with Client(address, timeout=f'{timeout:g}s', set_as_default=False) as client:
        futures = client.map(function, list(items), pure=False)
        index = {f.key: k for k, f in enumerate(futures)}
        for done, future in enumerate(dask_completed(futures, loop=client.loop), start=1):
            results[index[future.key]] = future.result()
            if progress is not None:
                progress(done, n)
    return results
