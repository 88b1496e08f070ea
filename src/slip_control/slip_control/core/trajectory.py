# SPDX-License-Identifier: Apache-2.0
"""Trapezoidal-velocity reference trajectory (control_and_estimation §4.3).

Distance or angle ``P`` over ``T`` with acceleration fraction ``f`` (default 0.2):
``t_c = f·T``, cruise speed ``v_c = P/((1 − f)·T)`` (``= 1.25·P/T`` for ``f = 0.2``),
acceleration ``a = v_c/t_c``.

=========================  ==========================================  =====================
time                       position                                    velocity
=========================  ==========================================  =====================
``t < 0``                  0                                           0
``0 ≤ t < t_c``            ``a t²/2``                                  ``a t``
``t_c ≤ t < T − t_c``      ``a t_c²/2 + v_c (t − t_c)``                ``v_c``
``T − t_c ≤ t < T``        ``… − a (t − T + t_c)²/2``                  ``v_c − a (t − T + t_c)``
``t ≥ T``                  ``P``                                       0
=========================  ==========================================  =====================

Position and velocity are continuous; ``P`` may be a distance [m] or an angle [rad].
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True, slots=True)
class TrapezoidalTrajectory:
    """Trapezoidal profile from 0 to ``distance`` in ``duration``.

    Attributes:
        distance: Target ``P`` [m or rad], > 0.
        duration: Total time ``T`` [s], > 0.
        accel_fraction: ``t_c/T`` in (0, 0.5].
    """

    distance: float
    duration: float
    accel_fraction: float = 0.2
    _t_c: float = field(init=False, repr=False)
    _v_c: float = field(init=False, repr=False)
    _a: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not (self.distance > 0.0 and self.duration > 0.0):
            raise ValueError(f'trajectory needs distance > 0 and duration > 0, got '
                             f'{self.distance!r}, {self.duration!r}')
        if not 0.0 < self.accel_fraction <= 0.5:
            raise ValueError(f'accel_fraction must be in (0, 0.5], got {self.accel_fraction!r}')
        t_c = self.accel_fraction * self.duration
        v_c = self.distance / (self.duration - t_c)
        object.__setattr__(self, '_t_c', t_c)
        object.__setattr__(self, '_v_c', v_c)
        object.__setattr__(self, '_a', v_c / t_c)

    @property
    def peak_speed(self) -> float:
        """Cruise speed ``v_c`` [m/s or rad/s]."""
        return self._v_c

    @property
    def acceleration(self) -> float:
        """Acceleration magnitude ``a`` [m/s² or rad/s²]."""
        return self._a

    def sample(self, t: float) -> tuple[float, float]:
        """Reference ``(position, velocity)`` at time ``t`` [s] since the start (scalar)."""
        if t <= 0.0:
            return 0.0, 0.0
        T, t_c, v_c, a = self.duration, self._t_c, self._v_c, self._a
        if t >= T:
            return self.distance, 0.0
        if t < t_c:
            return 0.5 * a * t * t, a * t
        x_c = 0.5 * a * t_c * t_c
        if t < T - t_c:
            return x_c + v_c * (t - t_c), v_c
        s = t - T + t_c
        return x_c + v_c * (t - t_c) - 0.5 * a * s * s, v_c - a * s

    def accel_at(self, t: float) -> float:
        """Reference acceleration at ``t`` [s] since the start [m/s² or rad/s²] (``+a``, 0,
        ``−a`` over the three phases; 0 outside ``[0, T)``)."""
        if t < 0.0 or t >= self.duration:
            return 0.0
        if t < self._t_c:
            return self._a
        if t < self.duration - self._t_c:
            return 0.0
        return -self._a

    def sample_array(self, t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Vectorised `sample`: ``t`` of any shape [s] → (positions, velocities), same shape."""
        tt = np.asarray(t, dtype=np.float64)
        T, t_c, v_c, a = self.duration, self._t_c, self._v_c, self._a
        x_c = 0.5 * a * t_c * t_c
        s = tt - T + t_c
        pos = np.select(
            [tt <= 0.0, tt < t_c, tt < T - t_c, tt < T],
            [0.0, 0.5 * a * tt * tt, x_c + v_c * (tt - t_c),
             x_c + v_c * (tt - t_c) - 0.5 * a * s * s],
            default=self.distance)
        vel = np.select(
            [tt <= 0.0, tt < t_c, tt < T - t_c, tt < T],
            [0.0, a * tt, v_c, v_c - a * s], default=0.0)
        return pos.astype(np.float64), vel.astype(np.float64)
