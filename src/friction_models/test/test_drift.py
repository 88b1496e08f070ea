# SPDX-License-Identifier: Apache-2.0
"""Creep under oscillating sub-breakaway loads (spec §2, §10.2; checks A12, A13).

Plain LuGre always has a plastic part (ż ≠ v whenever v ≠ 0), so an oscillating load creeps
the object towards the mean load. The Elasto-Plastic bristle stays inside its elastic band
(ż = v exactly), so the object only oscillates about its elastic offset. Drift is the change
of the period-averaged position between the start and the end of an oscillation phase.

Rigid-body coupling uses ``force_from='post_update'`` with ``x⁺ = x + v dt, v⁺ = v + a dt``
(module :mod:`friction_models.core.scenarios`): at dt = 0.1 ms the reference's pre-update
force would cost σ0 f_n dt/2 ≈ 490 N·s/m of damping, more than the EP arm's σ1 f_n = 785 can
spare at larger steps.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from friction_models.core.distributed import DistributedPlanarLuGre
from friction_models.core.one_d import AmendedLuGre
from friction_models.core.params import PARAMETER_SETS
from friction_models.core.reduced import ReducedPlanarLuGre
from friction_models.core.scenarios import DriftResult, simulate_drift
from friction_models.core.surfaces import circle

FN = 9.81
PERIOD = 1.0 / 3.0                        # loads oscillate at 3 Hz
LUGRE = PARAMETER_SETS['drift_lugre']
EP = PARAMETER_SETS['drift_elasto_plastic']


def drift_1d(elasto_plastic: bool, dt: float = 1e-4) -> tuple[float, float, list[float]]:
    """1 kg on a 1-D contact: f = 1 N (ramped) + 0.4 sin(6πt) N from t = 1 s."""
    model = AmendedLuGre(EP if elasto_plastic else LUGRE, elasto_plastic=elasto_plastic,
                         force_from='post_update')
    steps = round(5.0 / dt)
    xs = np.empty(steps)
    x = v = 0.0
    for n in range(steps):
        t = n * dt
        load = min(t / 0.2, 1.0) + (0.4 * math.sin(6 * math.pi * t) if t >= 1.0 else 0.0)
        f = float(model.step(v, FN, dt))
        x += v * dt
        v += (load + f) * dt
        xs[n] = x
    t = np.arange(steps) * dt

    def mean(t0: float) -> float:
        return float(xs[(t >= t0) & (t < t0 + PERIOD)].mean())

    offset = mean(0.6)
    means = [mean(t0) for t0 in np.arange(1.5, 5.0 - PERIOD, PERIOD)]
    return offset, means[-1] - means[0], means


def test_one_d_lugre_creeps_elasto_plastic_does_not() -> None:
    offset_ep, drift_ep, _ = drift_1d(True)
    _, drift_lg, means_lg = drift_1d(False)
    assert offset_ep == pytest.approx(1.0 / (EP.sigma0 * FN), rel=1e-3)    # A13: x_el
    assert abs(drift_ep) < 1e-10
    assert drift_lg > 5e-8 and np.all(np.diff(means_lg) > 0)               # monotonic creep


def windows(r: DriftResult, series: str, start: float, stop: float) -> float:
    """Creep inside one oscillation phase [start, stop)."""
    return r.period_mean(stop - PERIOD, PERIOD, series) - r.period_mean(start, PERIOD, series)


@pytest.mark.parametrize('case', ['tangential', 'normal'])
def test_reduced_planar_drift(case: str) -> None:
    s = circle(21, 0.05)
    lg = simulate_drift(ReducedPlanarLuGre(s, LUGRE, elasto_plastic=False,
                                           force_from='post_update'), case)
    ep = simulate_drift(ReducedPlanarLuGre(s, EP, force_from='post_update'), case)
    if case == 'tangential':     # x oscillates from 1 s, the torque from 3 s
        phases = [('x', 1.5, 2.8), ('x', 3.5, 5.0), ('theta', 3.5, 5.0)]
    else:                        # f_n oscillates from 1 s
        phases = [('x', 1.5, 5.0), ('theta', 1.5, 5.0)]
    for series, a, b in phases:
        creep_lg = windows(lg, series, a, b)
        creep_ep = windows(ep, series, a, b)
        assert creep_lg > 1e-8 if series == 'x' else creep_lg > 1e-7, (series, a, creep_lg)
        assert abs(creep_ep) < (1e-10 if series == 'x' else 1e-9), (series, a, creep_ep)
    if case == 'tangential':
        # A13 with a pure tangential load. (Under combined force and torque the reduced
        # model's elastic offset differs: the limit-surface direction h is not parallel to
        # the generalised velocity, so its pre-sliding stiffness is direction dependent.)
        assert ep.period_mean(0.6, PERIOD) == pytest.approx(1.0 / (EP.sigma0 * FN), rel=1e-3)


def test_distributed_planar_drift() -> None:
    """Distributed model, coarse 9 × 9 disc of 50 mm; also the rotational offset A13."""
    s = circle(9, 0.05)
    lg = simulate_drift(DistributedPlanarLuGre(s, LUGRE, elasto_plastic=False,
                                               force_from='post_update'), 'tangential')
    ep = simulate_drift(DistributedPlanarLuGre(s, EP, force_from='post_update'), 'tangential')
    assert windows(lg, 'x', 1.5, 5.0) > 1e-8 and windows(lg, 'theta', 3.5, 5.0) > 1e-7
    assert abs(windows(ep, 'x', 1.5, 5.0)) < 1e-10
    assert abs(windows(ep, 'theta', 3.5, 5.0)) < 1e-9
    theta_el = 0.03 / (EP.sigma0 * FN * s.polar_moment)
    assert ep.period_mean(3.5, PERIOD, 'theta') == pytest.approx(theta_el, rel=1e-3)
