# SPDX-License-Identifier: Apache-2.0
"""Position goals on the force-controlled gripper (`core.position_command`), ROS-free.

A quasi-static finger (speed = force / damping, the simulated actuator's law) stands in for the
gripper: positive force closes; an object of width ``w`` stops the fingers and then carries
the force.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import pytest

from slip_gripper_driver.core.position_command import (
    GripperView,
    Outcome,
    PositionCommand,
    PositionState,
    check_goal,
    report,
)

DAMPING = 185.6   # N·s/m (5 guide + k_FV·k_e/k_open of the simulated actuator)
DT = 0.002
VIEW = GripperView(homed=True, armed=True, stroke=0.08, max_grasp_force=40.0)


@dataclass
class Finger:
    opening: float
    object_width: float = 0.0
    force: float = 0.0
    rate: float = 0.0

    def step(self) -> None:
        before = self.opening
        self.opening = min(0.08, self.opening - DT * self.force / DAMPING)
        if self.object_width and self.opening < self.object_width:
            self.opening = self.object_width
        self.rate = (self.opening - before) / DT

    def state(self, t: float) -> PositionState:
        on_object = bool(self.object_width) and self.opening <= self.object_width + 1e-9
        load = max(self.force, 0.0) if on_object else 0.0
        return PositionState(t, self.opening, self.rate, load, load >= 0.5)


def _run(command: PositionCommand, finger: Finger, t_max: float = 15.0) -> float:
    t = 0.0
    while t < t_max:
        step = command.step(finger.state(t))
        if step.force is not None:
            finger.force = step.force
        if command.done:
            return t
        finger.step()
        t += DT
    raise AssertionError('goal did not end')


def test_goal_checks_name_the_reason() -> None:
    assert check_goal(0.02, 10.0, VIEW)[0] is not None
    goal, note = check_goal(0.02, 0.0, VIEW)
    assert goal is not None and goal.target_opening == 0.04 and goal.force_limit == 10.0
    goal, note = check_goal(0.0402, 100.0, VIEW)
    assert goal is not None and goal.target_opening == 0.08 and goal.force_limit == 40.0
    assert 'clipped' in note
    cases = {
        (0.05, 10.0, VIEW): 'outside [0, 0.0400] m',
        (math.nan, 10.0, VIEW): 'finite',
        (0.02, -1.0, VIEW): '>= 0',
        (0.02, 10.0, GripperView(False, True, math.nan, 40.0)): 'call gripper/home first',
        (0.02, 10.0, GripperView(True, False, 0.08, 40.0)): 'not armed',
        (0.02, 10.0, GripperView(True, True, 0.08, 40.0, 'the slip controller commanded')):
            'slip_control/set_mode OFF',
    }
    for (position, effort, view), reason in cases.items():
        goal, text = check_goal(position, effort, view)
        assert goal is None and reason in text, (position, effort, text)


def test_opens_and_closes_to_the_target_in_free_air() -> None:
    for start, target in ((0.08, 0.030), (0.02, 0.070)):
        finger = Finger(start)
        goal, _ = check_goal(target / 2.0, 10.0, VIEW)
        assert goal is not None
        command = PositionCommand(goal)
        _run(command, finger)
        assert command.outcome == Outcome.REACHED and command.final_force == 0.0
        assert finger.opening == pytest.approx(target, abs=command.params.tolerance)
        rep = report(finger.state(0.0), command)
        assert rep.reached_goal and not rep.stalled
        assert rep.position == pytest.approx(target / 2.0, abs=command.params.tolerance)


def test_closing_onto_an_object_stalls_and_holds_with_the_limit() -> None:
    finger = Finger(0.08, object_width=0.06)
    goal, _ = check_goal(0.0, 15.0, VIEW)
    assert goal is not None
    command = PositionCommand(goal)
    _run(command, finger)
    assert command.outcome == Outcome.STALLED and command.final_force == 15.0
    assert finger.opening == pytest.approx(0.06) and finger.force == 15.0
    rep = report(finger.state(0.0), command)
    assert rep.stalled and not rep.reached_goal and rep.effort == 15.0


def test_cancel_and_timeout_drop_the_force() -> None:
    finger = Finger(0.08)
    goal, _ = check_goal(0.0, 5.0, VIEW)
    assert goal is not None
    command = PositionCommand(goal)
    for i in range(50):
        step = command.step(finger.state(i * DT))
        finger.force = step.force if step.force is not None else finger.force
        finger.step()
    assert finger.force > 0.0 and finger.opening < 0.08
    command.cancel('cancelled by the client')
    step = command.step(finger.state(0.1))
    assert step.outcome == Outcome.CANCELLED and step.force == 0.0
    # A finger that moves too slowly to stall but never arrives times out.
    slow = PositionCommand(goal)
    slow.params = type(slow.params)(timeout=1.0, stall_speed=0.0)
    t = 0.0
    while not slow.done:
        slow.step(PositionState(t, 0.05, -1e-4, math.nan, False))
        t += DT
    assert slow.outcome == Outcome.TIMED_OUT and slow.final_force == 0.0
    assert 'timed out' in slow.message
