# SPDX-License-Identifier: Apache-2.0
"""Inner grasp-force controller, shared by the gripper driver and the simulator (ROS-free).

Control law (control_and_estimation §2.3), once per gripper telemetry line::

    bypass (open loop) if |F_m| < contact_threshold, the F/T is not biased, or F_d < 0:
        u = F_d;  E = 0;  e_prev = 0
    otherwise:
        e      = F_d − F_m
        s      = 1 + gamma · (e − e_prev)²        # per sample, not divided by dt
        e_prev = e
        E     += e · dt
        I      = ki · E
        if |I| > i_max / s:  I = sign(I) · i_max / s;  E = I / (ki + 1e-6)
        u      = F_d + I + (kp / s) · e

with ``F_m = −(Fz1 + Fz2)/2`` (or one finger, parameter ``measurement``), bias removed.

Additions of §2.5, applied in this order each step:

1. Safe state (deactivate, shutdown, link fault, not armed): ``u = 0``, state cleared.
2. Command expiry: a target with ``target_timeout > 0`` older than its timeout is replaced
   per ``on_command_timeout``: ``hold`` (keep), ``safe_force`` (``min(F_d, safe_hold_force)``),
   ``open`` (``−max_open_force``) or ``zero`` (0 N); ``command_expired`` reports it.
3. F/T fault (a used sample older than ``ft_fault_after``, or none): while the loop relies
   on the F/T (biased), the target is limited to ``safe_hold_force``. Not while the box's
   newer records wait unread at the host (``ft_host_lag``: a busy host, not a silent box):
   the sample then stays stale (open loop to the target).
4. Target limits ``F_d ← clip(F_d, −max_open_force, max_grasp_force)``.
5. Target rate limit: ``F_d`` slews at most ``target_rate_limit`` N/s (0 = off), from 0 N
   after `GraspForceController.reset`; a step with ``dt > 0.1 s`` slews at most 0.1 s worth.
6. End-stop protection: ``F_d < 0``, homed, opening within ``end_stop_margin`` of the stroke
   and ``|opening_rate| < end_stop_speed`` for ``end_stop_timeout`` → ``u = 0`` until the next
   target (a new stamp or value).
7. Bypass as above; additionally a stale F/T sample (older than ``ft_stale_after``) bypasses.
   A stale bypass that is not an F/T fault holds the integral action learnt so far, frozen:
   ``u = F_d + I`` (``I`` and ``e_prev`` kept, nothing integrated), so a reader that falls
   a few samples behind does not step the force by the plant's offset and the loop resumes
   bumplessly. Every other bypass clears the loop state (``u = F_d``).
   In a bypass with ``F_d > 0`` while homed the approach-speed limit applies:
   ``u = clip(F_d − approach_gain · max(0, v_close − approach_max_speed), 0, F_d)`` with
   ``v_close = −opening_rate`` (``approach_max_speed = 0`` = off).
8. Command ceiling ``u ← clip(u, −max_open_force, max_command_force)``.

Reference defects not reproduced (§2.6): there is no derivative term (``kd_vel`` was always
zero); ``dt`` comes from acquisition stamps; ``dt ≤ 0`` or ``dt > 0.1 s`` skips the integral
update for that step (CE-6).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum
from typing import NamedTuple

from slip_cell_common.core.param_schema import ranged_field as _f
from slip_cell_common.core.validation import validate_fields

#: Longest ``dt`` [s] accepted for the integral update; longer (or ≤ 0) steps skip it.
MAX_DT_S = 0.1

#: Regulariser of the anti-windup back-calculation ``E = I / (ki + 1e-6)`` [1/s].
_KI_EPS = 1e-6


@dataclass(frozen=True)
class ForceControlParams:
    """Inner grasp-force loop settings (parameter group ``force_control``; SI, runtime-tunable).

    Forces are per finger; positive squeezes.
    """

    kp: float = _f(2.0, '-', 0.0, 20.0, 'proportional gain on the force error')
    ki: float = _f(100.0, '1/s', 0.0, 1000.0, 'integral gain')
    gamma: float = _f(5.0, '1/N^2', 0.0, 1000.0,
                      'gain scheduling on the squared error change per sample')
    i_max: float = _f(10.0, 'N', 0.0, 40.0, 'integral authority before scheduling')
    contact_threshold: float = _f(0.5, 'N', 0.0, 10.0, 'below |F_m| the loop is open')
    measurement: str = field(default='mean', metadata={
        'choices': ('mean', 'finger_1', 'finger_2'),
        'description': 'force used as F_m: -(Fz1+Fz2)/2, -Fz1 or -Fz2'})
    max_grasp_force: float = _f(40.0, 'N', 0.0, 80.0, 'largest squeezing target')
    max_open_force: float = _f(8.0, 'N', 0.0, 80.0, 'largest opening target and command')
    max_command_force: float = _f(45.0, 'N', 0.0, 80.0,
                                  'hard ceiling of the squeezing command (set from hardware)')
    target_rate_limit: float = _f(0.0, 'N/s', 0.0, 1.0e4, 'target slew limit; 0 = off')
    approach_max_speed: float = _f(0.0, 'm/s', 0.0, 1.0,
                                   'free-air closing speed limit; 0 = off')
    approach_gain: float = _f(0.0, 'N/(m/s)', 0.0, 1.0e4,
                              'force reduction per m/s of closing speed above the limit')
    ft_stale_after: float = _f(0.010, 's', 0.001, 1.0, 'older F/T samples bypass the loop')
    ft_fault_after: float = _f(0.100, 's', 0.001, 10.0,
                               'older F/T samples limit the target to safe_hold_force')
    on_command_timeout: str = field(default='hold', metadata={
        'choices': ('hold', 'safe_force', 'open', 'zero'),
        'description': 'target used when a command passes its timeout'})
    safe_hold_force: float = _f(5.0, 'N', 0.0, 80.0, 'target limit for safe_force and F/T fault')
    end_stop_margin: float = _f(0.001, 'm', 0.0, 0.05, 'open-limit zone of end-stop protection')
    end_stop_speed: float = _f(0.001, 'm/s', 0.0, 0.1, 'speed below which the fingers rest')
    end_stop_timeout: float = _f(1.0, 's', 0.0, 60.0, 'rest time at the open limit before 0 V')

    def validate(self) -> None:
        """Raise `ParameterError` (a ValueError) listing every invalid field and combination."""
        problems: list[str] = []
        if self.ft_fault_after < self.ft_stale_after:
            problems.append(f'ft_fault_after {self.ft_fault_after} s is below ft_stale_after '
                            f'{self.ft_stale_after} s')
        if self.max_grasp_force > self.max_command_force:
            problems.append(f'max_grasp_force {self.max_grasp_force} N exceeds '
                            f'max_command_force {self.max_command_force} N')
        if self.safe_hold_force > self.max_grasp_force:
            problems.append(f'safe_hold_force {self.safe_hold_force} N exceeds '
                            f'max_grasp_force {self.max_grasp_force} N')
        validate_fields(self, problems)


class BypassReason(IntEnum):
    """Why the loop ran open this step (mirrors the slip_msgs/MotorCommand constants)."""

    NONE = 0
    NO_CONTACT = 1
    NOT_BIASED = 2
    OPEN_COMMAND = 3
    FT_STALE = 4
    APPROACH_LIMIT = 5
    END_STOP = 6
    SAFE_STATE = 7


_NAN = math.nan


class ForceLoopInput(NamedTuple):
    """Inputs of one controller step (SI; all stamps on the same clock; one per line).

    Attributes:
        t: Acquisition stamp of the triggering telemetry line [s].
        target: Latest commanded grasp force ``F_d`` [N]; positive squeezes, negative opens.
        target_stamp: Stamp of that command [s].
        target_timeout: Its expiry after ``target_stamp`` [s]; 0 = valid until replaced.
        fz_1: Bias-removed Fz of finger 1 [N] (squeezing gives negative values); NaN if none.
        fz_2: Same for finger 2 [N].
        ft_stamp_1: Acquisition stamp of ``fz_1`` [s]; NaN if none.
        ft_stamp_2: Acquisition stamp of ``fz_2`` [s]; NaN if none.
        ft_biased: The F/T values used are bias-removed.
        homed: Opening and stroke are known.
        opening: Finger separation [m]; NaN if unknown.
        opening_rate: Opening rate [m/s] (positive opening); NaN if unknown.
        stroke: Opening at the open limit [m]; NaN if unknown.
        safe_state: Apply the safe state (no force) this step.
        hold_integral: Keep the integral this step (the bridge limits the command while it
            resumes after a stall, so the error then is not the controller's to integrate).
        ft_host_lag: The old F/T sample is the host's delay, not the box's: its newer records
            wait unread at the host. A sample past ``ft_fault_after`` then stays stale
            (bypass) instead of faulting to ``safe_hold_force``.
    """

    t: float
    target: float
    target_stamp: float = 0.0
    target_timeout: float = 0.0
    fz_1: float = _NAN
    fz_2: float = _NAN
    ft_stamp_1: float = _NAN
    ft_stamp_2: float = _NAN
    ft_biased: bool = False
    homed: bool = False
    opening: float = _NAN
    opening_rate: float = _NAN
    stroke: float = _NAN
    safe_state: bool = False
    hold_integral: bool = False
    ft_host_lag: bool = False


class ForceLoopOutput(NamedTuple):
    """Result of one controller step.

    Attributes:
        force_target: ``F_d`` after expiry policy, limits and rate limit [N].
        force_cmd: ``u`` after the command ceiling [N] (the bridge converts it to volts).
        measured_force: ``F_m`` [N]; NaN unless biased and fresh.
        error: ``F_d − F_m`` [N]; 0 in bypass.
        integral: Integral action ``I`` [N]; the held value in a stale bypass, else 0 in
            bypass.
        gain_scale: ``s`` [-]; 1 in bypass.
        closed_loop: The PI loop was active this step.
        bypass_reason: Why the loop was open (``NONE`` when closed).
        command_expired: The command passed its timeout (the policy was applied).
        ft_fault: A used F/T sample is older than ``ft_fault_after`` (or missing).
    """

    force_target: float
    force_cmd: float
    measured_force: float
    error: float
    integral: float
    gain_scale: float
    closed_loop: bool
    bypass_reason: BypassReason
    command_expired: bool
    ft_fault: bool


def _clip(x: float, low: float, high: float) -> float:
    return low if x < low else high if x > high else x


class GraspForceController:
    """Stateful inner grasp-force loop; see the module docstring for the law and additions.

    Not thread-safe: call `step`, `set_params` and `reset` from one thread (the bridge holds
    its lock around them).

    Args:
        params: Validated settings.
    """

    _integral: float
    _error_integral: float

    def __init__(self, params: ForceControlParams = ForceControlParams()) -> None:
        self.params = params
        self.reset()

    def set_params(self, params: ForceControlParams) -> None:
        """Swap the settings between steps.

        A change of ``ki`` keeps the integral action ``I`` (bumpless): ``E`` is rescaled.
        """
        if params.ki != self.params.ki:
            self._error_integral = self._integral / (params.ki + _KI_EPS) if params.ki > 0.0 \
                else 0.0
        self.params = params

    def reset(self) -> None:
        """Forget all state (call when the clock jumps backwards or the link restarts)."""
        self._t_prev: float | None = None
        self._e_prev = 0.0
        self._error_integral = 0.0
        self._integral = 0.0
        self._target_prev = 0.0  # the rate limiter restarts from 0 N (nothing applied)
        self._end_stop_since: float | None = None
        self._end_stop_latch: tuple[float, float] | None = None
        self.steps = 0  #: steps since reset
        self.skipped_integrations = 0  #: steps whose dt was ≤ 0 or > MAX_DT_S
        self.saturations = 0  #: steps where the command ceiling clipped u
        self.invalid_targets = 0  #: non-finite targets treated as 0 N

    def step(self, inp: ForceLoopInput) -> ForceLoopOutput:
        """Run one step.

        Args:
            inp: Inputs for this telemetry line.

        Returns:
            The command and the loop state for logging.
        """
        p = self.params
        t = inp.t
        dt = _NAN if self._t_prev is None else t - self._t_prev
        self._t_prev = t
        dt_ok = 0.0 < dt <= MAX_DT_S
        if self.steps and not dt_ok:
            self.skipped_integrations += 1
        self.steps += 1

        target = inp.target
        if not math.isfinite(target):
            self.invalid_targets += 1
            target = 0.0
        expired = inp.target_timeout > 0.0 and t - inp.target_stamp > inp.target_timeout
        if expired:
            target = self._expiry_target(target)

        fm, fresh, fault = self._measure(inp)
        measured = fm if (fresh and inp.ft_biased) else _NAN

        if inp.safe_state:
            self._clear_loop()
            self._target_prev = 0.0
            self._end_stop_since = None
            return ForceLoopOutput(0.0, 0.0, measured, 0.0, 0.0, 1.0, False,
                                   BypassReason.SAFE_STATE, expired, fault)

        if fault and inp.ft_biased:
            target = min(target, p.safe_hold_force)
        fd = _clip(target, -p.max_open_force, p.max_grasp_force)
        if p.target_rate_limit > 0.0:
            slew_dt = _clip(dt, 0.0, MAX_DT_S) if math.isfinite(dt) else 0.0
            max_step = p.target_rate_limit * slew_dt
            fd = self._target_prev + _clip(fd - self._target_prev, -max_step, max_step)
        self._target_prev = fd

        if self._end_stop(inp, fd):
            self._clear_loop()
            return ForceLoopOutput(fd, 0.0, measured, 0.0, 0.0, 1.0, False,
                                   BypassReason.END_STOP, expired, fault)

        if fd < 0.0:
            reason = BypassReason.OPEN_COMMAND
        elif not inp.ft_biased:
            reason = BypassReason.NOT_BIASED
        elif not fresh:
            reason = BypassReason.FT_STALE
        elif abs(fm) < p.contact_threshold:
            reason = BypassReason.NO_CONTACT
        else:
            reason = BypassReason.NONE

        if reason != BypassReason.NONE:
            # A stale sample (a late reader, not a faulted box) keeps the integral action it
            # had learnt, frozen: clearing it would step the force by the plant's offset.
            held = self._integral if reason == BypassReason.FT_STALE and not fault else 0.0
            if held == 0.0:
                self._clear_loop()
            u = fd + held
            if fd > 0.0 and inp.homed and p.approach_max_speed > 0.0 and \
                    math.isfinite(inp.opening_rate):
                v_close = -inp.opening_rate
                limited = _clip(fd - p.approach_gain * max(0.0, v_close - p.approach_max_speed),
                                0.0, fd)
                if limited < fd:
                    u = limited
                    reason = BypassReason.APPROACH_LIMIT
            return ForceLoopOutput(fd, self._ceiling(u), measured, 0.0, held, 1.0, False,
                                   reason, expired, fault)

        error = fd - fm
        delta = error - self._e_prev
        scale = 1.0 + p.gamma * delta * delta
        self._e_prev = error
        if dt_ok and not inp.hold_integral:
            self._error_integral += error * dt
        integral = p.ki * self._error_integral
        limit = p.i_max / scale
        if abs(integral) > limit:
            integral = math.copysign(limit, integral)
            self._error_integral = integral / (p.ki + _KI_EPS)
        self._integral = integral
        u = fd + integral + (p.kp / scale) * error
        return ForceLoopOutput(fd, self._ceiling(u), fm, error, integral, scale, True,
                               BypassReason.NONE, expired, fault)

    # ------------------------------------------------------------------ helpers
    def _clear_loop(self) -> None:
        self._e_prev = 0.0
        self._error_integral = 0.0
        self._integral = 0.0

    def _ceiling(self, u: float) -> float:
        p = self.params
        clipped = _clip(u, -p.max_open_force, p.max_command_force)
        if clipped != u:
            self.saturations += 1
        return clipped

    def _expiry_target(self, target: float) -> float:
        policy = self.params.on_command_timeout
        if policy == 'safe_force':
            return min(target, self.params.safe_hold_force)
        if policy == 'open':
            return -self.params.max_open_force
        if policy == 'zero':
            return 0.0
        return target  # 'hold': keep the last target (reported through command_expired)

    def _measure(self, inp: ForceLoopInput) -> tuple[float, bool, bool]:
        """``(F_m, fresh, fault)`` for the configured measurement."""
        p = self.params
        t = inp.t
        # The older sample decides; NaN ages (no sample yet) compare False everywhere below,
        # so they count as stale and faulted (max() would drop a NaN, hence the branches).
        if p.measurement == 'finger_1':
            fm = -inp.fz_1
            age_1 = age_2 = t - inp.ft_stamp_1
        elif p.measurement == 'finger_2':
            fm = -inp.fz_2
            age_1 = age_2 = t - inp.ft_stamp_2
        else:
            fm = -0.5 * (inp.fz_1 + inp.fz_2)
            age_1, age_2 = t - inp.ft_stamp_1, t - inp.ft_stamp_2
        stale, fault_after = p.ft_stale_after, p.ft_fault_after
        fresh = math.isfinite(fm) and age_1 <= stale and age_2 <= stale
        fault = not (age_1 <= fault_after and age_2 <= fault_after) and not inp.ft_host_lag
        return fm, fresh, fault

    def _end_stop(self, inp: ForceLoopInput, fd: float) -> bool:
        p = self.params
        latch = self._end_stop_latch
        if latch is not None and (fd >= 0.0 or latch != (inp.target_stamp, inp.target)):
            self._end_stop_latch = latch = None
        resting = (fd < 0.0 and inp.homed and math.isfinite(inp.stroke)
                   and inp.opening >= inp.stroke - p.end_stop_margin
                   and abs(inp.opening_rate) < p.end_stop_speed)
        if not resting:
            self._end_stop_since = None
        elif self._end_stop_since is None:
            self._end_stop_since = inp.t
        if latch is None and resting and self._end_stop_since is not None and \
                inp.t - self._end_stop_since >= p.end_stop_timeout:
            self._end_stop_latch = latch = (inp.target_stamp, inp.target)
        return latch is not None
