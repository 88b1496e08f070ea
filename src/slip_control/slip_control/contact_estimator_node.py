# SPDX-License-Identifier: Apache-2.0
"""``contact_estimator``: contact-property estimation node (control_and_estimation §3).

Thin rclpy node around `slip_control.core.contact_estimator.ContactEstimator`:

* subscribes ``finger_k/ft/wrench`` and ``finger_k/slip/twist`` (QoS SENSOR_SUB); every
  callback replaces one immutable `SensorSnapshot`; each finger-1 twist steps the estimator
  with the snapshot and the node-clock time (CE-7, CE-8);
* serves ``contact/start`` (``slip_msgs/StartEstimation``) and ``contact/get_properties``;
* publishes ``contact/properties`` (LATCHED) at start (DEFAULT, ``valid = false``, or the preset
  named by ``preset_file``/``preset_name``) and whenever the set changes (a phase produced a
  valid result for at least one finger, an online update, a preset load). A failed phase
  changes nothing and publishes nothing; its reason is in the ``contact/get_properties``
  message, the log and diagnostics (CE-4: no silent defaults);
* a node-clock timer ends a phase whose window passed when no samples arrive;
* diagnostics task ``estimate``.

Single-threaded executor: every callback touches the state from one thread. Parameter changes
are validated on set and swapped in while the estimator is idle (a running phase keeps the
snapshot it started with).
"""
from __future__ import annotations

import math
import sys
from typing import Any

from geometry_msgs.msg import TwistStamped, WrenchStamped
from rclpy.node import Node
from slip_msgs.msg import ContactProperties as ContactPropertiesMsg
from slip_msgs.srv import GetContactProperties, StartEstimation

from slip_control.core.contact import ContactSource
from slip_control.core.contact_estimator import (ContactEstimator, EstimationPhase,
                                                 EstimatorReport, start_precheck)
from slip_control.core.params import ContactEstimatorParams
from slip_control.core.signals import SensorSnapshot
from slip_control.slip_msgs_conv import properties_to_msg, twist_from_msg, wrench_from_msg
from slip_cell_common.diagnostics import DiagnosticsPublisher
from slip_cell_common.core import names
from slip_cell_common.node_main import run_node
from slip_cell_common.param_binding import ParameterBinding
from slip_cell_common.qos import LATCHED, QUIET_SUB, SENSOR_SUB, overridable
from slip_cell_common.time_conv import clock_seconds, nanoseconds_to_stamp
from slip_cell_common.core.monitors import Level, Report
from slip_cell_common.core.param_schema import ParameterError

#: Period of the timer that ends phases whose window passed without samples [s, node clock].
POLL_PERIOD_S = 0.02


_SOURCE_TOPICS = {'finger 1 wrench': names.ft_wrench(1), 'finger 2 wrench': names.ft_wrench(2),
                  'finger 1 velocity': names.slip_twist(1),
                  'finger 2 velocity': names.slip_twist(2)}


class ContactEstimatorNode(Node):
    """The ``contact_estimator`` node.

    Args:
        node_name: Node name (``contact_estimator``).
        **kwargs: Passed to `rclpy.node.Node` (``context``, ``parameter_overrides``, ...).

    Raises:
        ParameterError: invalid parameters or a preset that cannot be loaded.
    """

    def __init__(self, node_name: str = 'contact_estimator', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._binding = ParameterBinding(self, ContactEstimatorParams)
        try:
            params = self._binding.load()
        except ParameterError as exc:
            self.get_logger().fatal(f'invalid parameters: {exc}')
            super().destroy_node()
            raise
        self._est = ContactEstimator(params)
        self._pending_params: ContactEstimatorParams | None = None
        if params.preset_name:
            ok, message = self._est.load_preset(params.preset_file, params.preset_name)
            if not ok:
                self.get_logger().fatal(message)
                super().destroy_node()
                raise ParameterError(message)
            self.get_logger().info(message)
        self._snap = SensorSnapshot()
        self._last_t: float | None = None
        self._published = 0

        self._pub = self.create_publisher(ContactPropertiesMsg, names.CONTACT_PROPERTIES, LATCHED,
                                          qos_overriding_options=overridable())
        self.create_subscription(WrenchStamped, names.ft_wrench(1),
                                 lambda m: self._on_wrench(1, m), SENSOR_SUB,
                                 event_callbacks=QUIET_SUB)
        self.create_subscription(WrenchStamped, names.ft_wrench(2),
                                 lambda m: self._on_wrench(2, m), SENSOR_SUB,
                                 event_callbacks=QUIET_SUB)
        self.create_subscription(TwistStamped, names.slip_twist(2), self._on_twist_2,
                                 SENSOR_SUB, event_callbacks=QUIET_SUB)
        # Created last: when several samples are ready at once, the trigger is handled last.
        self.create_subscription(TwistStamped, names.slip_twist(1), self._on_twist_1,
                                 SENSOR_SUB, event_callbacks=QUIET_SUB)
        self.create_service(StartEstimation, names.CONTACT_START_SRV, self._on_start)
        self.create_service(GetContactProperties, names.CONTACT_GET_PROPERTIES_SRV, self._on_get)
        self.create_timer(POLL_PERIOD_S, self._on_timer)
        self._binding.on_change(self._on_params)
        self._diag = DiagnosticsPublisher(self)
        self._diag.add('estimate', self._diagnose)
        self._publish()
        self.get_logger().info('contact estimator ready; publishing '
                               f'{self._est.properties.describe()}')

    # -- read-only views (tests, tools) ----------------------------------------------------

    @property
    def snapshot(self) -> SensorSnapshot:
        """Latest samples of both fingers."""
        return self._snap

    @property
    def estimator(self) -> ContactEstimator:
        """The core estimator (read it; do not drive it from another thread)."""
        return self._est

    # -- callbacks -------------------------------------------------------------------------

    def _now(self) -> float:
        """Node-clock time [s]; resets the phase window when the clock jumped backwards."""
        t = clock_seconds(self.get_clock())
        if self._last_t is not None and t < self._last_t:
            self.get_logger().warn(f'clock jumped backwards by {self._last_t - t:.3f} s: '
                                   'discarding a running LINEAR/ROTATIONAL phase')
            self._est.reset(t)
        self._last_t = t
        return t

    def _on_wrench(self, finger: int, msg: WrenchStamped) -> None:
        self._snap = self._snap.with_wrench(finger, wrench_from_msg(msg))

    def _on_twist_2(self, msg: TwistStamped) -> None:
        self._snap = self._snap.with_twist(2, twist_from_msg(msg))

    def _on_twist_1(self, msg: TwistStamped) -> None:
        self._snap = self._snap.with_twist(1, twist_from_msg(msg))
        self._handle(self._est.step(self._snap, self._now()))

    def _on_timer(self) -> None:
        self._handle(self._est.poll(self._now()))

    def _on_start(self, req: StartEstimation.Request,
                  res: StartEstimation.Response) -> StartEstimation.Response:
        t = self._now()
        if req.phase in (EstimationPhase.LINEAR, EstimationPhase.ROTATIONAL) and \
                math.isfinite(req.duration) and req.duration > 0.0:
            ok, why = start_precheck(self._snap, t, self._est.params)
            if not ok:
                for name, topic in _SOURCE_TOPICS.items():
                    why = why.replace(name, f'{name} ({topic})')
                res.accepted = False
                res.message = f'{EstimationPhase(req.phase).name} refused: {why}'
                self.get_logger().warn(res.message)
                return res
        outcome = self._est.start(req.phase, req.duration, t)
        self._handle(outcome.report)
        res.accepted, res.message = outcome.accepted, outcome.message
        if outcome.accepted:
            self.get_logger().info(f'{names.CONTACT_START_SRV}: {outcome.message}')
        else:
            self.get_logger().warn(f'{names.CONTACT_START_SRV} refused: {outcome.message}')
        return res

    def _on_get(self, req: GetContactProperties.Request,
                res: GetContactProperties.Response) -> GetContactProperties.Response:
        del req
        props, valid, message = self._est.get_properties()
        res.properties = properties_to_msg(props, self.get_clock().now().to_msg())
        res.valid = valid
        res.message = message
        return res

    def _on_params(self, params: ContactEstimatorParams) -> None:
        old = self._est.params
        if self._est.update_params(params):
            self.get_logger().info('parameters updated')
        else:
            self._pending_params = params
            self.get_logger().info('parameters updated; applied when the running '
                                   f'{self._est.phase.name} phase ends')
        if params.preset_name and params.preset_name != old.preset_name:
            ok, message = self._est.load_preset(params.preset_file, params.preset_name)
            if ok:
                self.get_logger().info(message)
                self._publish()
            else:
                self.get_logger().error(f'preset not loaded, properties unchanged: {message}')

    # -- internals -------------------------------------------------------------------------

    def _handle(self, report: EstimatorReport | None) -> None:
        if report is not None:
            if report.success:
                self.get_logger().info(report.message)
            else:
                self.get_logger().warn(report.message)
            if report.changed:
                self._publish()
        if self._pending_params is not None and self._est.update_params(self._pending_params):
            self._pending_params = None
            self.get_logger().info('deferred parameter update applied')

    def _publish(self) -> None:
        props = self._est.properties
        self._pub.publish(properties_to_msg(props, nanoseconds_to_stamp(
            self.get_clock().now().nanoseconds)))
        self._published += 1
        if self._published > 1:
            self.get_logger().info(f'{names.CONTACT_PROPERTIES}: {props.describe()}')

    def _diagnose(self, t: float) -> Report:
        del t
        d = self._est.diagnostics()
        props = self._est.properties
        values: list[tuple[str, str]] = [
            ('phase', d.phase.name), ('source', d.source.name), ('valid', str(d.valid)),
            ('preset', props.preset_name), ('online_updated', str(props.online_updated)),
            ('stale_samples_skipped', str(d.stale_skipped_total))]
        for k in (1, 2):
            f = props.finger(k)
            values += [
                (f'finger_{k}_mu_c', f'{f.mu_c:.4f}'),
                (f'finger_{k}_mu_c_std', f'{f.mu_c_std:.4f}'),
                (f'finger_{k}_r_m', f'{f.r:.5f}'), (f'finger_{k}_r_std_m', f'{f.r_std:.5f}'),
                (f'finger_{k}_counts', f'lin {f.n_linear} static {f.n_static} '
                                       f'rot {f.n_rotational}'),
                (f'finger_{k}_flags', f'linear {f.linear_valid} viscous {f.viscous_valid} '
                                      f'static {f.static_valid} rotational {f.rotational_valid}')]
            lin, sta, rot = d.samples[k - 1]
            values.append((f'finger_{k}_phase_samples', f'lin {lin} static {sta} rot {rot}'))
        values.append(('last_message', d.last_message))
        if d.source == ContactSource.DEFAULT:
            return Report(Level.WARN, 'no estimate: DEFAULT placeholder (valid = false)',
                          tuple(values))
        if d.source == ContactSource.PRESET:
            return Report(Level.WARN, f'preset {props.preset_name!r} in use', tuple(values))
        if not d.valid:
            return Report(Level.WARN, 'partial estimate (see flags)', tuple(values))
        return Report(Level.OK, 'valid estimate', tuple(values))


def main(args: list[str] | None = None) -> int:
    """Console script ``contact_estimator``."""
    return run_node(ContactEstimatorNode, args)


if __name__ == '__main__':
    sys.exit(main())
