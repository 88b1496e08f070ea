"""``sim_gripper``: the simulated gripper cell as a lifecycle node.

It publishes exactly what ``gripper_driver`` and both ``velocity_sensor`` nodes publish on
hardware (topics, types, frames, QoS, stamps at acquisition), accepts the same grasp-force
command, and offers the same services (``gripper/bias_ft``, ``gripper/home``,
``gripper/stop``, ``gripper/arm``, ``finger_k/slip/reset_pose``,
``finger_k/slip/set_chip_mode``). In addition it publishes ``/clock``, the ground truth
(``sim/state``, ``sim/object_pose``, ``sim/object_twist``, latched ``sim/true_contact``) and
serves the arm/scene interface (``sim/move_gripper``, ``sim/reset_scene``, ``sim/reset``,
``sim/apply_disturbance``).

Timing: a simulation thread advances the physics in chunks of ``step_period`` wall seconds
times ``realtime_factor`` and publishes every sensor event with its simulated acquisition
stamp, then ``/clock``; nodes with ``use_sim_time`` therefore see a consistent clock at any
real-time factor. A host too slow for that slows the simulation (at most ``max_catch_up`` of
simulated time per tick, `friction_models.core.pacing`): simulated time is never skipped and
never caught up in bursts, the achieved factor (``sim/state.realtime_factor``, the
``realtime_factor`` diagnostics with ``behind_real_time_s``) drops below the target, and every
node on ``/clock`` follows the slower world. It also waits for the controller that closes the
loop through it: never more than ``max_input_lag`` of simulated time beyond the stamp of the
newest streaming grasp-force command (``timeout`` > 0, the slip controller), so a starved
controller's corrections are not applied hundreds of simulated milliseconds late
(`friction_models.core.pacing.InputHorizon`; ``max_input_wait`` of wall time at most).
All physics and sensors are in `friction_models.core.sim_cell`, which runs
the gripper driver's own host side (its bridge: command gate, inner loop, homing, stop, F/T
bias); the gripper messages are built from the bridge's records by the driver's own
`slip_gripper_driver.gripper_msgs_conv`, so ``gripper/status`` and ``gripper/motor_command``
read exactly as on hardware.
"""
from __future__ import annotations

import functools
import math
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypedDict

from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
from rclpy.clock import ROSClock
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.time import Time
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from slip_msgs.msg import (ContactProperties, GraspForceCommand, GripperStatus, MotorCommand,
                           PlanarSlip, SimState, TransformArray)
from slip_msgs.srv import ApplyDisturbance, MoveGripper, ResetScene, SetChipMode
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from friction_models import sim_msgs_conv
from friction_models.core import NATIVE_STATUS
from friction_models.core.pacing import InputHorizon, RealTimePacer
from friction_models.core.presets import PresetError, load_presets, reference_presets
from friction_models.core.scene_frames import object_markers, scene_transforms
from friction_models.core.sim_cell import SimCell, SimParams
from slip_cell_common.diagnostics import DiagnosticsPublisher
from slip_cell_common.marker_conv import marker_array_msg
from slip_cell_common.time_conv import seconds_to_stamp
from slip_cell_common.core import names
from slip_cell_common.node_main import run_node
from slip_cell_common.param_binding import ParameterBinding
from slip_cell_common.qos import (CLOCK, COMMAND, LATCHED, QUIET_PUB, SENSOR_PUB,
                                            overridable)
from slip_cell_common.core.frames import finger_transforms, static_transforms
from slip_cell_common.core.gripper_urdf import GripperGeometry, finger_joint_names
from slip_cell_common.core.monitors import Level, Report
from slip_cell_common.core.param_schema import ParameterError
from slip_velocity_sensor.core.protocol import VelocityLine
from slip_velocity_sensor.core.session import SensorSession, SessionParams
from slip_velocity_sensor.velocity_msgs_conv import planar_slip_msg, twist_msg
from slip_gripper_driver import gripper_msgs_conv
from slip_gripper_driver.gripper_action import BridgePort, GripperActionServers
from slip_gripper_driver.gripper_model import GripperModelPublisher


#: Wall time the simulation thread sleeps after a tick even when behind [s]: the executor
#: thread (grasp-force commands, services) waits for the cell lock, and a loop that took it
#: again at once starved it (commands applied hundreds of simulated ms late under load).
MIN_YIELD_S = 0.0005


@dataclass(frozen=True)
class SimNodeParams:
    """Node-level settings of ``sim_gripper`` (the physics is `SimParams`)."""

    autostart: bool = field(default=True, metadata={
        'read_only': True, 'description': 'configure and activate on start'})
    publish_clock: bool = field(default=True, metadata={
        'read_only': True, 'description': 'publish /clock with the simulated time'})
    realtime_factor: float = field(default=1.0, metadata={
        'unit': '-', 'range': (0.01, 100.0),
        'description': 'simulated seconds per wall second'})
    step_period: float = field(default=0.002, metadata={
        'unit': 's', 'range': (0.0005, 0.05), 'read_only': True,
        'description': 'wall time between simulation/publication ticks'})
    max_catch_up: float = field(default=0.05, metadata={
        'unit': 's', 'range': (0.001, 1.0),
        'description': 'most simulated time advanced in one tick; a host too slow for real '
                       'time slows the simulation (real-time factor < target), nothing is '
                       'skipped'})
    max_input_lag: float = field(default=0.03, metadata={
        'unit': 's', 'range': (0.0, 10.0),
        'description': '(addition) most simulated time run ahead of the newest streaming '
                       'grasp-force command (timeout > 0: the slip controller); the simulation '
                       'waits for a controller that falls behind; 0 = never wait'})
    max_input_wait: float = field(default=0.5, metadata={
        'unit': 's', 'range': (0.01, 60.0),
        'description': '(addition) longest wall time to wait for the next streaming command; '
                       'then the simulation runs on and the last command expires'})
    preset: str = field(default='cardboard', metadata={
        'read_only': True, 'description': 'initial object/contact preset'})
    presets_file: str = field(default='', metadata={
        'read_only': True,
        'description': "extra presets YAML (absolute, or relative to this package's share "
                       "directory); '' = the installed config/sim_presets.yaml"})
    start_on_table: bool = field(default=True, metadata={
        'read_only': True, 'description': 'initial scene: object standing on the table'})
    ft_publish_decimation: int = field(default=2, metadata={
        'unit': '-', 'range': (1, 100), 'read_only': True,
        'description': 'publish every n-th F/T record (1 kHz box -> 500 Hz)'})
    publish_raw_ft: bool = field(default=False, metadata={
        'read_only': True, 'description': 'also publish finger_k/ft/raw'})
    joint_states_decimation: int = field(default=5, metadata={
        'unit': '-', 'range': (1, 100), 'read_only': True,
        'description': 'telemetry lines per joint state and finger frame (500 -> 100 Hz)'})
    ground_truth_rate: float = field(default=100.0, metadata={
        'unit': 'Hz', 'range': (1.0, 1000.0), 'read_only': True,
        'description': 'rate of sim/state, sim/object_pose, sim/object_twist'})
    velocity_stale_after: float = field(default=0.050, metadata={
        'unit': 's', 'range': (0.001, 10.0), 'read_only': True,
        'description': 'a velocity sample older than this is stale'})
    bias_timeout: float = field(default=2.0, metadata={
        'unit': 's', 'range': (0.2, 60.0),
        'description': 'longest simulated wait for gripper/bias_ft to complete'})


class _PublisherOptions(TypedDict):
    """Keyword options shared by the node's sensor-rate publishers."""

    qos_overriding_options: QoSOverridingOptions
    event_callbacks: PublisherEventCallbacks


class SimGripperNode(LifecycleNode):
    """Lifecycle node wrapping `SimCell` with the hardware drivers' ROS interface."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('sim_gripper', **kwargs)
        self._node_params = ParameterBinding(self, SimNodeParams)
        self._sim_params = ParameterBinding(self, SimParams)
        self._cfg: SimNodeParams | None = None
        self._cell: SimCell | None = None
        self._lock = threading.RLock()
        self._thread: threading.Thread | None = None
        self._running = threading.Event()
        self._drives_own_clock = False
        self._pubs: dict[str, Any] = {}
        self._endpoints: list[Any] = []
        self._diag: DiagnosticsPublisher | None = None
        self._model: GripperModelPublisher | None = None
        self._actions: GripperActionServers | None = None
        self._sessions: tuple[SensorSession, ...] | None = None  # fingers 1 and 2
        self._counters = {'line': 0, 'ft_1': 0, 'ft_2': 0, 'ticks': 0, 'late': 0,
                          'rejected_commands': 0, 'behind_s': 0.0}
        self._rtf_window: list[tuple[float, float]] = []
        self._next_truth = 0.0
        self._inputs = InputHorizon(0.0, 1.0)   # replaced with the parameters in _run

    # ------------------------------------------------------------------ lifecycle
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Validate parameters, load presets, build the cell and the ROS endpoints."""
        del state
        try:
            self._cfg = self._node_params.load()
            sim = self._sim_params.load()
            presets = self._load_presets(self._cfg.presets_file)
            self._cell = SimCell(sim, presets, self._cfg.preset)
            self._home_at_start(self._cell)
            self._cell.reset(None, self._cfg.start_on_table)
        except (ParameterError, PresetError, KeyError, ValueError) as exc:
            self.get_logger().error(f'configure failed: {exc.args[0] if exc.args else exc}')
            self._cell = None
            return TransitionCallbackReturn.FAILURE
        session_params = SessionParams(stale_after=self._cfg.velocity_stale_after,
                                       expected_rate=sim.velocity_sensor.rate)
        self._sessions = tuple(SensorSession(session_params, port=f'sim:finger_{k}',
                                             expected_name=f'sensor_{k}') for k in (1, 2))
        for s in self._sessions:
            s.mark_initialised(calibration_source='simulation', calibration_uploaded=False,
                               speed_term='zero')
        self._create_endpoints()
        self._drive_own_clock()
        self.get_logger().info(
            f'configured: preset {self._cfg.preset!r}, model {sim.model}, physics dt '
            f'{sim.physics_dt * 1e6:.0f} us, real-time factor {self._cfg.realtime_factor}, '
            f'simulation core {NATIVE_STATUS}')
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Publish the static frames and the truth, start the simulation thread."""
        assert self._cell is not None
        frames = self._cell.params.frames
        self._pubs['static_frames'].publish(
            gripper_msgs_conv.transforms_msg(self._cell.t, static_transforms(frames)))
        if self._model is not None:
            self._model.send_static(self._cell.t)
        self._publish_true_contact()
        self._publish_scene_markers()
        if not self._cell.ft_biased:
            self.get_logger().info(
                f'{names.ft_wrench(1)} and {names.ft_wrench(2)} stay silent until '
                f'{names.GRIPPER_BIAS_FT_SRV} has run (gripper open and empty): the wrench is '
                'published bias-removed only')
        self._running.set()
        self._thread = threading.Thread(target=self._run, name='sim_gripper', daemon=True)
        self._thread.start()
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop the simulation (the simulated motor gets 0 V)."""
        self._stop_thread()
        if self._cell is not None:
            with self._lock:
                self._cell.stop()
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Destroy the endpoints and the cell."""
        del state
        self._stop_thread()
        self._destroy_endpoints()
        self._cell = None
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop everything."""
        del state
        self._stop_thread()
        self._destroy_endpoints()
        return TransitionCallbackReturn.SUCCESS

    def _stop_thread(self) -> None:
        self._running.clear()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    # ------------------------------------------------------------------ setup
    def _home_at_start(self, cell: SimCell) -> None:
        """``homing_mode: instant``: adopt the simulated finger limits at power-up.

        The simulator knows its true stroke, so the opening (``gripper/status``,
        ``gripper/joint_states``, the finger frames on ``/tf``) is known from the start, as on
        a homed gripper. ``homing_mode: sequence`` leaves it unknown (NaN) until
        ``gripper/home`` has run the real stall sequence, as on hardware.
        """
        if cell.params.homing_mode != 'instant':
            self.get_logger().info('homing_mode sequence: opening unknown until gripper/home')
            return
        result = cell.home()
        if result.accepted:
            self.get_logger().info(f'homed with the simulated limits ({result.reason})')
        else:
            self.get_logger().warning(f'could not adopt the simulated limits: {result.reason}')

    def _load_presets(self, file: str) -> dict[str, Any]:
        if not file:
            default = self._share() / 'config' / 'sim_presets.yaml'
            return load_presets(default) if default.is_file() else reference_presets()
        path = Path(file)
        if not path.is_absolute():
            path = self._share() / path
        return load_presets(path)

    @staticmethod
    def _share() -> Path:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory('friction_models'))

    def _drive_own_clock(self) -> None:
        """Under ``use_sim_time``, set this node's clock from the simulation, not from /clock.

        The node *is* the /clock source: subscribing to its own /clock at the tick rate woke
        its executor 500 times a second and took most of a core (15 % → 70 % of a core alone,
        100 % in the sim graph, where the simulation then fell to ≈ 0.8× real time). Its clock
        is set directly by the simulation thread instead, so timers and diagnostics still run
        on simulated time.
        """
        clock_subs = [s for s in self.subscriptions if s.topic_name == names.CLOCK]
        if 'clock' not in self._pubs or not clock_subs:
            self._drives_own_clock = False
            return
        for sub in clock_subs:
            self.destroy_subscription(sub)
        self._drives_own_clock = True
        self.get_logger().info('use_sim_time: this node publishes /clock and sets its own clock '
                               'from the simulation (no /clock subscription)')

    def _create_endpoints(self) -> None:
        assert self._cell is not None and self._cfg is not None
        opts: _PublisherOptions = {'qos_overriding_options': overridable(),
                                   'event_callbacks': QUIET_PUB}
        pub = self.create_publisher
        self._pubs = {
            'status': pub(GripperStatus, names.GRIPPER_STATUS, SENSOR_PUB, **opts),
            'motor': pub(MotorCommand, names.MOTOR_COMMAND, SENSOR_PUB, **opts),
            'joints': pub(JointState, names.GRIPPER_JOINT_STATES, SENSOR_PUB, **opts),
            'static_frames': pub(TransformArray, names.STATIC_FRAMES, LATCHED),
            'finger_frames': pub(TransformArray, names.FINGER_FRAMES, SENSOR_PUB, **opts),
            'state': pub(SimState, names.SIM_STATE, SENSOR_PUB, **opts),
            'pose': pub(PoseStamped, names.SIM_OBJECT_POSE, SENSOR_PUB, **opts),
            'object_twist': pub(TwistStamped, names.SIM_OBJECT_TWIST, SENSOR_PUB, **opts),
            'truth': pub(ContactProperties, names.SIM_TRUE_CONTACT, LATCHED),
        }
        if self._cfg.publish_clock:
            self._pubs['clock'] = pub(Clock, names.CLOCK, CLOCK, event_callbacks=QUIET_PUB)
        self._pubs['markers'] = pub(MarkerArray, names.SIM_MARKERS, LATCHED)
        # /tf_static, /tf (fingers, arm, object) and robot_description (latched now).
        self._model = GripperModelPublisher(
            self, self._cell.params.frames,
            GripperGeometry(stroke=self._cell.params.actuator.stroke))
        # control_msgs GripperCommand / ParallelGripperCommand on the driver's bridge.
        self._actions = GripperActionServers(
            self, BridgePort(lambda: self._cell.bridge if self._cell is not None else None,
                             self._sim_now),
            finger_joint_names(self._cell.params.frames))
        for k in (1, 2):
            self._pubs[f'wrench_{k}'] = pub(WrenchStamped, names.ft_wrench(k), SENSOR_PUB,
                                            **opts)
            if self._cfg.publish_raw_ft:
                self._pubs[f'raw_{k}'] = pub(WrenchStamped, names.ft_raw(k), SENSOR_PUB,
                                             **opts)
            self._pubs[f'twist_{k}'] = pub(TwistStamped, names.slip_twist(k), SENSOR_PUB,
                                           **opts)
            self._pubs[f'slip_{k}'] = pub(PlanarSlip, names.slip_state(k), SENSOR_PUB,
                                          **opts)

            def reset_pose(req: Trigger.Request, res: Trigger.Response,
                           k: int = k) -> Trigger.Response:
                return self._on_reset_pose(k, res)

            self._endpoints += [
                self.create_service(Trigger, names.slip_reset_pose_srv(k), reset_pose),
                self.create_service(SetChipMode, names.slip_set_chip_mode_srv(k),
                                    functools.partial(self._on_chip_mode, k)),
            ]
        self._endpoints += [
            self.create_subscription(GraspForceCommand, names.GRASP_FORCE_CMD,
                                     self._on_force_cmd, COMMAND),
            self.create_service(Trigger, names.GRIPPER_BIAS_FT_SRV, self._on_bias),
            self.create_service(Trigger, names.GRIPPER_HOME_SRV, self._on_home),
            self.create_service(Trigger, names.GRIPPER_STOP_SRV, self._on_stop),
            self.create_service(Trigger, names.GRIPPER_ARM_SRV, self._on_arm),
            self.create_service(Trigger, names.SIM_RESET_SRV, self._on_reset),
            self.create_service(ResetScene, names.SIM_RESET_SCENE_SRV, self._on_reset_scene),
            self.create_service(MoveGripper, names.SIM_MOVE_GRIPPER_SRV, self._on_move),
            self.create_service(ApplyDisturbance, names.SIM_APPLY_DISTURBANCE_SRV,
                                self._on_disturb),
        ]
        self._diag = DiagnosticsPublisher(self, hardware_id='simulation')
        self._diag.add('realtime_factor', self._report_rtf)
        self._diag.add('scenario', self._report_scenario)
        for k, session in zip((1, 2), self._sessions or ()):

            def rate_report(now: float, s: SensorSession = session) -> Report:
                return s.reports(self._sim_now())['rate']

            self._diag.add(f'velocity_sensor_{k}', rate_report)

    def _destroy_endpoints(self) -> None:
        for ep in self._endpoints:
            if hasattr(ep, 'callback') and hasattr(ep, 'srv_type'):
                self.destroy_service(ep)
            else:
                self.destroy_subscription(ep)
        self._endpoints = []
        for p in self._pubs.values():
            self.destroy_publisher(p)
        self._pubs = {}
        if self._model is not None:
            self._model.destroy()
            self._model = None
        if self._actions is not None:
            self._actions.destroy()
            self._actions = None
        if self._diag is not None:
            self._diag.destroy()
            self._diag = None

    # ------------------------------------------------------------------ simulation thread
    def _sim_now(self) -> float:
        cell = self._cell
        return cell.t if cell is not None else 0.0

    def _run(self) -> None:
        assert self._cell is not None and self._cfg is not None
        period = self._cfg.step_period
        wall_prev = time.monotonic()
        next_tick = wall_prev + period
        pacer = RealTimePacer(self._cell.params.physics_dt)  # carries the fraction of a step
        with self._lock:
            self._inputs = InputHorizon(self._cfg.max_input_lag, self._cfg.max_input_wait)
        while self._running.is_set():
            now = time.monotonic()
            cfg = self._node_params.value
            with self._lock:
                cell = self._cell
                inputs = self._inputs
                inputs.max_lag_s, inputs.max_wait_s = cfg.max_input_lag, cfg.max_input_wait
                # Fell behind by more than max_catch_up, or ahead of the controller closing
                # the loop: slow down (never skip, never burst).
                target = pacer.next_target(cell.t, now - wall_prev, cfg.realtime_factor,
                                           cfg.max_catch_up, inputs.horizon())
                self._counters['behind_s'] += target.behind_s
                if inputs.waited(target.held, now):
                    self.get_logger().warn(
                        f'no streaming grasp-force command for {cfg.max_input_wait:.2f} s of '
                        f'wall time: the simulation runs on without waiting for it (its last '
                        'command expires on simulated time)', throttle_duration_sec=5.0)
                events = cell.advance(target.until_t)
                self._publish_events(events)
                self._publish_ground_truth()
                if 'clock' in self._pubs:   # _drives_own_clock implies a /clock publisher
                    stamp = seconds_to_stamp(cell.t)
                    self._pubs['clock'].publish(Clock(clock=stamp))
                    if self._drives_own_clock:
                        clock = self.get_clock()
                        assert isinstance(clock, ROSClock)  # a node's own clock always is
                        clock.set_ros_time_override(Time.from_msg(stamp))
                self._rtf_window.append((now, cell.t))
            wall_prev = now
            self._counters['ticks'] += 1
            delay = next_tick - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
                next_tick += period
            else:
                if delay < -period:
                    self._counters['late'] += 1
                next_tick = time.monotonic() + period
                # Behind: still let the executor thread in (it waits for the lock this loop
                # would otherwise take again at once), so commands are applied between ticks.
                time.sleep(MIN_YIELD_S)

    def _publish_events(self, events: Any) -> None:
        cell = self._cell
        cfg = self._cfg
        assert cell is not None and cfg is not None and self._sessions is not None
        frames = cell.params.frames
        for ft in events.ft:
            key = f'ft_{ft.finger}'
            self._counters[key] += 1
            if self._counters[key] % cfg.ft_publish_decimation:
                continue
            frame = frames.frame_id(names.ft_sensor_frame(ft.finger))
            if ft.biased is not None:
                self._pubs[f'wrench_{ft.finger}'].publish(
                    gripper_msgs_conv.wrench_msg(ft.stamp, frame, ft.biased))
            if cfg.publish_raw_ft:
                self._pubs[f'raw_{ft.finger}'].publish(
                    gripper_msgs_conv.wrench_msg(ft.stamp, frame, ft.raw))
        for vel in events.velocity:
            session = self._sessions[vel.finger - 1]
            sample = session.handle_parsed(vel.stamp, VelocityLine(vel.vx, vel.vy, vel.omega))
            if sample is None:
                continue
            frame = frames.frame_id(names.vel_sensor_frame(vel.finger))
            if sample.valid:
                self._pubs[f'twist_{vel.finger}'].publish(twist_msg(sample, frame))
            self._pubs[f'slip_{vel.finger}'].publish(
                planar_slip_msg(sample, frame, PlanarSlip.CHIP_MODE_FUSED))
        prefix = frames.tf_prefix
        joints = (prefix + names.finger_joint(1), prefix + names.finger_joint(2))
        for line in events.telemetry:
            # What gripper_driver publishes per line, from the same bridge records.
            status = line.status
            if status is not None:
                self._pubs['status'].publish(gripper_msgs_conv.status_msg(status))
                if self._actions is not None:
                    self._actions.on_status(status)   # gripper actions: position loop
                self._counters['line'] += 1
                if self._counters['line'] % cfg.joint_states_decimation == 0:
                    self._pubs['joints'].publish(gripper_msgs_conv.joint_state_msg(
                        status.stamp, joints, status.opening, status.opening_rate,
                        status.measured_grasp_force))
                    if math.isfinite(status.opening):   # frames need a homed opening
                        self._pubs['finger_frames'].publish(gripper_msgs_conv.transforms_msg(
                            status.stamp, finger_transforms(frames, status.opening)))
                    if self._model is not None:
                        self._model.send_fingers(status.stamp, status.opening)
            if line.motor is not None:
                self._pubs['motor'].publish(gripper_msgs_conv.motor_msg(line.motor))

    def _publish_ground_truth(self) -> None:
        cell, cfg = self._cell, self._cfg
        assert cell is not None and cfg is not None
        if cell.t + 1e-9 < self._next_truth:
            return
        period = 1.0 / cfg.ground_truth_rate
        # Absolute schedule (no drift from tick granularity); skip missed slots after a stall.
        self._next_truth = max(self._next_truth + period, cell.t - period)
        state = cell.state()
        frame = cell.params.frames.frame_id(names.GRIPPER_MIDDLE)
        self._pubs['state'].publish(sim_msgs_conv.sim_state_msg(state, frame, self._rtf()))
        self._pubs['pose'].publish(sim_msgs_conv.object_pose_msg(state, frame))
        self._pubs['object_twist'].publish(sim_msgs_conv.object_twist_msg(state, frame))
        if self._model is not None:
            self._model.send(scene_transforms(
                cell.params.frames, state.arm_lateral, state.arm_height, state.arm_angle,
                state.object_x, state.object_y, state.object_theta), state.stamp)

    def _publish_scene_markers(self) -> None:
        """Latch the object box (locked to ``sim_object``) and the table on ``sim/markers``."""
        cell = self._cell
        if cell is None or 'markers' not in self._pubs:
            return
        table = cell.params.table
        self._pubs['markers'].publish(marker_array_msg(object_markers(
            cell.params.frames, cell.preset, table.height if table.enabled else None)))

    def _publish_true_contact(self) -> None:
        cell = self._cell
        assert cell is not None
        self._pubs['truth'].publish(sim_msgs_conv.true_contact_msg(cell.true_contact(),
                                                              cell.preset.name, cell.t))

    def _rtf(self) -> float:
        window = self._rtf_window
        while len(window) > 2 and window[-1][0] - window[0][0] > 1.0:
            window.pop(0)
        if len(window) < 2 or window[-1][0] <= window[0][0]:
            return math.nan
        return (window[-1][1] - window[0][1]) / (window[-1][0] - window[0][0])

    # ------------------------------------------------------------------ callbacks
    def _on_force_cmd(self, msg: GraspForceCommand) -> None:
        force, stamp, timeout, source = gripper_msgs_conv.grasp_command(msg)
        with self._lock:
            if self._cell is None:
                return
            result = self._cell.command_grasp_force(force, stamp, timeout, source)
            if result.accepted:
                self._inputs.on_command(stamp, timeout, self._cell.t)
        if not result.accepted:
            self._counters['rejected_commands'] += 1
            self.get_logger().warn(f'grasp-force command {force!r} N rejected: {result.reason}',
                                   throttle_duration_sec=1.0)

    def _with_cell(self, res: Any, action: Any) -> Any:
        with self._lock:
            if self._cell is None:
                res.success, res.message = False, 'simulation not configured'
                return res
            out = action(self._cell)
        res.success, res.message = out[0], out[1]
        return res

    def _on_bias(self, req: Trigger.Request, res: Trigger.Response) -> Trigger.Response:
        """Start a host-side bias and answer when it completed (in simulated time).

        The simulation thread keeps running while this waits; the node's other callbacks
        wait (single-threaded executor, see `main`), which is why it is meant for an open
        gripper, as in every experiment sequence.
        """
        del req
        with self._lock:
            if self._cell is None:
                res.success, res.message = False, 'simulation not configured'
                return res
            ok, text = self._cell.bias_ft()
            deadline = self._cell.t + self._node_params.value.bias_timeout
        if not ok:
            res.success, res.message = False, text
            return res
        while self._running.is_set():
            with self._lock:
                cell = self._cell
                if cell is None:
                    break
                if not cell.bias_in_progress:
                    res.success, res.message = cell.bias_result()
                    return res
                if cell.t > deadline:
                    break
            time.sleep(0.002)
        res.success, res.message = False, 'bias did not complete (simulation stopped or timed out)'
        return res

    def _on_home(self, req: Trigger.Request, res: Trigger.Response) -> Trigger.Response:
        del req
        return self._with_cell(res, lambda c: c.home())

    def _on_stop(self, req: Trigger.Request, res: Trigger.Response) -> Trigger.Response:
        del req
        def stop(cell: SimCell) -> tuple[bool, str]:
            cell.stop()
            return True, 'safe voltage written; target 0 N until the next command'
        return self._with_cell(res, stop)

    def _on_arm(self, req: Trigger.Request, res: Trigger.Response) -> Trigger.Response:
        del req
        return self._with_cell(res, lambda c: c.arm())

    def _reset_sessions(self) -> None:
        for s in self._sessions or ():
            s.reset_pose()

    def _on_reset(self, req: Trigger.Request, res: Trigger.Response) -> Trigger.Response:
        del req
        cfg = self._cfg
        res = self._with_cell(res, lambda c: c.reset(None, cfg.start_on_table if cfg else True))
        if res.success:
            self._reset_sessions()
        return res

    def _on_reset_scene(self, req: ResetScene.Request,
                        res: ResetScene.Response) -> ResetScene.Response:
        res = self._with_cell(res, lambda c: c.reset(req.preset or None, req.object_on_table))
        if res.success:
            self._reset_sessions()
            self._publish_true_contact()
            self._publish_scene_markers()
        return res

    def _on_move(self, req: MoveGripper.Request, res: MoveGripper.Response
                 ) -> MoveGripper.Response:
        with self._lock:
            if self._cell is None:
                res.success, res.message = False, 'simulation not configured'
                return res
            ok, text, end = self._cell.move_gripper(req.lift, req.lateral, req.rotation,
                                                    req.duration)
        res.success, res.message, res.expected_end = ok, text, float(end)
        return res

    def _on_disturb(self, req: ApplyDisturbance.Request,
                    res: ApplyDisturbance.Response) -> ApplyDisturbance.Response:
        return self._with_cell(res, lambda c: c.apply_disturbance(
            req.force.x, req.force.y, req.torque, req.duration))

    def _on_reset_pose(self, finger: int, res: Trigger.Response) -> Trigger.Response:
        if self._sessions is None:
            res.success, res.message = False, 'simulation not configured'
            return res
        with self._lock:
            self._sessions[finger - 1].reset_pose()
        res.success, res.message = True, f'finger {finger}: integrated pose reset'
        return res

    def _on_chip_mode(self, finger: int, req: SetChipMode.Request,
                      res: SetChipMode.Response) -> SetChipMode.Response:
        if req.chip == SetChipMode.Request.FUSED:
            res.success, res.message = True, f'finger {finger}: fused mode'
        else:
            res.success = False
            res.message = (f'finger {finger}: single-chip mode {req.chip} is not simulated '
                           '(fused output only)')
        return res

    # ------------------------------------------------------------------ diagnostics
    def _report_rtf(self, now: float) -> Report:
        del now
        cfg = self._node_params.value
        rtf = self._rtf()
        ticks, late = self._counters['ticks'], self._counters['late']
        values = (('realtime_factor', f'{rtf:.3f}'), ('target', f'{cfg.realtime_factor:.3f}'),
                  ('ticks', str(ticks)), ('late_ticks', str(late)),
                  ('behind_real_time_s', f'{self._counters["behind_s"]:.3f}'),
                  ('waited_for_commands_s', f'{self._inputs.held_s:.3f}'),
                  ('silent_commander_releases', str(self._inputs.releases)),
                  ('rejected_commands', str(self._counters['rejected_commands'])),
                  ('simulation_core', str(NATIVE_STATUS)))
        if not math.isfinite(rtf):
            return Report(Level.WARN, 'not running', values)
        if abs(rtf - cfg.realtime_factor) > 0.1 * cfg.realtime_factor:
            return Report(Level.WARN, f'real-time factor {rtf:.2f} below target '
                          f'{cfg.realtime_factor:.2f}: the host is too slow, the simulation '
                          'slows (no simulated time is skipped)', values)
        return Report(Level.OK, 'running', values)

    def _report_scenario(self, now: float) -> Report:
        del now
        cell = self._cell
        if cell is None:
            return Report(Level.STALE, 'not configured')
        with self._lock:
            st = cell.state()
        values = (('preset', st.preset), ('in_grasp', str(st.in_grasp)),
                  ('on_table', str(st.on_table)), ('dropped', str(st.dropped)),
                  ('sim_time_s', f'{st.stamp:.3f}'))
        level = Level.WARN if st.dropped else Level.OK
        return Report(level, 'object dropped' if st.dropped else 'ok', values)


def main(args: list[str] | None = None) -> int:
    """Console script ``sim_gripper``."""
    # Single-threaded on purpose: rclpy's MultiThreadedExecutor re-polls a subscription until
    # a worker thread has taken its message, and with the simulation thread holding the GIL
    # that spin cost ~35 % of a core at 120 Hz of grasp-force commands (the simulation then
    # fell behind real time). gripper/bias_ft is the only callback that waits (one bias
    # window, ~0.25 s simulated, called with the gripper open); the simulation keeps running.
    return run_node(SimGripperNode, args, multithreaded=False)


if __name__ == '__main__':
    sys.exit(main())
