# SPDX-License-Identifier: Apache-2.0
"""Gripper bridge core: telemetry in, voltage out, fail-safe (ROS-free).

`GripperBridge` is the deterministic heart of the ``gripper_driver`` node. Per telemetry line
(500 Hz, on the serial reader thread) it parses the line, updates the opening-rate observer,
steps homing or the grasp-force controller, and writes exactly one ``T<volts>\\n`` command
through an injected writer. Everything else (grasp-force commands, F/T samples, homing and
stop requests, the link watchdog) arrives from other threads and is serialised by one lock,
so a command is never written after a state change that forbids it.

`GripperDriverCore` wires a bridge to a `transport.SerialLink` (port, reader thread,
reconnection) and exposes the lifecycle steps a node needs.

Fail-safe rules (issue 5 item 2, hardware_protocols §7):

* Hard force ceiling: every command is clipped to ``[−max_open_force, max_command_force]``
  and the voltage limit here, whatever the controller or a publisher asked for (HW-3, HW-5).
* Grasp-force commands that are not finite, not expressible by the actuator
  (``|F| > voltage_limit · newton_per_volt``), with a bad timeout or a stamp from the future
  are rejected and counted, never used. Values within that range but beyond the target limits
  are clipped by the controller (and counted here).
* Stale command (its timeout, or ``command.default_timeout`` when it carries none): the
  controller's ``on_command_timeout`` policy. Stale F/T: open loop; F/T fault: target limited
  to ``safe_hold_force`` (see `force_control`).
* Link supervision (`check_watchdog`, called from a timer with the current time): no
  telemetry for ``link.stale_after`` → the safe voltage is written and the driver is
  **disarmed**; after ``link.fault_after`` the caller reconnects. A read/write error or a
  vanished port is reported by the link at once. With a 10 ms timer, a silent link is
  detected within ``stale_after`` + 10 ms = 30 ms.
* Arming: activation arms. Any link fault, reconnection or firmware restart disarms; while
  disarmed the safe voltage is written on every line and grasp-force commands are ignored
  (counted). Only an explicit `GripperBridge.arm` call re-arms, and arming clears the target
  to 0 N: a command received before or during the fault must never apply force afterwards,
  and a new command alone is not an operator's confirmation that the cell is safe.
* Deactivate/shutdown: the safe voltage is written first, then the driver goes inactive.
* Firmware restart text after telemetry has flowed (``Voltage control``, SimpleFOC init):
  homing invalidated, observer and controller reset, disarmed. The same text before the first
  telemetry line of a connection is the boot banner and only counted.
* Every (re)connection first writes the safe voltage, so the firmware (which applies its last
  value forever) is in a known state.
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Callable, NamedTuple

from slip_gripper_driver.core.force_control import (BypassReason, ForceControlParams,
                                                    ForceLoopInput, ForceLoopOutput,
                                                    GraspForceController)
from slip_gripper_driver.core.homing import Homing, HomingParams, homing_refusal
from slip_gripper_driver.core.observer import ObserverParams, RateObserver
from slip_cell_common.core.param_schema import ParameterError
from slip_gripper_driver.core.protocol import (ActuatorParams, CommandError, LineKind,
                                               TelemetryParser, encode_force_command,
                                               format_voltage_command, voltage_to_force)
from slip_cell_common.core.serial_transport import (ByteStream, Clock, LinkError, LinkStats,
                                                ReconnectParams, SerialLink, open_stream)
from slip_cell_common.core.validation import validate_fields

#: Commands stamped further in the future than this (relative to their arrival) are rejected
#: as a clock mismatch between nodes [s].
MAX_COMMAND_CLOCK_SKEW_S = 0.5

_NAN = math.nan

#: Writes one command to the device; returns False when it was not written.
Writer = Callable[[bytes], bool]


class _FtSlot(NamedTuple):
    """Latest F/T sample of one finger, handed over as one immutable object."""

    fz: float  #: bias-removed Fz [N]; NaN if invalid
    stamp: float  #: acquisition stamp [s]; NaN before the first sample
    biased: bool


_NO_FT = _FtSlot(_NAN, _NAN, False)


@dataclass(frozen=True)
class LinkParams:
    """Telemetry supervision (parameter group ``link``)."""

    stale_after: float = field(default=0.020, metadata={
        'unit': 's', 'range': (0.004, 1.0),
        'description': 'no telemetry for this long: safe voltage, disarm'})
    fault_after: float = field(default=0.250, metadata={
        'unit': 's', 'range': (0.01, 10.0),
        'description': 'no telemetry for this long: reconnect'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        validate_fields(self, [] if self.fault_after >= self.stale_after else [
            f'fault_after {self.fault_after} s is below stale_after {self.stale_after} s'])


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


class LinkState(IntEnum):
    """Telemetry link state seen by the watchdog."""

    INACTIVE = 0  #: not activated (no supervision)
    OK = 1
    STALE = 2  #: no telemetry for stale_after: safe state
    FAULT = 3  #: no telemetry for fault_after: reconnect
    DOWN = 4  #: port closed (reconnecting)


class WatchdogResult(NamedTuple):
    """Result of `GripperBridge.check_watchdog`.

    Attributes:
        state: Link state.
        age_s: Seconds since the last telemetry line (or since connection/activation).
        reconnect: True once per fault: the caller must drop and reopen the port.
        reason: Human-readable reason naming the condition.
    """

    state: LinkState
    age_s: float
    reconnect: bool
    reason: str


class CommandResult(NamedTuple):
    """Outcome of a request (command, arm, homing).

    Attributes:
        accepted: True when the request took effect.
        reason: Why it was refused, or a short confirmation.
    """

    accepted: bool
    reason: str


@dataclass(frozen=True, slots=True)
class GripperStatusSnapshot:
    """Fields of ``slip_msgs/GripperStatus`` (SI; ``stamp`` = acquisition time [s])."""

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


@dataclass(frozen=True, slots=True)
class MotorCommandRecord:
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
        event: ``''``, ``'firmware_restart'``, ``'homing_done'`` or ``'homing_failed'``.
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


class GripperBridge:
    """Bridge core; see the module docstring. All public methods are thread-safe.

    Args:
        params: Validated parameters.
        writer: Writes one command to the device and returns True on success (normally
            `SerialLink.write`). Called with the bridge lock held, so commands are ordered.
    """

    def __init__(self, params: BridgeParams, writer: Writer) -> None:
        self._lock = threading.Lock()
        self._params = params
        self._writer = writer
        self._parser = TelemetryParser()
        self._observer = RateObserver(params.observer)
        self._homing = Homing(params.homing, params.actuator.opening_per_rad)
        self._controller = GraspForceController(params.force_control)
        self._safe_command = format_voltage_command(params.actuator.safe_voltage,
                                                    params.actuator.voltage_limit)
        # link session
        self._active = False
        self._armed = False
        self._stopped = False
        self._safe_reason = 'not activated'
        self._connected = False
        self._connections = 0
        self._reconnects = 0
        self._connect_t = _NAN
        self._activate_t = _NAN
        self._last_line_t = _NAN
        self._session_lines = 0
        self._stale_latched = False
        self._fault_reported = False
        self._pending_homing = False
        # latest values
        self._angle = _NAN
        self._rate = _NAN
        self._voltage_cmd = _NAN
        self._force_cmd = _NAN
        self._last_out: ForceLoopOutput | None = None
        # command
        self._target = 0.0
        self._target_stamp = 0.0
        self._target_timeout = 0.0
        self._target_source = 0
        # F/T (index 0 = finger 1): latest-sample slots, replaced whole without the lock
        self._ft = [_NO_FT, _NO_FT]
        self._ft_samples = [0, 0]
        # counters
        self._firmware_restarts = 0
        self._link_losses = 0
        self._stale_events = 0
        self._link_faults = 0
        self._writes = 0
        self._write_failures = 0
        self._accepted = 0
        self._rejected: dict[str, int] = {}
        self._ignored = 0
        self._clipped = 0

    # ------------------------------------------------------------------ parameters
    @property
    def params(self) -> BridgeParams:
        """Parameters in use."""
        return self._params

    def set_params(self, params: BridgeParams) -> None:
        """Swap the (validated) parameters between two lines.

        Read-only groups (``actuator.newton_per_volt``, ``opening_per_rad``) are bound at
        configure; the node must not change them at run time.
        """
        with self._lock:
            self._params = params
            self._observer.set_params(params.observer)
            self._homing.set_params(params.homing)
            self._controller.set_params(params.force_control)
            self._safe_command = format_voltage_command(params.actuator.safe_voltage,
                                                        params.actuator.voltage_limit)

    # ------------------------------------------------------------------ lifecycle
    def activate(self, t: float) -> None:
        """Start a session at time ``t`` [s]: counters zeroed, armed, optional auto-homing."""
        with self._lock:
            self._active = True
            self._armed = True
            self._stopped = False
            self._safe_reason = ''
            self._activate_t = t
            self._parser.reset()
            self._observer.reset()
            self._controller.reset()
            self._stale_latched = False
            self._fault_reported = False
            self._clear_target(t)
            self._pending_homing = self._params.homing.on_activate and not self._homing.homed

    def deactivate(self, t: float) -> bool:
        """Write the safe voltage first, then go inactive (also for shutdown).

        Returns:
            True when the safe voltage was written.
        """
        del t
        with self._lock:
            written = self._write(self._safe_command)
            self._voltage_cmd = self._params.actuator.safe_voltage
            self._active = False
            self._enter_safe('deactivated')
            return written

    shutdown = deactivate

    def arm(self, t: float) -> CommandResult:
        """Re-arm after a fault (explicit operator confirmation); clears the target to 0 N."""
        with self._lock:
            if not self._active:
                return CommandResult(False, 'not active')
            if not self._link_ok(t):
                return CommandResult(False, 'no telemetry from the gripper')
            self._armed = True
            self._stopped = False
            self._safe_reason = ''
            self._controller.reset()
            self._clear_target(t)
            return CommandResult(True, 'armed; target cleared to 0 N')

    def stop(self, t: float) -> bool:
        """Write the safe voltage now and hold it until the next accepted command.

        Returns:
            True when the safe voltage was written.
        """
        with self._lock:
            self._stopped = True
            self._clear_target(t)
            self._homing.abort('stop requested')
            self._voltage_cmd = self._params.actuator.safe_voltage
            return self._write(self._safe_command)

    def reset(self, t: float) -> None:
        """Forget time-dependent state after the node clock jumped backwards to ``t`` [s].

        Observer, controller and telemetry age restart; arming, homing and the target stay.
        """
        with self._lock:
            self._observer.reset()
            self._controller.reset()
            self._rate = _NAN
            self._last_line_t = _NAN
            self._connect_t = self._activate_t = t
            self._target_stamp = min(self._target_stamp, t)
            for i, slot in enumerate(self._ft):
                if math.isfinite(slot.stamp):
                    self._ft[i] = slot._replace(stamp=min(slot.stamp, t))

    # ------------------------------------------------------------------ link events
    def on_connected(self, t: float, port: str = '') -> None:
        """The port was (re)opened at ``t`` [s]: new link session, safe voltage written."""
        del port
        with self._lock:
            self._connected = True
            self._connections += 1
            if self._connections > 1:
                self._reconnects += 1
                self._enter_safe('reconnected; re-arm required')
            self._connect_t = t
            self._last_line_t = _NAN
            self._session_lines = 0
            self._stale_latched = False
            self._fault_reported = False
            self._new_session('link (re)connected')
            self._voltage_cmd = self._params.actuator.safe_voltage
            self._write(self._safe_command)

    def on_link_lost(self, t: float, reason: str) -> None:
        """The port failed or was dropped at ``t`` [s]: safe state, disarmed, homing void."""
        del t
        with self._lock:
            if self._connected:
                self._link_losses += 1
            self._connected = False
            self._enter_safe(f'link lost: {reason}')
            self._new_session(f'link lost: {reason}')

    def check_watchdog(self, t: float) -> WatchdogResult:
        """Supervise telemetry; call from a timer (≤ 10 ms period) with the current time [s].

        Writes the safe voltage once when the link goes stale; disarms and asks for a
        reconnection once when it faults.
        """
        # The usual case (fresh telemetry) without the lock: the watchdog runs every few ms
        # on its own thread, and a lock holder descheduled there would delay the reader.
        # Attribute reads are atomic; a NaN age (no line yet) takes the locked path.
        if self._connected and self._active:
            age = t - self._last_line_t
            if age <= self._params.link.stale_after:
                return WatchdogResult(LinkState.OK, age, False, 'ok')
        with self._lock:
            if not self._connected:
                return WatchdogResult(LinkState.DOWN, math.inf, False, 'port closed')
            if not self._active:
                return WatchdogResult(LinkState.INACTIVE, _NAN, False, 'inactive')
            age = self._line_age(t)
            p = self._params.link
            if age > p.fault_after:
                reason = f'no telemetry for {age:.3f} s (fault after {p.fault_after:.3f} s)'
                reconnect = not self._fault_reported
                if reconnect:
                    self._fault_reported = True
                    self._link_faults += 1
                    self._go_stale(reason, disarm=True)
                return WatchdogResult(LinkState.FAULT, age, reconnect, reason)
            if age > p.stale_after:
                reason = f'no telemetry for {age:.3f} s (stale after {p.stale_after:.3f} s)'
                self._go_stale(reason, disarm=False)
                return WatchdogResult(LinkState.STALE, age, False, reason)
            return WatchdogResult(LinkState.OK, age, False, 'ok')

    # ------------------------------------------------------------------ inputs
    def set_grasp_force(self, force: float, t: float, *, stamp: float = 0.0,
                        timeout: float = 0.0, source: int = 0) -> CommandResult:
        """Validate and store a grasp-force command (``slip_msgs/GraspForceCommand``).

        Args:
            force: Per-finger grasp force [N]; positive squeezes, negative opens.
            t: Arrival time on the node clock [s].
            stamp: ``header.stamp`` [s]; 0 = unstamped (the arrival time is used).
            timeout: Expiry after ``stamp`` [s]; 0 = ``command.default_timeout``.
            source: ``SOURCE_*`` constant (reported only).

        Returns:
            Accepted, or the reason for rejection (rejected values are never used).
        """
        with self._lock:
            a = self._params.actuator
            bound = a.voltage_limit * a.newton_per_volt
            if not math.isfinite(force):
                return self._reject('non_finite', f'force {force!r} is not finite')
            if abs(force) > bound:
                return self._reject('out_of_range', f'|force| {abs(force):.3g} N exceeds the '
                                    f'actuator range {bound:.1f} N')
            if not (math.isfinite(timeout) and timeout >= 0.0):
                return self._reject('bad_timeout', f'timeout {timeout!r} s is not finite >= 0')
            if not math.isfinite(stamp):
                return self._reject('bad_stamp', f'stamp {stamp!r} is not finite')
            if stamp > t + MAX_COMMAND_CLOCK_SKEW_S:
                return self._reject('future_stamp', f'stamp {stamp:.3f} s is {stamp - t:.3f} s '
                                    f'in the future (clock mismatch?)')
            if not (self._active and self._armed):
                self._ignored += 1
                return CommandResult(False, 'not armed: command ignored (re-arm first)')
            fc = self._params.force_control
            if not -fc.max_open_force <= force <= fc.max_grasp_force:
                self._clipped += 1
            self._target = force
            self._target_stamp = stamp if stamp != 0.0 else t
            self._target_timeout = timeout if timeout > 0.0 else \
                self._params.command.default_timeout
            self._target_source = source
            self._stopped = False
            self._accepted += 1
            return CommandResult(True, 'accepted')

    def on_ft_sample(self, finger: int, t: float, fz: float, biased: bool) -> None:
        """Store the latest bias-removed normal force of one finger.

        Lock-free: the sample replaces the finger's slot in one reference assignment (atomic
        under the GIL) and the 500 Hz step reads each slot once, so an F/T reader thread
        never waits for a control step nor makes one wait (it used to take the bridge lock
        at 1 kHz per box; a reader holding it while descheduled delayed the command write).
        One thread per finger calls this (its box's reader or the topic callback).

        Args:
            finger: 1 or 2.
            t: Acquisition stamp [s] (node clock when the datagram arrived).
            fz: Bias-removed Fz [N] (squeezing negative); NaN if invalid.
            biased: The sample has its bias removed.
        """
        if finger not in (1, 2):
            raise ValueError(f'finger must be 1 or 2, got {finger!r}')
        i = finger - 1
        self._ft[i] = _FtSlot(fz, t, biased)
        self._ft_samples[i] += 1

    def start_homing(self, t: float) -> CommandResult:
        """Start homing at ``t`` [s] unless a precondition fails (see `homing_refusal`)."""
        with self._lock:
            refusal = self._homing_refusal(t)
            if refusal is not None:
                return CommandResult(False, refusal)
            self._stopped = False
            self._controller.reset()
            self._homing.start(t)
            return CommandResult(True, 'homing started')

    # ------------------------------------------------------------------ the 500 Hz path
    def on_line(self, line: bytes, overflow: bool, t: float) -> LineResult:
        """Process one device line stamped at acquisition time ``t`` [s] and write a command.

        Signature matches `transport.SerialLink`'s ``on_line`` callback.
        """
        with self._lock:
            parsed = self._parser.parse(line, overflow)
            if parsed.kind != LineKind.TELEMETRY:
                if parsed.restart and self._session_lines > 0:
                    self._firmware_restarts += 1
                    self._session_lines = 0
                    self._enter_safe('firmware restart detected')
                    self._new_session('firmware restart detected')
                    self._voltage_cmd = self._params.actuator.safe_voltage
                    written = self._write(self._safe_command)
                    return LineResult(t, parsed.kind, self._safe_command, written, None, None,
                                      'firmware_restart')
                return LineResult(t, parsed.kind, None, False, None, None, '')
            return self._on_telemetry(parsed.angle_rad, t)

    def _on_telemetry(self, angle: float, t: float) -> LineResult:
        params = self._params
        a = params.actuator
        self._session_lines += 1
        self._last_line_t = t
        self._stale_latched = False
        self._fault_reported = False
        self._angle = angle
        self._rate = self._observer.update(t, angle * a.opening_per_rad).rate
        if not self._active:
            return LineResult(t, LineKind.TELEMETRY, None, False, self._snapshot(t), None, '')

        if self._pending_homing:
            self._pending_homing = False
            refusal = self._homing_refusal(t)
            if refusal is None:
                self._controller.reset()
                self._homing.start(t)
            else:
                self._homing.message = f'automatic homing refused: {refusal}'

        event = ''
        out: ForceLoopOutput | None = None
        ft = self._ft_pair()  # one consistent pair for this step
        if self._homing.active:
            step = self._homing.step(t, angle)
            if step.voltage_v is not None and self._armed:
                command = format_voltage_command(step.voltage_v, a.voltage_limit)
                voltage = float(command[1:-1])
            else:
                command, voltage = self._safe_command, a.safe_voltage
            if step.finished:
                event = 'homing_done' if self._homing.homed else 'homing_failed'
            self._force_cmd = voltage_to_force(voltage, a.newton_per_volt)
        else:
            out = self._controller.step(self._loop_input(t, ft))
            self._last_out = out
            command, voltage = self._safe_command, a.safe_voltage
            if not self._safe():
                fc = params.force_control
                try:
                    command, voltage = encode_force_command(
                        out.force_cmd, newton_per_volt=a.newton_per_volt,
                        max_close_force_n=fc.max_command_force,
                        max_open_force_n=fc.max_open_force, voltage_limit_v=a.voltage_limit)
                except CommandError as exc:  # cannot happen with finite inputs; stay safe
                    self._enter_safe(f'command encoding failed: {exc}')
            self._force_cmd = out.force_cmd
        self._voltage_cmd = voltage
        written = self._write(command)
        # Everything below only reports: it runs after the command left.
        motor = None if out is None else MotorCommandRecord(
            t, out.force_target, out.force_cmd, voltage, out.measured_force, out.error,
            out.integral, out.gain_scale, out.closed_loop, int(out.bypass_reason))
        return LineResult(t, LineKind.TELEMETRY, command, written, self._snapshot(t, ft), motor,
                          event)

    # ------------------------------------------------------------------ outputs
    def status(self, t: float) -> GripperStatusSnapshot:
        """Status at time ``t`` [s] (for publishing from a timer while no lines arrive)."""
        with self._lock:
            return self._snapshot(t)

    def diagnostics(self, t: float) -> BridgeDiagnostics:
        """Counters and state at time ``t`` [s]."""
        with self._lock:
            c = self._parser.counters()
            out = self._last_out
            ft = self._ft_pair()
            if not self._connected:
                state = LinkState.DOWN
            elif not self._active:
                state = LinkState.INACTIVE
            elif self._line_age(t) > self._params.link.fault_after:
                state = LinkState.FAULT
            elif self._line_age(t) > self._params.link.stale_after:
                state = LinkState.STALE
            else:
                state = LinkState.OK
            return BridgeDiagnostics(
                active=self._active, armed=self._armed and self._active,
                safe_reason=self._safe_reason, link_state=state,
                line_age_s=self._line_age(t), lines_good=c.good, lines_bad=c.bad,
                lines_unknown=c.unknown, lines_non_finite=c.non_finite,
                lines_too_long=c.too_long, firmware_rejects=c.firmware_rejects,
                firmware_restarts=self._firmware_restarts, reconnects=self._reconnects,
                link_losses=self._link_losses, stale_events=self._stale_events,
                link_faults=self._link_faults, writes=self._writes,
                write_failures=self._write_failures, commands_accepted=self._accepted,
                commands_rejected=sum(self._rejected.values()),
                rejected_by_reason=tuple(sorted(self._rejected.items())),
                commands_ignored=self._ignored, targets_clipped=self._clipped,
                command_age_s=t - self._target_stamp, command_source=self._target_source,
                homed=self._homing.homed, homing_active=self._homing.active,
                homing_message=self._homing.message,
                bypass_reason=out.bypass_reason if out else BypassReason.SAFE_STATE,
                closed_loop=out.closed_loop if out else False,
                saturations=self._controller.saturations,
                skipped_integrations=self._controller.skipped_integrations,
                ft_samples=(self._ft_samples[0], self._ft_samples[1]),
                ft_age_s=(t - ft[0].stamp, t - ft[1].stamp),
                ft_biased=(ft[0].biased, ft[1].biased))

    @property
    def homing(self) -> Homing:
        """The homing state machine (read its ``phase``, ``message``, ``result``)."""
        return self._homing

    # ------------------------------------------------------------------ internals
    def _write(self, command: bytes) -> bool:
        ok = bool(self._writer(command))
        if ok:
            self._writes += 1
        else:
            self._write_failures += 1
        return ok

    def _reject(self, key: str, message: str) -> CommandResult:
        self._rejected[key] = self._rejected.get(key, 0) + 1
        return CommandResult(False, message)

    def _clear_target(self, t: float) -> None:
        self._target = 0.0
        self._target_stamp = t
        self._target_timeout = 0.0
        self._target_source = 0

    def _enter_safe(self, reason: str) -> None:
        self._armed = False
        self._safe_reason = reason
        self._homing.abort(reason)

    def _new_session(self, reason: str) -> None:
        self._homing.invalidate(reason)
        self._observer.reset()
        self._controller.reset()
        self._rate = _NAN

    def _go_stale(self, reason: str, disarm: bool) -> None:
        """Write the safe voltage once when telemetry stops.

        A stale link (no line for ``link.stale_after``) only gets the safe voltage: the loop is
        clocked by telemetry, so it resumes with the next line. A fault (``link.fault_after``,
        reconnection follows) also disarms: after a reconnect nothing is applied until
        ``arm()``.
        """
        if disarm and (self._armed or self._homing.active):
            self._enter_safe(reason)
        elif self._homing.active:
            self._homing.abort(reason)
        if self._stale_latched:
            return
        self._stale_latched = True
        self._stale_events += 1
        self._voltage_cmd = self._params.actuator.safe_voltage
        self._write(self._safe_command)

    def _safe(self) -> bool:
        return not (self._active and self._armed) or self._stopped or self._stale_latched

    def _line_age(self, t: float) -> float:
        ref = self._last_line_t
        if not math.isfinite(ref):
            ref = max(self._connect_t, self._activate_t)
        return t - ref if math.isfinite(ref) else math.inf

    def _link_ok(self, t: float) -> bool:
        return self._connected and self._session_lines > 0 and \
            self._line_age(t) <= self._params.link.stale_after

    def _ft_pair(self) -> tuple[_FtSlot, _FtSlot]:
        """Both fingers' latest slots, each read once (writers replace slots, never edit)."""
        return self._ft[0], self._ft[1]

    def _ft_state(self, t: float, ft: tuple[_FtSlot, _FtSlot] | None = None
                  ) -> tuple[float, bool, bool]:
        """``(grasp force F_m = −(Fz1+Fz2)/2 or NaN, both biased, both fresh)``."""
        ft1, ft2 = ft if ft is not None else self._ft_pair()
        stale = self._params.force_control.ft_stale_after
        biased = ft1.biased and ft2.biased
        fresh = t - ft1.stamp <= stale and t - ft2.stamp <= stale
        force = -0.5 * (ft1.fz + ft2.fz) if biased and fresh else _NAN
        return force, biased, fresh

    def _homing_refusal(self, t: float) -> str | None:
        force, biased, fresh = self._ft_state(t)
        return homing_refusal(
            link_ok=self._link_ok(t), armed=self._armed and self._active,
            busy=self._homing.active, ft_checked=biased and fresh and math.isfinite(force),
            grasp_force=force, contact_threshold=self._params.force_control.contact_threshold,
            target_force=0.0 if self._stopped else self._target)

    def _loop_input(self, t: float, ft: tuple[_FtSlot, _FtSlot]) -> ForceLoopInput:
        result = self._homing.result
        k = self._params.actuator.opening_per_rad
        measurement = self._params.force_control.measurement
        ft1, ft2 = ft
        if measurement == 'finger_1':
            biased = ft1.biased
        elif measurement == 'finger_2':
            biased = ft2.biased
        else:
            biased = ft1.biased and ft2.biased
        if result is not None:
            opening = (self._angle - result.theta_closed) * k
            stroke = result.stroke
        else:
            opening = stroke = _NAN
        return ForceLoopInput(
            t=t, target=self._target, target_stamp=self._target_stamp,
            target_timeout=self._target_timeout, fz_1=ft1.fz, fz_2=ft2.fz,
            ft_stamp_1=ft1.stamp, ft_stamp_2=ft2.stamp, ft_biased=biased,
            homed=result is not None, opening=opening,
            opening_rate=self._rate if result is not None else _NAN, stroke=stroke,
            safe_state=self._safe())

    def _snapshot(self, t: float, ft: tuple[_FtSlot, _FtSlot] | None = None
                  ) -> GripperStatusSnapshot:
        c = self._parser.counters()
        result = self._homing.result
        k = self._params.actuator.opening_per_rad
        force, biased, fresh = self._ft_state(t, ft)
        out = self._last_out
        homed = result is not None
        return GripperStatusSnapshot(
            stamp=t, line_count=c.good, bad_line_count=c.bad + c.unknown,
            reconnect_count=self._reconnects, motor_angle=self._angle,
            opening=(self._angle - result.theta_closed) * k if result is not None else _NAN,
            opening_rate=self._rate if homed else _NAN, voltage_cmd=self._voltage_cmd,
            force_cmd=self._force_cmd,
            force_target=out.force_target if out is not None else _NAN,
            measured_grasp_force=force, homed=homed, ft_biased=biased, ft_fresh=fresh,
            link_ok=self._link_ok(t),
            in_contact=abs(force) >= self._params.force_control.contact_threshold,
            command_expired=out.command_expired if out is not None else False,
            armed=self._armed and self._active, safe_state=self._safe())


LineResultCallback = Callable[[LineResult], None]
EventCallback = Callable[[float, str, str], None]
#: ``(t, result)`` after each watchdog check, on the watchdog thread.
WatchdogCallback = Callable[[float, WatchdogResult], None]


class GripperDriverCore:
    """A `GripperBridge` wired to a `SerialLink`: what the lifecycle node wraps.

    Lifecycle mapping: configure → `configure` (opens the port; `LinkError` names it);
    activate → `activate` then `start_watchdog` (or a ≥ 100 Hz timer calling `watchdog`);
    deactivate → `deactivate` (safe voltage first); cleanup → `cleanup`; shutdown / process
    exit → `shutdown`.

    `start_watchdog` supervises the link from a thread of its own rather than an executor
    timer: it does not depend on (or add load to) the executor, so a starved or busy executor
    can neither delay link-loss detection nor, through the GIL, the 500 Hz reader.

    Args:
        port: Port path or pyserial URL.
        params: Bridge parameters.
        clock: Node clock [s]; stamps every line and event.
        baudrate: Baud rate [Bd].
        reconnect: Back-off parameters.
        on_result: Called on the reader thread after each line was handled and its command
            written (publish status/motor command here; must not block).
        on_event: ``(t, kind, message)`` for logging/diagnostics; kinds: ``'connected'``,
            ``'lost'``, ``'error'``, ``'firmware_restart'``, ``'homing_done'``,
            ``'homing_failed'``, ``'stale'``, ``'fault'``.
        opener: Stream factory (tests inject fakes).
        read_timeout_s: Serial read timeout [s].
        thread_setup: Called first on the serial reader thread (`realtime.ThreadTuning.apply`).
    """

    def __init__(self, port: str, params: BridgeParams, *, clock: Clock,
                 baudrate: int = 115200, reconnect: ReconnectParams = ReconnectParams(),
                 on_result: LineResultCallback | None = None,
                 on_event: EventCallback | None = None,
                 opener: Callable[..., ByteStream] = open_stream,
                 read_timeout_s: float = 0.02,
                 thread_setup: Callable[[], object] | None = None) -> None:
        self._clock = clock
        self._on_result = on_result
        self._on_event = on_event
        self._thread_setup = thread_setup
        self._last_state = LinkState.INACTIVE
        self._watchdog_stop = threading.Event()
        self._watchdog_thread: threading.Thread | None = None
        self.watchdog_errors = 0  #: exceptions raised in a watchdog tick (a bug; reported)
        self.link = SerialLink(port, clock=clock, on_line=self._handle_line,
                               on_connected=self._handle_connected, on_lost=self._handle_lost,
                               on_error=self._handle_error, baudrate=baudrate,
                               read_timeout_s=read_timeout_s, reconnect=reconnect,
                               opener=opener, thread_setup=thread_setup)
        self.bridge = GripperBridge(params, writer=self.link.write)

    @property
    def port(self) -> str:
        """Port path or URL."""
        return self.link.url

    def configure(self) -> None:
        """Open the port and write the safe voltage.

        Raises:
            LinkError: The port cannot be opened (message names it).
        """
        self.link.open()

    def activate(self, t: float) -> None:
        """Arm and start the reader thread (the 500 Hz loop).

        Raises:
            LinkError: `configure` never succeeded.
        """
        self.bridge.activate(t)
        try:
            self.link.start()
        except LinkError:
            self.bridge.deactivate(t)
            raise

    def watchdog(self, t: float) -> WatchdogResult:
        """Supervise the link at time ``t`` [s]; reconnects on a fault."""
        result = self.bridge.check_watchdog(t)
        if result.state != self._last_state and result.state in (LinkState.STALE,
                                                                 LinkState.FAULT):
            self._emit(t, 'stale' if result.state == LinkState.STALE else 'fault',
                       f'{self.port}: {result.reason}')
        self._last_state = result.state
        if result.reconnect:
            self.link.request_reconnect(result.reason)
        return result

    def start_watchdog(self, period_s: float, on_tick: WatchdogCallback | None = None) -> None:
        """Call `watchdog` every ``period_s`` [s] on a thread of its own until deactivation.

        The period is waited on the monotonic clock; each check uses ``clock()`` (the node
        clock), like a steady-clock timer would. ``on_tick(t, result)`` runs after each check
        on that thread (publish a degraded status there; must not block).
        """
        if self._watchdog_thread is not None and self._watchdog_thread.is_alive():
            return
        self._watchdog_stop.clear()
        self._watchdog_thread = threading.Thread(
            target=self._watchdog_loop, args=(period_s, on_tick),
            name=f'link-watchdog {self.port}', daemon=True)
        self._watchdog_thread.start()

    def stop_watchdog(self, timeout_s: float = 1.0) -> None:
        """Stop the watchdog thread (idempotent)."""
        self._watchdog_stop.set()
        thread = self._watchdog_thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout_s)
        self._watchdog_thread = None

    def deactivate(self, t: float) -> bool:
        """Write the safe voltage, then stop the reader and watchdog; True if written."""
        written = self.bridge.deactivate(t)
        self.link.stop()
        self.stop_watchdog()
        return written

    def cleanup(self, t: float) -> None:
        """Safe voltage (if still possible), stop and close the port."""
        self.bridge.deactivate(t)
        self.stop_watchdog()
        self.link.close()

    def shutdown(self, t: float) -> None:
        """Same as `cleanup`; safe to call more than once."""
        self.cleanup(t)

    def stats(self) -> LinkStats:
        """Link counters."""
        return self.link.stats()

    # ------------------------------------------------------------------ callbacks
    def _watchdog_loop(self, period_s: float, on_tick: WatchdogCallback | None) -> None:
        if self._thread_setup is not None:
            try:
                self._thread_setup()
            except Exception as exc:  # noqa: BLE001 - tuning is optional
                self._emit(self._clock(), 'error', f'{self.port}: watchdog thread setup: {exc}')
        stop = self._watchdog_stop
        while not stop.wait(period_s):
            t = self._clock()
            try:
                result = self.watchdog(t)
                if on_tick is not None:
                    on_tick(t, result)
            except Exception as exc:  # noqa: BLE001 - supervision must keep running
                self.watchdog_errors += 1
                self._emit(t, 'error', f'{self.port}: watchdog tick raised '
                           f'{type(exc).__name__}: {exc}')

    def _emit(self, t: float, kind: str, message: str) -> None:
        if self._on_event is not None:
            self._on_event(t, kind, message)

    def _handle_line(self, line: bytes, overflow: bool, t: float) -> None:
        result = self.bridge.on_line(line, overflow, t)
        if result.event:
            self._emit(t, result.event, f'{self.port}: {result.event.replace("_", " ")}')
        if self._on_result is not None:
            self._on_result(result)

    def _handle_connected(self, t: float, port: str) -> None:
        self.bridge.on_connected(t, port)
        self._emit(t, 'connected', f'{port}: connected')

    def _handle_lost(self, t: float, reason: str) -> None:
        self.bridge.on_link_lost(t, reason)
        self._emit(t, 'lost', reason)

    def _handle_error(self, t: float, message: str) -> None:
        self._emit(t, 'error', message)
