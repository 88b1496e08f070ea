# SPDX-License-Identifier: Apache-2.0
"""Metrics of control_and_estimation §6.4–6.7 on series with known answers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from slip_control.core.contact import ContactProperties, ContactSource, FingerContact
from slip_bringup.core.metrics import (cumulative_integral, estimation_spread, hold_metrics,
                                       linear_slip_distance, rotational_slip_angle, to_middle,
                                       tracking_errors)
from slip_control.core.trajectory import TrapezoidalTrajectory
from slip_cell_common.core.frames import FrameParams, planar_from_middle, planar_to_middle

FRAMES = FrameParams()


def test_cumulative_integral_skips_bad_intervals() -> None:
    t = np.array([0.0, 1.0, 1.0, 0.5, 2.0])
    y = np.ones(5)
    assert cumulative_integral(t, y) == pytest.approx([0.0, 1.0, 1.0, 1.0, 2.5])
    t = np.linspace(0.0, 2.0, 2001)
    tr = TrapezoidalTrajectory(0.02, 2.0)
    _, v = tr.sample_array(t)
    assert cumulative_integral(t, v)[-1] == pytest.approx(0.02, rel=1e-5)


def test_to_middle_matches_the_scalar_transform() -> None:
    rng = np.random.default_rng(0)
    x, y, z = rng.normal(size=(3, 5))
    for k in (1, 2):
        mx, my, mz = to_middle(FRAMES, k, x, y, z)
        for i in range(5):
            assert (mx[i], my[i], mz[i]) == pytest.approx(planar_to_middle(FRAMES, k, x[i], y[i],
                                                                           z[i]))


def test_linear_slip_magnitude_vs_signed() -> None:
    t = np.arange(0.0, 3.0, 1.0 / 120.0)
    # 2 s forward at 10 mm/s along (0.6, −0.8), then 1 s back at 5 mm/s.
    speed = np.where(t < 2.0, 0.01, -0.005)
    e = np.array([0.6, -0.8])
    v = speed[:, None] * e[None, :]
    rng = np.random.default_rng(1)
    v1 = v + rng.normal(0.0, 1e-4, v.shape)
    v2 = 2.0 * v - v1                               # fingers differ; mean is exact
    d = linear_slip_distance(t, v1, v2)
    assert d.signed == pytest.approx(0.02 - 0.005, abs=2e-4)
    assert d.magnitude == pytest.approx(0.02 + 0.005, abs=2e-4)
    assert d.direction == pytest.approx((0.6, -0.8), abs=1e-3)
    d2 = linear_slip_distance(t, v1, v2, direction=(0.0, 1.0))
    assert d2.signed == pytest.approx(-0.8 * 0.015, abs=2e-4)


def test_rotational_angle_uses_raw_frames_with_finger_2_flipped() -> None:
    t = np.arange(0.0, 2.0, 1.0 / 120.0)
    w_mid = np.full(t.size, math.radians(10.0))          # 20° in 2 s about middle +z
    w1 = np.array([planar_from_middle(FRAMES, 1, 0.0, 0.0, w)[2] for w in w_mid])
    w2 = np.array([planar_from_middle(FRAMES, 2, 0.0, 0.0, w)[2] for w in w_mid])
    assert np.all(w2 < 0.0)
    angle = rotational_slip_angle(t, w1, w2)
    assert angle == pytest.approx(math.radians(10.0) * (t[-1] - t[0]))


def test_tracking_errors() -> None:
    e = tracking_errors([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0, 1.0], [1.0, 1.0], [1.0, 0.0])
    assert e.pos_rms == pytest.approx(1.0) and e.pos_max == 2.0 and e.final_error == 2.0
    assert e.vel_rms == pytest.approx(math.sqrt(0.5)) and e.vel_max == 1.0


def test_hold_metrics_peak_excursion() -> None:
    t = np.arange(0.0, 2.0, 0.01)
    v = np.zeros((t.size, 2))
    v[(t >= 0.5) & (t < 0.6), 0] = 0.01                 # 1 mm out
    v[(t >= 1.0) & (t < 1.1), 0] = -0.01                # and back
    w = np.where((t >= 0.2) & (t < 0.3), -0.5, 0.0)     # −0.05 rad
    f = 4.0 + np.sin(t)
    m = hold_metrics(t, v, w, f)
    assert m.peak_slip_distance == pytest.approx(0.001, rel=0.05)
    assert m.final_slip_distance == pytest.approx(0.0, abs=5e-5)
    assert m.peak_slip_angle == pytest.approx(0.05, rel=0.05)
    assert m.force_range == pytest.approx(np.max(f) - np.min(f))


def test_estimation_spread_uses_valid_estimates_only() -> None:
    def f(mu: float, r: float, ok: bool = True) -> FingerContact:
        return FingerContact(mu_c=mu, mu_s=mu, mu_v=1.0, r=r, n_linear=40, n_rotational=30,
                             linear_valid=ok, viscous_valid=ok, static_valid=ok,
                             rotational_valid=ok)
    sets = [ContactProperties(f(0.4, 0.005), f(0.5, 0.004), ContactSource.ESTIMATED),
            ContactProperties(f(0.44, 0.007), f(0.5, 0.004), ContactSource.ESTIMATED),
            ContactProperties(f(9.0, 1.0, False), f(0.5, 0.004), ContactSource.ESTIMATED)]
    s1, s2 = estimation_spread(sets)
    assert s1.mu_c.mean == pytest.approx(0.42) and s1.mu_c.n == 2
    assert s1.mu_c.sd == pytest.approx(np.std([0.4, 0.44], ddof=1))
    assert s1.r.mean == pytest.approx(0.006) and s1.n_rotational_valid == 2
    assert s2.mu_c.sd == pytest.approx(0.0) and s2.n_linear_valid == 3 and s2.n_runs == 3
