# SPDX-License-Identifier: Apache-2.0
"""Host-side pose integration of velocity lines over their own firmware periods (ROS-free).

The firmware prints one velocity line per serial period (6–8 ms): the motion counted in that
period divided by its length. So every line stands for one period of motion, and the pose is
``Σ v_i · period_i`` over the lines that arrived (x, y in the sensor frame [m], θ [rad]).

The host only has acquisition stamps (the time a line was read). When the reader keeps up,
consecutive stamps are one period apart and the stamp difference is the period. When the
reader stalls (a loaded host), the OS queues the lines and one read returns them together with
one stamp. `PoseIntegrator` splits that time among them:

* A line that starts a new read (its stamp is at least half a nominal period after the
  previous line's) claims the time since the previous read, at most ``max_step``. Time beyond
  ``max_step`` goes into a pool of time not yet covered by a line.
* Each further line of the same read covers one nominal period (``period``): taken from the
  pool first, then from the first line's claim (which keeps at least one nominal period), so
  the queued lines each get their own period and the first line keeps what is left of the gap.
* A line that finds neither (more lines than elapsed time) adds nothing and is counted
  (``skipped``). Integrated time therefore never exceeds the stamps' span, and with a steady
  velocity it equals it: a stall loses nothing.
* Pool time that no line of the next read needed was a real gap (lines lost, device silent):
  it is dropped, so a gap adds at most ``max_step`` (counted in ``capped``).
* A stamp more than ``max_step`` before the previous one is a clock reset: re-anchor.
"""
from __future__ import annotations


class PoseIntegrator:
    """Integrate x, y, θ over each velocity line's own period; see the module docstring.

    Args:
        period: Nominal firmware period [s] (1 / expected line rate), > 0.
        max_step: Longest time one line may claim after a gap [s], > 0.
    """

    def __init__(self, period: float, max_step: float) -> None:
        self.configure(period, max_step)
        self.x = 0.0
        self.y = 0.0
        self.theta = 0.0
        #: Lines that got no time (more lines than elapsed time, stamps out of order).
        self.skipped = 0
        #: Reads whose gap exceeded ``max_step`` (the excess waits in the pool).
        self.capped = 0
        #: Backwards clock jumps that re-anchored the integration.
        self.clock_jumps = 0
        #: Pool time dropped because no queued line needed it [s].
        self.dropped_time = 0.0
        self._t: float | None = None
        self._first = (0.0, 0.0, 0.0)
        self._claim = 0.0
        self._pool = 0.0
        self._pool_used = False

    def configure(self, period: float, max_step: float) -> None:
        """Change the nominal period [s] and the per-line cap [s] (run-time parameters)."""
        if not (period > 0.0 and max_step > 0.0):
            raise ValueError('period and max_step must be > 0 s')
        self.period = period
        self.max_step = max_step

    def reanchor(self) -> None:
        """Forget the time anchor: the next line starts a new integration interval."""
        self._t = None
        self._claim = 0.0
        self._pool = 0.0
        self._pool_used = False

    def reset_pose(self) -> None:
        """Zero x, y, θ; the time anchor is kept (time already claimed is not re-split)."""
        self.x = self.y = self.theta = 0.0
        self._claim = 0.0

    def add(self, t: float, vx: float, vy: float, omega: float) -> None:
        """Integrate one valid line acquired at ``t`` [s]: vx, vy [m/s], ω [rad/s]."""
        if self._t is None:
            self._anchor(t, (vx, vy, omega))
            return
        delta = t - self._t
        if delta < -self.max_step:
            self.clock_jumps += 1
            self._anchor(t, (vx, vy, omega))
            return
        if delta >= 0.5 * self.period:
            self._new_read(t, delta, (vx, vy, omega))
        else:
            self._queued_line(t, delta, (vx, vy, omega))

    def _anchor(self, t: float, v: tuple[float, float, float]) -> None:
        self.reanchor()
        self._t = t
        self._first = v

    def _new_read(self, t: float, delta: float, v: tuple[float, float, float]) -> None:
        if self._pool > 0.0 and not self._pool_used:
            self.dropped_time += self._pool
            self._pool = 0.0
        self._pool_used = False
        claim = delta
        if claim > self.max_step:
            self.capped += 1
            self._pool += claim - self.max_step
            self._pool_used = True  # give the lines queued behind this one a chance
            claim = self.max_step
        self._step(v, claim)
        self._t = t
        self._first = v
        self._claim = claim

    def _queued_line(self, t: float, delta: float, v: tuple[float, float, float]) -> None:
        own = max(delta, 0.0)  # a slightly later stamp within the same read
        self._t = max(self._t if self._t is not None else t, t)
        want = max(self.period - own, 0.0)
        from_pool = min(want, self._pool)
        from_claim = min(want - from_pool, max(self._claim - self.period, 0.0))
        dt = own + from_pool + from_claim
        if dt <= 0.0:
            self.skipped += 1
            return
        if from_pool > 0.0:
            self._pool -= from_pool
            self._pool_used = True
        self._step(v, dt)
        if from_claim > 0.0:  # the first line of the read gives up that time
            self._claim -= from_claim
            self._step(self._first, -from_claim)

    def _step(self, v: tuple[float, float, float], dt: float) -> None:
        self.x += v[0] * dt
        self.y += v[1] * dt
        self.theta += v[2] * dt
