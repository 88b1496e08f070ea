# SPDX-License-Identifier: Apache-2.0
"""``gripper_driver``: lifecycle node around `core.driver_core.GripperDriverCore` (issue 5).

The 500 Hz grasp-force loop runs on the serial reader thread inside the core and never crosses
DDS: each telemetry line is parsed, the controller steps and ``T<volts>`` is written before the
line's results are published from that same thread (rclpy publishing is thread-safe). The
Net F/T boxes (``ft.mode: embedded``) feed the loop from their own reader threads; with
``ft.mode: topic`` the loop consumes ``finger_k/ft/wrench`` from standalone ``netft_driver``s.

Lifecycle: configure opens the port and starts both RDT streams. A port that cannot be opened
yet (missing, busy) is logged and configure succeeds without it: activate then keeps opening it
with back-off (``reconnect.*``) until it works or the node is deactivated. A Net F/T box that
does not answer yet (booting, unplugged) is logged too and opened with back-off on a thread of
its own (`ft_opener`) until it streams or the node is cleaned up; meanwhile no bias can be
taken and the loop runs open loop, as before any bias. Activate arms and starts the reader
and the link watchdog (a thread of the core checking every 5 ms, independent of the
executor); deactivate, cleanup and shutdown write the
safe voltage **first**, and cleanup/shutdown undo the GC freeze of configure (see
`core.realtime`). Link faults, reconnections and firmware restarts disarm: no force is
applied until ``gripper/arm``. ``gripper/bias_ft`` is refused while the pads may be loaded
(`GripperBridge.bias_refusal`).

Latency (``realtime.*``): the reader threads run ``SCHED_FIFO`` when permitted (a warning
otherwise) and the objects alive after configure are frozen out of the GC; see
`core.realtime`. Publishing happens after the command write, on the reader thread.

Spin with a multi-threaded executor (``main`` does): ``gripper/home`` and ``gripper/bias_ft``
answer when the procedure has finished and run in their own callback group.
"""
from __future__ import annotations

import functools
import math
import sys
import threading
import time
from typing import Any
from collections.abc import Callable

from geometry_msgs.msg import WrenchStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType, JumpThreshold, TimeJump
from rclpy.duration import Duration
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from sensor_msgs.msg import JointState
from slip_msgs.msg import GraspForceCommand, GripperStatus, MotorCommand, TransformArray
from std_srvs.srv import Trigger

from slip_gripper_driver import gripper_msgs_conv
from slip_cell_common.log_sink import log_event
from slip_cell_common.diagnostics import DiagnosticsPublisher
from slip_cell_common.time_conv import clock_seconds
from slip_cell_common.node_main import run_node
from slip_cell_common.param_binding import ParameterBinding
from slip_cell_common.qos import (COMMAND, LATCHED, QUIET_PUB, QUIET_SUB, SENSOR_PUB,
                                            SENSOR_SUB, overridable)
from slip_gripper_driver.core.driver_core import GripperDriverCore
from slip_gripper_driver.core.gripper_records import (BridgeDiagnostics, LineResult, LinkState,
                                                      WatchdogResult)
from slip_gripper_driver.core.force_control import BypassReason
from slip_cell_common.core.frames import FrameParams, finger_transforms, static_transforms
from slip_cell_common.core.gripper_urdf import finger_joint_names
from slip_cell_common.core import names
from slip_cell_common.core.monitors import Level, Report
from slip_gripper_driver.core.netft_client import NetFTError
from slip_cell_common.core.param_schema import ParameterError
from slip_gripper_driver.core.realtime import ThreadTuning, freeze_gc, unfreeze_gc
from slip_cell_common.core.serial_transport import ByteStream, LinkError, open_stream
from slip_gripper_driver.ft_channel import (FT_SUPERVISE_PERIOD_S, FtChannel, TopicFtInput,
                                            run_bias, wrench_publisher)
from slip_gripper_driver.gripper_action import BridgePort, GripperActionServers
from slip_gripper_driver.gripper_model import GripperModelPublisher
from slip_gripper_driver.node_params import GripperDriverParams

#: Link watchdog period [s] (≤ 10 ms: stale detection ≤ 20 + 5 ms). It runs on a thread of
#: the core (`GripperDriverCore.start_watchdog`), not as an executor timer.
WATCHDOG_PERIOD_S = 0.005
#: While the link is not OK, status is published from the watchdog every n-th tick.
DEGRADED_STATUS_EVERY = 4
#: Nominal firmware telemetry rate [Hz] (hardware_protocols §1.1) and diagnostics tolerance.
TELEMETRY_RATE_HZ = 500.0
TELEMETRY_RATE_TOLERANCE = 0.1
#: GIL switch interval for the driver process [s] (bench: keeps reader-thread latency low).
SWITCH_INTERVAL_S = 5e-4

SUCCESS = TransitionCallbackReturn.SUCCESS
FAILURE = TransitionCallbackReturn.FAILURE


class TaskDiagnostics(DiagnosticsPublisher):
    """`DiagnosticsPublisher` with a hardware id per task (port for the link, IP per box)."""

    def __init__(self, node: LifecycleNode, hardware_id: str = '', period_s: float = 1.0) -> None:
        super().__init__(node, hardware_id, period_s)
        self._ids: dict[str, str] = {}
        self._prefix = f'{node.get_name()}: '

    def add_task(self, name: str, task: Callable[[float], Report], hardware_id: str) -> None:
        """Register ``task`` reported with ``hardware_id``."""
        self._ids[self._prefix + name] = hardware_id
        self.add(name, task)

    def statuses(self) -> list[Any]:
        """Every task's status with its own hardware id."""
        out = super().statuses()
        for status in out:
            status.hardware_id = self._ids.get(status.name, self.hardware_id)
        return out


class GripperDriverNode(LifecycleNode):
    """The gripper bridge node; see the module docstring.

    Args:
        node_name: Node name.
        **kwargs: Passed to `rclpy.lifecycle.LifecycleNode` (``context``,
            ``parameter_overrides``, ...).
    """

    def __init__(self, node_name: str = 'gripper_driver', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.params = ParameterBinding(self, GripperDriverParams)
        self.frame_params = ParameterBinding(self, FrameParams, prefix='frames.')
        self.params.on_change(self._on_params)
        self.core: GripperDriverCore | None = None
        self._open_retry = False  # configure could not open the port: activation retries
        self._gc_frozen = False
        self.channels: list[FtChannel] = []
        self.topic_inputs: list[TopicFtInput] = []
        self.last_error = ''
        self._cfg = GripperDriverParams()
        self._tuning = ThreadTuning()
        self._frames = FrameParams()
        self._publishing = False
        self._lines = 0
        self._ticks = 0
        self._last_state = LinkState.INACTIVE
        self._rate_ref: tuple[float, int] | None = None
        self._homing_finished = threading.Event()
        self._entities: list[Any] = []
        self._endpoint_timers: list[Any] = []
        self._diag: TaskDiagnostics | None = None
        self._model: GripperModelPublisher | None = None
        self._actions: GripperActionServers | None = None
        self._action_group = ReentrantCallbackGroup()
        self._pubs: dict[str, Any] = {}
        self._bias_clients: list[Any] = []
        self._long_group = MutuallyExclusiveCallbackGroup()
        self._client_group = ReentrantCallbackGroup()
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._jump = self.get_clock().create_jump_callback(
            JumpThreshold(min_forward=None, min_backward=Duration(nanoseconds=-1_000_000),
                          on_clock_change=True), post_callback=self._on_clock_jump)

    # ------------------------------------------------------------------ helpers
    def now(self) -> float:
        """Node clock [s] (sim time under ``use_sim_time``): the stamp of every sample."""
        return clock_seconds(self.get_clock())

    def _fail(self, message: str) -> TransitionCallbackReturn:
        self.last_error = message
        self.get_logger().error(message)
        self._release(self.now())
        return FAILURE

    def _active(self) -> bool:
        return self.core is not None and self._publishing

    def tune_spin_thread(self) -> str:
        """Apply ``realtime.*`` scheduling to the calling thread (the thread that spins).

        The reader threads alone are not enough in a Python process: a normal-priority
        executor thread holding the GIL can be preempted by any other process, and the
        ``SCHED_FIFO`` reader then waits for the GIL (priority inversion; seen as 1–4 ms
        latency outliers through the node). ``main`` calls this on the spinning thread before
        the executor starts its worker threads, which inherit the policy. Fails soft.

        Returns:
            The outcome, e.g. ``'SCHED_FIFO 10'`` (also logged when it failed).
        """
        realtime = self.params.load().realtime
        tuning = ThreadTuning.from_params(realtime)
        tuning.apply()
        for problem in tuning.take_failures():
            self.get_logger().warning(f'realtime: {problem}; executor threads run with normal '
                                      'scheduling')
        return next(iter(tuning.results.values()), 'normal')

    # ------------------------------------------------------------------ lifecycle
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Validate parameters, open the port, start both RDT streams, create endpoints."""
        del state
        self.last_error = ''
        try:
            cfg = self.params.load()
            self._frames = self.frame_params.load()
        except ParameterError as exc:
            return self._fail(f'invalid parameters: {exc}')
        self._cfg = cfg
        # realtime.*: the serial and Net F/T reader threads tune themselves when they start.
        self._tuning = tuning = ThreadTuning.from_params(cfg.realtime)
        core = GripperDriverCore(cfg.serial.port, cfg.bridge(), clock=self.now,
                                 baudrate=cfg.serial.baudrate, reconnect=cfg.reconnect,
                                 on_result=self._on_result, on_event=self._on_event,
                                 opener=_opener(cfg.link.fault_after),
                                 thread_setup=tuning.apply)
        self._open_retry = False
        try:
            core.configure()
        except LinkError as exc:
            # Port missing, busy or still enumerating: configured without it; activation
            # keeps opening it with back-off until it works or the node is deactivated.
            self._open_retry = True
            self.last_error = f'cannot open the gripper serial port: {exc}'
            self.get_logger().error(
                f'{self.last_error}; configured without the port: it is opened with back-off '
                f'({cfg.reconnect.initial_delay:g} s doubling up to {cfg.reconnect.max_delay:g} '
                's) while the node is active')
        self.core = core
        if cfg.ft.mode == 'embedded':
            for finger, address, port, http_port in cfg.ft.boxes():
                channel = FtChannel(finger, address, cfg.ft.stream, cfg.bias, port=port,
                                    http_port=http_port,
                                    start=cfg.ft.start, clock=self.now, sink=self._ft_sink,
                                    restart_initial_s=cfg.reconnect.initial_delay,
                                    restart_max_s=cfg.reconnect.max_delay,
                                    thread_setup=tuning.apply)
                try:
                    channel.open()
                except NetFTError as exc:
                    # Booting, unplugged or unreachable: configured without it; the channel
                    # keeps opening it with back-off (no bias meanwhile: the loop runs open
                    # loop, as before any bias).
                    problem = f'finger {finger} Net F/T: {exc}'
                    self.last_error = '; '.join(filter(None, (self.last_error, problem)))
                    self.get_logger().error(
                        f'{problem}; configured without it: opened with back-off '
                        f'({cfg.reconnect.initial_delay:g} s doubling up to '
                        f'{cfg.reconnect.max_delay:g} s) until it works or the node is cleaned '
                        'up; until then gripper/bias_ft is refused and the loop runs open loop')
                    channel.keep_opening(str(exc), self._log_event)
                self.channels.append(channel)
            # An old F/T sample with records waiting unread is the host's delay, not a silent
            # box: the loop keeps it stale (open loop) instead of faulting (safe_hold_force).
            channels = list(self.channels)
            core.bridge.set_ft_backlog_probe(
                lambda finger: channels[finger - 1].input_pending() > 0)
        self._create_endpoints(cfg)
        if cfg.realtime.freeze_gc:
            # Everything configure keeps is alive now: later collections never scan it.
            freeze_gc()
            self._gc_frozen = True
        self.get_logger().info(
            f'configured: {cfg.serial.port}, F/T {cfg.ft.mode}'
            + (''.join(f', finger {c.finger} at {c.name}' for c in self.channels)))
        return SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Arm, start the 500 Hz reader and the watchdog, publish the static frames."""
        assert self.core is not None
        t = self.now()
        self._lines = 0
        self._publishing = True
        for channel in self.channels:
            channel.publishing = True
        try:
            self.core.activate(t, open_retry=self._open_retry)
        except LinkError as exc:
            self._publishing = False
            for channel in self.channels:
                channel.publishing = False
            self.last_error = f'cannot activate: {exc}'
            self.get_logger().error(self.last_error)
            return FAILURE
        self._pubs['static_frames'].publish(
            gripper_msgs_conv.transforms_msg(t, static_transforms(self._frames)))
        if self._model is not None:
            self._model.send_static(t)
        self._last_state = LinkState.INACTIVE
        self.core.start_watchdog(WATCHDOG_PERIOD_S, self._on_watchdog)
        if self._cfg.bias.on_activate:
            self._start_background_bias(t)
        else:
            self.get_logger().info(
                f'{names.ft_wrench(1)} and {names.ft_wrench(2)} stay silent until '
                f'{names.GRIPPER_BIAS_FT_SRV} has run (gripper open and empty): the wrench is '
                'published bias-removed only')
        if self.core.link.connected:
            self.get_logger().info(f'active: armed on {self.core.port}')
        else:
            self.get_logger().warning(f'active without the port: opening {self.core.port} with '
                                      'back-off until it works or the node is deactivated')
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Safe voltage first, then stop the reader thread, the watchdog and publishing."""
        if self.core is not None:
            written = self.core.deactivate(self.now())
            if written:
                self.get_logger().info(f'{self.core.port}: safe voltage written; inactive')
            else:
                self.get_logger().error(f'{self.core.port}: safe voltage could not be written '
                                        'on deactivate (link down)')
        self._publishing = False
        for channel in self.channels:
            channel.publishing = False
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Safe voltage (if still possible), stop the RDT streams, close everything."""
        del state
        self._release(self.now())
        return SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Same as cleanup, from any state (SIGINT/SIGTERM through `run_node`)."""
        del state
        self._release(self.now())
        return SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """A transition raised: make the gripper safe and return to unconfigured."""
        del state
        self._release(self.now())
        return SUCCESS

    def _release(self, t: float) -> None:
        """Safe voltage first, then streams, port and ROS endpoints (idempotent)."""
        self._publishing = False
        if self.core is not None:
            self.core.shutdown(t)
            self.core = None
        for channel in self.channels:
            channel.close()
        self.channels = []
        self._destroy_endpoints()
        if self._gc_frozen:
            # The loop threads have ended: let the final collection at exit tear rclpy and
            # DDS down again (frozen, they outlived it: heap corruption at exit, issue 16).
            unfreeze_gc()
            self._gc_frozen = False

    def _log_event(self, level: str, message: str) -> None:
        """``(level, message)`` sink of helper threads (``'info'``, ``'warn'``, ``'error'``)."""
        log_event(self.get_logger(), level, message)

    # ------------------------------------------------------------------ endpoints
    def _create_endpoints(self, cfg: GripperDriverParams) -> None:
        opts = overridable()
        pub = self.create_publisher
        self._pubs = {
            'status': pub(GripperStatus, names.GRIPPER_STATUS, SENSOR_PUB,
                          qos_overriding_options=opts, event_callbacks=QUIET_PUB),
            'motor': pub(MotorCommand, names.MOTOR_COMMAND, SENSOR_PUB,
                         qos_overriding_options=opts, event_callbacks=QUIET_PUB),
            'joints': pub(JointState, names.GRIPPER_JOINT_STATES, SENSOR_PUB,
                          qos_overriding_options=opts, event_callbacks=QUIET_PUB),
            'static_frames': pub(TransformArray, names.STATIC_FRAMES, LATCHED,
                                 qos_overriding_options=opts),
            'finger_frames': pub(TransformArray, names.FINGER_FRAMES, SENSOR_PUB,
                                 qos_overriding_options=opts, event_callbacks=QUIET_PUB),
        }
        entities: list[Any] = list(self._pubs.values())
        # /tf_static, /tf and robot_description (latched now, before activation).
        self._model = GripperModelPublisher(self, self._frames)
        # control_msgs GripperCommand / ParallelGripperCommand (goals need a homed gripper).
        self._actions = GripperActionServers(
            self, BridgePort(lambda: self.core.bridge if self.core is not None else None,
                             self.now),
            finger_joint_names(self._frames), callback_group=self._action_group)
        for channel in self.channels:
            k = channel.finger
            frame = self._frames.frame_id(names.ft_sensor_frame(k))
            wrench = pub(WrenchStamped, names.ft_wrench(k), SENSOR_PUB,
                         qos_overriding_options=opts, event_callbacks=QUIET_PUB)
            raw = pub(WrenchStamped, names.ft_raw(k), SENSOR_PUB,
                      qos_overriding_options=opts, event_callbacks=QUIET_PUB)
            channel.publish_wrench = wrench_publisher(wrench, frame)
            channel.publish_raw = wrench_publisher(raw, frame)
            entities += [wrench, raw]
        self.topic_inputs = []
        self._bias_clients = []
        if cfg.ft.mode == 'topic':
            for k in (1, 2):
                topic = names.ft_wrench(k)
                stream = cfg.ft.stream
                source = TopicFtInput(k, topic, stream.expected_rate / stream.publish_decimation,
                                      stream.rate_tolerance, self._ft_sink)
                self.topic_inputs.append(source)

                def on_wrench(msg: WrenchStamped, s: TopicFtInput = source) -> None:
                    s.on_wrench(*gripper_msgs_conv.wrench_from_msg(msg))

                # One group per finger: F/T delivery (1 kHz in all) never waits behind
                # timers, services or the other finger in the node's default group.
                entities.append(self.create_subscription(
                    WrenchStamped, topic, on_wrench, SENSOR_SUB,
                    callback_group=MutuallyExclusiveCallbackGroup(), event_callbacks=QUIET_SUB))
                client = self.create_client(Trigger, names.ft_bias_srv(k),
                                            callback_group=self._client_group)
                self._bias_clients.append(client)
                entities.append(client)
        entities.append(self.create_subscription(GraspForceCommand, names.GRASP_FORCE_CMD,
                                                 self._on_command, COMMAND))
        entities += [
            self.create_service(Trigger, names.GRIPPER_HOME_SRV, self._srv_home,
                                callback_group=self._long_group),
            self.create_service(Trigger, names.GRIPPER_BIAS_FT_SRV, self._srv_bias,
                                callback_group=self._long_group),
            self.create_service(Trigger, names.GRIPPER_STOP_SRV, self._srv_stop),
            self.create_service(Trigger, names.GRIPPER_ARM_SRV, self._srv_arm),
        ]
        self._entities = entities
        # Not `self._timers`: that name is rclpy.Node's own list of the node's timers.
        self._endpoint_timers = [self.create_timer(FT_SUPERVISE_PERIOD_S,
                                                   self._on_ft_supervise, clock=self._steady)]
        port = cfg.serial.port
        diag = TaskDiagnostics(self, port)
        diag.add_task('link', self._diag_link, port)
        diag.add_task('homing', self._diag_homing, port)
        diag.add_task('force_loop', self._diag_force_loop, port)
        for k in (1, 2):
            if self.channels:
                hw = self.channels[k - 1].address
            else:
                hw = names.ft_wrench(k)
            diag.add_task(f'ft_{k}', functools.partial(self._diag_ft, k), hw)
        self._diag = diag

    def _destroy_endpoints(self) -> None:
        for timer in self._endpoint_timers:
            self.destroy_timer(timer)
        self._endpoint_timers = []
        if self._diag is not None:
            self._diag.destroy()
            self._diag = None
        for entity in self._entities:
            kind = type(entity).__name__
            destroyers: dict[str, Callable[[Any], bool]] = {
                'Publisher': self.destroy_publisher,
                'Subscription': self.destroy_subscription,
                'Service': self.destroy_service,
                'Client': self.destroy_client}
            destroy = destroyers.get(kind)
            if destroy is not None:
                destroy(entity)
        self._entities = []
        self._pubs = {}
        if self._model is not None:
            self._model.destroy()
            self._model = None
        if self._actions is not None:
            self._actions.destroy()
            self._actions = None
        self.topic_inputs = []
        self._bias_clients = []

    # ------------------------------------------------------------------ reader threads
    def _on_result(self, result: LineResult) -> None:
        """Serial reader thread, after the command of this line was written."""
        if not self._publishing:
            return
        pubs = self._pubs
        status = result.status
        if status is not None:
            pubs['status'].publish(gripper_msgs_conv.status_msg(status))
            actions = self._actions
            if actions is not None:
                actions.on_status(status)   # gripper actions: outer position loop
            self._lines += 1
            if self._lines % self._cfg.joint_states.decimation == 0:
                self._publish_joints(status.stamp, status.opening, status.opening_rate,
                                     status.measured_grasp_force)
        if result.motor is not None:
            pubs['motor'].publish(gripper_msgs_conv.motor_msg(result.motor))

    def _publish_joints(self, stamp: float, opening: float, rate: float, force: float) -> None:
        prefix = self._frames.tf_prefix
        self._pubs['joints'].publish(gripper_msgs_conv.joint_state_msg(
            stamp, (prefix + names.finger_joint(1), prefix + names.finger_joint(2)), opening, rate,
            force))
        if math.isfinite(opening):  # frames need a homed opening
            self._pubs['finger_frames'].publish(
                gripper_msgs_conv.transforms_msg(stamp, finger_transforms(self._frames, opening)))
        model = self._model
        if model is not None:
            model.send_fingers(stamp, opening)

    def _ft_sink(self, finger: int, stamp: float, wrench: Any) -> None:
        """Net F/T reader thread (or topic callback): feed the loop's F_m."""
        core = self.core
        if core is None:
            return
        core.bridge.on_ft_wrench(finger, stamp, wrench)

    def _on_event(self, t: float, kind: str, message: str) -> None:
        del t
        log = self.get_logger()
        if kind in ('homing_done', 'homing_failed'):
            self._homing_finished.set()
        # Each message states what the driver did (core.driver_core.EVENT_TEXT and the link
        # watchdog): nothing is appended here that the driver did not do.
        if kind in ('connected', 'homing_done'):
            log.info(message)
        elif kind == 'lost':
            log.error(f'{message}; safe state, disarmed (gripper/arm required), reconnecting')
        elif kind in ('firmware_restart', 'fault', 'homing_failed', 'host_stall_fault'):
            log.error(message)
        elif kind in ('stale', 'host_stall'):
            log.warning(message)
        else:  # 'error': failed reopen attempts, repeated with back-off
            log.warning(message, throttle_duration_sec=1.0)

    # ------------------------------------------------------------------ watchdog thread
    def _on_watchdog(self, t: float, result: WatchdogResult) -> None:
        """After each link check (core watchdog thread, every `WATCHDOG_PERIOD_S`)."""
        core = self.core
        if core is None:
            return
        self._ticks += 1
        changed = result.state != self._last_state
        self._last_state = result.state
        pub = self._pubs.get('status')
        # LAGGING: telemetry waits at the port (the host is behind): the reader publishes
        # the status of those lines when it catches up; nothing to add from here.
        if result.state not in (LinkState.OK, LinkState.INACTIVE, LinkState.LAGGING) and \
                self._publishing and \
                pub is not None and (changed or self._ticks % DEGRADED_STATUS_EVERY == 0):
            # No lines arrive, so the reader publishes nothing: report link_ok = false here.
            pub.publish(gripper_msgs_conv.status_msg(core.bridge.status(t)))

    # ------------------------------------------------------------------ executor callbacks
    def _on_ft_supervise(self) -> None:
        for problem in self._tuning.take_failures():  # logged once per thread, soft failure
            self.get_logger().warning(f'realtime: {problem}; running with normal scheduling')
        t = self.now()
        for channel in self.channels:
            channel.supervise(t, self._cfg.force_control.ft_fault_after)

    def _on_command(self, msg: GraspForceCommand) -> None:
        core = self.core
        if core is None:
            return
        force, stamp, timeout, source = gripper_msgs_conv.grasp_command(msg)
        result = core.bridge.set_grasp_force(force, self.now(), stamp=stamp, timeout=timeout,
                                             source=source)
        if not result.accepted:
            self.get_logger().warning(f'{names.GRASP_FORCE_CMD}: command {force!r} N refused: '
                                      f'{result.reason}', throttle_duration_sec=1.0)

    def _on_params(self, cfg: GripperDriverParams) -> None:
        """Run-time parameter change: swap the immutable sets between two control steps."""
        self._cfg = cfg
        if self.core is not None:
            self.core.bridge.set_params(cfg.bridge())
        for channel in self.channels:
            channel.apply(cfg.ft.stream, cfg.bias)

    def _on_clock_jump(self, jump: TimeJump) -> None:
        if self.core is not None and jump.delta.nanoseconds < 0:
            self.core.bridge.reset(self.now())
            self.get_logger().warning('clock jumped backwards: observer, controller and '
                                      'ages reset')

    # ------------------------------------------------------------------ services
    def _srv_home(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        del request
        core = self.core
        if not self._active() or core is None:
            response.success, response.message = False, 'gripper_driver is not active'
            return response
        self._homing_finished.clear()
        started = core.bridge.start_homing(self.now())
        if not started.accepted:
            response.success, response.message = False, f'homing refused: {started.reason}'
            return response
        deadline = time.monotonic() + 2.0 * self._cfg.homing.timeout + 1.0
        homing = core.bridge.homing
        while homing.active and time.monotonic() < deadline:
            self._homing_finished.wait(0.05)
        response.success = homing.homed and not homing.active
        response.message = homing.message or ('homed' if response.success else 'not homed')
        return response

    def _srv_bias(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        del request
        if self.core is None:  # the streams run from configure on: inactive is fine
            response.success, response.message = False, 'gripper_driver is not configured'
            return response
        refusal = self.core.bridge.bias_refusal(self.now())
        if refusal is not None:
            response.success, response.message = False, f'bias refused: {refusal}'
            self.get_logger().error(response.message)
            return response
        if self.channels:
            ok, message = run_bias(self.channels, self.now,
                                   self._cfg.force_control.ft_fault_after)
        else:
            ok, message = self._bias_remote()
        response.success, response.message = ok, message
        log_event(self.get_logger(), 'info' if ok else 'error', f'bias: {message}')
        return response

    def _bias_remote(self) -> tuple[bool, str]:
        """``ft.mode: topic``: call ``finger_k/ft/bias`` of both standalone drivers."""
        timeout = self._cfg.bias.duration + 5.0
        results: list[str] = []
        ok = True
        for client in self._bias_clients:
            if not client.wait_for_service(timeout_sec=1.0):
                ok = False
                results.append(f'{client.srv_name}: service not available')
                continue
            done = threading.Event()
            future = client.call_async(Trigger.Request())
            future.add_done_callback(lambda _f, done=done: done.set())
            if not done.wait(timeout):
                client.remove_pending_request(future)
                ok = False
                results.append(f'{client.srv_name}: no answer within {timeout:.1f} s')
                continue
            reply = future.result()
            ok = ok and bool(reply.success)
            results.append(f'{client.srv_name}: {reply.message}')
        return ok, '; '.join(results)

    def _start_background_bias(self, t: float) -> None:
        """``bias.on_activate``: start the windows without waiting (results in diagnostics)."""
        refusal = self.core.bridge.bias_refusal(t) if self.core is not None else None
        if refusal is not None:
            self.get_logger().error(f'bias.on_activate: bias refused: {refusal}')
            return
        for channel in self.channels:
            channel.start_bias(t)
        for client in self._bias_clients:
            client.call_async(Trigger.Request())

    def _srv_stop(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        del request
        if self.core is None:
            response.success, response.message = False, 'gripper_driver is not configured'
            return response
        written = self.core.bridge.stop(self.now())
        response.success = written
        response.message = ('safe voltage written; target 0 N until the next command'
                            if written else f'{self.core.port}: safe voltage not written '
                            '(link down)')
        return response

    def _srv_arm(self, request: Trigger.Request, response: Trigger.Response
                 ) -> Trigger.Response:
        del request
        if not self._active() or self.core is None:
            response.success, response.message = False, 'gripper_driver is not active'
            return response
        result = self.core.bridge.arm(self.now())
        response.success, response.message = result.accepted, result.reason
        if result.accepted:
            self.get_logger().info('armed by gripper/arm; target cleared to 0 N')
        return response

    # ------------------------------------------------------------------ diagnostics
    def _diag_link(self, now: float) -> Report:
        core = self.core
        if core is None:
            return Report(Level.STALE, 'not configured')
        d = core.bridge.diagnostics(now)
        s = core.stats()
        rate = self._line_rate(now, d.lines_good)
        values = (
            ('port', core.port), ('connected', str(s.connected).lower()),
            ('link_state', d.link_state.name), ('rate_hz', f'{rate:.1f}'),
            ('expected_hz', f'{TELEMETRY_RATE_HZ:.1f}'), ('line_age_s', f'{d.line_age_s:.4f}'),
            ('lines_good', str(d.lines_good)), ('lines_bad', str(d.lines_bad)),
            ('lines_unknown', str(d.lines_unknown)), ('lines_non_finite', str(d.lines_non_finite)),
            ('lines_too_long', str(d.lines_too_long)),
            ('firmware_rejects', str(d.firmware_rejects)),
            ('firmware_restarts', str(d.firmware_restarts)), ('reconnects', str(d.reconnects)),
            ('link_losses', str(d.link_losses)), ('stale_events', str(d.stale_events)),
            ('host_stalls', str(d.host_stalls)),
            ('max_host_stall_s', f'{d.max_host_stall_s:.3f}'),
            ('max_watchdog_gap_s', f'{d.max_watchdog_gap_s:.3f}'),
            ('catch_up_lines', str(d.catch_up_lines)), ('resume_ramps', str(d.resume_ramps)),
            ('ft_host_lag_steps', str(d.ft_host_lag_steps)),
            ('connect_failures', str(s.connect_failures)),
            ('write_failures', str(d.write_failures)), ('armed', str(d.armed).lower()),
            ('safe_reason', d.safe_reason), ('last_error', s.last_error),
            ('scheduling', '; '.join(f'{k}: {v}' for k, v in
                                     sorted(self._tuning.results.items())) or 'not started'))
        if d.link_state in (LinkState.DOWN, LinkState.FAULT):
            return Report(Level.ERROR, f'{core.port}: link {d.link_state.name.lower()}'
                          + (f' ({s.last_error})' if s.last_error else ''), values)
        if d.link_state == LinkState.STALE:  # a gap shorter than link.fault_after
            action = ('safe voltage applied' if core.bridge.status(now).safe_state else
                      'the firmware keeps the last command')
            return Report(Level.WARN, f'{core.port}: link stale: no telemetry for '
                          f'{d.line_age_s:.3f} s ({action})', values)
        if d.link_state == LinkState.INACTIVE:
            return Report(Level.OK, f'{core.port}: connected, inactive', values)
        if d.link_state == LinkState.LAGGING:
            return Report(Level.WARN, f'{core.port}: host stall: telemetry waits unprocessed '
                          f'for {d.line_age_s:.3f} s (the firmware keeps sending)', values)
        if abs(rate - TELEMETRY_RATE_HZ) > TELEMETRY_RATE_TOLERANCE * TELEMETRY_RATE_HZ:
            return Report(Level.WARN, f'{core.port}: line rate {rate:.0f} Hz', values)
        if not d.armed:
            return Report(Level.WARN, f'{core.port}: disarmed ({d.safe_reason}); '
                          'call gripper/arm', values)
        return Report(Level.OK, f'{core.port}: telemetry ok, armed', values)

    def _line_rate(self, now: float, lines: int) -> float:
        ref = self._rate_ref
        self._rate_ref = (now, lines)
        if ref is None or now <= ref[0] or lines < ref[1]:
            return math.nan
        return (lines - ref[1]) / (now - ref[0])

    def _diag_homing(self, now: float) -> Report:
        core = self.core
        if core is None:
            return Report(Level.STALE, 'not configured')
        homing = core.bridge.homing
        result = homing.result
        values = (('homed', str(homing.homed).lower()), ('active', str(homing.active).lower()),
                  ('phase', homing.phase.name), ('message', homing.message),
                  ('stroke_m', f'{result.stroke:.4f}' if result is not None else 'nan'))
        if homing.active:
            return Report(Level.OK, 'homing in progress', values)
        if homing.homed:
            return Report(Level.OK, 'homed', values)
        return Report(Level.WARN, f'{homing.message or "not homed"}; call gripper/home', values)

    def _diag_force_loop(self, now: float) -> Report:
        core = self.core
        if core is None:
            return Report(Level.STALE, 'not configured')
        d: BridgeDiagnostics = core.bridge.diagnostics(now)
        mode = 'closed loop' if d.closed_loop else f'open loop ({d.bypass_reason.name.lower()})'
        values = (
            ('mode', mode), ('bypass_reason', d.bypass_reason.name),
            ('armed', str(d.armed).lower()), ('saturations', str(d.saturations)),
            ('skipped_integrations', str(d.skipped_integrations)),
            ('command_age_s', f'{d.command_age_s:.3f}'), ('command_source', str(d.command_source)),
            ('commands_accepted', str(d.commands_accepted)),
            ('commands_rejected', str(d.commands_rejected)),
            *((f'rejected_{k}', str(v)) for k, v in d.rejected_by_reason),
            ('commands_ignored', str(d.commands_ignored)),
            ('targets_clipped', str(d.targets_clipped)),
            ('ft_age_s', ' '.join(f'{a:.4f}' for a in d.ft_age_s)),
            ('ft_biased', ' '.join(str(b).lower() for b in d.ft_biased)))
        if not d.active:
            return Report(Level.OK, 'inactive', values)
        if not d.armed:
            return Report(Level.WARN, f'disarmed: {d.safe_reason}', values)
        if d.bypass_reason == BypassReason.FT_STALE:
            return Report(Level.ERROR, 'F/T stale while controlling', values)
        return Report(Level.OK, mode, values)

    def _diag_ft(self, finger: int, now: float) -> Report:
        stale = self._cfg.force_control.ft_fault_after
        if self.channels:
            return self.channels[finger - 1].report(now, stale)
        if self.topic_inputs:
            return self.topic_inputs[finger - 1].report(now, stale)
        return Report(Level.STALE, 'not configured')


def _opener(write_timeout_s: float) -> Callable[..., ByteStream]:
    """`open_stream` with the write timeout set to ``link.fault_after``.

    pyserial checks its write timeout *after* ``os.write`` returned, so a thread that waited
    for the GIL longer than the timeout gets ``Write timeout`` for bytes already written: with
    the 50 ms default a busy process sees false link faults (disarm, reconnect). A write that
    really blocks that long is a link fault anyway, so both limits are one parameter.
    """
    def opener(url: str, baudrate: int, timeout_s: float, **_: Any) -> ByteStream:
        return open_stream(url, baudrate, timeout_s, write_timeout_s=write_timeout_s)
    return opener


def _tuned_node() -> GripperDriverNode:
    """The node, with the main (spinning) thread tuned per ``realtime.*``."""
    node = GripperDriverNode()
    node.tune_spin_thread()
    return node


def main(args: list[str] | None = None) -> int:
    """Console entry point ``gripper_driver``."""
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    return run_node(_tuned_node, args, multithreaded=True)


if __name__ == '__main__':
    sys.exit(main())
