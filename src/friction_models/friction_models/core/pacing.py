# SPDX-License-Identifier: Apache-2.0
"""Pacing of the simulation against a wall clock (ROS-free).

The simulated cell advances in whole physics steps (`SimCell.advance` stops at the last step
boundary at or before its target). A real-time loop that asked for ``cell.t + elapsed`` on
every tick would lose the unfinished fraction of a step each time: at 2 ms ticks and 1 ms
steps the simulated clock ran at about 0.75× real time. `RealTimePacer` carries the target
from tick to tick instead, so simulated time = wall time × real-time factor, to within one
physics step, whatever the tick jitter.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class PacedTarget:
    """What one tick asks of the cell."""

    until_t: float    #: simulated time to advance to [s]
    dropped_s: float  #: simulated time given up because the loop fell too far behind [s]


class RealTimePacer:
    """Turns wall-clock ticks into simulated-time targets.

    Args:
        physics_dt: The cell's physics step [s]; a cell time further than this from the
            carried target (first tick, scene reset, external stepping) restarts from it.
    """

    def __init__(self, physics_dt: float) -> None:
        if not (physics_dt > 0.0 and math.isfinite(physics_dt)):
            raise ValueError(f'physics_dt must be finite and > 0, got {physics_dt!r}')
        self._dt = physics_dt
        self._target = math.nan

    def next_target(self, cell_t: float, wall_elapsed_s: float, realtime_factor: float,
                    max_catch_up_s: float) -> PacedTarget:
        """Target for this tick.

        Args:
            cell_t: Simulated time the cell has reached [s].
            wall_elapsed_s: Wall time since the previous tick [s].
            realtime_factor: Simulated seconds per wall second.
            max_catch_up_s: Most simulated time one tick may advance; the rest is dropped.
        """
        advance = max(0.0, wall_elapsed_s) * realtime_factor
        dropped = 0.0
        if advance > max_catch_up_s:
            dropped = advance - max_catch_up_s
            advance = max_catch_up_s
        if not abs(self._target - cell_t) <= self._dt:
            self._target = cell_t
        self._target += advance
        return PacedTarget(self._target, dropped)
