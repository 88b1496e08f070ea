# SPDX-License-Identifier: Apache-2.0
"""``netft_driver``: standalone lifecycle driver of one ATI Net F/T box (ros_interfaces §6.2).

Publishes ``finger_<k>/ft/wrench`` (bias removed; nothing before the first bias) and, with
``publish_raw``, ``finger_<k>/ft/raw``, both stamped at datagram arrival in frame
``ft_sensor_<k>``; serves ``finger_<k>/ft/bias``; reports diagnostics task ``ft``.

``finger_<k>/ft/bias`` is refused, with the reason, while the pads may be loaded: this box
measures normal force, or the newest ``gripper/status`` reports a squeezing target, command or
grasp force (`standalone_bias_guard`; ``gripper/bias_ft`` of the gripper driver checks more);
``bias.on_activate`` is subject to the same check.

``finger_<k>/ft/wrench`` carries measurements only: records with an error in the status word,
beyond the measuring range, or taken after a box restart lost the bias are never published on
it (``publish_on_error`` puts the first two on ``ft/raw`` only). A ``gripper_driver`` in
``ft.mode: topic`` thus sees such a box as stale and falls back safely (see `ft_channel`).

Lifecycle: configure reads ``netftapi2.xml`` (if asked), opens the socket and starts the RDT
stream (FAILURE naming the box); activate/deactivate switch publishing; cleanup and shutdown
send the stop command (0x0000) and close the socket. A box serves one client: never run this
node and an embedded ``gripper_driver`` client on the same box.
"""
from __future__ import annotations

import sys
from typing import Any

from geometry_msgs.msg import WrenchStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from std_srvs.srv import Trigger

from slip_msgs.msg import GripperStatus

from slip_cell_common.diagnostics import DiagnosticsPublisher
from slip_cell_common.log_sink import log_event
from slip_cell_common.time_conv import clock_seconds
from slip_cell_common.core import names
from slip_cell_common.node_main import run_node
from slip_cell_common.param_binding import ParameterBinding
from slip_cell_common.qos import SENSOR_PUB, SENSOR_SUB, overridable
from slip_cell_common.core.monitors import Level, Report
from slip_gripper_driver.core.netft_client import NetFTError
from slip_cell_common.core.param_schema import ParameterError
from slip_gripper_driver.ft_channel import (FT_SUPERVISE_PERIOD_S, FtChannel,
                                            run_bias, wrench_publisher)
from slip_gripper_driver.core.standalone_bias_guard import (BiasGuardVerdict, GripperLoadView,
                                                             standalone_bias_verdict)
from slip_gripper_driver.node_params import NetFTDriverParams

SUCCESS = TransitionCallbackReturn.SUCCESS
FAILURE = TransitionCallbackReturn.FAILURE


class NetFTDriverNode(LifecycleNode):
    """One Net F/T box; see the module docstring.

    Args:
        node_name: Node name.
        **kwargs: Passed to `rclpy.lifecycle.LifecycleNode`.
    """

    def __init__(self, node_name: str = 'netft_driver', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.params = ParameterBinding(self, NetFTDriverParams)
        self.params.on_change(self._on_params)
        self.channel: FtChannel | None = None
        self.last_error = ''
        self._cfg = NetFTDriverParams()
        self._entities: list[tuple[Any, Any]] = []
        self._diag: DiagnosticsPublisher | None = None
        self._bias_group = MutuallyExclusiveCallbackGroup()
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._bias_lost_logged = False
        self._gripper_load: GripperLoadView | None = None

    def now(self) -> float:
        """Node clock [s]: the stamp of every sample."""
        return clock_seconds(self.get_clock())

    def _fail(self, message: str) -> TransitionCallbackReturn:
        self.last_error = message
        self.get_logger().error(message)
        self._release()
        return FAILURE

    # ------------------------------------------------------------------ lifecycle
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Validate parameters, read the box configuration, start streaming."""
        del state
        self.last_error = ''
        try:
            cfg = self.params.load()
        except ParameterError as exc:
            return self._fail(f'invalid parameters: {exc}')
        self._cfg = cfg
        channel = FtChannel(cfg.finger, cfg.address, cfg.stream, cfg.bias, clock=self.now,
                            restart_initial_s=cfg.reconnect.initial_delay,
                            restart_max_s=cfg.reconnect.max_delay)
        try:
            channel.open()
        except NetFTError as exc:
            return self._fail(f'finger {cfg.finger} Net F/T: {exc}')
        self.channel = channel
        k = cfg.finger
        frame = cfg.resolved_frame_id()
        opts = overridable()
        wrench = self.create_publisher(WrenchStamped, names.ft_wrench(k), SENSOR_PUB,
                                       qos_overriding_options=opts)
        raw = self.create_publisher(WrenchStamped, names.ft_raw(k), SENSOR_PUB,
                                    qos_overriding_options=opts)
        channel.publish_wrench = wrench_publisher(wrench, frame)
        channel.publish_raw = wrench_publisher(raw, frame)
        self._entities = [
            (wrench, self.destroy_publisher), (raw, self.destroy_publisher),
            (self.create_service(Trigger, names.ft_bias_srv(k), self._srv_bias,
                                 callback_group=self._bias_group), self.destroy_service),
            # The gripper driver's status: the bias service refuses while the pads squeeze.
            (self.create_subscription(GripperStatus, names.GRIPPER_STATUS,
                                      self._on_gripper_status, SENSOR_SUB),
             self.destroy_subscription),
            (self.create_timer(FT_SUPERVISE_PERIOD_S, self._on_supervise, clock=self._steady),
             self.destroy_timer)]
        self._diag = DiagnosticsPublisher(self, channel.address)
        self._diag.add('ft', self._diag_ft)
        self.get_logger().info(f'configured: finger {k} box {channel.name}, frame {frame}')
        return SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Publish from now on (optionally bias first)."""
        assert self.channel is not None
        self.channel.publishing = True
        if self._cfg.bias.on_activate:
            refusal = self._bias_verdict(self.channel).refusal
            if refusal is None:
                self.channel.start_bias(self.now())
            else:
                self.get_logger().error(f'bias.on_activate: bias refused: {refusal}')
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop publishing (the stream keeps running until cleanup)."""
        if self.channel is not None:
            self.channel.publishing = False
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop streaming and close the socket."""
        del state
        self._release()
        return SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop streaming and close the socket (from any state)."""
        del state
        self._release()
        return SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """A transition raised: stop streaming and return to unconfigured."""
        del state
        self._release()
        return SUCCESS

    def _release(self) -> None:
        if self.channel is not None:
            self.channel.close()
            self.channel = None
        if self._diag is not None:
            self._diag.destroy()
            self._diag = None
        for entity, destroy in self._entities:
            destroy(entity)
        self._entities = []

    # ------------------------------------------------------------------ callbacks
    def _on_supervise(self) -> None:
        channel = self.channel
        if channel is None:
            return
        channel.supervise(self.now(), self._cfg.receive_timeout)
        if channel.bias_lost != self._bias_lost_logged:
            self._bias_lost_logged = channel.bias_lost
            if channel.bias_lost:
                k = channel.finger
                self.get_logger().error(f'{channel.name}: {channel.bias_lost_reason}; '
                                        f'finger_{k}/ft/wrench '
                                        f'withheld until finger_{k}/ft/bias succeeds (bias '
                                        'with the pads unloaded)')

    def _on_params(self, cfg: NetFTDriverParams) -> None:
        self._cfg = cfg
        if self.channel is not None:
            self.channel.apply(cfg.stream, cfg.bias)

    def _srv_bias(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        del request
        channel = self.channel
        if channel is None:
            response.success, response.message = False, 'netft_driver is not configured'
            return response
        cfg = self._cfg
        verdict = self._bias_verdict(channel)
        if verdict.refusal is not None:
            response.success, response.message = False, f'bias refused: {verdict.refusal}'
            self.get_logger().error(response.message)
            return response
        ok, message = run_bias([channel], self.now, cfg.receive_timeout)
        if verdict.note:
            message = f'{message} ({verdict.note})'
        response.success, response.message = ok, message
        log_event(self.get_logger(), 'info' if ok else 'error', f'bias: {message}')
        return response

    def _bias_verdict(self, channel: FtChannel) -> BiasGuardVerdict:
        """May this box be biased now (`standalone_bias_guard`)?"""
        cfg = self._cfg
        now = self.now()
        return standalone_bias_verdict(now, cfg.bias_guard, cfg.finger,
                                       channel.normal_force(now, cfg.receive_timeout),
                                       self._gripper_load)

    def _on_gripper_status(self, msg: GripperStatus) -> None:
        self._gripper_load = GripperLoadView(
            received=self.now(), force_target=msg.force_target, force_cmd=msg.force_cmd,
            armed=msg.armed, safe_state=msg.safe_state,
            measured_grasp_force=msg.measured_grasp_force)

    def _diag_ft(self, now: float) -> Report:
        if self.channel is None:
            return Report(Level.STALE, 'not configured')
        return self.channel.report(now, self._cfg.receive_timeout)


def main(args: list[str] | None = None) -> int:
    """Console entry point ``netft_driver``."""
    return run_node(NetFTDriverNode, args, multithreaded=True)


if __name__ == '__main__':
    sys.exit(main())
