# SPDX-License-Identifier: Apache-2.0
"""Explicit homing of the gripper, stepped once per telemetry line (hardware_protocols §2.6).

The firmware reports the shaft angle relative to its power-up position, so the closed and
open limits must be found by driving against them:

1. CLOSING: command ``−voltage``; per line ``avg ← f·avg + (1−f)·|Δθ|``; when
   ``avg < stall_threshold`` and the phase lasted at least ``min_phase_time``, store
   ``θ_closed``.
2. OPENING: command ``+voltage`` with the same stall test; store ``θ_open``.
3. Done: the bridge sends the safe voltage; ``stroke = (θ_open − θ_closed)·k_open``.

Ours, on top of the reference: ``avg`` starts at `STALL_AVG_INIT_RAD` (above any threshold)
and a minimum phase time is required, so the test cannot pass before the motor moves; every
phase has a timeout; an optional stroke check (``expected_stroke``) catches an object squeezed
between the fingers; a non-positive stroke (motor direction or sign error) always fails. The
limits stay valid while the link stays up; the bridge invalidates them on reconnection or a
firmware restart. Homing never starts by itself: the bridge calls `Homing.start` on an
explicit request. Note that every firmware (re)start moves the fingers (``initFOC``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum
from typing import NamedTuple

from slip_cell_common.core.validation import validate_fields

#: Initial value of the stall average [rad per line]: far above any sensible threshold.
STALL_AVG_INIT_RAD = 1.0


@dataclass(frozen=True)
class HomingParams:
    """Homing settings (parameter group ``homing``)."""

    on_activate: bool = field(default=False, metadata={
        'description': 'home automatically once after activation'})
    voltage: float = field(default=4.0, metadata={
        'unit': 'V', 'range': (0.5, 12.0), 'description': 'homing voltage magnitude'})
    stall_threshold: float = field(default=0.001, metadata={
        'unit': 'rad', 'range': (1.0e-5, 0.1),
        'description': 'stall when the averaged |dtheta| per line falls below this'})
    stall_filter: float = field(default=0.98, metadata={
        'unit': '-', 'range': (0.0, 0.9999), 'description': 'EMA factor of the stall average'})
    min_phase_time: float = field(default=0.5, metadata={
        'unit': 's', 'range': (0.0, 10.0), 'description': 'shortest closing/opening phase'})
    timeout: float = field(default=10.0, metadata={
        'unit': 's', 'range': (0.1, 120.0), 'description': 'longest closing/opening phase'})
    expected_stroke: float = field(default=0.0, metadata={
        'unit': 'm', 'range': (0.0, 0.5),
        'description': 'measured open-to-closed stroke; 0 = unchecked'})
    stroke_tolerance: float = field(default=0.002, metadata={
        'unit': 'm', 'range': (0.0, 0.1), 'description': 'allowed stroke deviation'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        extra = []
        if self.min_phase_time >= self.timeout:
            extra.append(f'min_phase_time {self.min_phase_time} s must be below timeout '
                         f'{self.timeout} s')
        validate_fields(self, extra)


class HomingPhase(IntEnum):
    """Homing state."""

    IDLE = 0
    CLOSING = 1
    OPENING = 2
    DONE = 3
    FAILED = 4


@dataclass(frozen=True)
class HomingResult:
    """Limits found by homing (valid for one link session).

    Attributes:
        theta_closed: Shaft angle at the closed stop [rad, firmware frame].
        theta_open: Shaft angle at the open stop [rad].
        stroke: ``(θ_open − θ_closed)·k_open`` [m].
    """

    theta_closed: float
    theta_open: float
    stroke: float


class HomingStep(NamedTuple):
    """Output of one homing step.

    Attributes:
        voltage_v: Voltage to command [V], or None when homing no longer drives the motor
            (the caller then sends its safe voltage).
        phase: Phase after this step.
        finished: True on the step that ended homing (success or failure).
    """

    voltage_v: float | None
    phase: HomingPhase
    finished: bool


def homing_refusal(*, link_ok: bool, armed: bool, busy: bool, ft_checked: bool,
                   grasp_force: float, contact_threshold: float,
                   target_force: float) -> str | None:
    """Reason to refuse a homing request, or None when it may start.

    Args:
        link_ok: Telemetry is flowing.
        armed: The driver may move the motor.
        busy: Homing is already running.
        ft_checked: The F/T is biased and fresh, so ``grasp_force`` is meaningful.
        grasp_force: Measured grasp force [N] (ignored unless ``ft_checked``).
        contact_threshold: Contact threshold [N].
        target_force: Active grasp-force target [N].
    """
    if busy:
        return 'homing already running'
    if not link_ok:
        return 'no telemetry from the gripper'
    if not armed:
        return 'driver not armed (re-arm after a fault or reconnection first)'
    if target_force > 0.0:
        return f'a grasp-force command of {target_force:.2f} N is active; release first'
    if ft_checked and abs(grasp_force) > contact_threshold:
        return (f'F/T reports contact ({grasp_force:.2f} N > {contact_threshold:.2f} N); '
                f'empty the gripper first')
    return None


class Homing:
    """Homing state machine; see the module docstring.

    Args:
        params: Homing settings.
        opening_per_rad: Finger separation per motor radian [m/rad].
    """

    def __init__(self, params: HomingParams, opening_per_rad: float) -> None:
        self.params = params
        self.opening_per_rad = opening_per_rad
        self.phase = HomingPhase.IDLE
        self.result: HomingResult | None = None
        self.message = 'not homed'
        self._phase_start = math.nan
        self._avg = STALL_AVG_INIT_RAD
        self._last_angle = math.nan
        self._theta_closed = math.nan

    @property
    def active(self) -> bool:
        """True while homing drives the motor."""
        return self.phase in (HomingPhase.CLOSING, HomingPhase.OPENING)

    @property
    def homed(self) -> bool:
        """True when valid limits are known."""
        return self.result is not None

    def set_params(self, params: HomingParams) -> None:
        """Swap the settings; they apply from the next phase on."""
        self.params = params

    def start(self, t: float) -> None:
        """Begin homing at time ``t`` [s]; previous limits are discarded.

        Preconditions (link, arming, contact, active command) are the caller's job; see
        `homing_refusal`.
        """
        self.result = None
        self._theta_closed = math.nan
        self._enter(HomingPhase.CLOSING, t)
        self.message = 'closing'

    def adopt(self, result: HomingResult) -> None:
        """Take known limits without running the sequence (aborts a run in progress)."""
        self.result = result
        self.phase = HomingPhase.DONE
        self.message = f'homed: stroke {result.stroke * 1e3:.2f} mm'

    def abort(self, reason: str) -> None:
        """Stop an active homing run (link loss, deactivate, stop request)."""
        if self.active:
            self.phase = HomingPhase.FAILED
            self.message = f'aborted: {reason}'

    def invalidate(self, reason: str) -> None:
        """Discard the limits (reconnection, firmware restart) and abort any run."""
        self.abort(reason)
        if self.result is not None or self.phase == HomingPhase.DONE:
            self.phase = HomingPhase.IDLE
            self.message = f'not homed: {reason}'
        self.result = None

    def step(self, t: float, angle_rad: float) -> HomingStep:
        """Advance by one telemetry line.

        Args:
            t: Acquisition stamp of the line [s].
            angle_rad: Shaft angle [rad].

        Returns:
            The voltage to command and the phase.
        """
        if not self.active:
            return HomingStep(None, self.phase, False)
        p = self.params
        if math.isfinite(self._last_angle):
            self._avg = p.stall_filter * self._avg + \
                (1.0 - p.stall_filter) * abs(angle_rad - self._last_angle)
        self._last_angle = angle_rad
        elapsed = t - self._phase_start
        name = 'closing' if self.phase == HomingPhase.CLOSING else 'opening'
        if elapsed > p.timeout:
            return self._fail(f'{name} phase timed out after {p.timeout:.1f} s without a stall')
        if elapsed >= p.min_phase_time and self._avg < p.stall_threshold:
            if self.phase == HomingPhase.CLOSING:
                self._theta_closed = angle_rad
                self._enter(HomingPhase.OPENING, t)
                self.message = 'opening'
                return HomingStep(p.voltage, self.phase, False)
            return self._finish(angle_rad)
        voltage = -p.voltage if self.phase == HomingPhase.CLOSING else p.voltage
        return HomingStep(voltage, self.phase, False)

    def _enter(self, phase: HomingPhase, t: float) -> None:
        self.phase = phase
        self._phase_start = t
        self._avg = STALL_AVG_INIT_RAD
        self._last_angle = math.nan

    def _fail(self, message: str) -> HomingStep:
        self.phase = HomingPhase.FAILED
        self.message = f'failed: {message}'
        return HomingStep(None, self.phase, True)

    def _finish(self, theta_open: float) -> HomingStep:
        p = self.params
        stroke = (theta_open - self._theta_closed) * self.opening_per_rad
        if stroke <= 0.0:
            return self._fail(f'stroke {stroke * 1e3:.2f} mm is not positive: check the motor '
                              f'direction and the sign of opening_per_rad')
        if p.expected_stroke > 0.0 and abs(stroke - p.expected_stroke) > p.stroke_tolerance:
            return self._fail(f'stroke {stroke * 1e3:.2f} mm differs from the expected '
                              f'{p.expected_stroke * 1e3:.2f} mm by more than '
                              f'{p.stroke_tolerance * 1e3:.2f} mm (object between the fingers?)')
        self.result = HomingResult(self._theta_closed, theta_open, stroke)
        self.phase = HomingPhase.DONE
        self.message = f'homed: stroke {stroke * 1e3:.2f} mm'
        return HomingStep(None, self.phase, True)
