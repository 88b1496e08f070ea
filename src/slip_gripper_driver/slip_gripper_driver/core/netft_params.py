# SPDX-License-Identifier: Apache-2.0
"""Parameters of the Net F/T boxes: addresses, ports, stream and start settings (ROS-free)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NamedTuple

from slip_cell_common.core.param_schema import flattened_group
from slip_cell_common.core.validation import validate_fields
from slip_gripper_driver.core.ft_scale import (ForceTorqueScale, force_unit_factor,
                                               torque_unit_factor)
from slip_gripper_driver.core.ft_validity import RangeLimits
from slip_gripper_driver.core.netft_config import HTTP_PORT
from slip_gripper_driver.core.rdt_codec import RDT_PORT

_BOX_PORT = {'range': (0, 65535), 'read_only': True,
             'description': 'RDT UDP port of this box; 0 = ft.port (two boxes behind one '
                            'address need one port each)'}
_BOX_HTTP_PORT = {'range': (0, 65535), 'read_only': True,
                  'description': 'HTTP port of this box\'s netftapi2.xml; 0 = ft.http_port'}


@dataclass(frozen=True)
class FtFinger1Params:
    """Box of finger 1 (parameter group ``ft.finger_1``)."""

    address: str = field(default='192.168.56.6', metadata={
        'read_only': True, 'description': 'Net F/T box IP address of finger 1'})
    port: int = field(default=0, metadata=_BOX_PORT)
    http_port: int = field(default=0, metadata=_BOX_HTTP_PORT)


@dataclass(frozen=True)
class FtFinger2Params:
    """Box of finger 2 (parameter group ``ft.finger_2``)."""

    address: str = field(default='192.168.56.5', metadata={
        'read_only': True, 'description': 'Net F/T box IP address of finger 2'})
    port: int = field(default=0, metadata=_BOX_PORT)
    http_port: int = field(default=0, metadata=_BOX_HTTP_PORT)


class FtBox(NamedTuple):
    """Where one box is reached: finger, address, RDT UDP port, HTTP port."""

    finger: int
    address: str
    port: int
    http_port: int


def _range_field(unit: str, axis: str) -> Any:
    return field(default=0.0, metadata={
        'unit': unit, 'range': (0.0, 1.0e6), 'read_only': True,
        'description': f'|{axis}| beyond which a record is out of range; 0 = cfgmr from '
                       'netftapi2.xml (read_config), else unchecked'})


@dataclass(frozen=True)
class FtRangeParams:
    """Measuring range of one transducer (group ``measuring_range``; 0 = from the box)."""

    fx: float = _range_field('N', 'Fx')
    fy: float = _range_field('N', 'Fy')
    fz: float = _range_field('N', 'Fz')
    tx: float = _range_field('N·m', 'Tx')
    ty: float = _range_field('N·m', 'Ty')
    tz: float = _range_field('N·m', 'Tz')

    def limits(self) -> RangeLimits:
        """(|Fx|, |Fy|, |Fz| [N], |Tx|, |Ty|, |Tz| [N·m]); 0 = not given here."""
        return (self.fx, self.fy, self.fz, self.tx, self.ty, self.tz)


@dataclass(frozen=True)
class FtStreamParams:
    """One box's stream: RDT port, scale when not read from the box, rate and publishing.

    Flattened into ``ft.*`` of ``gripper_driver`` (`FtParams`) and into the top level of
    ``netft_driver``, so both nodes declare these fields from this one class.
    """

    port: int = field(default=RDT_PORT, metadata={
        'range': (1, 65535), 'read_only': True, 'description': 'RDT UDP port'})
    http_port: int = field(default=HTTP_PORT, metadata={
        'range': (1, 65535), 'read_only': True,
        'description': 'HTTP port of netftapi2.xml (read_config)'})
    read_config: bool = field(default=True, metadata={
        'read_only': True, 'description': 'read netftapi2.xml on configure'})
    counts_per_force: float = field(default=0.0, metadata={
        'unit': 'counts/unit', 'range': (0.0, 1.0e12), 'read_only': True,
        'description': 'cfgcpf; required when read_config is false'})
    counts_per_torque: float = field(default=0.0, metadata={
        'unit': 'counts/unit', 'range': (0.0, 1.0e12), 'read_only': True,
        'description': 'cfgcpt; required when read_config is false'})
    force_unit: str = field(default='N', metadata={
        'read_only': True, 'description': 'box force unit (lbf, klbf, kgf, kN, N)'})
    torque_unit: str = field(default='N-m', metadata={
        'read_only': True,
        'description': 'box torque unit (lbf-in, lbf-ft, N-mm, kgf-cm, kN-m, N-m)'})
    expected_rate: float = field(default=1000.0, metadata={
        'unit': 'Hz', 'range': (1.0, 10000.0), 'description': 'RDT rate for diagnostics'})
    rate_tolerance: float = field(default=0.1, metadata={
        'unit': '-', 'range': (0.0, 1.0), 'description': 'relative rate tolerance'})
    publish_decimation: int = field(default=2, metadata={
        'range': (1, 100), 'description': 'publish every n-th wrench'})
    publish_raw: bool = field(default=False, metadata={
        'description': 'also publish finger_k/ft/raw'})
    publish_on_error: bool = field(default=False, metadata={
        'description': 'also publish error-flagged and out-of-range records on '
                       'finger_k/ft/raw (with publish_raw); finger_k/ft/wrench and the '
                       'grasp-force loop never get them'})
    measuring_range: FtRangeParams = field(default_factory=FtRangeParams)
    restart_after: float = field(default=0.02, metadata={
        'unit': 's', 'range': (0.001, 1.0), 'read_only': True,
        'description': 'no record for this long (at least 10 record periods): re-send the '
                       'start request at once, then with back-off'})

    def combination_problems(self) -> list[str]:
        """Problems of field combinations (the scale, the unit names, the range)."""
        problems: list[str] = []
        if not self.read_config and (self.counts_per_force <= 0.0
                                     or self.counts_per_torque <= 0.0):
            problems.append('counts_per_force and counts_per_torque are required (> 0) when '
                            'read_config is false')
        for name, check in (('force_unit', force_unit_factor),
                            ('torque_unit', torque_unit_factor)):
            try:
                check(getattr(self, name))
            except ValueError as exc:
                problems.append(str(exc))
        return problems

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field and combination."""
        validate_fields(self, self.combination_problems())

    def scale(self) -> ForceTorqueScale:
        """Scale from the parameters (when ``read_config`` is false)."""
        return ForceTorqueScale(self.counts_per_force, self.counts_per_torque,
                                self.force_unit, self.torque_unit)


@dataclass(frozen=True)
class FtStartParams:
    """How the embedded clients start a stream (flattened into ``ft.*``)."""

    start_retries: int = field(default=10, metadata={
        'range': (1, 100), 'read_only': True, 'description': 'start requests before failing'})
    start_wait: float = field(default=0.1, metadata={
        'unit': 's', 'range': (0.01, 5.0), 'read_only': True,
        'description': 'wait for data after each start request'})


@dataclass(frozen=True)
class FtParams:
    """Both Net F/T boxes (parameter group ``ft``; stream and start fields at its level)."""

    mode: str = field(default='embedded', metadata={
        'choices': ('embedded', 'topic'), 'read_only': True,
        'description': 'embedded UDP clients, or consume finger_k/ft/wrench'})
    # One class per finger: the schema rebuilds nested groups from their class defaults.
    finger_1: FtFinger1Params = field(default_factory=FtFinger1Params)
    finger_2: FtFinger2Params = field(default_factory=FtFinger2Params)
    stream: FtStreamParams = flattened_group(FtStreamParams)
    start: FtStartParams = flattened_group(FtStartParams)

    def boxes(self) -> tuple[FtBox, FtBox]:
        """Both boxes with their ports resolved (a per-box 0 takes ``ft.port``/``http_port``)."""
        s = self.stream
        return (FtBox(1, self.finger_1.address, self.finger_1.port or s.port,
                      self.finger_1.http_port or s.http_port),
                FtBox(2, self.finger_2.address, self.finger_2.port or s.port,
                      self.finger_2.http_port or s.http_port))

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field and combination."""
        problems = self.stream.combination_problems()
        one, two = self.boxes()
        if self.mode == 'embedded' and (one.address, one.port) == (two.address, two.port):
            problems.append(f'both boxes at {one.address}:{one.port}: give each box its own '
                            'address or ft.finger_k.port')
        validate_fields(self, problems)
