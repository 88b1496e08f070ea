# SPDX-License-Identifier: Apache-2.0
"""Observer of the object's slip state for the model-based slip laws (docs/model_slip_control.md
§3.1).

A linear Kalman filter (`filterpy.kalman.KalmanFilter`) on the progress along the commanded
slip, with the state

    s = (p, v, a)       progress [m | rad], its rate [m/s | rad/s], its acceleration [m/s² | rad/s²]

and a constant-acceleration model driven by white jerk of spectral density ``jerk_psd``::

    p⁺ = p + v·dt + a·dt²/2,   v⁺ = v + a·dt,   a⁺ = a
    Q  = filterpy.common.Q_continuous_white_noise(3, dt, jerk_psd)

Measurements, each optional per step:

* **progress** ``p`` — the fingers' integrated travel projected on the slip: the twist samples
  summed over their own stamps (`signals.Travel`), so a step that missed samples loses
  nothing and the noise is a count or two, not a rate noise. The slip laws feed this and not
  the twist samples themselves as well: the travel *is* their integral, and fusing both would
  count the same noise twice;
* **rate** ``v`` — a rate measurement, for callers without a travel (`update_rate`);
* **acceleration** ``a`` — from the pad forces (LINEAR: ``m̂·a = load − Σ friction``, read on the
  F/T sensors; its noise scales with the F/T noise over the object's weight, so heavy objects
  get a sharp acceleration and light ones almost none).

The filter gives the clean rate and position the feedback uses, and sees the start of motion
(break-away) within a few samples. Time is the sample stamps' (``dt`` passed in); nothing here
reads a clock.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.common import Q_continuous_white_noise
from filterpy.kalman import KalmanFilter


@dataclass(frozen=True, slots=True)
class ObserverNoise:
    """Noise levels of `SlipObserver` (1-σ, SI; ``[m | rad]`` as the progress).

    Attributes:
        jerk_psd: Spectral density of the model's white jerk [m²/s⁵ | rad²/s⁵].
        position: Noise of a progress measurement [m | rad].
        rate: Noise of a rate measurement [m/s | rad/s].
        initial_rate: Prior 1-σ of the rate at the start [m/s | rad/s].
        initial_accel: Prior 1-σ of the acceleration at the start [m/s² | rad/s²].
    """

    jerk_psd: float
    position: float
    rate: float = 1e-3
    initial_rate: float = 1e-3
    initial_accel: float = 0.1


@dataclass(frozen=True, slots=True)
class SlipEstimate:
    """Observer output after a step.

    Attributes:
        position: Estimated progress [m | rad].
        rate: Estimated rate [m/s | rad/s].
        accel: Estimated acceleration [m/s² | rad/s²].
        rate_std: 1-σ of the rate estimate [m/s | rad/s].
    """

    position: float
    rate: float
    accel: float
    rate_std: float


class SlipObserver:
    """Kalman filter on ``(progress, rate, acceleration)`` of one slip (module docstring).

    Args:
        noise: Noise levels.
        position: Initial progress [m | rad] (0 at the start of a trajectory).
    """

    def __init__(self, noise: ObserverNoise, position: float = 0.0) -> None:
        if not (noise.jerk_psd > 0.0 and noise.position > 0.0 and noise.rate > 0.0):
            raise ValueError(f'observer noise levels must be > 0, got {noise!r}')
        self._noise = noise
        kf = KalmanFilter(dim_x=3, dim_z=1)
        kf.x = np.array([[position], [0.0], [0.0]])
        kf.P = np.diag([noise.position ** 2, noise.initial_rate ** 2, noise.initial_accel ** 2])
        self._kf = kf
        self._h_pos = np.array([[1.0, 0.0, 0.0]])
        self._h_rate = np.array([[0.0, 1.0, 0.0]])
        self._h_acc = np.array([[0.0, 0.0, 1.0]])
        self._r_pos = np.array([[noise.position ** 2]])
        self._r_rate = np.array([[noise.rate ** 2]])

    @property
    def estimate(self) -> SlipEstimate:
        """The current estimate."""
        x = self._kf.x
        return SlipEstimate(position=float(x[0, 0]), rate=float(x[1, 0]), accel=float(x[2, 0]),
                            rate_std=float(np.sqrt(max(self._kf.P[1, 1], 0.0))))

    def predict(self, dt: float) -> None:
        """Propagate the state over ``dt`` [s] (> 0; other values leave the state alone)."""
        if not dt > 0.0:
            return
        f = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
        q = Q_continuous_white_noise(dim=3, dt=dt, spectral_density=self._noise.jerk_psd)
        self._kf.predict(F=f, Q=q)

    def update_position(self, position: float) -> None:
        """Fuse a progress measurement [m | rad]."""
        self._kf.update(np.array([[position]]), R=self._r_pos, H=self._h_pos)

    def update_rate(self, rate: float) -> None:
        """Fuse a rate measurement [m/s | rad/s]."""
        self._kf.update(np.array([[rate]]), R=self._r_rate, H=self._h_rate)

    def update_accel(self, accel: float, std: float) -> None:
        """Fuse an acceleration measurement [m/s² | rad/s²] with its 1-σ ``std`` (> 0)."""
        if not std > 0.0:
            raise ValueError(f'acceleration noise must be > 0, got {std!r}')
        self._kf.update(np.array([[accel]]), R=np.array([[std * std]]), H=self._h_acc)

    def step(self, dt: float, position: float | None = None, rate: float | None = None,
             accel: float | None = None, accel_std: float = 0.0) -> SlipEstimate:
        """`predict` then fuse whatever was measured this step; returns the estimate.

        Args:
            dt: Time since the previous step [s] (≤ 0: no prediction).
            position: Progress measurement [m | rad], or ``None``.
            rate: Rate measurement [m/s | rad/s], or ``None``.
            accel: Acceleration measurement [m/s² | rad/s²], or ``None``.
            accel_std: Its 1-σ (needed with ``accel``).
        """
        self.predict(dt)
        if position is not None:
            self.update_position(position)
        if rate is not None:
            self.update_rate(rate)
        if accel is not None:
            self.update_accel(accel, accel_std)
        return self.estimate
