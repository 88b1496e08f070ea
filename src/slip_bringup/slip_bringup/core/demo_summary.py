# SPDX-License-Identifier: Apache-2.0
"""The demo's verdict and summary table, from what the run recorded (ROS-free, pure).

``slip_demo`` reads its bag and hands this module plain data: the slip controller's state
reasons (``slip_control/state``: when each LINEAR/ROTATIONAL trajectory started and how it
ended), the analysis of each tracked segment, the simulator's ground truth (``sim/state``),
every ``/diagnostics`` status and the runner's result. `build_verdict` decides:

* one row per **expected** slip segment (`demo_targets`: the demo's own targets, not ones
  guessed from the recorded reference), matched in order to the trajectories of its mode; a
  segment that never ran or left no tracking still gets its row;
* a row passes only when the controller said "done", the trajectory lasted at least
  ``min_duration_fraction`` of the requested duration (a 20° "rotation" done in 0.2 s of 2 s
  was the object spinning away, not a controlled slip) **and** the simulator's truth is within
  the stated tolerance of the target (`Tolerances`); otherwise it is FAILED with the reason
  ("velocity stale", "not run", "true object 2.1 mm, 17.9 mm short of 20.0 mm", …);
* the run fails when any row fails or the runner reported failure;
* the worst ``/diagnostics`` level seen and the achieved real-time factor are reported.

Units: SI inside (m, rad); the table prints mm and degrees.
"""
from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from slip_control.core.runner_sequences import (DEMO_ANGLE, DEMO_DISTANCE, DEMO_DURATION,
                                                SETTLE_AFTER_SLIP)

#: ``diagnostic_msgs/DiagnosticStatus`` levels.
OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVEL_NAMES = {OK: 'OK', WARN: 'WARN', ERROR: 'ERROR', STALE: 'STALE'}
#: Severity order for "worst": ERROR > WARN > STALE > OK.
_SEVERITY = {OK: 0, STALE: 1, WARN: 2, ERROR: 3}

_START = re.compile(r'^(?:set_mode|execute): (LINEAR|ROTATIONAL)\b')
_END = re.compile(r'^(LINEAR|ROTATIONAL) ended: (.*)$')
_MODES = {'LINEAR': 'linear', 'ROTATIONAL': 'rotational'}


@dataclass(frozen=True)
class Tolerances:
    """How far the simulator's truth may miss a slip target and still pass."""

    linear: float = 0.005               #: [m]
    angle: float = math.radians(5.0)    #: [rad]
    #: A trajectory that ends "done" sooner than this fraction of its requested duration ran
    #: away from its reference (the controller does not reach the target early by design).
    min_duration_fraction: float = 0.5

    def of(self, mode: str) -> float:
        """The tolerance of a ``'linear'`` or ``'rotational'`` segment [m | rad]."""
        return self.linear if mode == 'linear' else self.angle


@dataclass(frozen=True)
class Target:
    """One slip segment the run was asked for: ``value`` [m | rad] (magnitude) in
    ``duration`` [s] (0: not known, not judged)."""

    mode: str
    value: float
    duration: float = 0.0


@dataclass(frozen=True)
class Trajectory:
    """One LINEAR/ROTATIONAL trajectory found in the recording.

    Attributes:
        mode: ``'linear'`` or ``'rotational'``.
        t_start: Start [s, sim time] (the state change that started it).
        t_end: End [s], ``None`` if it never ended in the recording.
        outcome: The controller's message ("done", "velocity stale", …; '' if it never
            ended).
        controller: Final progress the controller measured [m | rad], if tracked.
        sensors: Final slip integrated from the velocity sensors [m | rad], if tracked.
        truth: Object motion per the simulator over the trajectory and the settling time
            [m | rad] (magnitude), if known.
    """

    mode: str
    t_start: float
    t_end: float | None
    outcome: str
    controller: float | None = None
    sensors: float | None = None
    truth: float | None = None


@dataclass(frozen=True)
class SegmentRow:
    """A target, the trajectory that served it (if any) and the verdict."""

    target: Target
    trajectory: Trajectory | None
    passed: bool
    reason: str


@dataclass(frozen=True)
class DiagnosticsSeen:
    """The worst ``/diagnostics`` level of the run and the statuses that had it."""

    level: int | None                 #: None: no diagnostics recorded
    statuses: tuple[str, ...] = ()    #: ``'name: message'``, distinct, first seen first
    count: int = 0                    #: status reports at that level

    @property
    def name(self) -> str:
        """``'ERROR'``, ``'WARN'``, … or ``'none recorded'``."""
        return LEVEL_NAMES.get(self.level, str(self.level)) if self.level is not None \
            else 'none recorded'


@dataclass(frozen=True)
class RealTimeFactor:
    """Achieved real-time factor (``sim/state.realtime_factor``, 1 s windows)."""

    mean: float
    minimum: float
    target: float


@dataclass(frozen=True)
class DemoVerdict:
    """Everything the summary prints and the exit code depends on."""

    rows: tuple[SegmentRow, ...]
    runner_success: bool
    runner_message: str
    diagnostics: DiagnosticsSeen
    rtf: RealTimeFactor
    failures: tuple[str, ...]

    @property
    def ok(self) -> bool:
        """Nothing failed."""
        return not self.failures


def demo_targets(mode: str, distance: float = 0.0, angle: float = 0.0,
                 duration: float = 0.0) -> tuple[Target, ...]:
    """The slip segments runner mode ``mode`` performs, with the targets it uses.

    ``demo``: linear then rotational, the goal's values or the demo defaults when 0;
    ``linear_slippage``/``rotational_slippage``: the goal's value; other modes: none.
    """
    if mode == 'demo':
        d = duration if duration > 0.0 else DEMO_DURATION
        return (Target('linear', distance if distance > 0.0 else DEMO_DISTANCE, d),
                Target('rotational', abs(angle) if abs(angle) > 0.0 else DEMO_ANGLE, d))
    if mode == 'linear_slippage':
        return (Target('linear', distance, duration),)
    if mode == 'rotational_slippage':
        return (Target('rotational', abs(angle), duration),)
    return ()


def trajectories_from_states(states: Iterable[tuple[float, bool, str]]) -> list[Trajectory]:
    """Trajectories from ``slip_control/state`` ``(stamp [s], goal_active, reason)`` in time
    order.

    A start is a reason ``set_mode: LINEAR …``/``execute: ROTATIONAL …``; the end is the next
    ``LINEAR ended: <outcome>`` (the controller's `SlipResult.message`), or the first state
    without an active goal (the reason then is the outcome, e.g. a preempting mode request).
    """
    out: list[Trajectory] = []
    running: Trajectory | None = None
    for stamp, goal_active, reason in states:
        start = _START.match(reason)
        end = _END.match(reason)
        if start and goal_active:
            if running is not None:            # replaced by a new trajectory
                out.append(Trajectory(running.mode, running.t_start, stamp,
                                      f'preempted ({reason})'))
            running = Trajectory(_MODES[start.group(1)], stamp, None, '')
        elif running is not None and (end or not goal_active):
            outcome = end.group(2).strip() if end else f'ended: {reason}'
            out.append(Trajectory(running.mode, running.t_start, stamp, outcome))
            running = None
    if running is not None:
        out.append(running)
    return out


def object_motion(mode: str, t: ArrayLike, x: ArrayLike, y: ArrayLike, theta: ArrayLike,
                  t0: float, t1: float, max_gap: float = 0.05) -> float | None:
    """|Object displacement| [m] (linear) or |rotation| [rad] between ``t0`` and ``t1`` [s]
    from the simulator's ``sim/state`` series; ``None`` unless samples lie within ``max_gap``
    [s] of both ends (a recording that stops early must not pass for a short slide)."""
    ts = np.asarray(t, dtype=np.float64)
    sel = (ts >= t0) & (ts <= t1)
    if int(sel.sum()) < 2:
        return None
    idx = np.flatnonzero(sel)
    i0, i1 = int(idx[0]), int(idx[-1])
    if ts[i0] - t0 > max_gap or t1 - ts[i1] > max_gap:
        return None
    if mode == 'linear':
        xs, ys = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        return float(math.hypot(xs[i1] - xs[i0], ys[i1] - ys[i0]))
    th = np.asarray(theta, dtype=np.float64)
    return float(abs(th[i1] - th[i0]))


def truth_window(traj: Trajectory, last_t: float) -> tuple[float, float]:
    """The sim-time window the truth of ``traj`` is read over: its start to its end plus the
    runner's settling time (`SETTLE_AFTER_SLIP`), or to ``last_t`` if it never ended."""
    end = traj.t_end + SETTLE_AFTER_SLIP if traj.t_end is not None else last_t
    return traj.t_start, end


def _fmt(mode: str, value: float) -> str:
    if mode == 'linear':
        return f'{value * 1e3:.1f} mm'
    return f'{math.degrees(value):.1f} deg'


def judge_segment(target: Target, traj: Trajectory | None, tol: Tolerances) -> SegmentRow:
    """Pass only when the controller said "done" and the truth is within tolerance."""
    if traj is None:
        return SegmentRow(target, None, False, 'not run (no trajectory recorded)')
    if traj.t_end is None:
        return SegmentRow(target, traj, False, 'did not end (no outcome recorded)')
    if traj.outcome != 'done':
        return SegmentRow(target, traj, False, traj.outcome or 'ended without an outcome')
    lasted = traj.t_end - traj.t_start
    shortest = tol.min_duration_fraction * target.duration
    if target.duration > 0.0 and lasted < shortest:
        return SegmentRow(target, traj, False, (
            f'done after {lasted:.2f} s of the requested {target.duration:.2f} s (at least '
            f'{shortest:.2f} s): the object ran away from the trajectory'))
    if traj.truth is None:
        return SegmentRow(target, traj, False,
                          'simulator truth not recorded over the whole segment')
    miss = traj.truth - target.value
    limit = tol.of(target.mode)
    if not abs(miss) <= limit:
        side = 'short of' if miss < 0.0 else 'beyond'
        return SegmentRow(target, traj, False, (
            f'true object {_fmt(target.mode, traj.truth)}, {_fmt(target.mode, abs(miss))} '
            f'{side} {_fmt(target.mode, target.value)} (tolerance '
            f'{_fmt(target.mode, limit)})'))
    return SegmentRow(target, traj, True, 'done, truth within tolerance')


def judge_segments(targets: Sequence[Target], trajectories: Sequence[Trajectory],
                   tol: Tolerances) -> tuple[SegmentRow, ...]:
    """Match the k-th target of each mode to the k-th trajectory of that mode and judge it."""
    by_mode: dict[str, list[Trajectory]] = {}
    for traj in trajectories:
        by_mode.setdefault(traj.mode, []).append(traj)
    used: dict[str, int] = {}
    rows = []
    for target in targets:
        k = used.get(target.mode, 0)
        used[target.mode] = k + 1
        candidates = by_mode.get(target.mode, [])
        rows.append(judge_segment(target, candidates[k] if k < len(candidates) else None, tol))
    return tuple(rows)


def worst_diagnostics(statuses: Iterable[tuple[int, str, str]],
                      keep: int = 5) -> DiagnosticsSeen:
    """The worst level among ``(level, name, message)`` reports and up to ``keep`` distinct
    ``name: message`` texts that had it."""
    worst: int | None = None
    texts: list[str] = []
    count = 0
    for level, name, message in statuses:
        level = int(level)
        if worst is None or _SEVERITY.get(level, 0) > _SEVERITY.get(worst, 0):
            worst, texts, count = level, [], 0
        if level == worst:
            count += 1
            text = f'{name}: {message}'
            if text not in texts and len(texts) < keep:
                texts.append(text)
    return DiagnosticsSeen(worst, tuple(texts), count)


def realtime_factor(values: Iterable[float], target: float) -> RealTimeFactor:
    """Mean and minimum of the finite ``sim/state.realtime_factor`` values (NaN if none)."""
    arr = np.array([v for v in values if math.isfinite(v)], dtype=np.float64)
    if arr.size == 0:
        return RealTimeFactor(math.nan, math.nan, target)
    return RealTimeFactor(float(arr.mean()), float(arr.min()), target)


def build_verdict(targets: Sequence[Target], trajectories: Sequence[Trajectory],
                  tol: Tolerances, runner_success: bool, runner_message: str,
                  diagnostics: DiagnosticsSeen, rtf: RealTimeFactor) -> DemoVerdict:
    """Judge every expected segment and the runner's result (see the module docstring)."""
    rows = judge_segments(targets, trajectories, tol)
    failures = [f'{r.target.mode} slip: {r.reason}' for r in rows if not r.passed]
    if not runner_success:
        failures.append(f'runner: {runner_message or "failed"}')
    return DemoVerdict(rows, runner_success, runner_message, diagnostics, rtf, tuple(failures))


def format_verdict(verdict: DemoVerdict, tol: Tolerances) -> list[str]:
    """The slip, diagnostics, real-time and result lines of the summary table."""
    lines = [f'Slip: target vs achieved (pass: controller "done" after at least '
             f'{tol.min_duration_fraction:.0%} of the requested duration and true object '
             f'within {_fmt("linear", tol.linear)} / {_fmt("rotational", tol.angle)}):']

    def cell(mode: str, value: float | None) -> str:
        return f'{_fmt(mode, abs(value)):>9}' if value is not None and math.isfinite(value) \
            else f'{"n/a":>9}'
    for row in verdict.rows:
        mode, traj = row.target.mode, row.trajectory
        dur = (f'{traj.t_end - traj.t_start:4.1f} s' if traj is not None and
               traj.t_end is not None else '  n/a')
        lines.append(
            f'  {mode:<10} target {cell(mode, row.target.value)}   controller '
            f'{cell(mode, traj.controller if traj else None)}   sensors '
            f'{cell(mode, traj.sensors if traj else None)}   true object '
            f'{cell(mode, traj.truth if traj else None)}   ({dur})   '
            + ('PASS' if row.passed else f'FAILED: {row.reason}'))
    if not verdict.rows:
        lines.append('  (no slip segment in this run)')
    d = verdict.diagnostics
    lines.append(f'Diagnostics: worst level {d.name}'
                 + (f' ({d.count} report(s)): ' + '; '.join(d.statuses) if d.statuses else ''))
    r = verdict.rtf
    lines.append(f'Real-time factor (sim/state): mean {r.mean:.2f}, minimum {r.minimum:.2f}, '
                 f'target {r.target:.2f}'
                 + (' (the host was too slow: the simulation slowed, no time was skipped)'
                    if math.isfinite(r.minimum) and r.minimum < 0.9 * r.target else ''))
    lines.append(f'Runner: success={verdict.runner_success}: {verdict.runner_message}')
    if verdict.ok:
        lines.append('RESULT: PASSED (every slip segment done within tolerance)')
    else:
        lines.append('RESULT: FAILED: ' + ' | '.join(verdict.failures))
    return lines
