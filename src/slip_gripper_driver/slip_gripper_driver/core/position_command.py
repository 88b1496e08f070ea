# SPDX-License-Identifier: Apache-2.0
"""Finger-position goals on a force-controlled gripper (ROS-free): the logic behind the
standard ``control_msgs`` gripper actions.

The gripper has no position loop of its own: the firmware takes a motor voltage and the
driver's inner loop a grasp force (`core.force_control`). A position goal is reached with an
outer loop on the opening the observer measures, run once per telemetry line:

    e = opening − target_opening          (> 0: close)
    F = sign(e) · clip(gain · |e|, min_force, force_limit)     while |e| > tolerance

A positive ``F`` closes (in free air the inner loop is open and the fingers move at the speed
the force drives, bounded by its approach-speed limit; on an object it becomes the grasp
force), a negative one opens. The goal ends

* **reached** once ``|e| ≤ tolerance``: the command drops to 0 N (fingers stay), or, if the
  pads are on an object, stays at ``force_limit`` (the object is held);
* **stalled** when the fingers move slower than ``stall_speed`` for ``stall_time`` without
  reaching the target: closing, they hold with ``force_limit`` (a grasp, as MoveIt expects
  from a gripper closed onto an object); opening, the command drops to 0 N;
* **timed out** after ``timeout`` [s] (0 N), or **cancelled** (0 N).

Position semantics (MoveIt / ``control_msgs`` for a parallel gripper with prismatic joints):
a goal ``position`` is the position of ``finger_1_joint`` [m] = half the finger separation
(0 closed, ``stroke/2`` open); ``finger_2_joint`` mimics it (the URDF of
`slip_cell_common.core.gripper_urdf`, and ``gripper/joint_states``). ``max_effort`` is the
per-finger grasp-force limit [N] (the force loop's unit); 0 means `PositionCommandParams.
default_effort`, values above the loop's ``max_grasp_force`` are clipped to it. Times are
acquisition stamps [s] of the telemetry lines; nothing reads a clock.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

from slip_cell_common.core.param_schema import ranged_field as _f


@dataclass(frozen=True)
class PositionCommandParams:
    """Outer position loop of the gripper actions (SI)."""

    gain: float = _f(1000.0, 'N/m', 1.0, 1.0e5, 'force per metre of opening error')
    min_force: float = _f(0.5, 'N', 0.0, 10.0, 'smallest drive force outside the tolerance')
    tolerance: float = _f(0.0005, 'm', 1.0e-5, 0.01, 'opening error that counts as reached')
    stall_speed: float = _f(0.002, 'm/s', 0.0, 0.1, 'slower than this counts as not moving')
    stall_time: float = _f(0.3, 's', 0.01, 10.0, 'not moving this long (unreached) = stalled')
    timeout: float = _f(10.0, 's', 0.1, 120.0, 'longest goal')
    default_effort: float = _f(10.0, 'N', 0.1, 80.0, 'force limit when max_effort is 0')
    min_command_change: float = _f(0.1, 'N', 0.0, 5.0,
                                   'smallest change worth a new command while moving')
    position_margin: float = _f(0.0005, 'm', 0.0, 0.01,
                                'goals this far outside [0, stroke/2] are clipped, not refused')


class Outcome(Enum):
    """How a position goal ended."""

    RUNNING = 'running'
    REACHED = 'reached'
    STALLED = 'stalled'
    TIMED_OUT = 'timed out'
    CANCELLED = 'cancelled'
    FAILED = 'failed'


@dataclass(frozen=True)
class PositionGoal:
    """A validated goal: target finger separation [m] and per-finger force limit [N]."""

    target_opening: float
    force_limit: float
    note: str = ''


@dataclass(frozen=True)
class GripperView:
    """What the goal check needs to know about the gripper now (SI).

    Attributes:
        homed: The opening is known.
        armed: The driver may apply force (active, armed, link up).
        stroke: Open-limit finger separation [m] (NaN unless homed).
        max_grasp_force: The force loop's largest squeezing target [N].
        competing: A description of another live grasp-force source, or ''.
    """

    homed: bool
    armed: bool
    stroke: float
    max_grasp_force: float
    competing: str = ''


@dataclass(frozen=True)
class PositionState:
    """One sample of the gripper for the loop (a telemetry line; SI, stamp [s])."""

    stamp: float
    opening: float
    opening_rate: float
    measured_force: float
    in_contact: bool


@dataclass(frozen=True)
class PositionStep:
    """Result of one `PositionCommand.step`.

    Attributes:
        force: Grasp force to command now [N], or None (keep the last command).
        outcome: RUNNING, or how the goal ended (then ``force`` is the final command).
        message: Why it ended ('' while running).
    """

    force: float | None
    outcome: Outcome
    message: str = ''


def check_goal(position: float, max_effort: float, view: GripperView,
               params: PositionCommandParams = PositionCommandParams()
               ) -> tuple[PositionGoal | None, str]:
    """Validate a goal when it arrives.

    Args:
        position: ``finger_1_joint`` target [m] (half the finger separation).
        max_effort: Per-finger force limit [N]; 0 = ``params.default_effort``.
        view: The gripper now.
        params: Loop settings.

    Returns:
        ``(goal, note)`` when accepted (the note says what was clipped), or ``(None, reason)``.
    """
    if not (math.isfinite(position) and math.isfinite(max_effort)):
        return None, f'position {position!r} m and max_effort {max_effort!r} N must be finite'
    if max_effort < 0.0:
        return None, f'max_effort {max_effort!r} N must be >= 0 (0 = default)'
    if not view.homed or not math.isfinite(view.stroke):
        return None, 'the finger opening is unknown: call gripper/home first'
    if not view.armed:
        return None, 'the gripper is not armed or not active (gripper/arm re-arms)'
    if view.competing:
        return None, f'{view.competing}; stop it first (slip_control/set_mode OFF)'
    upper = 0.5 * view.stroke
    if position < -params.position_margin or position > upper + params.position_margin:
        return None, (f'position {position:.4f} m outside [0, {upper:.4f}] m '
                      '(finger_1_joint = half the finger separation)')
    notes = []
    target = min(max(position, 0.0), upper)
    if target != position:
        notes.append(f'position clipped to {target:.4f} m')
    limit = max_effort if max_effort > 0.0 else params.default_effort
    if limit > view.max_grasp_force:
        notes.append(f'max_effort {limit:.1f} N clipped to {view.max_grasp_force:.1f} N')
        limit = view.max_grasp_force
    note = '; '.join(notes)
    return PositionGoal(2.0 * target, limit, note), note


class PositionCommand:
    """The outer loop for one goal; `step` once per telemetry line (module docstring).

    Args:
        goal: The validated goal.
        params: Loop settings.
    """

    def __init__(self, goal: PositionGoal,
                 params: PositionCommandParams = PositionCommandParams()) -> None:
        self.goal = goal
        self.params = params
        self._t0: float | None = None
        self._still_since: float | None = None
        self._sent: float | None = None
        self._cancel = ''
        self.outcome = Outcome.RUNNING
        self.message = ''
        self.final_force = 0.0
        self.last: PositionState | None = None

    @property
    def done(self) -> bool:
        """The goal has ended (`outcome` says how)."""
        return self.outcome != Outcome.RUNNING

    def cancel(self, reason: str = 'cancelled') -> None:
        """End at the next `step` with 0 N (a client cancel, a preemption)."""
        self._cancel = reason

    def abort(self, message: str, outcome: Outcome = Outcome.FAILED) -> None:
        """End now without another command (a refused command, a silent gripper, a newer
        goal taking over)."""
        if not self.done:
            self.outcome, self.message = outcome, message

    def step(self, s: PositionState) -> PositionStep:
        """Advance with one gripper sample; the returned force is to be commanded now."""
        if self.done:
            return PositionStep(None, self.outcome, self.message)
        self.last = s
        p, g = self.params, self.goal
        if self._t0 is None:
            self._t0 = s.stamp
        if self._cancel:
            return self._finish(Outcome.CANCELLED, 0.0, self._cancel)
        if not math.isfinite(s.opening):
            return self._finish(Outcome.FAILED, 0.0, 'the finger opening became unknown')
        error = s.opening - g.target_opening
        if abs(error) <= p.tolerance:
            hold = g.force_limit if s.in_contact else 0.0
            return self._finish(Outcome.REACHED, hold,
                                'reached' + (' on an object: holding' if hold else ''))
        if s.stamp - self._t0 > p.timeout:
            return self._finish(Outcome.TIMED_OUT, 0.0,
                                f'timed out after {p.timeout:.1f} s, {error * 1e3:+.1f} mm '
                                'from the target')
        moving = math.isfinite(s.opening_rate) and abs(s.opening_rate) >= p.stall_speed
        if moving or self._still_since is None:
            self._still_since = s.stamp if not moving else None
        elif s.stamp - self._still_since >= p.stall_time:
            closing = error > 0.0
            return self._finish(Outcome.STALLED, g.force_limit if closing else 0.0,
                                ('stalled closing: holding with '
                                 f'{g.force_limit:.1f} N') if closing else 'stalled opening')
        magnitude = min(max(p.gain * abs(error), p.min_force), g.force_limit)
        force = math.copysign(magnitude, error)
        if self._sent is not None and abs(force - self._sent) < p.min_command_change:
            return PositionStep(None, Outcome.RUNNING)
        self._sent = force
        return PositionStep(force, Outcome.RUNNING)

    def _finish(self, outcome: Outcome, force: float, message: str) -> PositionStep:
        self.outcome, self.message, self.final_force = outcome, message, force
        self._sent = force
        return PositionStep(force, outcome, message)


@dataclass(frozen=True)
class PositionReport:
    """What the action results and feedback report (SI).

    Attributes:
        position: ``finger_1_joint`` position [m] (half the opening; NaN if unknown).
        velocity: Its rate [m/s].
        effort: Measured per-finger grasp force [N], or the commanded force when the F/T
            gives none (not biased).
        stalled, reached_goal: As in ``control_msgs/GripperCommand``.
    """

    position: float
    velocity: float
    effort: float
    stalled: bool = False
    reached_goal: bool = False
    message: str = field(default='', compare=False)


def report(state: PositionState | None, command: PositionCommand | None,
           commanded_force: float = math.nan) -> PositionReport:
    """The action's view of ``state`` and, when given, of how ``command`` ended."""
    if state is None:
        return PositionReport(math.nan, math.nan, math.nan)
    effort = state.measured_force if math.isfinite(state.measured_force) else commanded_force
    outcome = command.outcome if command is not None else Outcome.RUNNING
    return PositionReport(0.5 * state.opening, 0.5 * state.opening_rate, effort,
                          stalled=outcome == Outcome.STALLED,
                          reached_goal=outcome == Outcome.REACHED,
                          message=command.message if command is not None else '')
