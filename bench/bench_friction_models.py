# SPDX-License-Identifier: Apache-2.0
"""Benchmark of the friction models (issue 3; spec §10.5, §12). Prints tables; never asserts.

Settings of the paper's speed test (spec §10.5): square 20 mm patch, σ0 = 1e5 1/m,
σ1 = 20 s/m, σ2 = 0.2 s/m, dt = 1e-4 s, Elasto-Plastic on unless stated, exponential
integrator, constant pad-centre twist (0.1 m/s, −0.05 m/s, 1.59 rad/s). One Python call per
step, best of several repetitions (µs per step).

Targets (issue 3, 2-core development machine): distributed 21×21 with EP ≤ 100 µs/step;
reduced ≤ 20 µs per single-contact step and ≤ 1 µs per contact-step batched at N = 1000;
limit-surface pre-computation (21×21, n_ls = 20) ≤ 0.05 s.

Usage: ``python bench/bench_friction_models.py [--quick]``.
"""
from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path
from collections.abc import Callable

import numpy as np

_ROOT = Path(__file__).resolve().parents[1]
_PKG = str(_ROOT / 'src' / 'friction_models')
if _PKG not in sys.path:
    sys.path.insert(0, _PKG)

from friction_models.core import (NATIVE_STATUS, AmendedLuGre,  # noqa: E402
                                  DistributedPlanarLuGre, LimitSurface, LuGreParams,
                                  ReducedPlanarLuGre, ReducedPlanarLuGreBatch, square)

PARAMS = LuGreParams(sigma0=1e5, sigma1=20.0, sigma2=0.2)
TWIST = (0.1, -0.05, 1.59)
DT = 1e-4


def best_time(run: Callable[[], None], repeats: int) -> float:
    """Best wall time [s] of ``repeats`` calls of ``run``."""
    best = float('inf')
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - t0)
    return best


def per_step_us(step: Callable[[], object], steps: int, repeats: int) -> float:
    """Best µs per call of ``step`` over ``repeats`` loops of ``steps`` calls."""
    for _ in range(min(200, steps)):
        step()

    def loop() -> None:
        for _ in range(steps):
            step()
    return best_time(loop, repeats) / steps * 1e6


def verdict(value: float, target: float) -> str:
    return 'ok' if value <= target else 'MISSED'


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='fewer steps and repetitions')
    args = parser.parse_args()
    steps, repeats = (2000, 3) if args.quick else (10_000, 10)
    print(f'# friction_models benchmark: Python {platform.python_version()}, numpy '
          f'{np.__version__}, {platform.machine()}, steps={steps}, best of {repeats}')
    print(f'# simulation core: {NATIVE_STATUS} (limit_surface and reduced are among its modules)')

    print('\n## Per-step cost [µs/step]')
    print(f'{"model":<44}{"5x5":>9}{"21x21":>9}{"33x33":>9}   target')
    rows: dict[str, list[float]] = {}
    for label, ep in (('distributed, EP on', True), ('distributed, EP off', False)):
        rows[label] = []
        for n in (5, 21, 33):
            model = DistributedPlanarLuGre(square(n, 0.02), PARAMS, elasto_plastic=ep)
            rows[label].append(per_step_us(lambda m=model: m.step(TWIST, DT), steps, repeats))
    for label, ls in (('reduced, limit surface, EP on', True),
                      ('reduced, ellipsoid, EP on', False)):
        rows[label] = []
        for n in (5, 21, 33):
            red = ReducedPlanarLuGre(square(n, 0.02), PARAMS, limit_surface=ls)
            rows[label].append(per_step_us(lambda m=red: m.step(TWIST, DT), steps * 5, repeats))
    targets = {'distributed, EP on': (100.0, 1), 'reduced, limit surface, EP on': (20.0, 1)}
    for label, values in rows.items():
        target = targets.get(label)
        mark = f'   ≤ {target[0]:g} (21x21): {verdict(values[target[1]], target[0])}' \
            if target else ''
        print(f'{label:<44}' + ''.join(f'{v:>9.1f}' for v in values) + mark)
    ratio = rows['distributed, EP on'][1] / rows['reduced, limit surface, EP on'][1]
    print(f'# distributed/reduced cost ratio at 21x21 (EP on): {ratio:.0f}x')

    print('\n## Batched reduced model (21x21 square, limit surface, EP on)')
    print(f'{"contacts N":>10}{"µs/batch step":>16}{"µs/contact-step":>18}   target')
    rng = np.random.default_rng(0)
    for n_contacts in (2, 10, 100, 1000):
        batch = ReducedPlanarLuGreBatch(square(21, 0.02), PARAMS, n=n_contacts)
        twists = np.array(TWIST) * (1.0 + 0.1 * rng.standard_normal((n_contacts, 3)))
        n_steps = max(50, steps // max(1, n_contacts // 10))
        us = per_step_us(lambda b=batch, t=twists: b.step(t, DT), n_steps, repeats)
        note = f'   ≤ 1 per contact: {verdict(us / n_contacts, 1.0)}' if n_contacts == 1000 \
            else ''
        print(f'{n_contacts:>10}{us:>16.1f}{us / n_contacts:>18.3f}{note}')

    print('\n## Limit-surface pre-computation [ms]')
    surface = square(21, 0.02)
    build_s = best_time(lambda: LimitSurface.build(surface, 20), repeats)
    print(f'21x21, n_ls = 20: {build_s * 1e3:.2f} ms   target ≤ 50 ms: '
          f'{verdict(build_s, 0.05)}')
    print(f'{"n_ls":>6}' + ''.join(f'{n:>8}' for n in (5, 10, 20, 35)))
    print(f'{"ms":>6}' + ''.join(
        f'{best_time(lambda n=n: LimitSurface.build(surface, n), repeats) * 1e3:>8.2f}'
        for n in (5, 10, 20, 35)))
    print(f'{"grid":>6}' + ''.join(f'{n:>8}' for n in (5, 9, 21, 33)))
    print(f'{"ms":>6}' + ''.join(
        f'{best_time(lambda n=n: LimitSurface.build(square(n, 0.02), 20), repeats) * 1e3:>8.2f}'
        for n in (5, 9, 21, 33)))

    print('\n## 1-D amended LuGre / Elasto-Plastic [µs/step]')
    for shape in ((), (1000,)):
        model = AmendedLuGre(PARAMS, shape=shape, elasto_plastic=True)
        v = np.full(shape, 0.01)
        us = per_step_us(lambda m=model, vv=v: m.step(vv, 1.0, DT), steps, repeats)
        print(f'shape {shape!s:<8}: {us:8.1f} µs/step'
              + (f'  ({us / shape[0]:.3f} µs per element)' if shape else ''))
    return 0


if __name__ == '__main__':
    sys.exit(main())
