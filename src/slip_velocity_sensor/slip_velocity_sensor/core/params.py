# SPDX-License-Identifier: Apache-2.0
"""Parameters of the ``velocity_sensor`` lifecycle node (ros_interfaces §6.3), ROS-free.

One frozen dataclass; nested groups flatten with ``.`` (``handshake.timeout``,
``calibration.chip_1.x.a``). `slip_cell_common.core.param_schema` validates and rebuilds it;
``config/velocity_sensor.yaml`` must list every field. The host-processing settings are the
session's own `session.SessionParams`, flattened into this level (``stale_after``,
``expected_rate``, ...). Beyond the spec table: ``max_integration_dt``, ``chip_mode_settle``
and ``resync_timeout`` (of the session), ``lock_dir`` (name claim, `identity.NameClaim`),
``reconnect.*`` (back-off of reopening the port and of re-initialising the device,
`driver.SensorDriver`) and ``frames.tf_prefix`` (the shared frame prefix of the cell, also set
by ``cell.yaml``).

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

from slip_cell_common.core import names
from slip_cell_common.core.param_schema import (ParameterError, check_value, flatten,
                                                   flattened_group, specs)
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
    frame_id: str = field(default=names.vel_sensor_frame(1), metadata={
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
    session: SessionParams = flattened_group(SessionParams)
    reconnect: ReconnectParams = field(default_factory=ReconnectParams)
    lock_dir: str = field(default='', metadata={
        'read_only': True,
        'description': 'directory of the sensor-name claim files; empty: XDG_RUNTIME_DIR or /tmp'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        values = flatten(self)
        problems = [p for s in specs(type(self)) for p in check_value(s, values[s.name])]
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
