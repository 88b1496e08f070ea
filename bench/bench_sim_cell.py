# SPDX-License-Identifier: Apache-2.0
"""Benchmark of the in-process simulated cell (issue 4, "Performance"). Prints; never asserts.

Real-time factor (sim seconds per wall second) of the full cell: two reduced LuGre pads with
the pre-computed limit surface, the rigid object and table, the voltage-driven actuator, the
shared inner grasp-force loop at 500 Hz, F/T at 1 kHz per finger, velocity sensors at
120 Hz per finger (chip model or ideal) and every sensor event materialised — i.e. exactly
what `SimCell.advance` does for the ROS node or the harness. Three regimes:

* ``hold``: object lifted and held at 10 N (pads sticking; the common case);
* ``slip``: linear gravity slip: the plastic object (velocity-strengthening contact) held in
  the air at 1.5 N slides down between the pads at a steady ≈ 5 mm/s (both pads sliding);
* ``explore``: the estimation exploration (push down 1 cm, twist ±10°) on the table, where
  the pads slide and the table contact is active.

Then a per-component cost breakdown (µs per call, and ms per simulated second at
``physics_dt = 1e-3``) so the budget is visible: physics step, the two library pad steps,
F/T tick, telemetry tick (shared controller), velocity tick (each velocity sample one output
period after the last, as in the cell).

Target (issue 4): ≥ 50× real time in-process. Best of several repetitions; the machine may
be shared, so compare the best figures.

The header names the implementation that ran: the mypyc-compiled core (the normal build) or
pure Python (``FRICTION_MODELS_PURE_PYTHON=1``, mypy absent, or extensions out of date).

Usage: ``[FRICTION_MODELS_PURE_PYTHON=1] python bench/bench_sim_cell.py [--quick]``.
"""
from __future__ import annotations

import argparse
import math
import platform
import sys
import time
import timeit
from pathlib import Path
from collections.abc import Callable

_ROOT = Path(__file__).resolve().parents[1]
for _pkg in ('friction_models', 'slip_gripper_driver', 'slip_velocity_sensor'):
    _path = str(_ROOT / 'src' / _pkg)
    if _path not in sys.path:
        sys.path.insert(0, _path)

from friction_models.core import NATIVE_STATUS  # noqa: E402
from friction_models.core.harness import Harness  # noqa: E402
from friction_models.core.presets import reference_presets  # noqa: E402
from friction_models.core.sensors import SimEvents, VelocitySensorParams  # noqa: E402
from friction_models.core.sim_cell import SimCell, SimParams  # noqa: E402


def make_cell(dt: float, velocity: str, preset: str = 'wood') -> SimCell:
    """A cell (wood by default), homed and biased, at the pick-up pose."""
    cell = SimCell(SimParams(physics_dt=dt, velocity_sensor=VelocitySensorParams(model=velocity)),
                   reference_presets(), preset)
    h = Harness(cell)
    h.home()
    h.bias()
    return cell


def to_hold(cell: SimCell) -> None:
    """Grasp at 10 N, lift 0.1 m, settle."""
    h = Harness(cell)
    h.command_force(10.0)
    h.run_for(1.5)
    h.move(lift=0.1, duration=1.0)
    h.run_for(0.5)


def timed_advance(cell: SimCell, seconds: float, chunk: float) -> float:
    """Wall time [s] to advance ``seconds`` in ``chunk`` steps (as the node/harness do)."""
    t_end = cell.t + seconds
    t0 = time.perf_counter()
    while cell.t < t_end - 1e-9:
        cell.advance(min(cell.t + chunk, t_end))
    return time.perf_counter() - t0


def rtf_hold(dt: float, velocity: str, seconds: float, repeats: int) -> float:
    """Best real-time factor while holding."""
    best = math.inf
    for _ in range(repeats):
        cell = make_cell(dt, velocity)
        to_hold(cell)
        best = min(best, timed_advance(cell, seconds, 0.01))
    return seconds / best


def rtf_slip(dt: float, velocity: str, seconds: float, repeats: int) -> float:
    """Best real-time factor during a steady gravity slip (plastic object at 1.5 N)."""
    best = math.inf
    for _ in range(repeats):
        cell = make_cell(dt, velocity, 'plastic')
        h = Harness(cell)
        h.reset(object_on_table=False)
        h.command_force(10.0)
        h.run_for(0.5)
        h.command_force(1.5)
        h.run_for(0.5)
        best = min(best, timed_advance(cell, seconds, 0.01))
    return seconds / best


def rtf_explore(dt: float, velocity: str, repeats: int) -> float:
    """Best real-time factor over the exploration moves (grasp excluded)."""
    best = math.inf
    for _ in range(repeats):
        cell = make_cell(dt, velocity)
        h = Harness(cell)
        h.command_force(10.0)
        h.run_for(2.0)
        h.command_force(5.0)
        t0 = time.perf_counter()
        t_sim = cell.t
        h.move(lift=-0.01, duration=0.8)
        h.run_for(0.2)
        h.move(rotation=math.radians(10.0), duration=0.5)
        h.move(rotation=-math.radians(10.0), duration=0.5)
        wall = time.perf_counter() - t0
        best = min(best, wall / (cell.t - t_sim))
    return 1.0 / best


def per_call_us(stmt: Callable[[], object], number: int, repeats: int) -> float:
    """Best µs per call."""
    return min(timeit.repeat(stmt, number=number, repeat=repeats)) / number * 1e6


def breakdown(number: int, repeats: int) -> list[tuple[str, float, float]]:
    """``(component, µs per call, calls per sim second at dt = 1e-3)`` while holding."""
    rows = []
    cells = {m: make_cell(1e-3, m) for m in ('chips', 'ideal')}
    for cell in cells.values():
        to_hold(cell)
    cell = cells['chips']
    plant = cell.plant
    t = cell.t
    ev = SimEvents()
    pad = plant.pads[0]
    twist = pad.nu
    f_n = plant.f_n
    rows.append(('physics step (2 pads, object, actuator)',
                 per_call_us(lambda: plant.step(t), number, repeats), 1000.0))
    rows.append(('  of which: one library pad step',
                 per_call_us(lambda: pad.model.advance(*twist, 1e-3, f_n), number, repeats),
                 2000.0))
    rows.append(('F/T tick (both sensors)',
                 per_call_us(lambda: cell._ft_tick(t, ev), number, repeats), 1000.0))
    rows.append(('telemetry tick (observer, shared loop, encode)',
                 per_call_us(lambda: cell._tel_tick(t, ev), number, repeats), 500.0))
    period = 1.0 / cell.params.velocity_sensor.rate
    for name, c in (('chips', cell), ('ideal', cells['ideal'])):
        stamps = iter(range(1, 10 ** 9))
        rows.append((f'velocity tick, {name} (one finger)',
                     per_call_us(lambda c=c, s=stamps: c._vel_tick(0, t + next(s) * period, ev),
                                 number, repeats), 240.0))
    return rows


def main(argv: list[str] | None = None) -> int:
    """Run and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='shorter runs, fewer repeats')
    args = parser.parse_args(argv)
    seconds, repeats, number = (1.0, 2, 2000) if args.quick else (4.0, 3, 20000)
    print(f'Python {platform.python_version()} on {platform.machine()} '
          f'({platform.processor() or "cpu"}), best of {repeats}')
    print(f'simulation core: {NATIVE_STATUS}')
    print()
    print('Real-time factor of the full cell (sim s per wall s; target >= 50x)')
    print(f'{"physics_dt [s]":>15} {"velocity":>9} {"hold":>8} {"slip":>8} {"explore":>8}')
    for dt in (1e-4, 5e-4, 1e-3):
        for velocity in ('chips', 'ideal'):
            span = seconds if dt >= 5e-4 else seconds / 4
            hold = rtf_hold(dt, velocity, span, repeats)
            slip = rtf_slip(dt, velocity, span, repeats)
            explore = rtf_explore(dt, velocity, max(1, repeats - 1) if dt < 5e-4 else repeats)
            print(f'{dt:>15.0e} {velocity:>9} {hold:>7.1f}x {slip:>7.1f}x {explore:>7.1f}x')
    print()
    print('Cost breakdown while holding (physics_dt = 1e-3)')
    print(f'{"component":<48} {"us/call":>8} {"calls/s":>8} {"ms per sim s":>13}')
    total = 0.0
    for name, us, calls in breakdown(number, repeats):
        ms = us * calls / 1000.0
        if not name.startswith('  ') and 'ideal' not in name:
            total += ms
        print(f'{name:<48} {us:>8.2f} {calls:>8.0f} {ms:>13.2f}')
    print(f'{"sum (chips), without the advance loop":<48} {"":>8} {"":>8} {total:>13.2f}'
          f'   -> at most {1000.0 / total:.0f}x')
    return 0


if __name__ == '__main__':
    sys.exit(main())
