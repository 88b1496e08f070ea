# SPDX-License-Identifier: Apache-2.0
"""Parameter dataclasses of the ``gripper_driver`` and ``netft_driver`` nodes (ROS-free).

One frozen dataclass per node (ros_interfaces §6.1, §6.2); groups are the core's own parameter
classes, so a core never sees a value the node did not validate. ``config/<node>.yaml`` lists
every field. The shared ``frames.*`` block (`core.frames.FrameParams`) is bound separately by
the gripper driver and comes from ``cell.yaml``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from slip_gripper_driver.core.bridge_params import BridgeParams, CommandParams, LinkParams
from slip_gripper_driver.core.force_control import ForceControlParams
from slip_gripper_driver.core.homing import HomingParams
from slip_gripper_driver.core.ft_bias import BiasParams
from slip_gripper_driver.core.netft_params import FtParams, FtStreamParams
from slip_gripper_driver.core.observer import ObserverParams
from slip_cell_common.core.param_schema import ParameterError, flattened_group
from slip_cell_common.core import names
from slip_gripper_driver.core.protocol import ActuatorParams
from slip_gripper_driver.core.realtime import RealtimeParams
from slip_gripper_driver.core.standalone_bias_guard import StandaloneBiasGuardParams
from slip_cell_common.core.serial_transport import ReconnectParams, SerialParams
from slip_cell_common.core.validation import validate_fields

_AUTOSTART = {'read_only': True,
              'description': 'configure and activate on start (launch event handlers are '
                             'not available here)'}


@dataclass(frozen=True)
class JointStatesParams:
    """``gripper/joint_states`` publishing (parameter group ``joint_states``)."""

    decimation: int = field(default=5, metadata={
        'range': (1, 500),
        'description': 'publish joint states and finger frames every n-th telemetry line'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        validate_fields(self)


def _collect(groups: dict[str, object]) -> list[str]:
    problems: list[str] = []
    for name, group in groups.items():
        try:
            group.validate()  # type: ignore[attr-defined]
        except ParameterError as exc:
            problems.append(f'{name}: {exc}')
    return problems


@dataclass(frozen=True)
class GripperDriverParams:
    """Every parameter of ``gripper_driver`` except the shared ``frames.*`` (SI)."""

    autostart: bool = field(default=True, metadata=_AUTOSTART)
    serial: SerialParams = field(default_factory=SerialParams)
    link: LinkParams = field(default_factory=LinkParams)
    reconnect: ReconnectParams = field(default_factory=ReconnectParams)
    actuator: ActuatorParams = field(default_factory=ActuatorParams)
    observer: ObserverParams = field(default_factory=ObserverParams)
    homing: HomingParams = field(default_factory=HomingParams)
    force_control: ForceControlParams = field(default_factory=ForceControlParams)
    command: CommandParams = field(default_factory=CommandParams)
    ft: FtParams = field(default_factory=FtParams)
    bias: BiasParams = field(default_factory=BiasParams)
    joint_states: JointStatesParams = field(default_factory=JointStatesParams)
    realtime: RealtimeParams = field(default_factory=RealtimeParams)

    def bridge(self) -> BridgeParams:
        """The bridge core's parameter set."""
        return BridgeParams(actuator=self.actuator, link=self.link, observer=self.observer,
                            homing=self.homing, force_control=self.force_control,
                            command=self.command)

    def validate(self) -> None:
        """Raise `ParameterError` listing the problems of every group and combination."""
        problems: list[str] = []
        try:
            self.bridge().validate()
        except ParameterError as exc:
            problems.append(str(exc))
        problems += _collect({'serial': self.serial, 'reconnect': self.reconnect,
                              'ft': self.ft, 'bias': self.bias,
                              'joint_states': self.joint_states, 'realtime': self.realtime})
        if problems:
            raise ParameterError('; '.join(problems))


@dataclass(frozen=True)
class NetFTReconnectParams:
    """Stream restart back-off of the standalone driver (parameter group ``reconnect``)."""

    initial_delay: float = field(default=0.5, metadata={
        'unit': 's', 'range': (0.01, 60.0),
        'description': 'first delay before re-sending the start request to a silent box'})
    max_delay: float = field(default=5.0, metadata={
        'unit': 's', 'range': (0.01, 600.0), 'description': 'largest such delay'})


@dataclass(frozen=True)
class NetFTDriverParams:
    """Every parameter of ``netft_driver`` (one box, one finger; SI)."""

    autostart: bool = field(default=True, metadata=_AUTOSTART)
    finger: int = field(default=1, metadata={
        'range': (1, 2), 'read_only': True,
        'description': 'finger number: selects finger_<k>/ft/* and the default frame'})
    address: str = field(default='', metadata={
        'required': True, 'read_only': True, 'description': 'Net F/T box IP address'})
    frame_id: str = field(default='', metadata={
        'read_only': True, 'description': "wrench frame id; '' = ft_sensor_<finger>"})
    stream: FtStreamParams = flattened_group(FtStreamParams)
    receive_timeout: float = field(default=0.1, metadata={
        'unit': 's', 'range': (0.005, 10.0),
        'description': 'no record for this long: the stream is re-requested (back-off)'})
    reconnect: NetFTReconnectParams = field(default_factory=NetFTReconnectParams)
    bias: BiasParams = field(default_factory=BiasParams)
    bias_guard: StandaloneBiasGuardParams = field(default_factory=StandaloneBiasGuardParams)

    def resolved_frame_id(self) -> str:
        """``frame_id``, or ``ft_sensor_<finger>`` when empty."""
        return self.frame_id or names.ft_sensor_frame(self.finger)

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field and combination."""
        extra = self.stream.combination_problems()
        if self.reconnect.initial_delay > self.reconnect.max_delay:
            extra.append(f'reconnect.initial_delay {self.reconnect.initial_delay} s exceeds '
                         f'reconnect.max_delay {self.reconnect.max_delay} s')
        extra += _collect({'bias': self.bias, 'bias_guard': self.bias_guard})
        validate_fields(self, extra)
