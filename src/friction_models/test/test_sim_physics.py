# SPDX-License-Identifier: Apache-2.0
"""Physics of the simulated cell (issue 4): hold, gravity slip, torsion, energy, table."""
from __future__ import annotations

import math

import pytest

from friction_models.core.harness import (Harness, grasp_and_hold,
                                          open_loop_release)
from friction_models.core.presets import ContactPreset, ObjectPreset, reference_presets
from friction_models.core.sensors import FtSensorParams, VelocitySensorParams
from friction_models.core.sim_cell import SimCell, SimParams

G = 9.81

#: A slab whose CoM is the grasp point (no gravity torque), Coulomb-like contact (μ_v = 0).
SLAB = ObjectPreset(
    name='slab', mass=0.2, inertia=2.4e-4, com_offset=(0.0, 0.0), width=0.06,
    height_below=0.06, height_above=0.06, thickness=0.04, surface='circle',
    finger_1=ContactPreset(mu_c=0.30, mu_s=0.33, mu_v=0.0, r=0.005),
    finger_2=ContactPreset(mu_c=0.30, mu_s=0.33, mu_v=0.0, r=0.005))


def _cell(dt: float, preset: str = 'slab', model: str = 'reduced', **kw: object) -> SimCell:
    presets = reference_presets()
    presets['slab'] = SLAB
    params = SimParams(physics_dt=dt, model=model,
                       velocity_sensor=VelocitySensorParams(model='ideal'), **kw)
    return SimCell(params, presets, preset)


def _held(dt: float, force: float = 10.0, model: str = 'reduced') -> Harness:
    """Slab held in the air with ``force`` and the inner loop closed (biased, homed)."""
    h = Harness(_cell(dt, model=model, reset_grasp_force=force))
    h.home()
    h.bias()
    h.reset(object_on_table=False)
    h.command_force(force)
    h.run_for(0.5)
    assert h.state().in_grasp and not h.state().on_table
    return h


@pytest.mark.parametrize('dt', [1e-4, 1e-3])
def test_held_above_static_limit_does_not_slip(dt: float) -> None:
    # 2 μ_s f_n = 6.6 N ≫ m g = 1.96 N: relative slip over 2 s stays below 0.1 mm.
    h = _held(dt)
    s0 = h.state()
    h.run_for(2.0)
    s1 = h.state()
    assert math.hypot(s1.x - s0.x, s1.y - s0.y) < 1e-4
    assert abs(s1.theta - s0.theta) < 1e-3
    assert not s1.dropped


@pytest.mark.parametrize('dt,model', [(1e-4, 'reduced'), (1e-3, 'reduced'),
                                      (1e-3, 'distributed')])
def test_below_static_limit_accelerates_as_coulomb_predicts(dt: float, model: str) -> None:
    # f_n = 2.5 N: 2 μ_s f_n = 1.65 N < m g = 1.96 N, so the slab slides down with
    # a = (m g − 2 μ_c f_n)/m = 2.31 m/s² (μ_v = 0; v ≫ v_s = 1 mm/s within ~1 ms).
    h = _held(dt, model=model, force=4.0)   # kinetic limit 2 μ_c f_n = 2.4 N > m g: stays
    assert abs(h.state().vy) < 1e-4
    h.command_force(2.5)
    assert h.run_until(lambda hh: hh.state().vy < -0.02, 1.0)
    h.run_for(0.03)
    ts, ys, fns = [], [], []
    for _ in range(40):
        h.run_for(0.002)
        s = h.state()
        ts.append(s.stamp)
        ys.append(s.y)
        fns.append(s.normal_force_1)
    # Least-squares parabola y = a/2 t² + b t + c over the window.
    n = len(ts)
    t0 = ts[0]
    rows = [((t - t0) ** 2, t - t0, 1.0) for t in ts]
    ata = [[sum(r[i] * r[j] for r in rows) for j in range(3)] for i in range(3)]
    aty = [sum(r[i] * y for r, y in zip(rows, ys)) for i in range(3)]
    acc = -2.0 * _solve(ata, aty)[0]
    f_n = sum(fns) / n
    m, mu_c = SLAB.mass, SLAB.finger_1.mu_c
    expected = (m * G - 2.0 * mu_c * f_n) / m
    assert abs(f_n - 2.5) < 0.15
    assert acc == pytest.approx(expected, rel=0.03)


def _solve(a: list[list[float]], b: list[float]) -> list[float]:
    """Gaussian elimination for the 3×3 normal equations (no numpy needed)."""
    m = [row[:] + [v] for row, v in zip(a, b)]
    for i in range(3):
        p = max(range(i, 3), key=lambda r: abs(m[r][i]))
        m[i], m[p] = m[p], m[i]
        for r in range(3):
            if r != i:
                f = m[r][i] / m[i][i]
                m[r] = [x - f * y for x, y in zip(m[r], m[i])]
    return [m[i][3] / m[i][i] for i in range(3)]


@pytest.mark.parametrize('dt', [1e-4, 1e-3])
def test_torque_above_torsional_limit_rotates_below_does_not(dt: float) -> None:
    # Static torsional capacity ≈ 2 μ_s r f_n √(1 − (m g/2 / (μ_s f_n))²) ≈ 0.031 N·m at 10 N.
    h = _held(dt)
    s0 = h.state()
    h.disturb(0.0, 0.0, 0.015, 0.3)
    h.run_for(0.3)
    assert abs(h.state().theta - s0.theta) < 1e-3
    h.run_for(0.2)
    s1 = h.state()
    h.disturb(0.0, 0.0, 0.04, 0.2)
    h.run_for(0.2)
    s2 = h.state()
    assert s2.theta - s1.theta > 0.05          # turns with the applied (+z) torque
    assert s2.omega > 0.5
    # Kinetic torsional friction ≈ 2 μ_c r f_n = 0.03 N·m: α ≈ (0.04 − 0.03)/I ≈ 40 rad/s².
    assert s2.omega < 0.2 * (0.04 - 0.025) / SLAB.inertia
    h.run_for(0.3)                              # torque removed: friction stops it
    assert abs(h.state().omega) < 1e-3
    assert h.state().in_grasp


@pytest.mark.parametrize('dt,mode', [(1e-4, 'stop'), (1e-3, 'stop'), (1e-3, 'open')])
def test_energy_does_not_grow_in_a_passive_release(dt: float, mode: str) -> None:
    h = Harness(_cell(dt, preset='wood'))
    result = open_loop_release(h, lift=0.1, mode=mode, duration=0.6)
    e0 = result.energy[0]
    assert result.dropped and result.fall > 0.09
    assert result.max_rise < 1e-6 * e0
    assert sum(max(0.0, b - a) for a, b in zip(result.energy, result.energy[1:])) < 1e-5 * e0
    assert result.energy[-1] < e0 - 0.9 * 0.2 * G * 0.1   # the potential energy is gone


def test_object_slides_off_the_face_and_drops_to_the_table() -> None:
    h = Harness(_cell(1e-3, preset='wood'))
    grasp_and_hold(h, force=10.0, settle=1.0, lift=0.15, hold=0.2)
    h.command_force(0.8)                      # far below m g / (2 μ)
    assert h.run_until(lambda hh: hh.state().dropped, 1.0)
    h.run_for(1.0)
    s = h.state()
    assert not s.in_grasp and s.on_table and s.dropped
    assert abs(s.vy) < 1e-3                   # resting on the table


def test_ft_measures_the_friction_that_holds_the_object() -> None:
    # Held in the air: the pads carry the weight, F/T (force on the pad) points down.
    h = _held(1e-3)
    from slip_cell_common.core.frames import FrameParams, planar_to_middle
    frames = FrameParams()
    events = h.cell.advance(h.t + 0.2)
    sums = {1: [0.0, 0.0, 0.0], 2: [0.0, 0.0, 0.0]}
    counts = {1: 0, 2: 0}
    for e in events.ft:
        fx, fy, fz, _, _, tz = e.biased
        x, y, _ = planar_to_middle(frames, e.finger, fx, fy, tz)
        s = sums[e.finger]
        s[0] += x
        s[1] += y
        s[2] += fz
        counts[e.finger] += 1
    for k in (1, 2):
        x, y, fz = (v / counts[k] for v in sums[k])
        assert y == pytest.approx(-SLAB.mass * G / 2.0, abs=0.03)   # half the weight each
        assert abs(x) < 0.03
        assert fz == pytest.approx(-10.0, abs=0.1)                  # squeezing: negative


def test_physics_step_sizes_agree_on_a_rotational_slip() -> None:
    # CoM 3 cm beside the grasp point: gravity turns the object in the grasp until its torque
    # falls below the torsional friction; dt = 1e-3 and 1e-4 agree to a few percent.
    from pathlib import Path

    from friction_models.core.presets import load_presets
    presets = load_presets(Path(__file__).resolve().parents[1] / 'config' / 'sim_presets.yaml')
    finals = []
    for dt in (1e-4, 1e-3):
        cell = SimCell(SimParams(physics_dt=dt, ft=FtSensorParams(noise_std=0.0,
                                                                  torque_noise_std=0.0),
                                 velocity_sensor=VelocitySensorParams(model='ideal')),
                       presets, 'offset_box')
        h = Harness(cell)
        h.home()
        h.bias()
        h.command_force(10.0)
        h.run_for(1.0)
        h.move(lift=0.15, duration=1.0)
        h.run_for(0.5)
        s = h.state()
        assert s.in_grasp and abs(s.omega) < 1e-3
        finals.append(s.theta)
    assert finals[0] < -0.5                      # it turned (CoM swings down)
    assert finals[1] == pytest.approx(finals[0], rel=0.05)


@pytest.mark.parametrize('dt', [5e-4, 1e-3])
def test_reversing_rotational_slip_does_not_pump_energy(dt: float) -> None:
    # Fast wrist oscillation (strokes of ±2 rad in 0.15 s, peak 25 rad/s, 500 rad/s²) with a
    # grip whose torsional capacity (≈ 0.02 N·m) cannot drag the slab along (≈ 0.12 N·m
    # needed): the pads slide rotationally and the slip reverses with every stroke. Friction
    # only drags the object, so it can never spin faster than the wrist.
    h = _held(dt, force=6.0)
    peak_wrist = 1.875 * 2.0 / 0.15
    omega_max = 0.0
    slid = False
    for rotation, duration in ((1.0, 0.1), (-2.0, 0.15), (2.0, 0.15), (-2.0, 0.15),
                               (1.0, 0.1)):
        h.move(rotation=rotation, duration=duration, wait=False)
        while h.cell.arm_moving:
            h.run_for(dt)
            omega_max = max(omega_max, abs(h.cell.plant.W))
            slid = slid or h.state().sliding_1
    h.run_for(0.3)
    s = h.state()
    assert slid and s.in_grasp
    assert omega_max < peak_wrist
    assert s.energy < 0.5 and abs(s.omega) < 1e-3


@pytest.mark.parametrize('dt', [5e-4, 1e-3])
def test_spinning_object_comes_to_rest_without_reversing(dt: float) -> None:
    # High grip, light object: kinetic torsional friction changes ω by ≈ 0.4 rad/s per
    # millisecond step, comparable with the speed near the stop. Once the torque pulse ends,
    # friction must only decelerate the object to rest — never reverse or re-accelerate it.
    h = _held(dt, force=30.0)
    h.disturb(0.0, 0.0, 0.25, 0.1)       # ≫ the ≈ 0.1 N·m torsional capacity
    h.run_for(0.1)
    w0 = h.state().omega
    assert w0 > 20.0
    speeds = []
    for _ in range(int(round(0.2 / dt))):
        h.run_for(dt)
        speeds.append(h.state().omega)
    stop = next(i for i, w in enumerate(speeds) if w < 1.0)
    # Sliding: friction only decelerates (≈ 2 μ_c r f_n / I ≈ 400 rad/s² for the slab).
    assert all(b < a for a, b in zip(speeds[:stop], speeds[1:stop + 1]))
    # Stuck: only the elastic ring-down of the torsional bristles (≈ 0.7 mrad deflection
    # at ω_n ≈ 800 rad/s), decaying; never a re-acceleration.
    assert max(abs(w) for w in speeds[stop:]) < 1.0
    assert abs(speeds[-1]) < 0.01 and h.state().in_grasp
