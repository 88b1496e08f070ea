# SPDX-License-Identifier: Apache-2.0
"""The force-tracking test profile (control_and_estimation §5.4): the one definition.

Played by the driver's ``force_tracking_test`` tool and by the experiment runner's
``force_tracking_test`` mode, and analysed by `slip_gripper_driver.core.force_tracking`;
both players sit on this foundation, which is why the profile lives here. Forces in N, times
in s from the start of the recording:

1. 5 N for 2 s (``initial_hold``).
2. Square wave, 1 s per level: 5, 10, 5, 15, 5, 20, 5, 25, 5, 25, 15, 25, 5 N.
3. 5 N (``pre_sine_hold``; the spec gives no duration, 1 s here), then sinusoids
   ``F = 5 + 10·(sin(2πf·τ) + 1)/2`` (5…15 N, ``τ`` from the start of each sine, so each
   starts at 10 N) at f = 1, 2, 4, 8, 16, 32, 64 Hz, 5 s each.
4. 5 N (``final_hold``, 1 s here), end of recording, then ``final_force`` (0 N).

Published at ``rate_hz`` (500 Hz).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


class Segment(NamedTuple):
    """One piece of the profile.

    Attributes:
        kind: ``'hold'``, ``'level'`` or ``'sine'``.
        t_start: Start [s].
        t_end: End [s].
        value: Force [N] for holds and levels; mean force for sines.
        frequency: Sine frequency [Hz]; 0 otherwise.
    """

    kind: str
    t_start: float
    t_end: float
    value: float
    frequency: float


@dataclass(frozen=True)
class ForceTrackingProfile:
    """The force-tracking test profile; see the module docstring (forces in N, times in s)."""

    initial_force: float = 5.0
    initial_hold: float = 2.0
    levels: tuple[float, ...] = (5.0, 10.0, 5.0, 15.0, 5.0, 20.0, 5.0, 25.0, 5.0, 25.0, 15.0,
                                 25.0, 5.0)
    level_duration: float = 1.0
    pre_sine_hold: float = 1.0
    sine_frequencies: tuple[float, ...] = (1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0)
    sine_duration: float = 5.0
    sine_low: float = 5.0
    sine_high: float = 15.0
    final_hold: float = 1.0
    final_force: float = 0.0
    rate_hz: float = 500.0
    step_level_index: int = 7  #: the 5 → 25 N step used for step metrics

    def segments(self) -> list[Segment]:
        """All segments in order; the profile ends at `duration` (then ``final_force``)."""
        out = [Segment('hold', 0.0, self.initial_hold, self.initial_force, 0.0)]
        t = self.initial_hold
        for level in self.levels:
            out.append(Segment('level', t, t + self.level_duration, level, 0.0))
            t += self.level_duration
        out.append(Segment('hold', t, t + self.pre_sine_hold, self.initial_force, 0.0))
        t += self.pre_sine_hold
        mean = 0.5 * (self.sine_low + self.sine_high)
        for f in self.sine_frequencies:
            out.append(Segment('sine', t, t + self.sine_duration, mean, f))
            t += self.sine_duration
        out.append(Segment('hold', t, t + self.final_hold, self.initial_force, 0.0))
        return out

    @property
    def duration(self) -> float:
        """End of the recorded part [s]."""
        return self.segments()[-1].t_end

    def targets(self, t: ArrayLike) -> FloatArray:
        """Commanded force [N] at times ``t`` [s] (vectorised)."""
        tt = np.asarray(t, dtype=np.float64)
        out = np.full(tt.shape, self.final_force, dtype=np.float64)
        out[tt < 0.0] = self.initial_force
        for seg in self.segments():
            mask = (tt >= seg.t_start) & (tt < seg.t_end)
            out[mask] = self._force(seg, tt[mask] - seg.t_start)
        return out

    def target(self, t: float) -> float:
        """Commanded force [N] at time ``t`` [s] (one sample: what a player sends now)."""
        if t < 0.0:
            return self.initial_force
        for seg in self.segments():
            if seg.t_start <= t < seg.t_end:
                return float(self._force(seg, t - seg.t_start))
        return self.final_force

    def _force(self, seg: Segment, tau: float | FloatArray) -> float | FloatArray:
        """Force [N] of ``seg`` at ``tau`` [s] from its start (scalar or array)."""
        if seg.kind == 'sine':
            amplitude = 0.5 * (self.sine_high - self.sine_low)
            return self.sine_low + amplitude * (np.sin(2 * np.pi * seg.frequency * tau) + 1.0)
        return seg.value

    def sample_times(self) -> FloatArray:
        """Publishing instants at ``rate_hz`` over the recorded part [s]."""
        n = int(round(self.duration * self.rate_hz))
        return np.arange(n, dtype=np.float64) / self.rate_hz

    def step_segment(self) -> tuple[float, float, float, float]:
        """``(t_step, f_from, f_to, t_end)`` of the analysed step [s, N, N, s]."""
        levels = [s for s in self.segments() if s.kind == 'level']
        seg = levels[self.step_level_index]
        before = levels[self.step_level_index - 1].value if self.step_level_index > 0 \
            else self.initial_force
        return seg.t_start, before, seg.value, seg.t_end

    def sine_segments(self) -> list[Segment]:
        """The sine segments."""
        return [s for s in self.segments() if s.kind == 'sine']
