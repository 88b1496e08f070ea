# SPDX-License-Identifier: Apache-2.0
"""``velocity_sensor``: one optical velocity sensor (one finger) as a lifecycle node.

Run one instance per finger::

    velocity_sensor --ros-args -r __node:=velocity_sensor_1 \\
        --params-file $(share)/config/velocity_sensor_1.yaml -p port:=/dev/serial/by-id/...

Transitions (house_style §3):

* **configure**: validate every parameter (all problems in one message), resolve the
  calibration (``calibration.file``, default ``config/calibration_{expected_name}.yaml``:
  absolute, ``package://pkg/path`` or relative to this package's share directory; '' selects
  the inline ``calibration.chip_*`` values), open the port,
  identify with timeout and retries, upload the calibration and the chip mode, claim the sensor
  name host-wide. Invalid parameters or calibration, a wrong sensor name and a name claimed by
  another port return FAILURE with a message naming the port (also on ``/diagnostics``);
  nothing stays open. A start that may succeed later (port missing or busy, sensor silent or
  re-syncing, link failure) is logged and configure succeeds without the sensor.
* **activate**: publish. If the sensor has not started, the start is retried on a thread with
  back-off (``reconnect.initial_delay`` doubling up to ``reconnect.max_delay``), every failure
  logged and reported on ``/diagnostics`` (link ERROR), until it starts or the node is
  deactivated (`core.starter.DriverStarter`). The serial reader runs from the start on (the
  handshake needs it), so board restarts and unplugging are handled and diagnosed in the
  inactive state too, and the pose keeps integrating (it is the displacement since the last
  reset). The services work in both configured states.
* **deactivate**: stop publishing and stop start retries. **cleanup / shutdown / error**: stop
  the retries, the reader and the supervisor, close the port, release the name.

Topics (``k`` = ``finger``; SENSOR_PUB, QoS overridable from YAML), stamped with the node clock
when the line arrived and published from the reader thread:

* ``finger_k/slip/twist`` (TwistStamped): valid fused samples only.
* ``finger_k/slip/state`` (PlanarSlip): every sample with the integrated pose and validity,
  plus one invalid marker when the stream goes stale (``stale_after``).
* ``finger_k/slip/chips`` (OpticalChipArray): single-chip mode samples (raw chip-frame speeds).

Services: ``finger_k/slip/set_chip_mode`` (SetChipMode), ``finger_k/slip/reset_pose``
(Trigger). Diagnostics tasks ``link``, ``rate``, ``chips``, ``calibration`` with the port as
hardware id. All device logic is in `slip_velocity_sensor.core.driver`.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import sys
from typing import Any

from geometry_msgs.msg import TwistStamped
from rclpy.clock import JumpThreshold, TimeJump
from rclpy.duration import Duration
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from slip_msgs.msg import OpticalChipArray, PlanarSlip
from slip_msgs.srv import SetChipMode
from std_srvs.srv import Trigger

from slip_cell_common.log_sink import log_event
from slip_cell_common.diagnostics import DiagnosticsPublisher
from slip_cell_common.time_conv import clock_seconds, nanoseconds_to_seconds
from slip_cell_common.core import names
from slip_cell_common.node_main import run_node
from slip_cell_common.param_binding import ParameterBinding
from slip_cell_common.qos import SENSOR_PUB, overridable
from slip_cell_common.core.monitors import Level, Report
from slip_cell_common.core.param_schema import ParameterError
from slip_velocity_sensor.velocity_msgs_conv import chip_array_msg, planar_slip_msg, twist_msg
from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.calibration import CalibrationError, resolve_calibration
from slip_velocity_sensor.core.driver import DriverError, SensorDriver
from slip_velocity_sensor.core.handshake import HandshakeResult
from slip_velocity_sensor.core.params import VelocitySensorParams
from slip_velocity_sensor.core.session import Sample
from slip_velocity_sensor.core.starter import DriverStarter
from slip_velocity_sensor.resources import ResourceError, resolve_path

DIAGNOSTIC_TASKS = ('link', 'rate', 'chips', 'calibration')


class VelocitySensorNode(LifecycleNode):
    """Lifecycle node around `SensorDriver`; see the module docstring.

    Args:
        node_name: Default name (instances are renamed with ``-r __node:=velocity_sensor_k``).
        **kwargs: Passed to `LifecycleNode` (``context``, ``parameter_overrides``, ...).
    """

    def __init__(self, node_name: str = 'velocity_sensor', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._binding = ParameterBinding(self, VelocitySensorParams)
        self._binding.on_change(self._on_params_changed)
        self._diagnostics = DiagnosticsPublisher(self)
        for task in DIAGNOSTIC_TASKS:
            self._diagnostics.add(task, functools.partial(self._report, task))
        self._cfg: VelocitySensorParams | None = None
        self._driver: SensorDriver | None = None
        self._starter: DriverStarter | None = None
        self._frame_id = ''
        self._active = False
        self._last_error = ''
        self._prev_stamp = math.nan
        self._twist_pub: Any = None
        self._state_pub: Any = None
        self._chips_pub: Any = None
        self._service_handles: list[Any] = []
        self._stale_timer: Any = None
        self._jump_handle: Any = None

    # ---------------------------------------------------------------- public state

    @property
    def last_error(self) -> str:
        """Why the last configure or start attempt failed ('' once the sensor started)."""
        return self._last_error

    @property
    def driver(self) -> SensorDriver | None:
        """The device driver while configured."""
        return self._driver

    # ---------------------------------------------------------------- lifecycle

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Validate, open, identify, upload, claim; FAILURE names the port."""
        del state
        try:
            cfg = self._binding.load()
        except ParameterError as exc:
            return self._fail(f'invalid parameters: {exc}')
        self._diagnostics.hardware_id = cfg.port
        try:
            calibration_params = dataclasses.replace(
                cfg.calibration, file=resolve_path(cfg.calibration_file))
            calibration = resolve_calibration(calibration_params, cfg.radius, cfg.expected_name)
        except (ResourceError, CalibrationError) as exc:
            return self._fail(f'{cfg.port}: calibration: {exc}')
        self._cfg = cfg
        self._frame_id = cfg.resolved_frame_id
        self._create_endpoints(cfg)

        def make_driver() -> SensorDriver:
            return SensorDriver(cfg, calibration, clock=self._now_s, on_sample=self._on_sample,
                                on_event=self._on_driver_event)
        driver = make_driver()
        try:
            result = driver.connect()
        except DriverError as exc:
            if not exc.retryable:  # wrong name, name taken: retrying cannot help
                self._destroy_endpoints()
                self._cfg = None
                return self._fail(str(exc))
            self._starter = DriverStarter(cfg.port, make_driver, cfg.reconnect,
                                          on_started=self._on_driver_started,
                                          on_event=self._on_driver_event)
            self._starter.record_failure(exc)
            self._last_error = str(exc)
            self.get_logger().error(
                f'start failed: {exc}; configured without the sensor: the start is retried '
                f'with back-off ({cfg.reconnect.initial_delay:g} s doubling up to '
                f'{cfg.reconnect.max_delay:g} s) while the node is active')
            return TransitionCallbackReturn.SUCCESS
        self._on_driver_started(driver, result)
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Start publishing; retry a failed start with back-off until deactivated."""
        self._prev_stamp = math.nan
        self._active = True
        starter = self._starter
        if self._driver is None and starter is not None:
            status = starter.status()
            if status.gave_up:
                self.get_logger().error(
                    f'{starter.port}: sensor not started and not retried: {status.last_error}')
            else:
                self.get_logger().warning(
                    f'{starter.port}: sensor not started ({status.attempts} attempt(s) '
                    'failed); retrying with back-off until deactivated')
                starter.start()
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop publishing (the port stays open and supervised); stop start retries."""
        self._active = False
        starter = self._starter
        if starter is not None and starter.status().running:
            starter.stop()
            if self._driver is None:
                self.get_logger().warning(
                    f'{starter.port}: start retries stopped (inactive); activate to resume')
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Close the port and remove the endpoints."""
        del state
        self._teardown()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Close the port and remove the endpoints."""
        del state
        self._teardown()
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Release everything; the node returns to unconfigured."""
        del state
        self._teardown()
        return TransitionCallbackReturn.SUCCESS

    def destroy_node(self) -> None:
        """Stop the device threads before the node goes away."""
        self._teardown()
        self._diagnostics.destroy()
        super().destroy_node()

    # ---------------------------------------------------------------- internals

    def _now_s(self) -> float:
        return clock_seconds(self.get_clock())

    def _fail(self, message: str) -> TransitionCallbackReturn:
        self._last_error = message
        self.get_logger().error(f'configure failed: {message}')
        return TransitionCallbackReturn.FAILURE

    def _create_endpoints(self, cfg: VelocitySensorParams) -> None:
        k = cfg.finger
        self._twist_pub = self.create_lifecycle_publisher(
            TwistStamped, names.slip_twist(k), SENSOR_PUB, qos_overriding_options=overridable())
        self._state_pub = self.create_lifecycle_publisher(
            PlanarSlip, names.slip_state(k), SENSOR_PUB, qos_overriding_options=overridable())
        self._chips_pub = self.create_lifecycle_publisher(
            OpticalChipArray, names.slip_chips(k), SENSOR_PUB,
            qos_overriding_options=overridable())
        self._service_handles = [
            self.create_service(SetChipMode, names.slip_set_chip_mode_srv(k),
                                self._on_set_chip_mode),
            self.create_service(Trigger, names.slip_reset_pose_srv(k), self._on_reset_pose)]
        self._stale_timer = self.create_timer(cfg.session.stale_after, self._check_stale)

    def _destroy_endpoints(self) -> None:
        if self._stale_timer is not None:
            self.destroy_timer(self._stale_timer)
            self._stale_timer = None
        for service in self._service_handles:
            self.destroy_service(service)
        self._service_handles = []
        for name in ('_twist_pub', '_state_pub', '_chips_pub'):
            pub = getattr(self, name)
            if pub is not None:
                setattr(self, name, None)
                self.destroy_lifecycle_publisher(pub)

    def _teardown(self) -> None:
        self._active = False
        starter, self._starter = self._starter, None
        if starter is not None:
            starter.stop()  # joins: no driver is handed over after this
        if self._jump_handle is not None:
            self._jump_handle.unregister()
            self._jump_handle = None
        driver, self._driver = self._driver, None
        if driver is not None:
            driver.close()  # the reader thread is gone before its publishers are
        self._destroy_endpoints()
        self._cfg = None

    # ---------------------------------------------------------------- data path (reader thread)

    def _on_sample(self, sample: Sample) -> None:
        if not self._active:
            return
        dt = sample.stamp - self._prev_stamp
        self._prev_stamp = sample.stamp
        twist_pub, state_pub, chips_pub = self._twist_pub, self._state_pub, self._chips_pub
        driver = self._driver
        if state_pub is None or driver is None:
            return
        if sample.valid:
            twist_pub.publish(twist_msg(sample, self._frame_id))
        state_pub.publish(planar_slip_msg(sample, self._frame_id, driver.requested_chip_mode))
        if sample.chip_mode > 0 and math.isfinite(sample.chip_vx):
            chips_pub.publish(chip_array_msg(
                sample, self._frame_id, dt if dt > 0.0 else math.nan))

    def _check_stale(self) -> None:
        driver = self._driver
        if driver is None or not self._active:
            return
        marker = driver.stale_marker(self._now_s())
        if marker is not None and self._state_pub is not None:
            self._state_pub.publish(planar_slip_msg(marker, self._frame_id,
                                                    driver.requested_chip_mode))

    def _on_driver_started(self, driver: SensorDriver, result: HandshakeResult) -> None:
        """Take over a connected driver (from configure or from the start-retry thread)."""
        cfg = driver.params
        self._driver = driver
        self._last_error = ''
        self._jump_handle = self.get_clock().create_jump_callback(
            JumpThreshold(min_forward=None, min_backward=Duration(nanoseconds=-1_000_000),
                          on_clock_change=True), post_callback=self._on_clock_jump)
        self.get_logger().info(
            f'{cfg.port}: {result.name} identified (attempt {result.attempts}), calibration '
            f'uploaded from {driver.calibration.source} (speed_term '
            f'{cfg.calibration.speed_term}); frame {self._frame_id}')

    def _on_driver_event(self, level: str, message: str) -> None:
        log_event(self.get_logger(), level, message)

    def _on_params_changed(self, cfg: VelocitySensorParams) -> None:
        driver = self._driver
        if driver is None:
            return  # read again at the next configure
        self._cfg = cfg
        deferred = driver.update_params(cfg)
        if deferred:
            self.get_logger().warning(
                f'{", ".join(deferred)}: take effect at the next configure '
                '(they are bound to the calibration upload and the link)')

    def _on_clock_jump(self, jump: TimeJump) -> None:
        driver = self._driver
        if driver is not None:
            self.get_logger().warning(
                f'clock jumped by {nanoseconds_to_seconds(jump.delta.nanoseconds):.3f} s: '
                'pose and monitors reset')
            driver.session.reset()

    # ---------------------------------------------------------------- services

    def _on_set_chip_mode(self, request: SetChipMode.Request,
                          response: SetChipMode.Response) -> SetChipMode.Response:
        driver, cfg = self._driver, self._cfg
        mode = int(request.chip)
        if driver is None or cfg is None:
            response.success, response.message = False, self._why_no_driver()
            return response
        if mode > protocol.MAX_CHIP_MODE:
            response.success = False
            response.message = (f'chip must be {SetChipMode.Request.FUSED} (fused) or '
                                f'1..{protocol.MAX_CHIP_MODE} (single chip), got {mode}')
            return response
        try:
            driver.set_chip_mode(mode)
        except DriverError as exc:
            response.success, response.message = False, str(exc)
            return response
        response.success = True
        if mode == SetChipMode.Request.FUSED:
            response.message = f'{cfg.port}: fused mode'
        else:
            response.message = (f'{cfg.port}: single-chip mode {mode}: raw chip-frame speeds on '
                                f'{names.slip_chips(cfg.finger)}; no twist, state invalid')
        self.get_logger().info(response.message)
        return response

    def _on_reset_pose(self, request: Trigger.Request,
                       response: Trigger.Response) -> Trigger.Response:
        del request
        driver = self._driver
        if driver is None:
            response.success, response.message = False, self._why_no_driver()
            return response
        driver.reset_pose()
        response.success, response.message = True, 'integrated pose reset'
        return response

    # ---------------------------------------------------------------- diagnostics

    def _report(self, task: str, now: float) -> Report:
        driver = self._driver
        if driver is None and self._starter is not None:
            return self._start_report(task, self._starter)
        if driver is None:
            if self._last_error:
                return Report(Level.ERROR, f'configure failed: {self._last_error}')
            return Report(Level.STALE, 'not configured')
        report = driver.reports(now)[task]
        if task == 'rate' and not self._active:
            return Report(report.level, f'{report.message} (inactive: not publishing)',
                          report.values)
        return report


    def _why_no_driver(self) -> str:
        starter = self._starter
        if starter is None:
            return 'not configured'
        return f'{starter.port}: sensor not started: {starter.status().last_error}'

    @staticmethod
    def _start_report(task: str, starter: DriverStarter) -> Report:
        """Diagnostics while the sensor has not started: the link task says why."""
        if task != 'link':
            return Report(Level.STALE, 'sensor not started')
        st = starter.status()
        values = (('port', st.port), ('start_attempts', str(st.attempts)),
                  ('retry_in_s', f'{st.retry_in_s:.2f}'), ('last_error', st.last_error))
        if st.gave_up:
            action = 'not retrying (fix the port or the sensor name, then reconfigure)'
        elif st.running:
            action = f'retrying in {st.retry_in_s:.1f} s'
        else:
            action = 'retries resume when the node is activated'
        return Report(Level.ERROR, f'{st.port}: sensor not started after {st.attempts} '
                                   f'attempt(s): {st.last_error}; {action}', values)


def main(args: list[str] | None = None) -> int:
    """Console script ``velocity_sensor``."""
    return run_node(VelocitySensorNode, args)


if __name__ == '__main__':
    sys.exit(main())
