# SPDX-License-Identifier: Apache-2.0
"""Unconditional stability: dt = 1 ms with σ0 = 1e6 1/m cannot make a model diverge (spec §8).

The exponential update keeps every bristle inside ``max(|z₀|, z_max)`` with
``z_max ≤ μ_S/σ0``; the force is then bounded by ``(μ_S + 2σ1 μ_S/(σ0 dt) + σ2 |v|)·f_n``.
Inputs are hostile: random speeds up to 1 m/s and 30 rad/s, reversing every step, and random
normal forces including zero.
"""
from __future__ import annotations

import numpy as np
import pytest

from friction_models.core.distributed import DistributedPlanarLuGre
from friction_models.core.integrators import UnstableStepError
from friction_models.core.one_d import AmendedLuGre, Dahl, ElastoPlastic, LuGre
from friction_models.core.params import ClassicLuGreParams, DahlParams, LuGreParams
from friction_models.core.reduced import ReducedPlanarLuGre, ReducedPlanarLuGreBatch
from friction_models.core.surfaces import line_grad, square

DT = 1e-3
P = LuGreParams(sigma0=1e6)
Z_BOUND = P.mu_s / P.sigma0 * (1 + 1e-12)


def force_bound(speed: float, f_n: float) -> float:
    return (P.mu_s + 2 * P.sigma1 * P.mu_s / (P.sigma0 * DT) + P.sigma2 * speed) * f_n


@pytest.mark.parametrize('model', [AmendedLuGre(P, shape=(200,)),
                                   ElastoPlastic(P, shape=(200,))], ids=['lugre', 'ep'])
def test_one_d_amended(model: AmendedLuGre) -> None:
    rng = np.random.default_rng(0)
    for _ in range(300):
        v = rng.uniform(-1.0, 1.0, 200) * rng.choice([1e-6, 1e-3, 1.0], 200)
        fn = rng.uniform(0.0, 20.0, 200)
        f = model.step(v, fn, DT)
        assert np.all(np.abs(model.z) <= Z_BOUND)
        assert np.all(np.abs(f) <= force_bound(1.0, 20.0))


def test_one_d_classic_laws() -> None:
    rng = np.random.default_rng(1)
    lg = LuGre(ClassicLuGreParams(sigma0=1e6), shape=(100,))
    dahl = Dahl(DahlParams(sigma0=1e6), shape=(100,))
    for _ in range(300):
        v = rng.uniform(-1.0, 1.0, 100)
        fn = rng.uniform(0.0, 20.0, 100)
        assert np.all(np.isfinite(lg.step(v, fn, DT)))
        assert np.all(np.abs(dahl.step(v, fn, DT)) <= 1.0 * 20.0 + 1e-9)


@pytest.mark.parametrize('ep', [False, True])
@pytest.mark.parametrize('make', [square, line_grad])
def test_distributed(ep: bool, make: object) -> None:
    s = make(21, 0.02)  # type: ignore[operator]
    model = DistributedPlanarLuGre(s, P, elasto_plastic=ep)
    rng = np.random.default_rng(2)
    for _ in range(150):
        tw = rng.uniform(-1, 1, 3) * [1.0, 1.0, 30.0] * rng.choice([1e-4, 1.0])
        fn = rng.choice([0.0, rng.uniform(0, 20)])
        w = model.step(tw, DT, f_n=fn)
        speed = np.hypot(tw[0], tw[1]) + abs(tw[2]) * 0.015
        assert np.linalg.norm(model.state, axis=-1).max() <= Z_BOUND
        assert np.hypot(w.fx, w.fy) <= force_bound(speed, fn) + 1e-12


@pytest.mark.parametrize('ep', [False, True])
@pytest.mark.parametrize('ls', [True, False])
def test_reduced_single_and_batch(ep: bool, ls: bool) -> None:
    s = line_grad(21, 0.02)
    single = ReducedPlanarLuGre(s, P, limit_surface=ls, elasto_plastic=ep)
    batch = ReducedPlanarLuGreBatch(s, P, n=50, limit_surface=ls, elasto_plastic=ep)
    h_max = 1.0 if single.limit_surface is None else float(
        np.linalg.norm(single.limit_surface.table, axis=-1).max())
    bound = h_max * Z_BOUND
    scale = np.array([1.0, 1.0, 1.0 / single.r_a])
    rng = np.random.default_rng(3)
    for _ in range(300):
        tws = rng.uniform(-1, 1, (50, 3)) * [1.0, 1.0, 30.0] * rng.choice([1e-4, 1.0], (50, 1))
        fns = rng.uniform(0.0, 20.0, 50)
        w = single.step(tws[0], DT, f_n=fns[0])
        wb = batch.step(tws, DT, f_n=fns)
        assert np.linalg.norm(single.state * scale) <= bound
        assert np.linalg.norm(batch.state * scale, axis=1).max() <= bound
        speed = np.hypot(tws[0, 0], tws[0, 1])
        assert np.hypot(w.fx, w.fy) <= force_bound(speed, fns[0]) * h_max + 1e-12
        assert np.all(np.isfinite(np.stack(wb)))


def test_explicit_euler_refuses_to_diverge() -> None:
    """Explicit Euler without its limiter raises instead of silently blowing up at dt = 1 ms.

    The reference scheme is kept for regression work only.
    """
    with pytest.raises(UnstableStepError):
        m = AmendedLuGre(P, integrator='explicit_euler')
        for _ in range(3):
            m.step(0.05, 1.0, DT)
    with pytest.raises(UnstableStepError):
        r = ReducedPlanarLuGre(square(9), P, elasto_plastic=False, integrator='explicit_euler')
        r.step((0.05, 0.0, 0.0), DT)
    limited = ReducedPlanarLuGre(square(9), P, integrator='explicit_euler', rate_limiter=True)
    for _ in range(50):
        w = limited.step((0.05, 0.0, 3.0), DT)
    assert np.all(np.isfinite(w)) and abs(w.fx) < 2.0
