# SPDX-License-Identifier: Apache-2.0
"""Stick-slip of a mass pulled through a spring (LuGre with a Stribeck peak, spec §2)."""
from __future__ import annotations

import numpy as np
import pytest

from friction_models.core.params import LuGreParams
from friction_models.core.scenarios import simulate_stick_slip

BASE = {'mu_c': 1.0, 'v_s': 1e-3, 'sigma0': 1e5, 'sigma1': 20.0, 'sigma2': 1.0}


@pytest.mark.parametrize('elasto_plastic', [False, True])
def test_stick_slip_with_static_peak(elasto_plastic: bool) -> None:
    r = simulate_stick_slip(LuGreParams(mu_s=1.2, **BASE), elasto_plastic=elasto_plastic)
    assert r.stick_phases(after=0.5) >= 2
    late = r.t > 1.0
    # Breakaway near μ_S f_n, release well below it: a saw-tooth spring force.
    assert r.spring_force[late].max() > 0.95 * 1.2 * 10.0
    assert r.spring_force[late].min() < 0.9 * 1.0 * 10.0


def test_no_stick_slip_without_static_peak() -> None:
    r = simulate_stick_slip(LuGreParams(mu_s=1.0, **BASE))
    assert r.stick_phases(after=0.5) == 0
    late = r.t > 1.5
    np.testing.assert_allclose(r.v[late], r.drive_speed, rtol=0.02)
    np.testing.assert_allclose(r.spring_force[late], (1.0 + 1.0 * 1e-3) * 10.0, rtol=2e-3)
