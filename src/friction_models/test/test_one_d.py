# SPDX-License-Identifier: Apache-2.0
"""One-dimensional laws (thesis §2.1, spec §2; checks A1-A3, A12, A14)."""
from __future__ import annotations

import numpy as np
import pytest

from friction_models.core.one_d import (AmendedLuGre, Coulomb, Dahl, ElastoPlastic, LuGre,
                                        Stribeck, ep_weight, lugre_steady_state)
from friction_models.core.params import (ClassicLuGreParams, DahlParams, LuGreParams,
                                         StribeckParams)

P = LuGreParams()


def test_coulomb_sliding_and_sticking() -> None:
    c = Coulomb(0.5)
    np.testing.assert_allclose(c.force([0.1, -0.1], 2.0), [-1.0, 1.0])
    np.testing.assert_allclose(c.force(0.0, 2.0, f_applied=[0.3, -2.5]), [-0.3, 1.0])


def test_stribeck_curve_limits_and_oddness() -> None:
    s = Stribeck(StribeckParams(mu_c=0.4, mu_s=0.5, v_s=1e-3, mu_v=2.0))
    assert s.coefficient(1e-9) == pytest.approx(0.5 + 2e-9, rel=1e-12)  # μ_S + μ_v|v| at v → 0
    assert s.coefficient(0.1) == pytest.approx(0.4 + 0.2, rel=1e-9)  # μ_C + μ_v|v|, v ≫ v_s
    v = np.linspace(-0.05, 0.05, 11)
    np.testing.assert_allclose(s.force(v, 3.0), -s.force(-v, 3.0))
    assert float(s.force(0.0, 3.0, f_applied=10.0)) == pytest.approx(-1.5)


@pytest.mark.parametrize('v', [-0.02, -2e-3, 1e-3, 5e-4, 0.05])
def test_amended_lugre_steady_sliding(v: float) -> None:
    """A1: constant v until steady: f = −(g(v) sgn v + σ2 v) f_n (exact integrator)."""
    for model in (AmendedLuGre(P), ElastoPlastic(P)):
        for _ in range(50):
            f = model.step(v, 2.5, 1e-2)
        assert float(f) == pytest.approx(float(lugre_steady_state(v, 2.5, P)), rel=1e-9)
    g = P.mu_c + (P.mu_s - P.mu_c) * np.exp(-(abs(v) / P.v_s) ** 2)
    assert float(lugre_steady_state(v, 2.5, P)) == pytest.approx(
        -(g * np.sign(v) + P.sigma2 * v) * 2.5)


def test_classic_lugre_and_dahl_steady_state() -> None:
    cp = ClassicLuGreParams(mu_c=0.3, mu_s=0.4, sigma0=1e5, sigma1=50.0, sigma2=2.0)
    lg = LuGre(cp)
    dahl = Dahl(DahlParams(mu_c=0.3, sigma0=1e5))
    for _ in range(100):
        f_l = lg.step(0.01, 10.0, 1e-2)
        f_d = dahl.step(-0.01, 10.0, 1e-2)
    assert float(f_l) == pytest.approx(float(lg.steady_state(0.01, 10.0)), rel=1e-9)
    assert float(f_l) == pytest.approx(-(3.0 + 2.0 * 0.01), rel=1e-6)
    assert float(f_d) == pytest.approx(3.0, rel=1e-9)


@pytest.mark.parametrize('model_cls', [AmendedLuGre, ElastoPlastic])
def test_presliding_is_a_spring(model_cls: type) -> None:
    """A2: a small displacement x from rest gives f ≈ −σ0 x f_n."""
    model = model_cls(P, force_from='post_update')
    x = 2e-8                       # 2 % of z_max = μ_S/σ0
    for _ in range(100):
        f = model.step(x / 100 / 1e-4, 3.0, 1e-4)
    sigma1_part = P.sigma1 * (x / 100 / 1e-4) * 3.0
    assert float(f) + sigma1_part == pytest.approx(-P.sigma0 * x * 3.0, rel=0.02)


def test_sticking_freezes_the_state() -> None:
    """A3: v = 0 ⇒ ż = 0 and the force is the constant spring −σ0 z f_n."""
    model = ElastoPlastic(P)
    model.set_state(4e-7)
    forces = [float(model.step(0.0, 2.0, dt)) for dt in (1e-4, 1e-2, 1.0)]
    np.testing.assert_allclose(forces, -P.sigma0 * 4e-7 * 2.0, rtol=1e-15)
    assert float(model.z) == 4e-7


def test_ep_weight_bands() -> None:
    z_max = 1e-6
    z = np.array([0.0, 0.5e-6, 0.9e-6, 0.95e-6, 1e-6, 2e-6, -0.95e-6])
    alpha = ep_weight(z, 1.0, z_max, 0.9)
    np.testing.assert_allclose(alpha, [0, 0, 0, 0.5, 1, 1, 0], atol=1e-12)
    # Against the thesis form ½ sin(π(|z| − (z_max + z_ba)/2)/(z_max − z_ba)) + ½.
    zz = 0.93e-6
    ref = 0.5 * np.sin(np.pi * (zz - 0.95e-6) / 0.1e-6) + 0.5
    assert float(ep_weight(zz, -0.0 + 1.0, z_max, 0.9)) == pytest.approx(ref, rel=1e-12)


def test_elasto_plastic_band_is_purely_elastic() -> None:
    """A12: inside the band ż = v exactly (no plastic slip); plain LuGre always slips."""
    ep, lg = ElastoPlastic(P), AmendedLuGre(P)
    v, dt = 1e-4, 1e-3
    for _ in range(5):
        ep.step(v, 1.0, dt)
        lg.step(v, 1.0, dt)
    assert float(ep.z) == pytest.approx(5 * v * dt, rel=1e-14)
    assert float(lg.z) < 5 * v * dt * (1 - 1e-3)


def test_batch_shapes_are_vectorised() -> None:
    model = ElastoPlastic(P, shape=(3, 4))
    rng = np.random.default_rng(0)
    v = rng.normal(scale=1e-3, size=(3, 4))
    f = model.step(v, np.full((3, 4), 2.0), 1e-3)
    assert f.shape == (3, 4) and model.z.shape == (3, 4)
    single = ElastoPlastic(P)
    assert float(single.step(v[1, 2], 2.0, 1e-3)) == pytest.approx(f[1, 2], rel=1e-15)
