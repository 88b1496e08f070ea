# SPDX-License-Identifier: Apache-2.0
"""RealTimePacer: simulated time keeps up with the wall clock although the cell steps whole."""
from __future__ import annotations

import math

import numpy as np
import pytest

from friction_models.core.pacing import RealTimePacer
from friction_models.core.presets import reference_presets
from friction_models.core.sim_cell import SimCell, SimParams


def _run(cell: SimCell, pacer: RealTimePacer, deltas: np.ndarray, rtf: float,
         max_catch_up: float = 0.05) -> float:
    dropped = 0.0
    for dt_wall in deltas:
        target = pacer.next_target(cell.t, float(dt_wall), rtf, max_catch_up)
        dropped += target.dropped_s
        cell.advance(target.until_t)
    return dropped


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


def test_falling_behind_drops_time_and_a_reset_restarts_from_the_cell() -> None:
    cell = SimCell(SimParams(physics_dt=1e-3), reference_presets(), 'cardboard')
    pacer = RealTimePacer(cell.params.physics_dt)
    dropped = _run(cell, pacer, np.array([0.002, 0.5, 0.002]), 1.0, max_catch_up=0.05)
    assert dropped == pytest.approx(0.45)
    t = cell.t
    assert t == pytest.approx(0.054, abs=1e-3)
    # The cell moved on its own (e.g. stepped by a harness): the pacer follows it.
    cell.advance(t + 0.3)
    target = pacer.next_target(cell.t, 0.002, 1.0, 0.05)
    assert target.until_t == pytest.approx(cell.t + 0.002)


def test_bad_step_is_refused() -> None:
    with pytest.raises(ValueError):
        RealTimePacer(math.nan)
    with pytest.raises(ValueError):
        RealTimePacer(0.0)
