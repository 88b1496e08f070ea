# SPDX-License-Identifier: Apache-2.0
"""``slip_controller``: the four slip controllers behind one node (control_and_estimation §4).

Thin rclpy wiring around `slip_control.core.controller_host.ControllerHost`, which holds the
logic described here (the in-process evaluation runs the same host on the simulated cell):

* subscribes ``finger_k/ft/wrench`` (SENSOR_SUB) and ``finger_k/slip/twist`` (`TWIST_SUB`);
  each callback replaces one immutable `SensorSnapshot` (whose per-finger travel integrates
  every twist sample, so trajectory progress is exact even when steps see only some), and
  ``contact/properties`` (LATCHED);
* ROTATIONAL/LINEAR end with "contact lost" when the pads measure no normal force (dropped);
* one control step per finger-1 twist, plus a watchdog step every ``WATCHDOG_PERIOD_S`` on the
  node clock, so stale inputs are noticed when a stream stops (safe hold within
  ``velocity_stale_after`` + ``stale_confirm`` + one watchdog period). Staleness and ``dt``
  come from message stamps and the node clock (sim time under ``use_sim_time``; CE-3, CE-7);
  a stale verdict is acted on once the other stream delivered a few samples while the stale
  one delivered none, or after ``stale_confirm`` of node-clock time, because a node behind
  its queues sees its clock before the samples queued with it (`StaleDebounce`). Under
  ``use_sim_time`` that is simulated time: a host too slow for real time slows the
  simulation, and no verdict is confirmed while simulated time stands still, so a slow host
  cannot end a slip as "velocity stale". On the system clock (hardware) the steady clock is
  used instead (read here, passed to the host), because the system clock may jump;
* publishes ``gripper/grasp_force_cmd`` (COMMAND; stamp = computation time, ``timeout =
  command_timeout``, source SLIP_CONTROLLER) on every step that yields a force,
  ``slip_control/tracking`` (SENSOR_PUB) on every LINEAR/ROTATIONAL step and
  ``slip_control/state`` (LATCHED) when the state changes;
* serves ``slip_control/set_mode`` (``slip_msgs/SetSlipMode``): the request is validated
  completely, a new controller is built and swapped in with one assignment (CE-2); rejections
  are ``success = false`` with the reason, and change nothing. ``control_law`` picks the law
  family (``thesis``, ``model``; empty = parameter ``default_control_law``); the model laws
  also refuse a slip the measured load cannot produce, with the numbers;
* serves the ``slip_control/execute`` action (``slip_msgs/ExecuteSlip``, LINEAR or ROTATIONAL):
  feedback = each tracking row; the goal ends with the trajectory ("done" within the
  tolerance of the target; failures "stalled: 4.1 of 20.0 mm", "timeout: …", "slip reversed",
  "contact lost", "velocity stale", "F/T stale", …), when an accepted
  ``set_mode`` request or a new goal preempts it ("preempted"), or on cancel ("canceled";
  HOLD takes over). In every case the controller falls back to HOLD (or to the requested
  mode);
* diagnostics tasks ``mode``, ``inputs``, ``contact``.

All callbacks, including the action's execute coroutine, run on one single-threaded executor
(CE-8). Parameter changes are validated on set and swapped in between steps (a running
trajectory keeps its snapshot; its HOLD successor gets the new one).
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

from geometry_msgs.msg import TwistStamped, WrenchStamped
from rclpy.action import ActionServer, CancelResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.clock import Clock, ClockType, ROSClock
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile
from rclpy.task import Future
from slip_msgs.action import ExecuteSlip
from slip_msgs.msg import ContactProperties as ContactPropertiesMsg
from slip_msgs.msg import GraspForceCommand, SlipControllerState, SlipTracking
from slip_msgs.srv import SetSlipMode

from slip_cell_common.core.monitors import Level, Report
from slip_cell_common.core import names
from slip_cell_common.core.param_schema import ParameterError
from slip_cell_common.diagnostics import DiagnosticsPublisher
from slip_cell_common.node_main import run_node
from slip_cell_common.param_binding import ParameterBinding
from slip_cell_common.qos import (COMMAND, LATCHED, QUIET_PUB, QUIET_SUB, SENSOR_PUB,
                                  SENSOR_SUB, overridable)
from slip_cell_common.time_conv import clock_seconds, seconds_to_stamp
from slip_control.core.controller_host import WATCHDOG_PERIOD_S, ControllerHost
from slip_control.core.controllers import ControlOutput, SlipController, SlipMode, SlipResult
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import SensorSnapshot
from slip_control.slip_msgs_conv import (controller_state, fill_slip_result, grasp_force_command,
                                         mode_request, properties_from_msg, tracking_to_msg,
                                         twist_from_msg, wrench_from_msg)


#: Twist subscriptions keep 0.25 s of samples (30 at 120 Hz) instead of SENSOR_SUB's 5: the
#: trajectory progress integrates every sample, so a burst (a sim catching up, a busy host)
#: must not overflow the queue. Best effort, volatile, like SENSOR_SUB.
TWIST_SUB = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=30,
                       reliability=SENSOR_SUB.reliability, durability=SENSOR_SUB.durability)

_TRAJECTORY_MODES = (SlipMode.LINEAR, SlipMode.ROTATIONAL)


@dataclass
class _Goal:
    """The running ExecuteSlip goal and the future its execute coroutine awaits."""

    handle: ServerGoalHandle
    future: Future


class SlipControllerNode(Node):
    """The ``slip_controller`` node: ROS wiring around one `ControllerHost`.

    Args:
        node_name: Node name (``slip_controller``).
        **kwargs: Passed to `rclpy.node.Node` (``context``, ``parameter_overrides``, ...).

    Raises:
        ParameterError: invalid parameters.
    """

    def __init__(self, node_name: str = 'slip_controller', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._binding = ParameterBinding(self, SlipControllerParams)
        try:
            params = self._binding.load()
        except ParameterError as exc:
            self.get_logger().fatal(f'invalid parameters: {exc}')
            super().destroy_node()
            raise
        self._host = ControllerHost(params, log=self._log)
        self._goal: _Goal | None = None
        self._commands = 0
        # Stale verdicts are confirmed in the node clock's domain (see StaleDebounce and
        # _step): a backlog in this process must not end a trajectory whose sensor streams are
        # fine. The steady clock serves only a node on the system clock (hardware).
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)

        self._cmd_pub = self.create_publisher(GraspForceCommand, names.GRASP_FORCE_CMD,
                                              COMMAND, event_callbacks=QUIET_PUB,
                                              qos_overriding_options=overridable())
        self._track_pub = self.create_publisher(SlipTracking, names.SLIP_TRACKING,
                                                SENSOR_PUB, event_callbacks=QUIET_PUB,
                                                qos_overriding_options=overridable())
        self._state_pub = self.create_publisher(SlipControllerState, names.SLIP_CONTROLLER_STATE,
                                                LATCHED, event_callbacks=QUIET_PUB,
                                                qos_overriding_options=overridable())
        self.create_subscription(ContactPropertiesMsg, names.CONTACT_PROPERTIES,
                                 self._on_properties, LATCHED)
        self.create_subscription(WrenchStamped, names.ft_wrench(1),
                                 lambda m: self._host.on_wrench(1, wrench_from_msg(m)),
                                 SENSOR_SUB, event_callbacks=QUIET_SUB)
        self.create_subscription(WrenchStamped, names.ft_wrench(2),
                                 lambda m: self._host.on_wrench(2, wrench_from_msg(m)),
                                 SENSOR_SUB, event_callbacks=QUIET_SUB)
        self.create_subscription(TwistStamped, names.slip_twist(2),
                                 lambda m: self._on_twist(2, m), TWIST_SUB,
                                 event_callbacks=QUIET_SUB)
        # Created last: when several samples are ready at once, the trigger is handled last.
        self.create_subscription(TwistStamped, names.slip_twist(1),
                                 lambda m: self._on_twist(1, m), TWIST_SUB,
                                 event_callbacks=QUIET_SUB)
        self.create_service(SetSlipMode, names.SLIP_SET_MODE_SRV, self._on_set_mode)
        self._action = ActionServer(self, ExecuteSlip, names.SLIP_EXECUTE_ACTION,
                                    execute_callback=self._execute,
                                    cancel_callback=self._on_cancel)
        self.create_timer(WATCHDOG_PERIOD_S, self._on_watchdog)
        self._binding.on_change(self._host.set_params)
        self._diag = DiagnosticsPublisher(self)
        self._diag.add('mode', self._diag_mode)
        self._diag.add('inputs', self._host.inputs_report)
        self._diag.add('contact', lambda t: self._host.contact_report())
        self._publish_state(self._now(), 'started: OFF', force=True)
        self.get_logger().info('slip controller ready (mode OFF)')

    def destroy_node(self) -> None:
        """Destroy the action server too (rclpy does not, and it keeps the node alive)."""
        self._action.destroy()
        super().destroy_node()

    # -- read-only views (tests, tools) ----------------------------------------------------

    @property
    def host(self) -> ControllerHost:
        """The controller host (the node's logic)."""
        return self._host

    @property
    def snapshot(self) -> SensorSnapshot:
        """Latest samples of both fingers."""
        return self._host.snapshot

    @property
    def controller(self) -> SlipController:
        """The controller in charge."""
        return self._host.controller

    # -- inputs ----------------------------------------------------------------------------

    def _log(self, level: str, text: str) -> None:
        if level == 'warn':
            self.get_logger().warn(text)
        else:
            self.get_logger().info(text)

    def _now(self) -> float:
        """Node-clock time [s]; the host forgets its stamp history on a backwards jump."""
        t = clock_seconds(self.get_clock())
        self._host.observe_time(t)
        return t

    def _on_twist(self, finger: int, msg: TwistStamped) -> None:
        if self._host.on_twist(finger, twist_from_msg(msg)):
            self._step(self._now())

    def _on_watchdog(self) -> None:
        self._step(self._now())

    def _on_properties(self, msg: ContactPropertiesMsg) -> None:
        try:
            props = properties_from_msg(msg)
        except ValueError as exc:
            self.get_logger().error(f'ignoring contact/properties: {exc}')
            return
        reason = self._host.set_properties(props)
        self._publish_state(self._now(), reason, force=True)

    # -- control ---------------------------------------------------------------------------

    def _step(self, t: float) -> None:
        # Simulated time (use_sim_time with /clock): confirm on t itself. System clock: on
        # the steady clock, which never jumps.
        clock = self.get_clock()
        sim_time = isinstance(clock, ROSClock) and clock.ros_time_is_active
        steady = None if sim_time else clock_seconds(self._steady)
        out = self._host.step(t, steady)
        if out is not None:
            self._emit(out, t)

    def _emit(self, out: ControlOutput, t: float) -> None:
        if out.force is not None:
            self._command(out.force, out.timeout, t)
        if out.tracking is not None:
            track = tracking_to_msg(out.tracking)
            self._track_pub.publish(track)
            if self._goal is not None:
                self._goal.handle.publish_feedback(ExecuteSlip.Feedback(tracking=track))
        if out.result is not None:
            self._finish_goal(out.result)
        self._publish_state(t, out.reason)

    def _command(self, force: float, timeout: float, t: float) -> None:
        self._cmd_pub.publish(grasp_force_command(
            force, timeout, seconds_to_stamp(t), GraspForceCommand.SOURCE_SLIP_CONTROLLER))
        self._commands += 1

    def _switch(self, request: ModeRequest, origin: str) -> tuple[bool, str]:
        """Validate, build and swap in the controller for ``request`` (CE-2)."""
        t = self._now()
        outcome = self._host.switch(request, t, origin)
        if not outcome.ok:
            return False, outcome.message
        if outcome.preempted is not None:
            self._finish_goal(outcome.preempted)
        if outcome.final_force is not None:
            # Explicit hand-over: the last output stays valid until someone replaces it.
            self._command(outcome.final_force, 0.0, t)
        self._publish_state(t, f'{origin}: {outcome.message}', force=True)
        return True, outcome.message

    def _finish_goal(self, result: SlipResult) -> None:
        goal, self._goal = self._goal, None
        if goal is not None and not goal.future.done():
            goal.future.set_result(result)

    # -- service and action ----------------------------------------------------------------

    def _on_set_mode(self, req: SetSlipMode.Request,
                     res: SetSlipMode.Response) -> SetSlipMode.Response:
        res.success, res.message = self._switch(mode_request(req), 'set_mode')
        return res

    async def _execute(self, handle: ServerGoalHandle) -> ExecuteSlip.Result:
        result = ExecuteSlip.Result()
        request = mode_request(handle.request)
        if request.mode not in _TRAJECTORY_MODES:
            handle.abort()
            result.message = (f'ExecuteSlip runs LINEAR (2) or ROTATIONAL (1) trajectories, '
                              f'got mode {request.mode}; use slip_control/set_mode for others')
            return result
        ok, message = self._switch(request, 'execute')
        if not ok:
            handle.abort()
            result.message = message
            return result
        goal = _Goal(handle, Future())
        self._goal = goal
        slip = await goal.future
        fill_slip_result(result, slip)
        if handle.is_cancel_requested:
            handle.canceled()
        elif slip.success:
            handle.succeed()
        else:
            handle.abort()
        return result

    def _on_cancel(self, handle: ServerGoalHandle) -> CancelResponse:
        if self._goal is None or self._goal.handle is not handle:
            return CancelResponse.REJECT
        t = self._now()
        result = self._host.cancel('canceled', t)
        if result is not None:
            self._finish_goal(result)
        self._publish_state(t, 'execute canceled: HOLD', force=True)
        return CancelResponse.ACCEPT

    # -- state and diagnostics -------------------------------------------------------------

    def _publish_state(self, t: float, reason: str, *, force: bool = False) -> None:
        st = self._host.state_update(t, reason, force=force)
        if st is None:
            return
        self._state_pub.publish(controller_state(
            seconds_to_stamp(t), int(st.mode), st.goal_active, st.contact_valid,
            st.velocity_fresh, st.ft_fresh, st.safe_hold, st.reason))

    def _diag_mode(self, t: float) -> Report:
        del t
        h = self._host
        c = h.controller
        last = c.last_force
        values = (('mode', c.mode.name), ('control_law', c.control_law),
                  ('goal_active', str(c.goal_active)),
                  ('execute_goal', str(self._goal is not None)),
                  ('last_force_n', 'none' if last is None else f'{last:.3f}'),
                  ('commands_published', str(self._commands)),
                  ('preset_in_use', str(h.preset_in_use)), ('reason', h.reason))
        return Report(Level.OK, f'{c.mode.name}: {h.reason}', values)


def main(args: list[str] | None = None) -> int:
    """Console script ``slip_controller``."""
    return run_node(SlipControllerNode, args)


if __name__ == '__main__':
    sys.exit(main())
