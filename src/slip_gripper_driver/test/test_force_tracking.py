# SPDX-License-Identifier: Apache-2.0
"""Force-tracking profile and analysis on synthetic systems with known answers."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from slip_cell_common.core.force_profile import ForceTrackingProfile
from slip_gripper_driver.core.force_tracking import (align_profile, analyze, bandwidth_3db,
                                                     format_report, frequency_point, main,
                                                     step_metrics)

PROFILE = ForceTrackingProfile()


def test_profile_levels_and_sines() -> None:
    p = PROFILE
    assert p.target(0.5) == 5.0 and p.target(2.5) == 5.0 and p.target(3.5) == 10.0
    assert p.target(9.5) == 25.0  # 8th level: 2 s + 7 s
    assert p.step_segment() == (9.0, 5.0, 25.0, 10.0)
    sines = p.sine_segments()
    assert [s.frequency for s in sines] == [1, 2, 4, 8, 16, 32, 64]
    assert sines[0].t_start == 2.0 + 13.0 + 1.0
    t = np.linspace(sines[0].t_start, sines[0].t_end, 10001)[:-1]
    f = p.targets(t)
    assert f.min() == pytest.approx(5.0, abs=1e-6) and f.max() == pytest.approx(15.0, abs=1e-6)
    assert f[0] == pytest.approx(10.0)  # each sine starts at mid range
    assert p.target(sines[-1].t_end + 0.5) == 5.0
    assert p.target(p.duration + 0.1) == 0.0 and p.duration == 2 + 13 + 1 + 35 + 1
    assert len(p.sample_times()) == int(p.duration * 500)


def simulate(num: list[float], den: list[float], fs_sim: float = 10_000.0,
             seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Play the profile through G(s), record at ≈500 Hz with jittered stamps."""
    t = np.arange(0.0, PROFILE.duration, 1.0 / fs_sim)
    u = PROFILE.targets(t)
    numd, dend, _ = signal.cont2discrete((num, den), 1.0 / fs_sim, method='zoh')
    y = signal.lfilter(np.ravel(numd), dend, u - u[0]) + u[0]  # at rest at 5 N (dc gain 1)
    rng = np.random.default_rng(seed)
    stamps = np.arange(0.0, PROFILE.duration - 0.01, 0.002) + rng.uniform(0, 2e-4, 1)
    stamps = np.sort(stamps + rng.normal(0.0, 5e-5, stamps.size))
    return stamps, PROFILE.targets(stamps), np.interp(stamps, t, y)


def test_first_order_step_metrics_and_bandwidth() -> None:
    tau = 0.02
    t, target, measured = simulate([1.0], [tau, 1.0])
    rep = analyze(t, target, t, measured, subsample=True)
    s = rep.step
    assert s.rise_time == pytest.approx(tau * math.log(9.0), abs=1.5e-3)
    assert s.t50 == pytest.approx(tau * math.log(2.0), abs=1e-3)
    assert s.overshoot == pytest.approx(0.0, abs=0.02)
    assert s.settling_time == pytest.approx(tau * math.log(20.0 / 0.4), abs=2.5e-3)
    for p in rep.response:
        w = 2 * math.pi * p.frequency_hz * tau
        assert p.magnitude_db == pytest.approx(-10 * math.log10(1 + w * w), abs=0.15)
        if p.frequency_hz <= 16:
            assert p.phase_deg == pytest.approx(-math.degrees(math.atan(w)), abs=4.0)
    exact = math.sqrt(10 ** 0.3 - 1) / (2 * math.pi * tau)
    assert rep.bandwidth_hz == pytest.approx(exact, rel=0.05)
    assert 'bandwidth' in format_report(rep)


def test_second_order_overshoot() -> None:
    wn, zeta = 2 * math.pi * 12.0, 0.4
    t, target, measured = simulate([wn * wn], [1.0, 2 * zeta * wn, wn * wn])
    s = analyze(t, target, t, measured).step
    expected = 20.0 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta * zeta))
    assert s.overshoot == pytest.approx(expected, abs=0.1)
    assert s.peak == pytest.approx(25.0 + expected, abs=0.1)
    assert s.rise_time < s.settling_time


def test_pure_delay_phase() -> None:
    fs = 500.0
    t = np.arange(0.0, 5.0, 1.0 / fs)
    x = 10.0 + 5.0 * np.sin(2 * np.pi * 4.0 * t)
    y = 10.0 + 5.0 * np.sin(2 * np.pi * 4.0 * (t - 0.01))  # 10 ms = 5 samples
    p = frequency_point(t, x, y, frequency=4.0, t_start=0.0, duration=5.0)
    assert p.lag_s == pytest.approx(0.01) and p.phase_deg == pytest.approx(-14.4)
    assert p.magnitude_db == pytest.approx(0.0, abs=0.01)


def test_never_reaching_the_level_gives_nan() -> None:
    t = np.arange(0.0, 2.0, 0.002)
    y = np.where(t < 1.0, 5.0, 12.0)
    s = step_metrics(t, y, t_step=1.0, f_from=5.0, f_to=25.0, window_s=0.9)
    assert math.isnan(s.rise_time) and math.isnan(s.settling_time)
    assert s.overshoot == pytest.approx(-13.0)


def test_bandwidth_interpolation_in_log_f() -> None:
    assert bandwidth_3db([1, 2, 4, 8], [0.0, -1.0, -2.0, -4.0]) == pytest.approx(
        10 ** (math.log10(4) + 0.5 * math.log10(2)))
    assert math.isnan(bandwidth_3db([1, 2], [0.0, -1.0]))
    assert math.isnan(bandwidth_3db([1, 2], [-4.0, -6.0]))


def test_alignment_finds_the_profile_start() -> None:
    t = np.arange(0.0, 30.0, 0.002) + 3.21
    target = PROFILE.targets(t - 3.21)
    assert align_profile(t, target) == pytest.approx(3.21, abs=0.0021)


def test_cli_on_a_csv(tmp_path, capsys) -> None:
    t, target, measured = simulate([1.0], [0.01, 1.0])
    path = tmp_path / 'run.csv'
    rows = ['t,target,measured'] + [f'{a},{b},{c}' for a, b, c in zip(t, target, measured)]
    path.write_text('\n'.join(rows))
    assert main([str(path)]) == 0
    out = capsys.readouterr().out
    assert 'rise time' in out and '-3 dB bandwidth' in out
