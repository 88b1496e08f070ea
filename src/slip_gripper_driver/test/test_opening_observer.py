# SPDX-License-Identifier: Apache-2.0
"""Opening-rate tracking observer (hardware_protocols §2.4)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from slip_gripper_driver.core.observer import MAX_DT_S, ObserverParams, RateObserver


def test_first_sample_initialises() -> None:
    obs = RateObserver()
    est = obs.update(1.0, 0.03)
    assert est.position == 0.03 and est.rate == 0.0 and not est.updated


def test_ramp_is_tracked_without_steady_state_error() -> None:
    obs = RateObserver(ObserverParams())
    rate = 0.025  # m/s
    for k in range(1500):  # 3 s at 500 Hz
        t = 10.0 + k * 0.002
        est = obs.update(t, 0.01 + rate * (t - 10.0))
    assert est.rate == pytest.approx(rate, rel=1e-6)


def test_step_response_matches_second_order_design() -> None:
    """Rate estimate of a ramp start follows the design loop ωn = √ki, ζ = kp/(2√ki)."""
    params = ObserverParams(kp=40.0, ki=500.0)
    obs = RateObserver(params)
    dt = 1e-4
    rates = []
    for k in range(20000):
        t = k * dt
        rates.append(obs.update(t, 0.0 if t < 0.1 else 0.01 * (t - 0.1)).rate)
    zeta = params.kp / (2.0 * math.sqrt(params.ki))
    assert zeta == pytest.approx(0.894, abs=1e-3)
    # v_hat/p = s·H(s) with H(s) = (kp·s + ki)/(s² + kp·s + ki): a ramp's rate estimate is
    # the step response of H (continuous limit of the per-line update)
    tc, yc = signal.step(([params.kp, params.ki], [1.0, params.kp, params.ki]),
                         T=np.arange(0.0, 1.9, dt))
    peak = max(rates) / 0.01
    assert peak == pytest.approx(float(np.max(yc)), abs=0.01)
    assert peak > 1.05  # the zero makes it overshoot despite ζ = 0.894
    assert rates[-1] == pytest.approx(0.01, rel=1e-4)


@pytest.mark.parametrize('dt', [0.0, -0.002])
def test_non_positive_dt_is_skipped(dt: float) -> None:
    obs = RateObserver()
    obs.update(0.0, 0.0)
    obs.update(0.002, 0.001)
    before = (obs.position, obs.rate)
    est = obs.update(0.002 + dt, 5.0)
    assert not est.updated and (est.position, est.rate) == before and obs.skipped == 1


def test_gap_reinitialises_and_non_finite_is_skipped() -> None:
    obs = RateObserver()
    for k in range(100):
        obs.update(k * 0.002, 0.001 * k)
    est = obs.update(0.198 + MAX_DT_S + 0.01, 0.5)
    assert not est.updated and est.position == 0.5 and est.rate == 0.0 and obs.reinits == 1
    assert not obs.update(1.0, math.nan).updated


def test_reset_forgets_state() -> None:
    obs = RateObserver()
    obs.update(0.0, 0.0)
    obs.update(0.002, 0.01)
    obs.reset()
    assert math.isnan(obs.rate)
    assert obs.update(0.004, 0.02).position == 0.02


def test_noise_is_attenuated() -> None:
    rng = np.random.default_rng(0)
    obs = RateObserver()
    res = 0.0086751614 * 2 * math.pi / 4096  # one encoder count of opening [m]
    rates = [obs.update(k * 0.002, res * round(rng.normal(0, 1))).rate for k in range(5000)]
    naive = res / 0.002  # a one-count finite difference
    assert np.std(rates[500:]) < 0.2 * naive
