# SPDX-License-Identifier: Apache-2.0
"""Metrics of control_and_estimation §6.4–6.7 on series with known answers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from slip_bringup.core.excitation import fit_sine, is_excited
from slip_bringup.core.metrics import (
    cumulative_integral,
    estimation_spread,
    force_stats,
    hold_metrics,
    last_valid,
    linear_slip_distance,
    rotational_slip_angle,
    to_middle,
    tracking_errors,
)
from slip_bringup.core.phases import StateChange, mode_ends, phase_at, phases
from slip_cell_common.core.frames import FrameParams, planar_from_middle, planar_to_middle
from slip_control.core.contact import ContactProperties, ContactSource, FingerContact
from slip_control.core.trajectory import TrapezoidalTrajectory

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


def test_last_valid_takes_the_last_complete_value_not_a_mean() -> None:
    nan = math.nan
    # Linear phase: r still NaN (and not valid); rotational phase: r = 5 mm ± 0.1 mm.
    r = last_valid([nan, 0.005], [nan, 1e-4], [False, True])
    assert (r.value, r.std, r.index) == (0.005, 1e-4, 1)
    # A later partial set (valid flag down, or a NaN) does not replace it.
    r = last_valid([0.004, 0.005, nan, 0.009], [1e-4, 2e-4, nan, nan], [True, True, True, False])
    assert (r.value, r.std, r.index) == (0.005, 2e-4, 1)
    none = last_valid([nan], [nan], [True])
    assert math.isnan(none.value) and none.index == -1


def test_force_stats_ignore_nan() -> None:
    s = force_stats([4.0, math.nan, 6.0, 5.0])
    assert (s.min, s.max, s.mean, s.n, s.span) == (4.0, 6.0, 5.0, 3, 2.0)
    assert s.sd == pytest.approx(1.0)
    assert force_stats([math.nan]).n == 0


@pytest.mark.parametrize('rate', [500.0, 120.0])
def test_sine_is_found_only_where_it_is(rate: float) -> None:
    rng = np.random.default_rng(3)
    t = 100.0 + np.arange(0.0, 4.8, 1.0 / rate) + rng.uniform(0.0, 2e-4, int(4.8 * rate))
    sine = 10.0 + 5.0 * np.sin(2 * np.pi * 4.0 * (t - 99.93))
    fit = fit_sine(t, sine + rng.normal(0.0, 0.05, t.size), 4.0)
    assert fit.amplitude == pytest.approx(5.0, rel=0.01) and fit.explained > 0.99
    assert fit.offset == pytest.approx(10.0, abs=0.05) and is_excited(fit, 5.0)
    assert not is_excited(fit_sine(t, sine, 8.0), 5.0)           # another frequency
    assert not is_excited(fit_sine(t, np.full(t.size, 4.0), 4.0), 5.0)     # constant
    step = np.where(t < t[t.size // 2], 5.0, 25.0)
    assert not is_excited(fit_sine(t, step, 4.0), 5.0)            # a step
    held = 4.0 + np.abs(rng.normal(0.0, 3.0, t.size))             # a controller's output
    assert not is_excited(fit_sine(t, held, 4.0), 5.0)
    assert not is_excited(fit_sine(t[:3], sine[:3], 4.0), 5.0)    # too few samples
    with pytest.raises(ValueError):
        fit_sine(t, sine, 0.0)


def test_phases_and_aborts_from_state_changes() -> None:
    changes = [StateChange(1.0, 0, 'off'), StateChange(2.0, 4, 'set_mode: HOLD'),
               StateChange(2.5, 4, 'velocity stale: slip term 0, no decrease'),
               StateChange(3.0, 2, 'set_mode: LINEAR 0.0200 m in 2.000 s'),
               StateChange(4.0, 4, 'LINEAR ended: velocity stale'),
               StateChange(4.1, 4, 'LINEAR ended: velocity stale'),     # safe-hold toggle
               StateChange(6.0, 1, 'set_mode: ROTATIONAL'),
               StateChange(8.0, 4, 'ROTATIONAL ended: done')]
    runs = phases(changes, t_begin=1.5, t_end=9.0)
    assert [(p.mode, p.t_start, p.t_end) for p in runs] == [
        ('off', 1.5, 2.0), ('hold', 2.0, 3.0), ('linear', 3.0, 4.0), ('hold', 4.0, 6.0),
        ('rotational', 6.0, 8.0), ('hold', 8.0, 9.0)]
    ends = mode_ends(changes)
    assert [(e.mode, e.t, e.success, e.message) for e in ends] == [
        ('linear', 4.0, False, 'velocity stale'), ('rotational', 8.0, True, 'done')]
    assert phase_at(runs, 5.0).mode == 'hold' and phase_at(runs, 0.5) is None
    assert phases([], 0.0, 1.0) == []
