# SPDX-License-Identifier: Apache-2.0
"""Opening-rate tracking observer (hardware_protocols §2.4).

Per telemetry line, with ``dt`` the difference of consecutive acquisition stamps::

    p_hat += v_hat · dt
    e      = p − p_hat
    I     += ki · e · dt
    v_hat  = kp · e + I

A second-order tracking loop: ``ωn = √ki`` (22.4 rad/s = 3.56 Hz for ki = 500 1/s²) and
``ζ = kp / (2·√ki)`` (0.894 for kp = 40 1/s). It estimates the rate of a ramp without a
steady-state error.

Guards (ours; the reference used wall-clock ``dt`` without any): the first sample and every
`reset` initialise ``p_hat = p, I = 0``; a sample with ``dt ≤ 0`` is skipped; a gap longer than
`MAX_DT_S` re-initialises (the explicit loop is only stable for ``kp·dt`` well below 1, and a
rate from before a gap is meaningless).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

from slip_cell_common.core.validation import validate_fields

#: Longest accepted stamp difference [s]; longer gaps re-initialise the observer.
MAX_DT_S = 0.1


@dataclass(frozen=True)
class ObserverParams:
    """Observer gains (parameter group ``observer``)."""

    kp: float = field(default=40.0, metadata={
        'unit': '1/s', 'range': (0.0, 1000.0), 'description': 'proportional gain'})
    ki: float = field(default=500.0, metadata={
        'unit': '1/s^2', 'range': (0.0, 1.0e5), 'description': 'integral gain'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        validate_fields(self)


class ObserverEstimate(NamedTuple):
    """Observer output.

    Attributes:
        position: Filtered position ``p_hat`` [same unit as the input, e.g. m].
        rate: Rate estimate ``v_hat`` [input unit per s].
        updated: False when the sample was skipped (``dt ≤ 0``) or (re)initialised the state.
    """

    position: float
    rate: float
    updated: bool


class RateObserver:
    """Tracking observer of a position signal's rate; see the module docstring.

    Args:
        params: Gains.
    """

    def __init__(self, params: ObserverParams = ObserverParams()) -> None:
        self.params = params
        self.skipped = 0  #: samples skipped (``dt ≤ 0`` or non-finite input)
        self.reinits = 0  #: re-initialisations after gaps longer than MAX_DT_S
        self.reset()

    def set_params(self, params: ObserverParams) -> None:
        """Swap the gains (between samples); the state is kept."""
        self.params = params

    def reset(self) -> None:
        """Forget the state; the next sample initialises it (call after a reconnection)."""
        self._t: float | None = None
        self._p_hat = math.nan
        self._integral = 0.0
        self._v_hat = math.nan

    @property
    def rate(self) -> float:
        """Latest rate estimate (NaN before the first sample)."""
        return self._v_hat

    @property
    def position(self) -> float:
        """Latest filtered position (NaN before the first sample)."""
        return self._p_hat

    def update(self, t: float, p: float) -> ObserverEstimate:
        """Process one sample.

        Args:
            t: Acquisition stamp [s].
            p: Measured position (any linear unit; the rate has that unit per second).

        Returns:
            The estimate after this sample.
        """
        if not (math.isfinite(t) and math.isfinite(p)):
            self.skipped += 1
            return ObserverEstimate(self._p_hat, self._v_hat, False)
        if self._t is None:
            return self._init(t, p)
        dt = t - self._t
        if dt <= 0.0:
            self.skipped += 1
            return ObserverEstimate(self._p_hat, self._v_hat, False)
        if dt > MAX_DT_S:
            self.reinits += 1
            return self._init(t, p)
        self._t = t
        self._p_hat += self._v_hat * dt
        error = p - self._p_hat
        self._integral += self.params.ki * error * dt
        self._v_hat = self.params.kp * error + self._integral
        return ObserverEstimate(self._p_hat, self._v_hat, True)

    def _init(self, t: float, p: float) -> ObserverEstimate:
        self._t = t
        self._p_hat = p
        self._integral = 0.0
        self._v_hat = 0.0
        return ObserverEstimate(p, 0.0, False)
