# SPDX-License-Identifier: Apache-2.0
"""The standard gripper actions on a gripper node: ``control_msgs`` GripperCommand and
ParallelGripperCommand, shared by ``gripper_driver`` and the simulator's ``sim_gripper``.

Both actions drive `core.position_command.PositionCommand` (semantics there: ``position`` =
``finger_1_joint`` [m] = half the finger separation, ``max_effort`` = per-finger grasp-force
limit [N]) through the driver's own bridge (`core.bridge.GripperBridge`, which the simulator
runs too):

* ``gripper/gripper_cmd`` (``control_msgs/action/GripperCommand``): the MoveIt gripper
  interface. Result and feedback: ``position`` [m], ``effort`` (measured grasp force [N], or
  the commanded force while the F/T is not biased), ``stalled``, ``reached_goal``.
* ``gripper/parallel_gripper_cmd`` (``control_msgs/action/ParallelGripperCommand``): the goal
  is a ``sensor_msgs/JointState`` naming ``finger_1_joint`` and/or ``finger_2_joint`` (with the
  frame prefix; no names = finger 1) with ``position`` and optionally ``effort`` (the limit);
  ``velocity`` is ignored (the speed follows from the force and the loop's approach-speed
  limit). Both joints, if given, must agree (finger 2 mimics finger 1). Results carry both
  joints' state.

Goals are checked when they arrive and **rejected** (the reason logged) when the opening is
unknown (call ``gripper/home``), the driver is disarmed or inactive, the slip controller is
commanding the grasp force, or the target is outside ``[0, stroke/2]``. Accepted goals end
``succeeded`` when reached or when the fingers stall closing (an object is held with
``max_effort``; ``stalled`` says so), ``aborted`` when stalled opening, timed out or when the
link fails, ``canceled`` on a cancel request (the command drops to 0 N). A newer goal preempts
the running one (aborted, "preempted").

Threads: `on_status` runs where the node handles telemetry lines (the driver's serial reader
thread, the simulator's simulation thread) and commands the bridge directly, at the line rate;
a 20 Hz steady-clock timer on the node's executor publishes feedback, forwards cancel requests
and completes the goal's future, which the (async) execute callback awaits. Nothing blocks an
executor thread, so this works on the simulator's single-threaded executor too.
"""
from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from control_msgs.action import GripperCommand, ParallelGripperCommand
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import CallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import JointState

from slip_cell_common.core import names
from slip_cell_common.time_conv import clock_seconds, seconds_to_stamp
from slip_gripper_driver.core.bridge import GripperBridge
from slip_gripper_driver.core.gripper_records import CommandResult, GripperStatusSnapshot, LinkState
from slip_gripper_driver.core.position_command import (
    GripperView,
    Outcome,
    PositionCommand,
    PositionCommandParams,
    PositionGoal,
    PositionReport,
    PositionState,
    check_goal,
    report,
)
from slip_msgs.msg import GraspForceCommand

#: The outer position loop's default settings.
DEFAULT_PARAMS = PositionCommandParams()
#: Feedback, cancel and completion poll period [s, steady clock] while a goal runs.
POLL_PERIOD_S = 0.05
#: A slip-controller command younger than this [s] means it is driving the grasp force.
COMPETING_COMMAND_AGE_S = 0.25
#: Extra wait beyond the goal timeout for a gripper that stopped reporting [s, steady clock].
STATUS_SILENCE_MARGIN_S = 2.0


class BridgePort:
    """The gripper seen through its `GripperBridge` (driver or simulated cell).

    Args:
        bridge: Returns the bridge, or None while the node is not configured.
        now: Node time [s] (simulated time in the simulator).
    """

    def __init__(self, bridge: Callable[[], GripperBridge | None],
                 now: Callable[[], float]) -> None:
        self._bridge = bridge
        self._now = now

    def view(self) -> GripperView:
        """Homed, armed, stroke, force limit and competing commands, now."""
        bridge = self._bridge()
        if bridge is None:
            return GripperView(False, False, math.nan, 0.0)
        d = bridge.diagnostics(self._now())
        result = bridge.homing.result
        competing = ''
        if d.command_source == GraspForceCommand.SOURCE_SLIP_CONTROLLER and \
                d.command_age_s < COMPETING_COMMAND_AGE_S:
            competing = f'the slip controller commanded the grasp force {d.command_age_s:.2f} s ago'
        return GripperView(homed=result is not None,
                           armed=d.armed and d.link_state == LinkState.OK,
                           stroke=result.stroke if result is not None else math.nan,
                           max_grasp_force=bridge.params.force_control.max_grasp_force,
                           competing=competing)

    def command(self, force: float, t: float) -> CommandResult:
        """Grasp-force command [N] at ``t`` [s], valid until replaced (source MANUAL)."""
        bridge = self._bridge()
        if bridge is None:
            return CommandResult(False, 'not configured')
        return bridge.set_grasp_force(force, t, source=GraspForceCommand.SOURCE_MANUAL)


@dataclass
class _Run:
    """One accepted goal."""

    handle: ServerGoalHandle
    command: PositionCommand
    kind: str
    started: float
    future: Future = field(default_factory=Future)
    commanded: float = math.nan


def _state(s: GripperStatusSnapshot) -> PositionState:
    return PositionState(s.stamp, s.opening, s.opening_rate, s.measured_grasp_force,
                         s.in_contact)


class GripperActionServers:
    """``gripper/gripper_cmd`` and ``gripper/parallel_gripper_cmd`` on ``node``.

    Args:
        node: The gripper node.
        port: The gripper (`BridgePort`).
        joint_names: ``(finger_1_joint, finger_2_joint)`` with the frame prefix.
        callback_group: Group of the action servers and the poll timer.
        params: Outer position loop settings.
    """

    def __init__(self, node: Node, port: BridgePort, joint_names: tuple[str, str], *,
                 callback_group: CallbackGroup | None = None,
                 params: PositionCommandParams = DEFAULT_PARAMS) -> None:
        self._node = node
        self._port = port
        self._joints = joint_names
        self._params = params
        self._lock = threading.Lock()
        self._runs: list[_Run] = []
        self._active: _Run | None = None
        self._latest: PositionState | None = None
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = node.create_timer(POLL_PERIOD_S, self._poll, clock=self._steady,
                                        callback_group=callback_group, autostart=False)
        self._servers = [
            ActionServer(node, GripperCommand, names.GRIPPER_COMMAND_ACTION,
                         execute_callback=self._execute_gripper,
                         goal_callback=lambda g: self._on_goal(g, 'gripper'),
                         cancel_callback=self._on_cancel, callback_group=callback_group),
            ActionServer(node, ParallelGripperCommand, names.PARALLEL_GRIPPER_COMMAND_ACTION,
                         execute_callback=self._execute_parallel,
                         goal_callback=lambda g: self._on_goal(g, 'parallel'),
                         cancel_callback=self._on_cancel, callback_group=callback_group),
        ]

    def destroy(self) -> None:
        """End running goals (aborted) and destroy both servers and the timer."""
        with self._lock:
            for run in self._runs:
                run.command.abort('the gripper node is shutting down')
        self._poll()
        for server in self._servers:
            server.destroy()
        self._node.destroy_timer(self._timer)

    # ------------------------------------------------------------------ telemetry thread
    def on_status(self, status: GripperStatusSnapshot) -> None:
        """One telemetry line (any thread): step the running goal and command the bridge."""
        state = _state(status)
        with self._lock:
            self._latest = state
            run = self._active
            if run is None or run.command.done:
                return
            step = run.command.step(state)
            if step.force is None:
                return
            result = self._port.command(step.force, status.stamp)
            if result.accepted:
                run.commanded = step.force
            elif not run.command.done:
                run.command.abort(f'grasp-force command refused: {result.reason}')

    # ------------------------------------------------------------------ goals
    def _goal_of(self, request: Any, kind: str) -> tuple[PositionGoal | None, str]:
        if kind == 'gripper':
            position, effort = request.command.position, request.command.max_effort
        else:
            parsed = self._parallel_goal(request.command)
            if isinstance(parsed, str):
                return None, parsed
            position, effort = parsed
        return check_goal(position, effort, self._port.view(), self._params)

    def _parallel_goal(self, js: JointState) -> tuple[float, float] | str:
        """``(position, max_effort)`` of a ParallelGripperCommand goal, or the reason it is bad."""
        if not js.position:
            return 'the goal JointState has no position'
        joint_names = list(js.name) or [self._joints[0]]
        if len(joint_names) != len(js.position):
            return f'{len(joint_names)} names but {len(js.position)} positions'
        unknown = [n for n in joint_names if n not in self._joints]
        if unknown:
            return f'unknown joints {unknown}: this gripper has {list(self._joints)}'
        positions = [float(p) for p in js.position]
        if max(positions) - min(positions) > self._params.position_margin:
            return (f'finger positions {positions} differ: {self._joints[1]} mimics '
                    f'{self._joints[0]}, both move together')
        efforts = [float(e) for e in js.effort] if js.effort else [0.0]
        return positions[0], max(efforts)

    def _on_goal(self, request: Any, kind: str) -> GoalResponse:
        goal, note = self._goal_of(request, kind)
        action = self._name(kind)
        if goal is None:
            self._node.get_logger().warning(f'{action}: goal rejected: {note}')
            return GoalResponse.REJECT
        self._node.get_logger().info(
            f'{action}: goal accepted: opening {goal.target_opening * 1e3:.1f} mm, '
            f'force limit {goal.force_limit:.1f} N' + (f' ({note})' if note else ''))
        return GoalResponse.ACCEPT

    def _on_cancel(self, handle: ServerGoalHandle) -> CancelResponse:
        del handle
        return CancelResponse.ACCEPT

    async def _execute_gripper(self, handle: ServerGoalHandle) -> GripperCommand.Result:
        return await self._execute(handle, 'gripper')

    async def _execute_parallel(self, handle: ServerGoalHandle
                                ) -> ParallelGripperCommand.Result:
        return await self._execute(handle, 'parallel')

    async def _execute(self, handle: ServerGoalHandle, kind: str) -> Any:
        goal, reason = self._goal_of(handle.request, kind)
        if goal is None:   # the gripper changed since the goal was accepted
            handle.abort()
            self._node.get_logger().warning(f'{self._name(kind)}: aborted: {reason}')
            return self._result(kind, report(self._latest, None), reason)
        run = _Run(handle, PositionCommand(goal, self._params), kind,
                   clock_seconds(self._steady))
        with self._lock:
            previous = self._active
            if previous is not None and not previous.command.done:
                previous.command.abort('preempted by a newer goal', Outcome.CANCELLED)
            self._active = run
            self._runs.append(run)
        self._timer.reset()
        final: PositionReport = await run.future
        outcome = run.command.outcome
        log = self._node.get_logger()
        text = f'{self._name(kind)}: {final.message} at {final.position * 2e3:.1f} mm opening'
        if outcome == Outcome.CANCELLED and handle.is_cancel_requested:
            handle.canceled()
            log.info(text)
        elif outcome == Outcome.REACHED or (outcome == Outcome.STALLED and
                                            run.command.final_force > 0.0):
            handle.succeed()
            log.info(text)
        else:
            handle.abort()
            log.warning(text)
        return self._result(kind, final, final.message)

    def _poll(self) -> None:
        """Executor thread: cancel requests, feedback, completion of finished goals."""
        wall = clock_seconds(self._steady)
        finished: list[tuple[_Run, PositionReport]] = []
        feedback: list[tuple[_Run, PositionReport]] = []
        with self._lock:
            for run in list(self._runs):
                command = run.command
                if not command.done:
                    if run.handle.is_cancel_requested:
                        command.cancel('cancelled by the client')
                        self._send_now(run, 0.0)
                    elif wall - run.started > self._params.timeout + STATUS_SILENCE_MARGIN_S:
                        command.abort('no gripper status: the link is down or the node stopped')
                if command.done:
                    self._runs.remove(run)
                    if self._active is run:
                        self._active = None
                    finished.append((run, report(command.last or self._latest, command,
                                                 run.commanded)))
                elif run is self._active:
                    feedback.append((run, report(self._latest, None, run.commanded)))
            idle = not self._runs
        for run, rep in feedback:
            run.handle.publish_feedback(self._feedback(run.kind, rep))
        for run, rep in finished:
            if not run.future.done():
                run.future.set_result(rep)
        if idle:
            self._timer.cancel()

    def _send_now(self, run: _Run, force: float) -> None:
        """Command ``force`` outside the telemetry thread (cancel), stamped with the last line."""
        stamp = self._latest.stamp if self._latest is not None else 0.0
        if self._port.command(force, stamp).accepted:
            run.commanded = force

    # ------------------------------------------------------------------ messages
    @staticmethod
    def _name(kind: str) -> str:
        return names.GRIPPER_COMMAND_ACTION if kind == 'gripper' else \
            names.PARALLEL_GRIPPER_COMMAND_ACTION

    def _joint_state(self, rep: PositionReport) -> JointState:
        state = self._latest
        msg = JointState(name=list(self._joints), position=[rep.position] * 2,
                         velocity=[rep.velocity] * 2, effort=[rep.effort] * 2)
        if state is not None:
            msg.header.stamp = seconds_to_stamp(state.stamp)
        return msg

    def _result(self, kind: str, rep: PositionReport, message: str) -> Any:
        del message  # logged; neither result type has a message field
        if kind == 'gripper':
            return GripperCommand.Result(position=rep.position, effort=rep.effort,
                                         stalled=rep.stalled, reached_goal=rep.reached_goal)
        return ParallelGripperCommand.Result(state=self._joint_state(rep), stalled=rep.stalled,
                                             reached_goal=rep.reached_goal)

    def _feedback(self, kind: str, rep: PositionReport) -> Any:
        if kind == 'gripper':
            return GripperCommand.Feedback(position=rep.position, effort=rep.effort,
                                           stalled=False, reached_goal=False)
        return ParallelGripperCommand.Feedback(state=self._joint_state(rep))
