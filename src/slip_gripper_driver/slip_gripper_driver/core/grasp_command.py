# SPDX-License-Identifier: Apache-2.0
"""The gate every grasp-force command passes on the host (ROS-free).

A ``slip_msgs/GraspForceCommand`` (per-finger force [N], positive squeezes; ``header.stamp``;
``timeout`` [s]; ``source``) is **rejected** (counted by reason, never used) when

* the force is not finite (``non_finite``);
* ``|force|`` exceeds what the actuator can express, ``voltage_limit · newton_per_volt``
  (``out_of_range``);
* the timeout is not finite and ≥ 0 (``bad_timeout``);
* the stamp is not finite (``bad_stamp``);
* the stamp lies more than `MAX_COMMAND_CLOCK_SKEW_S` after its arrival, i.e. the sender's
  clock disagrees with the node's (``future_stamp``).

A valid command that arrives while the driver is disarmed is **ignored** (counted): only an
explicit re-arm may apply force again. Otherwise it becomes the target: stamp 0 means
"now" (the arrival time), timeout 0 means ``command.default_timeout`` (0 = valid until
replaced). Values beyond the target limits ``[−max_open_force, max_grasp_force]`` are accepted
and counted; the controller clips them.

`GripperBridge` owns one gate; the simulated cell runs that bridge, so the same gate decides
on hardware and in simulation.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from slip_gripper_driver.core.bridge_params import BridgeParams
from slip_gripper_driver.core.gripper_records import CommandResult
from slip_gripper_driver.core.protocol import ActuatorParams

#: Commands stamped further in the future than this (relative to their arrival) are rejected
#: as a clock mismatch between nodes [s].
MAX_COMMAND_CLOCK_SKEW_S = 0.5


class GraspTarget(NamedTuple):
    """The grasp-force target in use.

    Attributes:
        force: Per-finger grasp force [N]; positive squeezes, negative opens.
        stamp: Reference time of the timeout [s] (the command stamp, or its arrival).
        timeout: Expiry after ``stamp`` [s]; 0 = valid until replaced.
        source: ``SOURCE_*`` constant of the command (reported only).
    """

    force: float
    stamp: float
    timeout: float
    source: int


def command_rejection(force: float, t: float, stamp: float, timeout: float,
                      actuator: ActuatorParams) -> tuple[str, str] | None:
    """``(reason key, message)`` for a command that must not be used, or None when valid.

    Args:
        force: Commanded force [N].
        t: Arrival time on the node clock [s].
        stamp: Command stamp [s]; 0 = unstamped.
        timeout: Command timeout [s].
        actuator: Actuator constants (bound ``voltage_limit · newton_per_volt``).
    """
    bound = actuator.voltage_limit * actuator.newton_per_volt
    if not math.isfinite(force):
        return 'non_finite', f'force {force!r} is not finite'
    if abs(force) > bound:
        return 'out_of_range', (f'|force| {abs(force):.3g} N exceeds the actuator range '
                                f'{bound:.1f} N')
    if not (math.isfinite(timeout) and timeout >= 0.0):
        return 'bad_timeout', f'timeout {timeout!r} s is not finite >= 0'
    if not math.isfinite(stamp):
        return 'bad_stamp', f'stamp {stamp!r} is not finite'
    if stamp > t + MAX_COMMAND_CLOCK_SKEW_S:
        return 'future_stamp', (f'stamp {stamp:.3f} s is {stamp - t:.3f} s in the future '
                                f'(clock mismatch?)')
    return None


class GraspCommandGate:
    """Validates grasp-force commands and holds the accepted target and the counters.

    Not thread-safe: the bridge calls it with its lock held.

    Args:
        t: Time of creation [s] (stamp of the initial 0 N target).
    """

    def __init__(self, t: float = 0.0) -> None:
        self.target = GraspTarget(0.0, t, 0.0, 0)
        self.accepted = 0
        self.ignored = 0  #: valid commands that arrived while disarmed
        self.clipped = 0  #: accepted commands beyond the target limits
        self._rejected: dict[str, int] = {}

    @property
    def rejected(self) -> int:
        """Rejected commands (every reason)."""
        return sum(self._rejected.values())

    def rejected_by_reason(self) -> tuple[tuple[str, int], ...]:
        """``(reason key, count)`` pairs sorted by key."""
        return tuple(sorted(self._rejected.items()))

    def submit(self, force: float, t: float, *, stamp: float, timeout: float, source: int,
               armed: bool, params: BridgeParams) -> CommandResult:
        """Validate a command arriving at ``t`` [s] and make it the target if it may be used.

        Args:
            force: Per-finger grasp force [N].
            t: Arrival time on the node clock [s].
            stamp: ``header.stamp`` [s]; 0 = unstamped (the arrival time is used).
            timeout: Expiry after ``stamp`` [s]; 0 = ``command.default_timeout``.
            source: ``SOURCE_*`` constant.
            armed: The driver may apply force (otherwise a valid command is ignored).
            params: Bridge parameters in use.

        Returns:
            Accepted, or the reason for rejection or for ignoring it.
        """
        rejection = command_rejection(force, t, stamp, timeout, params.actuator)
        if rejection is not None:
            key, message = rejection
            self._rejected[key] = self._rejected.get(key, 0) + 1
            return CommandResult(False, message)
        if not armed:
            self.ignored += 1
            return CommandResult(False, 'not armed: command ignored (re-arm first)')
        fc = params.force_control
        if not -fc.max_open_force <= force <= fc.max_grasp_force:
            self.clipped += 1
        self.target = GraspTarget(force, stamp if stamp != 0.0 else t,
                                  timeout if timeout > 0.0 else params.command.default_timeout,
                                  source)
        self.accepted += 1
        return CommandResult(True, 'accepted')

    def clear(self, t: float) -> None:
        """Target 0 N from ``t`` [s], valid until replaced."""
        self.target = GraspTarget(0.0, t, 0.0, 0)

    def rewind(self, t: float) -> None:
        """The clock jumped back to ``t`` [s]: no target stamp may lie after it."""
        target = self.target
        self.target = target._replace(stamp=min(target.stamp, t))
