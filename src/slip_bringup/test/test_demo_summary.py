# SPDX-License-Identifier: Apache-2.0
"""The demo's verdict (issue 16): no success claimed when a slip failed or missed its target;
the rows carry the demo's own targets, one per expected segment; the worst diagnostics level
and the achieved real-time factor are reported."""
from __future__ import annotations

import math

import numpy as np
import pytest

from slip_bringup.core.demo_summary import (
    ERROR,
    OK,
    STALE,
    WARN,
    DiagnosticsSeen,
    RealTimeFactor,
    Target,
    Tolerances,
    Trajectory,
    build_verdict,
    demo_targets,
    format_verdict,
    judge_segments,
    object_motion,
    realtime_factor,
    trajectories_from_states,
    worst_diagnostics,
)

TOL = Tolerances(linear=0.005, angle=math.radians(5.0))
DIAG_OK = DiagnosticsSeen(OK, ('sim_gripper: realtime_factor: running',), 3)
RTF = RealTimeFactor(1.0, 0.97, 1.0)

#: The controller's state reasons of the issue's run: both slips ended "velocity stale".
STALE_RUN = [
    (10.0, False, 'set_mode: HOLD'),
    (14.1, True, 'set_mode: LINEAR 0.0200 m in 2.000 s, direction latched'),
    (15.4, False, 'LINEAR ended: velocity stale'),
    (15.5, False, 'velocity stale: slip term 0, no decrease'),
    (21.4, False, 'set_mode: HINGE'),
    (23.3, False, 'HINGE ended: velocity stale'),
    (36.3, True, 'execute: ROTATIONAL 0.3491 rad in 2.000 s, sign latched'),
    (36.35, False, 'ROTATIONAL ended: velocity stale'),
]


def _done(mode: str, truth: float, t0: float = 1.0) -> Trajectory:
    return Trajectory(mode, t0, t0 + 2.0, 'done', controller=truth, sensors=truth, truth=truth)


def test_demo_targets_are_the_demos_own() -> None:
    assert demo_targets('demo') == (Target('linear', 0.02, 2.0),
                                    Target('rotational', pytest.approx(math.radians(20.0)), 2.0))
    assert demo_targets('demo', 0.04, -1.0, 3.0) == (Target('linear', 0.04, 3.0),
                                                     Target('rotational', 1.0, 3.0))
    assert demo_targets('linear_slippage', 0.03, duration=2.5) == (Target('linear', 0.03, 2.5),)
    assert demo_targets('rotational_slippage', angle=-0.5) == (Target('rotational', 0.5),)
    assert demo_targets('grasp') == ()


def test_trajectories_and_their_outcomes_come_from_the_state_reasons() -> None:
    trajs = trajectories_from_states(STALE_RUN)
    assert [(t.mode, t.t_start, t.t_end, t.outcome) for t in trajs] == [
        ('linear', 14.1, 15.4, 'velocity stale'),
        ('rotational', 36.3, 36.35, 'velocity stale')]
    # Preempted by a mode request (no "ended" reason), and one still running at the end.
    trajs = trajectories_from_states([
        (1.0, True, 'execute: LINEAR 0.0200 m in 2.000 s'),
        (1.5, False, 'set_mode: HOLD'),
        (2.0, True, 'set_mode: ROTATIONAL 0.3 rad in 2.000 s')])
    assert [(t.mode, t.t_end, t.outcome) for t in trajs] == [
        ('linear', 1.5, 'ended: set_mode: HOLD'), ('rotational', None, '')]


def test_the_issues_run_is_failed_with_both_rows_and_their_reasons() -> None:
    """Issue 16: linear stopped at 2.1 of 20 mm, rotational at 0 of 20 deg, both "velocity
    stale"; the runner said success. The verdict fails and names both segments."""
    trajs = [Trajectory(t.mode, t.t_start, t.t_end, t.outcome, 0.0021, 0.0021, 0.0021)
             if t.mode == 'linear' else t for t in trajectories_from_states(STALE_RUN)]
    verdict = build_verdict(demo_targets('demo'), trajs, TOL, True, 'demo done', DIAG_OK, RTF)
    assert not verdict.ok
    assert [(r.target.mode, r.passed, r.reason) for r in verdict.rows] == [
        ('linear', False, 'velocity stale'), ('rotational', False, 'velocity stale')]
    assert verdict.failures == ('linear slip: velocity stale', 'rotational slip: velocity stale')
    text = '\n'.join(format_verdict(verdict, TOL))
    assert 'linear     target   20.0 mm' in text           # the demo's target, not a guess
    assert 'rotational target  20.0 deg' in text           # the row exists without tracking
    assert text.count('FAILED: velocity stale') == 2
    assert 'RESULT: FAILED: linear slip: velocity stale | rotational slip: velocity stale' \
        in text


def test_a_done_slip_whose_truth_misses_the_target_fails() -> None:
    targets = demo_targets('demo')
    trajs = [_done('linear', 0.0265), _done('rotational', math.radians(19.0), t0=5.0)]
    rows = judge_segments(targets, trajs, TOL)
    assert not rows[0].passed and rows[1].passed
    assert rows[0].reason == ('true object 26.5 mm, 6.5 mm beyond 20.0 mm '
                              '(tolerance 5.0 mm)')
    short = judge_segments(targets[:1], [_done('linear', 0.012)], TOL)[0]
    assert not short.passed and '8.0 mm short of 20.0 mm' in short.reason
    # Within tolerance both ways: passes; an impossible tolerance fails the same run.
    good = [_done('linear', 0.0212), _done('rotational', math.radians(21.0), t0=5.0)]
    verdict = build_verdict(targets, good, TOL, True, 'demo done', DIAG_OK, RTF)
    assert verdict.ok and verdict.failures == ()
    assert format_verdict(verdict, TOL)[-1] == \
        'RESULT: PASSED (every slip segment done within tolerance)'
    strict = build_verdict(targets, good, Tolerances(linear=1e-4, angle=1e-4), True,
                           'demo done', DIAG_OK, RTF)
    assert not strict.ok and len(strict.failures) == 2


def test_a_slip_done_far_sooner_than_requested_ran_away_and_fails() -> None:
    """A controller starved on a loaded host: 20 deg "done" in 0.2 s of 2 s (the object spun
    in the pads; truth 22.1 deg, within the angle tolerance). Not a controlled slip."""
    targets = demo_targets('demo')
    spun = Trajectory('rotational', 35.56, 35.76, 'done', math.radians(21.7),
                      math.radians(21.4), math.radians(22.1))
    row = judge_segments(targets[1:], [spun], TOL)[0]
    assert not row.passed
    assert row.reason == ('done after 0.20 s of the requested 2.00 s (at least 1.00 s): '
                          'the object ran away from the trajectory')
    # A trajectory that ends a little early (the controller's tolerance) still passes.
    early = Trajectory('rotational', 35.0, 36.8, 'done', 0.35, 0.35, math.radians(20.1))
    assert judge_segments(targets[1:], [early], TOL)[0].passed
    # Without a requested duration the rule does not apply.
    unknown = judge_segments((Target('rotational', spun.truth),), [spun], TOL)[0]
    assert unknown.passed


def test_missing_segments_and_a_failed_runner_fail_the_run() -> None:
    targets = demo_targets('demo')
    verdict = build_verdict(targets, [_done('linear', 0.02)], TOL, False,
                            "demo: step 'LINEAR slip' failed: contact lost", DIAG_OK, RTF)
    assert [r.passed for r in verdict.rows] == [True, False]
    assert verdict.rows[1].reason == 'not run (no trajectory recorded)'
    assert verdict.failures[-1] == "runner: demo: step 'LINEAR slip' failed: contact lost"
    unfinished = Trajectory('linear', 1.0, None, '')
    assert judge_segments(targets[:1], [unfinished], TOL)[0].reason == \
        'did not end (no outcome recorded)'
    no_truth = Trajectory('linear', 1.0, 3.0, 'done', 0.02, 0.02, None)
    assert judge_segments(targets[:1], [no_truth], TOL)[0].reason == \
        'simulator truth not recorded over the whole segment'


def test_worst_diagnostics_level() -> None:
    seen = worst_diagnostics([
        (OK, 'sim_gripper: realtime_factor', 'running'),
        (WARN, 'slip_controller: contact', 'no contact properties received'),
        (STALE, 'sim_gripper: scenario', 'not configured'),
        (ERROR, 'slip_controller: inputs', 'stale inputs while controlling (velocity)'),
        (WARN, 'sim_gripper: realtime_factor', 'real-time factor 0.36 below target'),
        (ERROR, 'slip_controller: inputs', 'stale inputs while controlling (velocity)'),
    ])
    assert seen.name == 'ERROR' and seen.count == 2
    assert seen.statuses == ('slip_controller: inputs: stale inputs while controlling '
                             '(velocity)',)
    assert worst_diagnostics([(STALE, 'a', 'b'), (OK, 'c', 'd')]).name == 'STALE'
    assert worst_diagnostics([]).name == 'none recorded'
    verdict = build_verdict((), (), TOL, True, 'grasp done', seen, RTF)
    assert verdict.ok                                  # diagnostics are reported, not judged
    line = next(x for x in format_verdict(verdict, TOL) if x.startswith('Diagnostics'))
    assert line.startswith('Diagnostics: worst level ERROR (2 report(s)): slip_controller')


def test_achieved_realtime_factor() -> None:
    rtf = realtime_factor([math.nan, 0.9, 0.36, 0.6], 1.0)
    assert rtf.mean == pytest.approx(0.62) and rtf.minimum == pytest.approx(0.36)
    verdict = build_verdict((), (), TOL, True, 'x', DIAG_OK, rtf)
    line = next(x for x in format_verdict(verdict, TOL) if x.startswith('Real-time'))
    assert line.startswith('Real-time factor (sim/state): mean 0.62, minimum 0.36, target 1.00')
    assert 'the simulation slowed, no time was skipped' in line
    assert math.isnan(realtime_factor([], 1.0).mean)


def test_object_motion_from_the_ground_truth() -> None:
    t = np.arange(0.0, 3.0, 0.01)
    x = np.zeros_like(t)
    y = np.where(t < 1.0, 0.0, np.minimum(t - 1.0, 1.0) * -0.02)   # slides 20 mm in 1..2 s
    theta = np.where(t < 1.0, 0.0, np.minimum(t - 1.0, 1.0) * 0.3)
    assert object_motion('linear', t, x, y, theta, 0.5, 2.5) == pytest.approx(0.02)
    assert object_motion('rotational', t, x, y, theta, 0.5, 2.5) == pytest.approx(0.3)
    assert object_motion('linear', t, x, y, theta, 5.0, 6.0) is None
    # Samples that stop before the window's end (a recorder that fell behind): no truth.
    assert object_motion('rotational', t[t < 1.5], x, y, theta, 0.5, 2.5) is None
