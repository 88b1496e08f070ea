# SPDX-License-Identifier: Apache-2.0
"""RealTimePacer: simulated time keeps up with the wall clock although the cell steps whole,
slows (never skips) on a slow host, and waits for a controller that falls behind."""
from __future__ import annotations

import math

import numpy as np
import pytest

from friction_models.core.pacing import InputHorizon, RealTimePacer
from friction_models.core.presets import reference_presets
from friction_models.core.sim_cell import SimCell, SimParams


def _run(cell: SimCell, pacer: RealTimePacer, deltas: np.ndarray, rtf: float,
         max_step: float = 0.05, ft_stamps: list[float] | None = None) -> float:
    behind = 0.0
    for dt_wall in deltas:
        target = pacer.next_target(cell.t, float(dt_wall), rtf, max_step)
        behind += target.behind_s
        events = cell.advance(target.until_t)
        if ft_stamps is not None:
            ft_stamps.extend(e.stamp for e in events.ft if e.finger == 1)
    return behind


@pytest.mark.parametrize('rtf', [1.0, 2.5])
def test_jittery_ticks_keep_simulated_time_at_wall_time_times_rtf(rtf: float) -> None:
    cell = SimCell(SimParams(physics_dt=1e-3), reference_presets(), 'cardboard')
    pacer = RealTimePacer(cell.params.physics_dt)
    rng = np.random.default_rng(3)
    deltas = rng.uniform(0.0021, 0.0029, 800)  # 2 ms ticks, always a little late
    t0 = cell.t
    assert _run(cell, pacer, deltas, rtf) == 0.0
    # Restarting from cell.t each tick would reach only ~0.75 of this (steps are whole).
    assert cell.t - t0 == pytest.approx(deltas.sum() * rtf, abs=cell.params.physics_dt)


def test_a_host_too_slow_slows_the_simulation_without_skipping_time() -> None:
    """A 0.5 s stall: the next tick runs at most ``max_step`` of simulated time, the rest is
    never caught up (the real-time factor drops) and nothing is skipped: the F/T box's 1 kHz
    samples stay gap-free across the stall."""
    cell = SimCell(SimParams(physics_dt=1e-3), reference_presets(), 'cardboard')
    pacer = RealTimePacer(cell.params.physics_dt)
    t0 = cell.t
    stamps: list[float] = []
    behind = _run(cell, pacer, np.array([0.002, 0.5, 0.002, 0.002]), 1.0, max_step=0.05,
                  ft_stamps=stamps)
    assert behind == pytest.approx(0.45)
    assert cell.t - t0 == pytest.approx(0.056, abs=1e-3)     # slowed: 0.056 s in 0.506 s
    gaps = np.diff(stamps)
    assert len(stamps) >= 50 and gaps.max() == pytest.approx(1e-3, abs=1e-6)
    # The cell moved on its own (e.g. stepped by a harness): the pacer follows it.
    cell.advance(cell.t + 0.3)
    target = pacer.next_target(cell.t, 0.002, 1.0, 0.05)
    assert target.until_t == pytest.approx(cell.t + 0.002)


def test_bad_step_is_refused() -> None:
    with pytest.raises(ValueError):
        RealTimePacer(math.nan)
    with pytest.raises(ValueError):
        RealTimePacer(0.0)


def test_the_simulation_waits_for_a_streaming_controller_that_falls_behind() -> None:
    """Issue 16: a starved controller's corrections must not reach the world hundreds of
    simulated milliseconds late. With streaming commands (timeout > 0) the cell stops
    ``max_lag`` beyond the newest command stamp and goes on as soon as the next one arrives;
    nothing is skipped."""
    cell = SimCell(SimParams(physics_dt=1e-3), reference_presets(), 'cardboard')
    pacer = RealTimePacer(cell.params.physics_dt)
    inputs = InputHorizon(max_lag_s=0.05, max_wait_s=1.0)
    assert inputs.horizon() == math.inf                        # nothing streams: no limit
    t0 = cell.t
    inputs.on_command(t0, 0.1, t0)                             # slip controller, at t0
    wall = 0.0
    held_ticks = 0
    for _ in range(100):                                       # 0.2 s of wall time
        wall += 0.002
        target = pacer.next_target(cell.t, 0.002, 1.0, 0.05, inputs.horizon())
        held_ticks += target.held
        assert not inputs.waited(target.held, wall)
        cell.advance(target.until_t)
    assert cell.t == pytest.approx(t0 + 0.05, abs=1e-3)       # stopped at the horizon
    assert held_ticks >= 70
    inputs.on_command(t0 + 0.04, 0.1, cell.t)                  # the controller caught up
    target = pacer.next_target(cell.t, 0.002, 1.0, 0.05, inputs.horizon())
    assert not target.held and target.until_t == pytest.approx(t0 + 0.052, abs=1e-3)
    # A command valid until replaced (the runner, a hand-over) ends the streaming.
    inputs.on_command(0.0, 0.0, cell.t)
    assert inputs.horizon() == math.inf and not inputs.streaming


def test_a_silent_controller_is_given_up_on_after_max_wait() -> None:
    inputs = InputHorizon(max_lag_s=0.05, max_wait_s=0.5)
    inputs.on_command(10.0, 0.1, 10.0)
    assert inputs.horizon() == pytest.approx(10.05)
    assert not inputs.waited(True, 100.0)
    assert not inputs.waited(True, 100.4)
    assert inputs.waited(True, 100.6)                          # 0.6 s > 0.5 s: released
    assert inputs.horizon() == math.inf and inputs.releases == 1
    assert inputs.held_s == pytest.approx(0.6)
    inputs.on_command(10.5, 0.1, 10.6)                         # streams again: followed again
    assert inputs.horizon() == pytest.approx(10.55)
    assert InputHorizon(0.0, 1.0).horizon() == math.inf        # 0 = never wait
    with pytest.raises(ValueError):
        InputHorizon(-1.0, 1.0)
    with pytest.raises(ValueError):
        InputHorizon(0.05, 0.0)
