# SPDX-License-Identifier: Apache-2.0
"""``slip_controller``: the four slip controllers behind one node (control_and_estimation §4).

Thin rclpy node around `slip_control.core.controllers` and `slip_control.core.mode_switch`:

* subscribes ``finger_k/ft/wrench`` (SENSOR_SUB) and ``finger_k/slip/twist`` (`TWIST_SUB`);
  each callback replaces one immutable `SensorSnapshot` (whose per-finger travel integrates
  every twist sample, so trajectory progress is exact even when steps see only some), and
  ``contact/properties`` (LATCHED);
* ROTATIONAL/LINEAR end with "contact lost" when the pads measure no normal force (dropped);
* one control step per finger-1 twist, plus a watchdog step every `WATCHDOG_PERIOD_S` on the
  node clock, so stale inputs are noticed when a stream stops (safe hold within
  ``velocity_stale_after`` + ``stale_confirm`` + one watchdog period). Staleness and ``dt``
  come from message stamps and the node clock (sim time under ``use_sim_time``; CE-3, CE-7);
  a stale verdict is acted on once the other stream delivered a few samples while the stale
  one delivered none, or after ``stale_confirm`` on the steady clock, because a node behind
  its queues sees its clock before the samples queued with it (`StaleDebounce`);
* publishes ``gripper/grasp_force_cmd`` (COMMAND; stamp = computation time, ``timeout =
  command_timeout``, source SLIP_CONTROLLER) on every step that yields a force,
  ``slip_control/tracking`` (SENSOR_PUB) on every LINEAR/ROTATIONAL step and
  ``slip_control/state`` (LATCHED) when the state changes;
* serves ``slip_control/set_mode`` (``slip_msgs/SetSlipMode``): the request is validated
  completely, a new controller is built and swapped in with one assignment (CE-2); rejections
  are ``success = false`` with the reason, and change nothing;
* serves the ``slip_control/execute`` action (``slip_msgs/ExecuteSlip``, LINEAR or ROTATIONAL):
  feedback = each tracking row; the goal ends with the trajectory ("done", "timeout",
  "slip reversed", "contact lost", "velocity stale", "F/T stale"), when an accepted ``set_mode`` request or a
  new goal preempts it ("preempted"), or on cancel ("canceled"; HOLD takes over). In every
  case the controller falls back to HOLD (or to the requested mode);
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
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile
from rclpy.task import Future
from slip_msgs.action import ExecuteSlip
from slip_msgs.msg import ContactProperties as ContactPropertiesMsg
from slip_msgs.msg import GraspForceCommand, SlipControllerState, SlipTracking
from slip_msgs.srv import SetSlipMode

from slip_control.core.contact import ContactProperties, ContactSource
from slip_control.core.controllers import (ControlOutput, OffController, SlipController,
                                           SlipMode, SlipResult)
from slip_control.core.mode_switch import (ModeRequest, build_controller, check_contact,
                                           hold_successor, with_params)
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import (InputStatus, SensorSnapshot, StaleDebounce,
                                      assess_inputs)
from slip_control.ros_conv import (controller_state, fill_slip_result, grasp_force_command, 
                                   mode_request, properties_from_msg, seconds_to_stamp,
                                   tracking_to_msg, twist_from_msg, wrench_from_msg)
from slip_cell_common.diagnostics import DiagnosticsPublisher
from slip_cell_common.node_main import run_node
from slip_cell_common.param_binding import ParameterBinding
from slip_cell_common.qos import (COMMAND, LATCHED, QUIET_PUB, QUIET_SUB, SENSOR_PUB,
                                            SENSOR_SUB, overridable)
from slip_cell_common.core.monitors import Level, Report
from slip_cell_common.core.param_schema import ParameterError

#: Watchdog period [s, node clock]: stale inputs are acted on at most this late.
WATCHDOG_PERIOD_S = 0.01


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
    """The ``slip_controller`` node.

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
            self._params = self._binding.load()
        except ParameterError as exc:
            self.get_logger().fatal(f'invalid parameters: {exc}')
            super().destroy_node()
            raise
        self._params_pending = False
        self._controller: SlipController = OffController(self._params)
        self._props: ContactProperties | None = None
        self._snap = SensorSnapshot()
        self._goal: _Goal | None = None
        self._last_t: float | None = None
        self._state_key: tuple[Any, ...] | None = None
        self._reason = 'started'
        self._status: InputStatus | None = None
        self._safe_hold = False
        self._preset_in_use = False
        self._commands = 0
        # Stale verdicts are confirmed on the steady clock (see StaleDebounce): a backlog in
        # this process must not end a trajectory whose sensor streams are fine.
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._stale_gate = StaleDebounce(self._params.stale_confirm)
        self._twists_received = 0
        self._wrenches_received = 0

        self._cmd_pub = self.create_publisher(GraspForceCommand, 'gripper/grasp_force_cmd',
                                              COMMAND, event_callbacks=QUIET_PUB,
                                              qos_overriding_options=overridable())
        self._track_pub = self.create_publisher(SlipTracking, 'slip_control/tracking',
                                                SENSOR_PUB, event_callbacks=QUIET_PUB,
                                                qos_overriding_options=overridable())
        self._state_pub = self.create_publisher(SlipControllerState, 'slip_control/state',
                                                LATCHED, event_callbacks=QUIET_PUB,
                                                qos_overriding_options=overridable())
        self.create_subscription(ContactPropertiesMsg, 'contact/properties',
                                 self._on_properties, LATCHED)
        self.create_subscription(WrenchStamped, 'finger_1/ft/wrench',
                                 lambda m: self._on_wrench(1, m), SENSOR_SUB,
                                 event_callbacks=QUIET_SUB)
        self.create_subscription(WrenchStamped, 'finger_2/ft/wrench',
                                 lambda m: self._on_wrench(2, m), SENSOR_SUB,
                                 event_callbacks=QUIET_SUB)
        self.create_subscription(TwistStamped, 'finger_2/slip/twist', self._on_twist_2,
                                 TWIST_SUB, event_callbacks=QUIET_SUB)
        # Created last: when several samples are ready at once, the trigger is handled last.
        self.create_subscription(TwistStamped, 'finger_1/slip/twist', self._on_twist_1,
                                 TWIST_SUB, event_callbacks=QUIET_SUB)
        self.create_service(SetSlipMode, 'slip_control/set_mode', self._on_set_mode)
        self._action = ActionServer(self, ExecuteSlip, 'slip_control/execute',
                                    execute_callback=self._execute,
                                    cancel_callback=self._on_cancel)
        self.create_timer(WATCHDOG_PERIOD_S, self._on_watchdog)
        self._binding.on_change(self._on_params)
        self._diag = DiagnosticsPublisher(self)
        self._diag.add('mode', self._diag_mode)
        self._diag.add('inputs', self._diag_inputs)
        self._diag.add('contact', self._diag_contact)
        self._publish_state(self._now(), 'started: OFF', force=True)
        self.get_logger().info('slip controller ready (mode OFF)')

    def destroy_node(self) -> None:
        """Destroy the action server too (rclpy does not, and it keeps the node alive)."""
        self._action.destroy()
        super().destroy_node()

    # -- read-only views (tests, tools) ----------------------------------------------------

    @property
    def snapshot(self) -> SensorSnapshot:
        """Latest samples of both fingers."""
        return self._snap

    @property
    def controller(self) -> SlipController:
        """The controller in charge."""
        return self._controller

    # -- inputs ----------------------------------------------------------------------------

    def _now(self) -> float:
        """Node-clock time [s]; controllers forget their stamp history on a backwards jump."""
        t = self.get_clock().now().nanoseconds * 1e-9
        if self._last_t is not None and t < self._last_t:
            self.get_logger().warn(f'clock jumped backwards by {self._last_t - t:.3f} s: '
                                   'resetting the controller timing')
            self._controller.reset(t)
        self._last_t = t
        return t

    def _on_wrench(self, finger: int, msg: WrenchStamped) -> None:
        self._snap = self._snap.with_wrench(finger, wrench_from_msg(msg))
        self._wrenches_received += 1

    def _on_twist_2(self, msg: TwistStamped) -> None:
        self._snap = self._snap.with_twist(2, twist_from_msg(msg))
        self._twists_received += 1

    def _on_twist_1(self, msg: TwistStamped) -> None:
        self._snap = self._snap.with_twist(1, twist_from_msg(msg))
        self._twists_received += 1
        self._step(self._now())

    def _on_watchdog(self) -> None:
        self._step(self._now())

    def _on_properties(self, msg: ContactPropertiesMsg) -> None:
        try:
            props = properties_from_msg(msg)
        except ValueError as exc:
            self.get_logger().error(f'ignoring contact/properties: {exc}')
            return
        self._props = props
        self.get_logger().info(f'contact properties received: {props.describe()} '
                               '(used from the next mode request)')
        self._publish_state(self._now(), f'contact properties: {props.source.name}, '
                                         f'valid={props.valid}', force=True)

    def _on_params(self, params: SlipControllerParams) -> None:
        self._params = params
        self._stale_gate.confirm_s = params.stale_confirm
        self._params_pending = True
        self._apply_params()

    def _apply_params(self) -> None:
        if not self._params_pending:
            return
        new = with_params(self._controller, self._params)
        if new is None:
            return                         # a trajectory runs: retry after it ends
        self._controller = new
        self._params_pending = False
        self.get_logger().info(f'parameters updated ({new.mode.name} rebuilt)')

    # -- control ---------------------------------------------------------------------------

    def _step(self, t: float) -> None:
        self._apply_params()
        status = self._current_status(t)
        steady = self._steady.now().nanoseconds * 1e-9
        if self._stale_gate.defer(not status.velocity_fresh, not status.ft_fresh, steady,
                                  self._twists_received, self._wrenches_received):
            return  # the last command stays in force (it carries command_timeout)
        out = self._controller.step(self._snap, t)
        self._emit(out, t)

    def _emit(self, out: ControlOutput, t: float) -> None:
        if out.force is not None:
            self._command(out.force, out.timeout, t)
        if out.tracking is not None:
            track = tracking_to_msg(out.tracking)
            self._track_pub.publish(track)
            if self._goal is not None:
                self._goal.handle.publish_feedback(ExecuteSlip.Feedback(tracking=track))
        if out.next_controller is not None:
            self._controller = out.next_controller
        if out.result is not None:
            self._finish_goal(out.result)
        self._status = out.status
        self._safe_hold = out.safe_hold
        self._publish_state(t, out.reason)

    def _command(self, force: float, timeout: float, t: float) -> None:
        self._cmd_pub.publish(grasp_force_command(
            force, timeout, seconds_to_stamp(t), GraspForceCommand.SOURCE_SLIP_CONTROLLER))
        self._commands += 1

    def _switch(self, request: ModeRequest, origin: str) -> tuple[bool, str]:
        """Validate, build and swap in the controller for ``request`` (CE-2)."""
        t = self._now()
        self._apply_params()
        outcome = build_controller(request, self._props, self._params, t,
                                   previous=self._controller)
        if not outcome.ok:
            self.get_logger().warn(f'{origin} refused: {outcome.message}')
            return False, outcome.message
        if outcome.preempted is not None:
            self._finish_goal(outcome.preempted)
        if outcome.final_force is not None:
            # Explicit hand-over: the last output stays valid until someone replaces it.
            self._command(outcome.final_force, 0.0, t)
        assert outcome.controller is not None
        self._controller = outcome.controller
        self._safe_hold = False
        self._preset_in_use = outcome.preset_in_use
        self.get_logger().info(f'{origin}: {outcome.message}')
        self._publish_state(t, f'{origin}: {outcome.message}', force=True)
        return True, outcome.message

    def _finish_goal(self, result: SlipResult) -> None:
        goal, self._goal = self._goal, None
        text = (f'{result.mode.name} trajectory ended: {result.message} (progress '
                f'{result.final_pos:.4f}, error {result.final_error:.4f}, '
                f'{result.elapsed:.2f} s)')
        if result.success:
            self.get_logger().info(text)
        else:
            self.get_logger().warn(text)
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
        hold, result = hold_successor(self._controller, 'canceled', t)
        self._controller = hold
        if result is not None:
            self._finish_goal(result)
        self._publish_state(t, 'execute canceled: HOLD', force=True)
        return CancelResponse.ACCEPT

    # -- state and diagnostics -------------------------------------------------------------

    def _contact_ok(self) -> bool:
        return check_contact(SlipMode.HOLD, self._props, self._params)[0]

    def _current_status(self, t: float) -> InputStatus:
        p = self._params
        return assess_inputs(self._snap, t, velocity_stale_after=p.velocity_stale_after,
                             ft_stale_after=p.ft_stale_after, sync_tolerance=p.sync_tolerance)

    def _publish_state(self, t: float, reason: str, *, force: bool = False) -> None:
        st = self._status if self._status is not None else self._current_status(t)
        c = self._controller
        key = (int(c.mode), c.goal_active, self._contact_ok(), st.velocity_fresh, st.ft_fresh,
               self._safe_hold)
        if not force and key == self._state_key:
            return
        self._state_key = key
        if reason:
            self._reason = reason
        self._state_pub.publish(controller_state(
            seconds_to_stamp(t), key[0], key[1], key[2], key[3], key[4], key[5], self._reason))

    def _diag_mode(self, t: float) -> Report:
        del t
        c = self._controller
        last = c.last_force
        values = (('mode', c.mode.name), ('goal_active', str(c.goal_active)),
                  ('execute_goal', str(self._goal is not None)),
                  ('last_force_n', 'none' if last is None else f'{last:.3f}'),
                  ('commands_published', str(self._commands)),
                  ('preset_in_use', str(self._preset_in_use)), ('reason', self._reason))
        return Report(Level.OK, f'{c.mode.name}: {self._reason}', values)

    def _diag_inputs(self, t: float) -> Report:
        st = self._current_status(t)
        values = (('velocity_age_s', f'{st.velocity_age:.4f}'), ('ft_age_s', f'{st.ft_age:.4f}'),
                  ('velocity_fresh', str(st.velocity_fresh)), ('ft_fresh', str(st.ft_fresh)),
                  ('synchronised', str(st.synced)), ('safe_hold', str(self._safe_hold)),
                  ('steps_deferred_stale', str(self._stale_gate.deferred)))
        if st.all_fresh:
            return Report(Level.OK, 'inputs fresh', values)
        stale = ', '.join(n for n, ok in (('velocity', st.velocity_fresh), ('F/T', st.ft_fresh),
                                          ('finger sync', st.synced)) if not ok)
        if self._controller.mode != SlipMode.OFF:
            return Report(Level.ERROR, f'stale inputs while controlling ({stale}): safe hold',
                          values)
        return Report(Level.WARN, f'inputs not fresh ({stale}); not controlling', values)

    def _diag_contact(self, t: float) -> Report:
        del t
        p = self._props
        if p is None:
            return Report(Level.WARN, 'no contact properties received: slip modes refused')
        values = (('source', p.source.name), ('preset', p.preset_name), ('valid', str(p.valid)),
                  ('mu_c', f'{p.mean_mu_c():.4f}'), ('r_m', f'{p.mean_r():.5f}'),
                  ('allow_preset_properties', str(self._params.allow_preset_properties)))
        ok, why = check_contact(SlipMode.HOLD, p, self._params)
        if p.source == ContactSource.PRESET and ok:
            return Report(Level.WARN, f'preset {p.preset_name!r} in use', values)
        if not ok:
            return Report(Level.WARN, why, values)
        return Report(Level.OK, f'{p.source.name} properties valid', values)


def main(args: list[str] | None = None) -> int:
    """Console script ``slip_controller``."""
    return run_node(SlipControllerNode, args)


if __name__ == '__main__':
    sys.exit(main())
