# SPDX-License-Identifier: Apache-2.0
"""Parameters of the ``velocity_sensor`` lifecycle node (ros_interfaces spec §6.3), ROS-free.

One frozen dataclass; nested groups flatten with ``.`` (``handshake.timeout``,
``calibration.chip_1.x.a``). `slip_cell_common.core.param_schema` validates and rebuilds it;
``config/velocity_sensor.yaml`` must list every field. Beyond the spec table:
``max_integration_dt``, ``chip_mode_settle`` and ``resync_timeout`` (host processing, see
`session.SessionParams`), ``lock_dir`` (name claim, `identity.NameClaim`), ``reconnect.*``
(back-off of reopening the port and of re-initialising the device, `driver.SensorDriver`) and
``frames.tf_prefix`` (the shared frame prefix of the cell, also set by ``cell.yaml``).

``calibration.file`` defaults to ``config/calibration_{expected_name}.yaml``: the
placeholders ``{expected_name}`` and ``{finger}`` are substituted, and a relative path refers to
the package's share directory (the node resolves it), so every instance loads the installed
calibration of its own board unless told otherwise; '' selects the inline values.
A ``frame_id`` of the form ``vel_sensor_<j>`` must name this node's finger (a copied YAML with
``finger: 2`` but ``frame_id: vel_sensor_1`` fails configure instead of publishing in the wrong
frame).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from slip_cell_common.core.param_schema import ParameterError, check_value, specs
from slip_cell_common.core.serial_transport import ReconnectParams
from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.calibration import CalibrationParams
from slip_velocity_sensor.core.handshake import HandshakeParams
from slip_velocity_sensor.core.session import SessionParams


_FINGER_FRAME = re.compile(r'vel_sensor_(\d+)')


@dataclass(frozen=True)
class FrameParams:
    """The part of the cell's shared ``frames.*`` parameters this node uses."""

    tf_prefix: str = field(default='', metadata={
        'read_only': True, 'description': 'prefix of every frame id (shared with cell.yaml)'})


@dataclass(frozen=True)
class VelocitySensorParams:
    """All parameters of one velocity-sensor node instance (SI)."""

    autostart: bool = field(default=True, metadata={
        'read_only': True, 'description': 'configure and activate on start-up'})
    port: str = field(default='', metadata={
        'read_only': True, 'required': True,
        'description': '/dev/serial/by-id/... path or pyserial URL'})
    baudrate: int = field(default=115200, metadata={
        'unit': 'Bd', 'range': (1200, 4000000), 'read_only': True,
        'description': 'CP2102N baud rate (115200 8N1)'})
    finger: int = field(default=1, metadata={
        'range': (1, 2), 'read_only': True, 'description': 'finger number; selects topic names'})
    expected_name: str = field(default='sensor_1', metadata={
        'read_only': True, 'description': 'name the sensor must answer to "n"'})
    frame_id: str = field(default='vel_sensor_1', metadata={
        'read_only': True, 'description': 'frame of the published samples (without tf_prefix)'})
    frames: FrameParams = field(default_factory=FrameParams)
    handshake: HandshakeParams = field(default_factory=HandshakeParams)
    command_spacing: float = field(default=0.010, metadata={
        'unit': 's', 'range': (0.010, 1.0),
        'description': 'minimum time between device commands'})
    radius: float = field(default=0.0243, metadata={
        'unit': 'm', 'range': (0.001, 0.5),
        'description': 'chip radius uploaded as mm (a calibration file overrides it)'})
    calibration: CalibrationParams = field(default_factory=CalibrationParams)
    stale_after: float = field(default=0.050, metadata={
        'unit': 's', 'range': (0.001, 10.0),
        'description': 'a sample older than this is stale for the slip controllers'})
    expected_rate: float = field(default=120.0, metadata={
        'unit': 'Hz', 'range': (1.0, 10000.0), 'description': 'nominal line rate'})
    rate_tolerance: float = field(default=0.1, metadata={
        'unit': '-', 'range': (0.0, 1.0), 'description': 'allowed relative rate deviation'})
    integrate_pose: bool = field(default=True, metadata={
        'description': 'integrate x, y, theta from valid fused samples'})
    max_integration_dt: float = field(default=0.050, metadata={
        'unit': 's', 'range': (0.001, 1.0),
        'description': 'cap on the integration step after gaps between samples'})
    chip_mode_settle: float = field(default=0.025, metadata={
        'unit': 's', 'range': (0.0, 1.0),
        'description': 'samples are invalid this long after a chip-mode command'})
    resync_timeout: float = field(default=0.2, metadata={
        'unit': 's', 'range': (0.0, 10.0),
        'description': 'longest a chip re-sync keeps samples invalid without its end line'})
    reconnect: ReconnectParams = field(default_factory=ReconnectParams)
    lock_dir: str = field(default='', metadata={
        'read_only': True,
        'description': 'directory of the sensor-name claim files; empty: XDG_RUNTIME_DIR or /tmp'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        problems = [p for s in specs(type(self)) for p in check_value(s, _get(self, s.name))]
        if not protocol.is_valid_name(self.expected_name):
            problems.append(f'expected_name {self.expected_name!r} is not a sensor name')
        match = _FINGER_FRAME.fullmatch(self.frame_id)
        if match and int(match[1]) != self.finger:
            problems.append(f'frame_id {self.frame_id!r} names finger {match[1]}, but finger is '
                            f'{self.finger}')
        if self.reconnect.initial_delay > self.reconnect.max_delay:
            problems.append(f'reconnect.initial_delay {self.reconnect.initial_delay} s exceeds '
                            f'reconnect.max_delay {self.reconnect.max_delay} s')
        if problems:
            raise ParameterError('; '.join(problems))

    @property
    def resolved_frame_id(self) -> str:
        """Frame id of the published messages: ``frames.tf_prefix`` + ``frame_id``."""
        return self.frames.tf_prefix + self.frame_id

    @property
    def calibration_file(self) -> str:
        """``calibration.file`` with ``{expected_name}`` and ``{finger}`` substituted."""
        return (self.calibration.file.replace('{expected_name}', self.expected_name)
                .replace('{finger}', str(self.finger)))

    def session_params(self) -> SessionParams:
        """The host-processing subset."""
        return SessionParams(stale_after=self.stale_after, expected_rate=self.expected_rate,
                             rate_tolerance=self.rate_tolerance,
                             integrate_pose=self.integrate_pose,
                             max_integration_dt=self.max_integration_dt,
                             chip_mode_settle=self.chip_mode_settle,
                             resync_timeout=self.resync_timeout)


def _get(instance: object, dotted: str) -> object:
    for part in dotted.split('.'):
        instance = getattr(instance, part)
    return instance
