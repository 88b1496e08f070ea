# SPDX-License-Identifier: Apache-2.0
"""Pacing of the simulation against a wall clock (ROS-free).

The simulated cell advances in whole physics steps (`SimCell.advance` stops at the last step
boundary at or before its target). A real-time loop that asked for ``cell.t + elapsed`` on
every tick would lose the unfinished fraction of a step each time: at 2 ms ticks and 1 ms
steps the simulated clock ran at about 0.75× real time. `RealTimePacer` carries the target
from tick to tick instead, so simulated time = wall time × real-time factor, to within one
physics step, whatever the tick jitter.

When the host cannot keep up (a stalled tick, a busy machine), the simulation **slows**: one
tick advances at most ``max_step_s`` of simulated time, and what the wall clock asked for
beyond that is never caught up. Simulated time itself stays continuous — every physics step
runs and every sensor sample is produced with its own stamp, nothing is skipped — so every
node on ``/clock`` sees a slower, not a broken, world; the achieved real-time factor drops
below its target and `PacedTarget.behind_s` says by how much. `InputHorizon` slows it
further when the controller that closes a loop through it falls behind: the world never runs
more than a bound of simulated time ahead of the controller's newest command.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class PacedTarget:
    """What one tick asks of the cell."""

    until_t: float    #: simulated time to advance to [s]
    behind_s: float   #: simulated time the wall clock asked for but this tick did not run:
    #: the simulation ran slower than its real-time factor (never skipped, never caught up) [s]
    held: bool = False  #: stopped at the input horizon (waiting for a streaming commander)


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
                    max_step_s: float, horizon: float = math.inf) -> PacedTarget:
        """Target for this tick.

        Args:
            cell_t: Simulated time the cell has reached [s].
            wall_elapsed_s: Wall time since the previous tick [s].
            realtime_factor: Simulated seconds per wall second.
            max_step_s: Most simulated time one tick may advance [s]; beyond it the
                simulation slows (the excess is reported as ``behind_s``).
            horizon: Simulated time not to pass [s] (`InputHorizon.horizon`); what the wall
                clock asked for beyond it is ``behind_s`` too, and ``held`` is set.
        """
        advance = max(0.0, wall_elapsed_s) * realtime_factor
        behind = 0.0
        if advance > max_step_s:
            behind = advance - max_step_s
            advance = max_step_s
        if not abs(self._target - cell_t) <= self._dt:
            self._target = cell_t
        target = self._target + advance
        held = target > horizon
        if held:
            allowed = max(horizon, self._target)      # never backwards
            behind += target - allowed
            target = allowed
        self._target = target
        return PacedTarget(target, behind, held)


class InputHorizon:
    """How far simulated time may run ahead of the node that closes a loop through it.

    A controller that streams commands with an expiry (the slip controller: a grasp-force
    command per control step, ``timeout`` 0.1 s, stamped with its clock) reacts to what the
    simulation published. On a busy host it may fall behind — its process starved, or the
    simulation thread hogging its own process — and a simulation that ran on would let the
    object slide for hundreds of simulated milliseconds while the controller's corrections
    are still on their way. The simulation therefore waits: it advances at most ``max_lag_s``
    of simulated time beyond the stamp of the newest streaming command it has applied. A
    command valid until replaced (``timeout`` 0: the runner, a controller's hand-over) ends
    the streaming, and so does a commander silent for ``max_wait_s`` of wall time (then its
    last command expires on simulated time, as on hardware).

    The lead should be a few control periods (the node's default is 30 ms, about four
    steps of the slip controller at the 120 Hz velocity rate): a controller that falls
    further behind is starved, and a world that runs on meanwhile is not the cell the
    controller was tuned on. With 100 ms, an 80 ms starvation of the controller at the end of
    a 20 deg rotational slip let the object turn 6.7 deg further (`make demo` beside two CPU
    burners); stopping the controller process for 60 ms every 250 ms failed 2 of 3 demos
    (rotation errors up to 21 deg), and passed 3 of 3 at 30 ms (errors at most 2.2 deg). The
    lead does not delay a stale-input verdict: the controller's velocity comes from the
    simulation itself, which publishes every sample up to the horizon.

    Args:
        max_lag_s: Largest lead [s, simulated] over the newest streaming command; 0 = off.
        max_wait_s: Longest wall time [s] the simulation waits for the next command.
    """

    def __init__(self, max_lag_s: float, max_wait_s: float) -> None:
        if not (max_lag_s >= 0.0 and math.isfinite(max_lag_s)):
            raise ValueError(f'max_lag_s must be finite and >= 0, got {max_lag_s!r}')
        if not (max_wait_s > 0.0 and math.isfinite(max_wait_s)):
            raise ValueError(f'max_wait_s must be finite and > 0, got {max_wait_s!r}')
        self.max_lag_s = max_lag_s
        self.max_wait_s = max_wait_s
        self._stamp: float | None = None
        self._held_since: float | None = None
        self.releases = 0       #: times a silent commander was given up on
        self.held_s = 0.0       #: wall time spent waiting for commands [s]

    @property
    def streaming(self) -> bool:
        """A streaming commander is being followed."""
        return self._stamp is not None

    def on_command(self, stamp: float, timeout: float, arrival_t: float) -> None:
        """An accepted command: ``stamp`` [s] (0 = unstamped: ``arrival_t``), ``timeout`` [s]
        (0 = valid until replaced, which ends the streaming)."""
        if timeout <= 0.0:
            self._stamp = None
            return
        s = stamp if stamp != 0.0 else arrival_t
        self._stamp = s if self._stamp is None else max(self._stamp, s)

    def horizon(self) -> float:
        """Simulated time the simulation may advance to [s] (``inf`` when nothing streams)."""
        if self._stamp is None or self.max_lag_s <= 0.0:
            return math.inf
        return self._stamp + self.max_lag_s

    def waited(self, held: bool, wall_now: float) -> bool:
        """Note whether this tick was held at the horizon (``wall_now`` [s], monotonic).

        Returns:
            True when the wait exceeded ``max_wait_s``: the commander is given up on (the
            simulation runs on until it streams again).
        """
        if not held:
            if self._held_since is not None:
                self.held_s += wall_now - self._held_since
            self._held_since = None
            return False
        if self._held_since is None:
            self._held_since = wall_now
            return False
        if wall_now - self._held_since <= self.max_wait_s:
            return False
        self.held_s += wall_now - self._held_since
        self._held_since = None
        self._stamp = None
        self.releases += 1
        return True
