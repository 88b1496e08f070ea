# SPDX-License-Identifier: Apache-2.0
"""``experiment_runner``: the experiment sequences of control_and_estimation §5 as an action.

Serves ``experiment/run`` (``slip_msgs/RunExperiment``): builds the mode's step data with
`slip_control.core.runner_sequences.build_sequence` and executes it with
`slip_control.core.sequence_runner.SequenceRunner` over `RosCell`, a `CellInterface` made of
ROS calls:

=======================  ======================================================================
grasp force              ``gripper/grasp_force_cmd`` (COMMAND; source EXPERIMENT_RUNNER,
                         ``timeout = 0``: valid until replaced)
slip mode                ``slip_control/set_mode`` (a refusal fails the step with its message)
slip segment             ``slip_control/execute`` (LINEAR, ROTATIONAL: the step ends with the
                         trajectory and reports its outcome; cancelled when the runner gives
                         up on it)
estimation               ``contact/start``, ``contact/get_properties``
F/T bias                 ``gripper/bias_ft``
arm                      the ``arm.backend`` (`slip_control.arm_backends`: mock, sim, ur)
recording                in-process `TopicRecorder` under ``recording.directory``
=======================  ======================================================================

Nothing blocks the executor: service calls are futures polled by a steady-clock timer (100 Hz;
500 Hz while the §5.4 force profile is commanded); the step machine runs on the node clock (sim
time under ``use_sim_time``), and every step is time-limited (``step_timeout`` beyond its own
duration) with a message naming the step and what it waited for. The action's execute
coroutine awaits a future that the timer completes, on the same single-threaded executor.

Goal handling: a goal is checked when it arrives and **rejected** (reason logged and kept in
the ``goals`` diagnostics: the action protocol's goal response has no text field) when another
runs ("busy"), the mode or its arguments are invalid, the recording name is bad, or the cell
flags miss the mode's leading preconditions (the reason names the runner modes that set them,
e.g. "run 'grasp' or 'pick_up_object' first"). Feedback (``phase`` = current step name,
``elapsed`` [s]) on every step change and at least once a second, each step's outcome logged;
the result carries ``success``, the message (the failing step and why), the last contact
properties read (NaN/DEFAULT when none) and the bag path. Cancel aborts the
remaining steps; the cleanup steps (stop recording, …) still run. A node clock that stops
advancing for ``step_timeout`` (e.g. no ``/clock``) aborts the run. The cell flags (holding,
at pick-up pose, …) and the tool offset persist between goals.

Honest results: every slip segment's outcome is logged and listed in the result message; a
segment that failed (e.g. "velocity stale", "stalled: …") makes the result ``success =
false`` naming it, although the remaining segments still run. A lost object — the arm
backend's drop detection (``sim/state.object_dropped``) while holding, or a slip that ended
"contact lost" — stops the sequence and marks the object lost (``object_dropped``): later
goals that need it are refused naming the re-grasp steps (``release``, ``go_to_object``,
``grasp``) instead of being aborted at once, and ``go_to_object`` puts it back (the simulated
cell resets its scene there; on hardware the operator places the object at the pick-up
pose). ``demo`` does this by itself when it starts after a drop.
"""
from __future__ import annotations

import math
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.task import Future
from slip_msgs.action import ExecuteSlip, RunExperiment
from slip_msgs.msg import GraspForceCommand
from slip_msgs.srv import GetContactProperties, SetSlipMode, StartEstimation
from std_srvs.srv import Trigger

from slip_control.arm_backends import ArmBackend, ArmUnavailableError, ServiceCall, make_arm
from slip_control.core.contact import ContactProperties
from slip_control.core.contact_estimator import EstimationPhase
from slip_control.core.controllers import SlipMode, SlipResult
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.params import ExperimentRunnerParams
from slip_control.core.runner_cell import CallResult, CallReturn, describe_read
from slip_control.core.runner_sequences import RECORDING_MODES, build_sequence
from slip_control.core.runner_steps import FLAG_NAMES, Sequence
from slip_control.core.sequence_runner import (CellFlags, PoseOffset, RunnerProgress,
                                               SequenceRunner, preflight)
from slip_control.slip_msgs_conv import (grasp_force_command, properties_from_msg,
                                         properties_to_msg)
from slip_cell_common.bag_io import default_bag_directory
from slip_cell_common.diagnostics import DiagnosticsPublisher
from slip_cell_common.core import names
from slip_cell_common.node_main import run_node
from slip_cell_common.param_binding import ParameterBinding
from slip_cell_common.qos import COMMAND, overridable
from slip_cell_common.recorder import TopicRecorder
from slip_cell_common.time_conv import (clock_seconds, nanoseconds_to_stamp,
                                        seconds_to_nanoseconds)
from slip_cell_common.core.monitors import Level, Report
from slip_cell_common.core.param_schema import ParameterError

#: Poll period of a running sequence [s, steady clock].
POLL_PERIOD_S = 0.01
#: Poll period while the §5.4 force profile is commanded (500 Hz) [s, steady clock].
FAST_POLL_PERIOD_S = 0.002
#: Feedback is sent on every step change and at least this often [s, steady clock].
FEEDBACK_PERIOD_S = 1.0

_NAME_RE = re.compile(r'^[A-Za-z0-9][A-Za-z0-9_.-]*$')


class ActionCall:
    """An action goal as a runner `Pending`: sent once the server is up, done with its result.

    Args:
        client: rclpy action client.
        name: The action's name (messages).
        goal: Goal message.
        convert: ``(status, result message)`` → `CallResult` (``status``: a
            ``GoalStatus.STATUS_*`` value).
    """

    def __init__(self, client: ActionClient, name: str, goal: Any,
                 convert: Callable[[int, Any], CallResult]) -> None:
        self._client = client
        self._name = name
        self._goal = goal
        self._convert = convert
        self._sent: Any = None
        self._result: Any = None
        self._send()

    def _send(self) -> None:
        if self._sent is None and self._client.server_is_ready():
            self._sent = self._client.send_goal_async(self._goal)

    def _handle(self) -> Any:
        if self._sent is None or not self._sent.done() or self._sent.exception() is not None:
            return None
        return self._sent.result()

    def done(self) -> bool:
        """The goal was refused or its result arrived."""
        self._send()
        if self._sent is None or not self._sent.done():
            return False
        handle = self._handle()
        if handle is None or not handle.accepted:
            return True
        if self._result is None:
            self._result = handle.get_result_async()
        return self._result.done()

    def result(self) -> CallResult:
        """The converted result, or a failure naming the action."""
        handle = self._handle()
        if handle is None:
            return CallResult(False, f'action {self._name} failed: {self._sent.exception()!r}')
        if not handle.accepted:
            return CallResult(False, f'action {self._name}: goal rejected')
        if self._result.exception() is not None or self._result.result() is None:
            return CallResult(False, f'action {self._name} returned no result')
        response = self._result.result()
        return self._convert(int(response.status), response.result)

    def describe(self) -> str:
        """What the call is waiting for (timeout messages)."""
        if self._sent is None:
            return f'action {self._name} not available'
        if self._result is None:
            return f'no goal response from action {self._name}'
        return f'no result from action {self._name}'

    def cancel(self) -> None:
        """Cancel the goal (the runner gave up on it; the controller falls back to HOLD)."""
        handle = self._handle()
        if handle is not None and handle.accepted and \
                (self._result is None or not self._result.done()):
            handle.cancel_goal_async()


class RosCell:
    """`CellInterface` over ROS topics, services, the arm backend and the recorder.

    Args:
        node: The runner node.
        arm: Arm backend.
        params: Returns the current runner parameters.
    """

    def __init__(self, node: Node, arm: ArmBackend,
                 params: Any) -> None:
        self._node = node
        self.arm = arm
        self._params = params
        self._cmd = node.create_publisher(GraspForceCommand, names.GRASP_FORCE_CMD, COMMAND,
                                          qos_overriding_options=overridable())
        self._set_mode = node.create_client(SetSlipMode, names.SLIP_SET_MODE_SRV)
        self._start = node.create_client(StartEstimation, names.CONTACT_START_SRV)
        self._get = node.create_client(GetContactProperties, names.CONTACT_GET_PROPERTIES_SRV)
        self._bias = node.create_client(Trigger, names.GRIPPER_BIAS_FT_SRV)
        self._execute = ActionClient(node, ExecuteSlip, names.SLIP_EXECUTE_ACTION)
        self.recorder: TopicRecorder | None = None

    def destroy(self) -> None:
        """Release the action client (rclpy does not destroy it with the node)."""
        self._execute.destroy()

    def command_force(self, force: float, t: float) -> CallReturn:
        """Publish a grasp-force command [N] valid until replaced (``timeout = 0``)."""
        self._cmd.publish(grasp_force_command(
            force, 0.0, nanoseconds_to_stamp(self._node.get_clock().now().nanoseconds),
            GraspForceCommand.SOURCE_EXPERIMENT_RUNNER))
        return CallResult(True, f'{force:.2f} N commanded')

    def set_slip_mode(self, request: ModeRequest, t: float) -> CallReturn:
        """``slip_control/set_mode``; a refusal fails the step with the controller's reason."""
        req = SetSlipMode.Request(mode=int(request.mode), duration=float(request.duration),
                                  distance=float(request.distance), angle=float(request.angle),
                                  latch_direction=bool(request.latch_direction),
                                  control_law=request.control_law)
        req.direction.x, req.direction.y, req.direction.z = (float(v) for v in request.direction)
        return ServiceCall(self._set_mode, req, lambda r: CallResult(
            bool(r.success),
            r.message if r.success else f'{names.SLIP_SET_MODE_SRV}: {r.message}'))

    def execute_slip(self, request: ModeRequest, t: float) -> CallReturn:
        """``slip_control/execute``: done when the trajectory ends; ``value`` = `SlipResult`."""
        goal = ExecuteSlip.Goal(mode=int(request.mode), duration=float(request.duration),
                                distance=float(request.distance), angle=float(request.angle),
                                latch_direction=bool(request.latch_direction),
                                control_law=request.control_law)
        goal.direction.x, goal.direction.y, goal.direction.z = \
            (float(v) for v in request.direction)
        mode = SlipMode(int(request.mode))

        def convert(status: int, r: Any) -> CallResult:
            if status == GoalStatus.STATUS_CANCELED:
                return CallResult(False, f'{names.SLIP_EXECUTE_ACTION}: canceled')
            result = SlipResult(mode, bool(r.success), str(r.message), float(r.final_pos),
                                float(r.final_error), float(r.elapsed))
            ok = status == GoalStatus.STATUS_SUCCEEDED and result.success
            return CallResult(ok, result.message, value=result)
        return ActionCall(self._execute, names.SLIP_EXECUTE_ACTION, goal, convert)

    def start_estimation(self, phase: EstimationPhase, duration: float, t: float) -> CallReturn:
        """``contact/start``; a refusal fails the step with the estimator's reason."""
        req = StartEstimation.Request(phase=int(phase), duration=float(duration))
        return ServiceCall(self._start, req, lambda r: CallResult(
            bool(r.accepted),
            r.message if r.accepted else f'{names.CONTACT_START_SRV}: {r.message}'))

    def read_properties(self, t: float) -> CallReturn:
        """``contact/get_properties``; ``value`` = `ContactProperties` (valid or not)."""
        def convert(r: Any) -> CallResult:
            try:
                props = properties_from_msg(r.properties)
            except ValueError as exc:
                return CallResult(False, f'{names.CONTACT_GET_PROPERTIES_SRV}: {exc}')
            return CallResult(True, describe_read(props, str(r.message)), value=props)
        return ServiceCall(self._get, GetContactProperties.Request(), convert)

    def bias_ft(self, t: float) -> CallReturn:
        """``gripper/bias_ft``."""
        return ServiceCall(self._bias, Trigger.Request(), lambda r: CallResult(
            bool(r.success),
            r.message if r.success else f'{names.GRIPPER_BIAS_FT_SRV}: {r.message}'))

    def move_gripper(self, lift: float, lateral: float, rotation: float, duration: float,
                     t: float) -> CallReturn:
        """Arm backend: relative motion."""
        return self.arm.move_gripper(lift, lateral, rotation, duration, t)

    def move_to_pickup(self, position: tuple[float, ...], euler_xyz: tuple[float, ...],
                       t: float) -> CallReturn:
        """Arm backend: pick-up pose."""
        return self.arm.move_to_pickup(position, euler_xyz, t)

    def move_joints(self, names: tuple[str, ...], positions: tuple[float, ...],
                    duration: float, t: float) -> CallReturn:
        """Arm backend: joint move."""
        return self.arm.move_joints(names, positions, duration, t)

    def start_recording(self, name: str, topics: tuple[str, ...], t: float) -> CallReturn:
        """Start the in-process recorder at ``<recording.directory>/<name>`` (suffix if taken)."""
        if self.recorder is not None:
            return CallResult(False, f'already recording to {self.recorder.path}')
        directory = Path(self._params().recording.directory or default_bag_directory()
                         ).expanduser()
        try:
            directory.mkdir(parents=True, exist_ok=True)
            path = directory / name
            n = 2
            while path.exists():
                path = directory / f'{name}_{n}'
                n += 1
            self.recorder = TopicRecorder(self._node, path, topics=topics)
        except (OSError, ValueError) as exc:
            return CallResult(False, f'cannot record to {directory / name}: {exc}')
        return CallResult(True, f'recording to {self.recorder.path}',
                          value=str(self.recorder.path))

    def stop_recording(self, t: float) -> CallReturn:
        """Stop the recorder; ``value`` = bag path."""
        rec, self.recorder = self.recorder, None
        if rec is None:
            return CallResult(True, 'not recording')
        try:
            path = rec.stop()
        except (OSError, ValueError) as exc:
            return CallResult(False, f'closing the bag {rec.path} failed: {exc}')
        return CallResult(True, f'bag {path}: {rec.message_count} messages', value=str(path))


@dataclass
class _Run:
    """A running goal."""

    handle: ServerGoalHandle
    runner: SequenceRunner
    mode: str
    future: Future = field(default_factory=Future)
    cancel: bool = False
    phase: str = ''
    logged: int = 0
    feedback_at: float = -math.inf
    clock_value: float = math.nan
    clock_since: float = 0.0


class ExperimentRunnerNode(Node):
    """The ``experiment_runner`` node.

    Args:
        node_name: Node name (``experiment_runner``).
        **kwargs: Passed to `rclpy.node.Node` (``context``, ``parameter_overrides``, ...).

    Raises:
        ParameterError: invalid parameters.
        ArmUnavailableError: the configured arm backend cannot run here (``ur``).
    """

    def __init__(self, node_name: str = 'experiment_runner', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._binding = ParameterBinding(self, ExperimentRunnerParams)
        try:
            self._params = self._binding.load()
            self._arm = make_arm(self._params.arm.backend, self, self._params.step_timeout)
        except (ParameterError, ArmUnavailableError) as exc:
            self.get_logger().fatal(str(exc))
            super().destroy_node()
            raise
        self._binding.on_change(self._on_params)
        self._cell = RosCell(self, self._arm, lambda: self._params)
        self._flags = CellFlags()
        self._offset = PoseOffset()
        self._run: _Run | None = None
        self._last_bag = ''
        self._lost_note = ''   # where and how the object was lost (while object_dropped)
        self._rejections = 0
        self._last_rejection = ''
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = self.create_timer(POLL_PERIOD_S, self._poll, clock=self._steady,
                                        autostart=False)
        self._action = ActionServer(self, RunExperiment, names.EXPERIMENT_RUN_ACTION,
                                    execute_callback=self._execute,
                                    goal_callback=self._on_goal,
                                    cancel_callback=self._on_cancel)
        self._diag = DiagnosticsPublisher(self, hardware_id=f'arm:{self._arm.name}')
        self._diag.add('arm', self._diag_arm)
        self._diag.add('recording', self._diag_recording)
        self._diag.add('goals', self._diag_goals)
        self.get_logger().info(f'experiment runner ready (arm backend {self._arm.name!r})')

    def destroy_node(self) -> None:
        """Close a bag still being written, then destroy the action server and the arm."""
        rec = self._cell.recorder
        if rec is not None:
            self._cell.recorder = None
            path = rec.stop()
            self.get_logger().warn(f'shutting down during a run: bag {path} closed')
        self._action.destroy()
        self._cell.destroy()
        self._arm.destroy()
        super().destroy_node()

    # -- views (tests, tools) --------------------------------------------------------------

    @property
    def arm(self) -> ArmBackend:
        """The arm backend."""
        return self._arm

    @property
    def flags(self) -> CellFlags:
        """Cell state flags carried between goals."""
        return self._flags

    @property
    def last_rejection(self) -> str:
        """``'<mode>': <reason>`` of the last goal rejected on arrival ('' if none)."""
        return self._last_rejection

    # -- action ----------------------------------------------------------------------------

    def _now(self) -> float:
        return clock_seconds(self.get_clock())

    def _on_params(self, params: ExperimentRunnerParams) -> None:
        self._params = params
        self.get_logger().info('parameters updated (used from the next goal)')

    def _refuse(self, handle: ServerGoalHandle, message: str) -> RunExperiment.Result:
        self.get_logger().error(f'{names.EXPERIMENT_RUN_ACTION} refused: {message}')
        handle.abort()
        return self._result(False, message, None, '')

    def _result(self, success: bool, message: str, estimate: ContactProperties | None,
                bag: str) -> RunExperiment.Result:
        res = RunExperiment.Result(success=success, message=message, bag_path=bag)
        res.estimate = properties_to_msg(estimate if estimate is not None
                                         else ContactProperties(), self.get_clock().now().to_msg())
        return res

    def _prepare(self, goal: RunExperiment.Goal) -> tuple[Sequence | None, str]:
        """The goal's step sequence, or None and why it cannot run now (the checks made when
        a goal arrives: busy, recording name, mode and arguments, leading preconditions)."""
        if self._run is not None:
            return None, f'busy: experiment {self._run.mode!r} is running'
        name = goal.recording_name
        if name and (len(name) < 3 or not _NAME_RE.match(name)):
            return None, (
                f'recording_name {name!r} is invalid: >= 3 characters of letters, digits, '
                "'_', '-', '.' (not starting with a symbol), or empty for no recording")
        try:
            seq = build_sequence(goal.mode, self._params, duration=goal.duration,
                                 distance=goal.distance, angle=goal.angle,
                                 recording_name=name)
        except ValueError as exc:
            return None, str(exc)
        refusal = preflight(seq, self._flags)
        if refusal:
            if self._flags.object_dropped and self._lost_note:
                refusal += f' (object lost {self._lost_note})'
            return None, refusal
        return seq, ''

    def _on_goal(self, goal: RunExperiment.Goal) -> GoalResponse:
        """Reject a goal that cannot run, when it arrives (the reason is logged and kept in
        the ``goals`` diagnostics); the action protocol's goal response carries no text."""
        seq, reason = self._prepare(goal)
        if seq is None:
            self._rejections += 1
            self._last_rejection = f'{goal.mode!r}: {reason}'
            self.get_logger().error(f'{names.EXPERIMENT_RUN_ACTION}: goal {goal.mode!r} '
                                    f'rejected: {reason}')
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    async def _execute(self, handle: ServerGoalHandle) -> RunExperiment.Result:
        goal = handle.request
        name = goal.recording_name
        seq, reason = self._prepare(goal)
        if seq is None:   # changed since the goal was accepted (e.g. a second goal started)
            return self._refuse(handle, reason)
        if name and goal.mode not in RECORDING_MODES:
            self.get_logger().warn(f'mode {goal.mode!r} does not record; recording_name '
                                   f'{name!r} ignored')
        run = _Run(handle, SequenceRunner(seq, self._cell, self._params, self._flags,
                                          self._offset), goal.mode)
        self._run = run
        self.get_logger().info(f'experiment {goal.mode!r} started ({len(seq.steps)} steps'
                               + (f', recording {name!r})' if name else ')'))
        self._timer.reset()
        progress: RunnerProgress = await run.future
        self._flags, self._offset = run.runner.flags, run.runner.offset
        if progress.object_lost:
            self._lost_note = f'{progress.object_lost} (in {goal.mode!r})'
            self.get_logger().error(
                f'the object was lost {self._lost_note}: goals that need it are refused until '
                "it is re-grasped ('release', 'go_to_object', 'grasp'; 'demo' does this itself)")
        elif not self._flags.object_dropped:
            self._lost_note = ''
        for line in progress.segments:
            self.get_logger().info(f'[{goal.mode}] slip segment {line}')
        if progress.bag_path:
            self._last_bag = progress.bag_path
        if progress.success:
            self.get_logger().info(f'experiment {goal.mode!r} done in {progress.elapsed:.1f} s')
        else:
            self.get_logger().error(progress.message)
        if handle.is_cancel_requested:
            handle.canceled()
        elif progress.success:
            handle.succeed()
        else:
            handle.abort()
        return self._result(progress.success, progress.message, progress.estimate,
                            progress.bag_path)

    def _on_cancel(self, handle: ServerGoalHandle) -> CancelResponse:
        run = self._run
        if run is None or run.handle is not handle:
            return CancelResponse.REJECT
        run.cancel = True
        return CancelResponse.ACCEPT

    def _poll(self) -> None:
        run = self._run
        if run is None:
            self._timer.cancel()
            return
        t = self._now()
        wall = clock_seconds(self._steady)
        runner = run.runner
        if t != run.clock_value:
            run.clock_value, run.clock_since = t, wall
        elif wall - run.clock_since > self._params.step_timeout:
            runner.abort(f'the node clock has not advanced for {wall - run.clock_since:.1f} s '
                         '(use_sim_time without /clock? is the simulator running?)', t)
        if run.cancel:
            runner.abort('canceled by the client', t)
        if runner.flags.holding:
            dropped = self._arm.object_dropped()
            if dropped:
                runner.lose_object(dropped, t)
            fault = self._arm.fault()
            if fault:
                runner.abort(fault, t)
        progress = runner.poll(t)
        period_ns = seconds_to_nanoseconds(
            FAST_POLL_PERIOD_S if runner.fast_poll else POLL_PERIOD_S)
        if self._timer.timer_period_ns != period_ns:
            self._timer.timer_period_ns = period_ns
        for line in progress.log[run.logged:]:
            if 'FAILED' in line or 'ABORTED' in line:
                self.get_logger().error(f'[{run.mode}] {line}')
            else:
                self.get_logger().info(f'[{run.mode}] {line}')
        run.logged = len(progress.log)
        if progress.phase != run.phase or wall - run.feedback_at >= FEEDBACK_PERIOD_S:
            run.phase = progress.phase
            run.feedback_at = wall
            run.handle.publish_feedback(RunExperiment.Feedback(phase=progress.phase,
                                                               elapsed=progress.elapsed))
        if progress.finished:
            self._run = None
            self._timer.cancel()
            self._timer.timer_period_ns = seconds_to_nanoseconds(POLL_PERIOD_S)
            run.future.set_result(progress)

    # -- diagnostics -----------------------------------------------------------------------

    def _diag_arm(self, t: float) -> Report:
        del t
        ok, text = self._arm.ready()
        f = self._flags
        values = (('backend', self._arm.name), ('connected', str(ok)),
                  ('running', self._run.mode if self._run is not None else ''),
                  ('flags', ' '.join(k for k in FLAG_NAMES if getattr(f, k))),
                  ('object_lost', self._lost_note))
        if f.object_dropped:
            return Report(Level.WARN, f'object lost {self._lost_note}: re-grasp it '
                          "('release', 'go_to_object', 'grasp')", values)
        return Report(Level.OK if ok else Level.WARN, text, values)

    def _diag_goals(self, t: float) -> Report:
        del t
        values = (('rejected', str(self._rejections)), ('last_rejection', self._last_rejection),
                  ('running', self._run.mode if self._run is not None else ''))
        if self._last_rejection:
            return Report(Level.OK, f'last goal rejected: {self._last_rejection}', values)
        return Report(Level.OK, 'no goal rejected', values)

    def _diag_recording(self, t: float) -> Report:
        del t
        rec = self._cell.recorder
        if rec is None:
            return Report(Level.OK, 'not recording', (('last_bag', self._last_bag),))
        return Report(Level.OK, f'recording to {rec.path}',
                      (('path', str(rec.path)), ('messages', str(rec.message_count)),
                       ('topics', ' '.join(rec.topics))))


def main(args: list[str] | None = None) -> int:
    """Console script ``experiment_runner``."""
    return run_node(ExperimentRunnerNode, args)


if __name__ == '__main__':
    sys.exit(main())
