# SPDX-License-Identifier: Apache-2.0
"""Bristle integrators (spec §8, check A14)."""
from __future__ import annotations

import numpy as np
import pytest

from friction_models.core.integrators import (UnstableStepError, explicit_euler_step,
                                              exponential_step, phi, phi_scalar, rate_limit)


def test_phi_values_and_limit() -> None:
    x = np.array([0.0, 1e-300, 1e-12, 1e-3, 1.0, 50.0, 1e300])
    expected = np.array([1.0, 1.0, 1.0 - 5e-13, (1 - np.exp(-1e-3)) / 1e-3, 1 - np.exp(-1.0),
                         1 / 50.0, 0.0])
    np.testing.assert_allclose(phi(x), expected, rtol=1e-12, atol=1e-300)
    assert phi_scalar(0.0) == 1.0
    assert phi_scalar(2.0) == pytest.approx((1 - np.exp(-2.0)) / 2.0, rel=1e-15)


@pytest.mark.parametrize('dt', [1e-6, 1e-3, 1.0, 1e3])
def test_exponential_reaches_fixed_point_without_overshoot(dt: float) -> None:
    """A14: at constant q, k the state approaches q/k monotonically for any dt."""
    q, k = 0.02, 1e4          # fixed point 2e-6
    z = np.array(-5e-6)
    history = []
    for _ in range(200):
        z, _ = exponential_step(z, q, k, dt)
        history.append(float(z))
    h = np.array(history)
    assert np.all(h <= q / k + 1e-18)                  # never past the fixed point
    assert np.all(np.diff(h) >= -1e-21)                # monotone
    if dt >= 1e-3:
        assert h[-1] == pytest.approx(q / k, rel=1e-12)


def test_exponential_is_exact_for_constant_rates() -> None:
    q, k, z0, t = 0.3, 40.0, 0.01, 0.05
    z_exact = q / k + (z0 - q / k) * np.exp(-k * t)
    z1, _ = exponential_step(z0, q, k, t)
    z = np.array(z0)
    for _ in range(7):
        z, _ = exponential_step(z, q, k, t / 7)
    assert float(z1) == pytest.approx(z_exact, rel=1e-13)
    assert float(z) == pytest.approx(z_exact, rel=1e-13)


def test_exponential_covers_zero_rate_and_matches_euler_to_first_order() -> None:
    z, rate = exponential_step(1e-6, 0.01, 0.0, 1e-3)
    assert float(z) == pytest.approx(1e-6 + 1e-5, rel=1e-15) and float(rate) == 0.01
    errors = []
    for dt in (1e-4, 5e-5):
        ze, _ = exponential_step(0.0, 0.01, 1e3, dt)
        zu, _ = explicit_euler_step(0.0, 0.01, 1e3, dt)
        errors.append(abs(float(ze) - float(zu)) / dt)
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.05)   # O(dt) per unit time


def test_explicit_euler_guard_and_limiter() -> None:
    with pytest.raises(UnstableStepError):
        explicit_euler_step(0.0, 1.0, 1e6, 1e-3)
    z, rate = explicit_euler_step(0.0, 1.0, 1e6, 1e-3, z_ss=1e-6)
    assert float(z) == pytest.approx(1e-6) and float(rate) == pytest.approx(1e-3)
    limited = rate_limit(np.array([5.0, -5.0, 0.1]), np.zeros(3), np.array([1e-3, 1e-3, 1.0]),
                         1e-3)
    np.testing.assert_allclose(limited, [1.0, -1.0, 0.1])
