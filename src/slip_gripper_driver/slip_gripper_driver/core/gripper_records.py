# SPDX-License-Identifier: Apache-2.0
"""Records the gripper's host side hands out (ROS-free).

One gripper status (``slip_msgs/GripperStatus``) and one motor-command record
(``slip_msgs/MotorCommand``) per telemetry line, the result of handling one line, the outcome
of a request (grasp-force command, arm, homing), the link watchdog's verdict and the
diagnostics counters. The real driver and the simulated cell both publish these records,
built by `bridge.GripperBridge`.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple

from slip_gripper_driver.core.force_control import BypassReason
from slip_gripper_driver.core.protocol import LineKind


class LinkState(IntEnum):
    """Telemetry link state seen by the watchdog."""

    INACTIVE = 0  #: not activated (no supervision)
    OK = 1
    STALE = 2  #: no telemetry arrived for stale_after (still armed; see link.stale_action)
    FAULT = 3  #: no telemetry arrived for fault_after: disarmed, reconnect
    DOWN = 4  #: port closed (reconnecting)
    LAGGING = 5  #: telemetry arrives but waits unprocessed (the host is behind, not the link)


class WatchdogResult(NamedTuple):
    """Result of `GripperBridge.check_watchdog`.

    Attributes:
        state: Link state.
        age_s: Seconds since the last telemetry line (or since connection/activation).
        reconnect: True once per fault: the caller must drop and reopen the port.
        reason: Human-readable reason naming the condition.
        disarmed: True once when this check disarmed the driver (link fault, or a loop stuck
            beyond ``link.host_stall_limit`` while the watchdog ran on time).
        held: Stale, and nothing was written: the firmware keeps applying the last command
            (``link.stale_action`` ``hold_last`` while armed and not homing).
    """

    state: LinkState
    age_s: float
    reconnect: bool
    reason: str
    disarmed: bool = False
    held: bool = False


class CommandResult(NamedTuple):
    """Outcome of a request (command, arm, homing).

    Attributes:
        accepted: True when the request took effect.
        reason: Why it was refused, or a short confirmation.
    """

    accepted: bool
    reason: str


class GripperStatusSnapshot(NamedTuple):
    """Fields of ``slip_msgs/GripperStatus`` (SI; ``stamp`` = acquisition time [s]).

    One per telemetry line: a NamedTuple, built several times faster than a frozen dataclass.
    """

    stamp: float
    line_count: int
    bad_line_count: int
    reconnect_count: int
    motor_angle: float
    opening: float
    opening_rate: float
    voltage_cmd: float
    force_cmd: float
    force_target: float
    measured_grasp_force: float
    homed: bool
    ft_biased: bool
    ft_fresh: bool
    link_ok: bool
    in_contact: bool
    command_expired: bool
    armed: bool
    safe_state: bool


class MotorCommandRecord(NamedTuple):
    """Fields of ``slip_msgs/MotorCommand`` for one controller step (``stamp`` [s])."""

    stamp: float
    force_target: float
    force_cmd: float
    voltage_cmd: float
    measured_force: float
    error: float
    integral: float
    gain_scale: float
    closed_loop: bool
    bypass_reason: int


class LineResult(NamedTuple):
    """What one line did.

    Attributes:
        stamp: Acquisition stamp of the line [s].
        kind: Line classification.
        command: Bytes written to the device (None if nothing was written).
        written: The writer reported success.
        status: Status after a telemetry line (None for other lines).
        motor: Controller step record (None unless the controller stepped).
        event: ``''``, ``'firmware_restart'``, ``'homing_done'``, ``'homing_failed'`` or
            ``'host_stall'`` (the first line after telemetry waited unprocessed longer than
            ``link.stale_after``; see `BridgeDiagnostics.last_host_stall_s`).
    """

    stamp: float
    kind: LineKind
    command: bytes | None
    written: bool
    status: GripperStatusSnapshot | None
    motor: MotorCommandRecord | None
    event: str


@dataclass(frozen=True)
class BridgeDiagnostics:
    """Counters and state for diagnostics (ages in s, forces in N)."""

    active: bool
    armed: bool
    safe_reason: str
    link_state: LinkState
    line_age_s: float
    lines_good: int
    lines_bad: int
    lines_unknown: int
    lines_non_finite: int
    lines_too_long: int
    firmware_rejects: int
    firmware_restarts: int
    reconnects: int
    link_losses: int
    stale_events: int
    link_faults: int
    writes: int
    write_failures: int
    commands_accepted: int
    commands_rejected: int
    rejected_by_reason: tuple[tuple[str, int], ...]
    commands_ignored: int
    targets_clipped: int
    command_age_s: float
    command_source: int
    homed: bool
    homing_active: bool
    homing_message: str
    bypass_reason: BypassReason
    closed_loop: bool
    saturations: int
    skipped_integrations: int
    ft_samples: tuple[int, int]
    ft_age_s: tuple[float, float]
    ft_biased: tuple[bool, bool]
    host_stalls: int = 0  #: times telemetry waited unprocessed longer than link.stale_after
    last_host_stall_s: float = 0.0  #: how late the loop was at the newest one [s]
    max_host_stall_s: float = 0.0  #: the longest one [s]
    #: Longest interval between two watchdog checks [s]: how long the whole driver process
    #: did not run (the watchdog timer fires every few ms).
    max_watchdog_gap_s: float = 0.0
    catch_up_lines: int = 0  #: lines of a backlog that updated the state without a step
    #: control steps whose old F/T sample was the host's delay (records waiting unread)
    ft_host_lag_steps: int = 0
    resume_ramps: int = 0  #: command resumptions rate-limited from the last applied value
    #: Motor angle where the pads last touched something [rad]; NaN once they reopened.
    contact_angle: float = float('nan')
