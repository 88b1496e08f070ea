# SPDX-License-Identifier: Apache-2.0
"""Cost of one slip-controller step and one estimator step (ROS-free cores), in µs.

Prints p50/p99/max per mode; never asserts (target from issue 7: controller step ≤ 100 µs).
The inputs are pre-built snapshots from the synthetic streams, so only the core step is timed.

Usage: python bench/bench_slip_control.py [--quick]
(run from the repository root; `make bench` passes --quick).
"""
from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for pkg in ('slip_control', 'slip_gripper_driver'):
    sys.path.insert(0, str(ROOT / 'src' / pkg))

from slip_control.core.contact import ContactProperties, ContactSource, FingerContact  # noqa: E402
from slip_control.core.controllers import (ControlContact, HingeController,  # noqa: E402
                                           HoldController, LinearController, OffController,
                                           RotationalController, SlipController, SlipMode)
from slip_control.core.estimator import ContactEstimator, EstimationPhase  # noqa: E402
from slip_control.core.mode_switch import ModeRequest, build_controller  # noqa: E402
from slip_control.core.params import (ContactEstimatorParams,  # noqa: E402
                                      EstimatorOnlineParams, SlipControllerParams)
from slip_control.core.signals import SensorSnapshot  # noqa: E402
from slip_control.core.synthetic import (TrueContact, controlled_slip,  # noqa: E402
                                         exploration_linear, exploration_rotational)


def _stats(ns: list[int]) -> tuple[float, float, float]:
    a = np.asarray(ns, dtype=np.float64) / 1000.0
    return float(np.percentile(a, 50)), float(np.percentile(a, 99)), float(a.max())


def _snapshots(n: int) -> list[SensorSnapshot]:
    """≥ n realistic snapshots with increasing stamps (controlled slip, repeated)."""
    truth = (TrueContact(), TrueContact(mu_c=0.4, r=0.005))
    base = controlled_slip(truth, seed=0)
    period = len(base) / 120.0 + 1.0
    out: list[SensorSnapshot] = []
    k = 0
    while len(out) < n:
        out.extend(controlled_slip(truth, t0=k * period, seed=k))
        k += 1
    return out[:n]


def _time_controller(make: Callable[[float], SlipController], snaps: list[SensorSnapshot],
                     repeats: int) -> list[int]:
    samples: list[int] = []
    clock = time.perf_counter_ns
    for _ in range(repeats):
        ctrl = make(snaps[0].twist_1.stamp)  # type: ignore[union-attr]
        for s in snaps:
            t = s.twist_1.stamp + 0.0005  # type: ignore[union-attr]
            t0 = clock()
            out = ctrl.step(s, t)
            samples.append(clock() - t0)
            if out.next_controller is not None:      # keep timing the mode under test
                ctrl = make(t)
    return samples


def _props() -> ContactProperties:
    f = FingerContact(mu_c=0.45, mu_s=0.5, mu_v=1.0, r=0.006, u=3.6e-5, mu_c_std=0.005,
                      r_std=2e-4, n_linear=60, n_static=5, n_rotational=60, linear_valid=True,
                      viscous_valid=True, static_valid=True, rotational_valid=True)
    return ContactProperties(f, f, ContactSource.ESTIMATED)


def main() -> None:
    """Run the benchmarks and print a table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--quick', action='store_true', help='fewer repetitions')
    args = ap.parse_args()
    n, repeats = (960, 3) if args.quick else (4800, 10)

    p = SlipControllerParams()
    c = ControlContact(mu_c=0.45, r=0.006, r_valid=True)
    snaps = _snapshots(n)
    rows: list[tuple[str, list[int]]] = []
    modes: dict[str, Callable[[float], SlipController]] = {
        'OFF': lambda t: OffController(p),
        'HOLD': lambda t: HoldController(p, c, initial_force=5.0),
        'HINGE': lambda t: HingeController(p, c),
        'LINEAR (direction-aware)': lambda t: LinearController(p, c, 0.1, 60.0, t),
        'LINEAR (reference)': lambda t: LinearController(
            SlipControllerParams(direction_aware=False), c, 0.1, 60.0, t),
        'ROTATIONAL': lambda t: RotationalController(p, c, 6.0, 60.0, t),
    }
    for name, make in modes.items():
        rows.append((f'controller step {name}', _time_controller(make, snaps, repeats)))

    # Safe-hold path (velocity stale: watchdog steps with an old twist).
    stale = [SensorSnapshot(s.wrench_1, s.wrench_2, snaps[0].twist_1, snaps[0].twist_2)
             for s in snaps]
    samples: list[int] = []
    hold = HoldController(p, c, initial_force=5.0)
    for i, s in enumerate(stale):
        t = 1.0 + i * 0.01
        t0 = time.perf_counter_ns()
        hold.step(s, t)
        samples.append(time.perf_counter_ns() - t0)
    rows.append(('controller step HOLD safe-hold (stale velocity)', samples))

    # Mode switch: validate + build a complete controller.
    props = _props()
    samples = []
    req = ModeRequest(int(SlipMode.LINEAR), duration=2.0, distance=0.02)
    for i in range(n):
        t0 = time.perf_counter_ns()
        build_controller(req, props, p, float(i))
        samples.append(time.perf_counter_ns() - t0)
    rows.append(('mode switch build_controller(LINEAR)', samples))

    # Estimator steps (per finger-1 twist; both fingers processed).
    ep = ContactEstimatorParams(online=EstimatorOnlineParams(enabled=True))
    truth = (TrueContact(), TrueContact(mu_c=0.4, r=0.005))
    for phase, gen in ((EstimationPhase.LINEAR, exploration_linear),
                       (EstimationPhase.ROTATIONAL, exploration_rotational)):
        samples = []
        fit_ns: list[int] = []
        for r in range(max(3, repeats * 3)):
            est = ContactEstimator(ep, props)
            data = gen(truth, t0=10.0, seed=r)
            est.start(phase, 1.0, 10.0)
            for s in data:
                t = s.twist_1.stamp  # type: ignore[union-attr]
                t0 = time.perf_counter_ns()
                est.step(s, t)
                samples.append(time.perf_counter_ns() - t0)
            t0 = time.perf_counter_ns()
            est.poll(11.0)                          # window over: fit and flags
            fit_ns.append(time.perf_counter_ns() - t0)
        rows.append((f'estimator step {phase.name} (collect)', samples))
        rows.append((f'estimator {phase.name} end of phase (fit)', fit_ns))
    samples = []
    est = ContactEstimator(ep, props)
    est.start(EstimationPhase.ONLINE, 0.0, 0.0)
    for s in snaps:
        t = s.twist_1.stamp  # type: ignore[union-attr]
        t0 = time.perf_counter_ns()
        est.step(s, t)
        samples.append(time.perf_counter_ns() - t0)
    rows.append(('estimator step ONLINE (RLS update)', samples))

    width = max(len(r[0]) for r in rows)
    print(f'slip_control core step cost (python {sys.version.split()[0]}, '
          f'{"quick" if args.quick else "full"} run)')
    print(f'{"step":<{width}}  {"n":>6}  {"p50 µs":>8}  {"p99 µs":>8}  {"max µs":>8}')
    for name, ns in rows:
        p50, p99, mx = _stats(ns)
        print(f'{name:<{width}}  {len(ns):>6}  {p50:>8.1f}  {p99:>8.1f}  {mx:>8.1f}')
    worst = max(_stats(ns)[1] for name, ns in rows if name.startswith('controller step'))
    print(f'worst controller-step p99: {worst:.1f} µs (target ≤ 100 µs)')


if __name__ == '__main__':
    main()
