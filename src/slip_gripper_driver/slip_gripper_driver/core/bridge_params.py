# SPDX-License-Identifier: Apache-2.0
"""Parameters of the gripper bridge: link supervision, command handling and the whole set.

`BridgeParams` nests the groups the bridge uses (actuator link constants, link watchdog,
opening-rate observer, homing, grasp-force loop, command handling); in ROS they flatten to
``actuator.*``, ``link.*`` and so on. ROS-free.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from slip_cell_common.core.param_schema import ParameterError
from slip_cell_common.core.validation import validate_fields
from slip_gripper_driver.core.force_control import ForceControlParams
from slip_gripper_driver.core.homing import HomingParams
from slip_gripper_driver.core.observer import ObserverParams
from slip_gripper_driver.core.protocol import ActuatorParams


@dataclass(frozen=True)
class LinkParams:
    """Telemetry supervision (parameter group ``link``).

    Staleness is judged from the device: a telemetry gap counts only while no bytes wait at
    the port and the kernel holds none on their way there. Telemetry that waits unprocessed
    means the host is behind, not the device: the last command stays applied (the firmware
    holds it) until ``host_stall_limit`` (``kernel_hold_limit`` while the kernel holds it). A gap
    shorter than ``fault_after`` is a validity state (status ``link_ok`` false, diagnostics
    WARN); ``stale_action`` says whether it also writes the safe voltage. The safe state
    proper (safe voltage, disarm, reconnect) belongs to the link fault.
    """

    stale_after: float = field(default=0.020, metadata={
        'unit': 's', 'range': (0.004, 1.0),
        'description': 'no telemetry arrived for this long: the link is stale (status link_ok '
                       'false; see stale_action; stays armed, the loop resumes with the next '
                       'line)'})
    stale_action: str = field(default='hold_last', metadata={
        'choices': ('hold_last', 'safe_voltage'),
        'description': 'what a stale link does before fault_after: hold_last = write nothing, '
                       'the firmware keeps the last command (the grasp holds through a '
                       'telemetry gap); safe_voltage = write the safe voltage once (the grasp '
                       'relaxes until telemetry resumes)'})
    fault_after: float = field(default=0.250, metadata={
        'unit': 's', 'range': (0.01, 10.0),
        'description': 'no telemetry arrived for this long: link fault, disarm, reconnect'})
    host_stall_limit: float = field(default=1.0, metadata={
        'unit': 's', 'range': (0.02, 60.0),
        'description': 'telemetry waited unprocessed at the port this long while the watchdog '
                       'kept running on time (the loop itself is stuck): safe voltage, disarm. '
                       'A pause of the whole driver process is reported, not disarmed (the '
                       'firmware kept the last command)'})
    kernel_hold_limit: float = field(default=5.0, metadata={
        'unit': 's', 'range': (0.02, 60.0),
        'description': 'telemetry the device sent stayed in the kernel this long (its tty '
                       'worker thread had not run; the reader waits for it): safe voltage, '
                       'disarm. Shorter holds are host stalls: the firmware keeps the last '
                       'command'})
    resume_rate: float = field(default=200.0, metadata={
        'unit': 'N/s', 'range': (1.0, 1.0e4),
        'description': 'after the loop wrote nothing for stale_after (host stall, telemetry '
                       'gap) the force command moves from the last applied value at most '
                       'this fast'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        problems = []
        for name in ('fault_after', 'host_stall_limit', 'kernel_hold_limit'):
            limit = getattr(self, name)
            if limit < self.stale_after:  # every bound follows the first missed deadline
                problems.append(f'{name} {limit} s is below stale_after {self.stale_after} s')
        validate_fields(self, problems)


@dataclass(frozen=True)
class CommandParams:
    """Grasp-force command handling (parameter group ``command``)."""

    default_timeout: float = field(default=0.0, metadata={
        'unit': 's', 'range': (0.0, 60.0),
        'description': 'expiry of commands that carry no timeout; 0 = valid until replaced'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        validate_fields(self)


@dataclass(frozen=True)
class BridgeParams:
    """Everything the bridge core needs (nested groups flatten to ``actuator.*`` etc.)."""

    actuator: ActuatorParams = field(default_factory=ActuatorParams)
    link: LinkParams = field(default_factory=LinkParams)
    observer: ObserverParams = field(default_factory=ObserverParams)
    homing: HomingParams = field(default_factory=HomingParams)
    force_control: ForceControlParams = field(default_factory=ForceControlParams)
    command: CommandParams = field(default_factory=CommandParams)

    def validate(self) -> None:
        """Raise `ParameterError` listing the problems of every group and combination."""
        problems: list[str] = []
        for name in ('actuator', 'link', 'observer', 'homing', 'force_control', 'command'):
            try:
                getattr(self, name).validate()
            except ParameterError as exc:
                problems.append(f'{name}: {exc}')
        homing_force = self.homing.voltage * self.actuator.newton_per_volt
        if homing_force > self.force_control.max_command_force:
            problems.append(f'homing.voltage {self.homing.voltage} V squeezes '
                            f'{homing_force:.1f} N, above force_control.max_command_force')
        if self.homing.voltage > self.actuator.voltage_limit:
            problems.append(f'homing.voltage {self.homing.voltage} V exceeds '
                            f'actuator.voltage_limit {self.actuator.voltage_limit} V')
        if problems:
            raise ParameterError('; '.join(problems))
