# SPDX-License-Identifier: Apache-2.0
"""In-process harness: agents, event order, scripted scenarios, a closed slip loop."""
from __future__ import annotations

import math

import pytest

from slip_cell_common.core.frames import FrameParams, planar_to_middle

from friction_models.core.harness import (Harness, HarnessError, Recorder,
                                          default_motion_time, grasp_and_hold)
from friction_models.core.presets import reference_presets
from friction_models.core.sensors import FtSample, TelemetrySample, VelocitySample
from friction_models.core.sim_cell import SimCell, SimParams, SimState


def _harness(agents: tuple = (), **kw: object) -> Harness:
    cell = SimCell(SimParams(physics_dt=1e-3, **kw), reference_presets(), 'wood')
    return Harness(cell, agents)


class _Log:
    """Agent that keeps every event it is handed."""

    def __init__(self) -> None:
        self.events: list[object] = []

    def on_ft(self, h: Harness, e: FtSample) -> None:
        self.events.append(e)

    def on_velocity(self, h: Harness, e: VelocitySample) -> None:
        self.events.append(e)

    def on_telemetry(self, h: Harness, e: TelemetrySample) -> None:
        self.events.append(e)


def test_agents_get_every_event_in_time_order() -> None:
    log = _Log()
    h = _harness((log,))
    h.run_for(0.5)
    stamps = [e.stamp for e in log.events]
    assert stamps == sorted(stamps)
    kinds = {type(e) for e in log.events}
    assert kinds == {FtSample, VelocitySample, TelemetrySample}
    assert sum(isinstance(e, TelemetrySample) for e in log.events) == 250
    assert h.t == pytest.approx(0.5)


def test_partial_agents_and_chunk_validation() -> None:
    class OnlyTelemetry:
        n = 0

        def on_telemetry(self, h: Harness, e: TelemetrySample) -> None:
            self.n += 1

    agent = OnlyTelemetry()
    h = _harness((agent,))
    h.run_for(0.1)
    assert agent.n == 50
    with pytest.raises(ValueError, match='chunk'):
        Harness(h.cell, chunk=1e-5)


class _SlipGuard:
    """Minimal slip controller: raise the grasp force while the object slips.

    On each finger-1 velocity sample, the sliding speed in ``gripper_middle`` above 2 mm/s
    (about two sensor counts) raises the command by 1 N.
    """

    def __init__(self, start: float) -> None:
        self.force = start
        self.frames = FrameParams()
        self.reactions = 0

    def on_velocity(self, h: Harness, e: VelocitySample) -> None:
        if e.finger != 1:
            return
        vx, vy, _ = planar_to_middle(self.frames, 1, e.vx, e.vy, e.omega)
        if math.hypot(vx, vy) > 0.002:
            self.force += 1.0
            self.reactions += 1
            h.command_force(self.force, timeout=0.5)


@pytest.mark.parametrize('guarded', [False, True])
def test_a_slip_agent_closes_the_loop_through_the_harness(guarded: bool) -> None:
    h = _harness(reset_grasp_force=10.0)
    h.home()
    h.bias()
    h.reset(object_on_table=False)
    h.command_force(10.0)
    h.run_for(0.3)
    guard = _SlipGuard(1.8)
    if guarded:
        h.add_agent(guard)
    h.command_force(1.8)            # 2 μ_s f_n ≈ 1.6 N < m g = 1.96 N: starts to slip
    h.run_for(1.5)
    s = h.state()
    if guarded:
        assert guard.reactions >= 1
        assert s.in_grasp and not s.dropped and abs(s.vy) < 1e-3
        assert abs(s.y) < 0.02       # caught within 2 cm
    else:
        assert s.dropped


def test_grasp_and_hold_scenario() -> None:
    rec = Recorder(every=5)
    h = _harness((rec,))
    r = grasp_and_hold(h, force=10.0, settle=1.5, lift=0.1, hold=1.0)
    assert r.measured_force == pytest.approx(10.0, abs=0.1)
    assert r.true_force == pytest.approx(10.0, abs=0.1)
    assert r.slip < 1e-5 and r.rotation < 1e-4 and not r.dropped
    assert h.state().arm_height == pytest.approx(0.07 + 0.1)
    assert len(rec.t) == pytest.approx(h.t * 500 / 5, abs=2)
    held = rec.window('normal_force', r.t_hold, r.t_end)
    assert min(held) > 9.5
    last = rec.window('object_y', r.t_end - 0.01, r.t_end)[-1]   # rows every 5 lines (10 ms)
    assert last == pytest.approx(h.state().object_y, abs=1e-6)


def test_scripted_steps_report_refusals() -> None:
    h = _harness()
    with pytest.raises(HarnessError, match='not finite'):
        h.command_force(math.nan)
    h.move(lift=0.05, duration=1.0, wait=False)
    with pytest.raises(HarnessError, match='moving'):
        h.move(lift=0.05)
    with pytest.raises(HarnessError, match='unknown preset'):
        h.reset('glass')
    assert default_motion_time(0.2, 0.0) == pytest.approx(4.0)
    assert default_motion_time(0.0, math.radians(60)) == pytest.approx(4.19, abs=0.01)
    assert default_motion_time(0.01, 0.0) == 1.0


def test_runs_faster_than_real_time_deterministically() -> None:
    # Not a timing assertion: the same script twice gives the same trajectory.
    def run() -> tuple[float, float, float]:
        h = _harness(seed=7)
        grasp_and_hold(h, force=6.0, settle=1.0, lift=0.05, hold=0.3)
        s = h.state()
        return s.object_x, s.object_y, h.cell.status().measured_grasp_force

    assert run() == run()


def test_run_for_handles_times_between_physics_steps() -> None:
    # Regression: a target 0.6 step ahead must not spin forever; time is whole steps.
    cell = SimCell(SimParams(physics_dt=1e-3), reference_presets(), 'wood')
    h = Harness(cell)
    h.run_for(0.0016)
    assert cell.steps == 1 and cell.t == pytest.approx(1e-3)
    h.run_for(0.0004)
    assert cell.steps == 1
    assert h.run_until(lambda hh: False, 0.0013) is False
    assert cell.steps == 2
    h.run_until_time(0.01234)
    assert cell.steps == 12


def _random_script(trial: int, presets: dict) -> SimState:
    """Random forces, moves, disturbances, stops and resets (a reproducible fuzz script)."""
    import random

    from friction_models.core.plant import SimActuatorParams
    rnd = random.Random(trial)
    dt = rnd.choice([1e-4, 5e-4, 1e-3])
    name = rnd.choice(sorted(presets))
    actuator = SimActuatorParams(model=rnd.choice(['voltage', 'first_order']))
    model = rnd.choice(['reduced'] * 4 + ['distributed'])
    cell = SimCell(SimParams(physics_dt=dt, seed=trial, actuator=actuator, model=model),
                   presets, name)
    h = Harness(cell)
    h.home()
    h.bias()
    if rnd.random() < 0.5:
        h.reset(object_on_table=False)
    s = h.state()
    for _ in range(8):
        a = rnd.random()
        if a < 0.3:
            cell.command_grasp_force(rnd.uniform(-8, 40), cell.t, 0.0)
        elif a < 0.55 and not cell.arm_moving:
            cell.move_gripper(rnd.uniform(-0.05, 0.1), rnd.uniform(-0.05, 0.05),
                              rnd.uniform(-1.5, 1.5), rnd.uniform(0.2, 1.0))
        elif a < 0.75:
            cell.apply_disturbance(rnd.uniform(-5, 5), rnd.uniform(-5, 5),
                                   rnd.uniform(-0.1, 0.1), rnd.uniform(0.01, 0.3))
        elif a < 0.8:
            cell.stop()
        elif a < 0.85:
            cell.reset(rnd.choice(sorted(presets)), rnd.random() < 0.5)
        h.run_for(rnd.uniform(0.05, 0.4) if dt > 1e-4 else rnd.uniform(0.02, 0.1))
        s = h.state()
        values = (s.x, s.y, s.theta, s.vx, s.vy, s.omega, s.normal_force_1, s.energy)
        assert all(math.isfinite(v) for v in values), (trial, s)
        assert abs(s.vx) < 50.0 and abs(s.omega) < 500.0 and s.normal_force_1 < 100.0, \
            (trial, s)
    return s


@pytest.mark.parametrize('trial', [0, 1, 2, 3, 45])
def test_random_scripts_stay_finite(trial: int) -> None:
    # Reproducible fuzz scripts over every preset, both actuator and both friction models.
    # Trial 45 once pumped energy (a slide reversing at speed reused the previous friction
    # wrench, which then pointed along the motion): the object spun up to > 1000 rad/s.
    from pathlib import Path

    from friction_models.core.presets import load_presets
    presets = load_presets(Path(__file__).resolve().parents[1] / 'config' / 'sim_presets.yaml')
    _random_script(trial, presets)
