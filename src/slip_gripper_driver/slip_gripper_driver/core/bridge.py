# SPDX-License-Identifier: Apache-2.0
"""Gripper bridge: telemetry in, voltage out, fail-safe — the driver's host side (ROS-free).

`GripperBridge` is the deterministic heart of the ``gripper_driver`` node, and the simulated
cell (``friction_models.core.sim_cell``) runs the same class on its simulated telemetry. Per
telemetry line (500 Hz, on the serial reader thread) it parses the line, updates the
opening-rate observer, steps homing or the grasp-force controller, and writes exactly one
``T<volts>\\n`` command through an injected writer. Everything else (grasp-force commands, F/T
samples, homing and stop requests, the link watchdog) arrives from other threads and is
serialised by one lock, so a command is never written after a state change that forbids it.
`driver_core.GripperDriverCore` wires a bridge to its serial port.

Fail-safe rules (issue 5 item 2, hardware_protocols §7):

* Hard force ceiling: every command is clipped to ``[−max_open_force, max_command_force]``
  and the voltage limit here, whatever the controller or a publisher asked for (HW-3, HW-5).
* Grasp-force commands that are not finite, not expressible by the actuator
  (``|F| > voltage_limit · newton_per_volt``), with a bad timeout or a stamp from the future
  are rejected and counted, never used. Values within that range but beyond the target limits
  are clipped by the controller (and counted). See `grasp_command`.
* Stale command (its timeout, or ``command.default_timeout`` when it carries none): the
  controller's ``on_command_timeout`` policy. Stale F/T: open loop; F/T fault: target limited
  to ``safe_hold_force`` (see `force_control`).
* Link supervision (`check_watchdog`, called from a timer with the current time) judges the
  **device**, not the host: telemetry counts as missing only while no bytes wait at the port
  (``input_pending``). No telemetry for ``link.stale_after`` → the link is stale: status
  ``link_ok`` false, and by ``link.stale_action`` either nothing is written (``hold_last``,
  default: the firmware keeps the last command, so a telemetry gap does not drop the grasp)
  or the safe voltage once (``safe_voltage``); the driver stays armed and the loop resumes
  with the next line. No telemetry for ``link.fault_after`` → link fault: safe voltage,
  **disarmed**, the caller reconnects. Telemetry that waits
  unprocessed (the host was descheduled, the firmware kept sending) is a host stall: nothing
  is written, the firmware keeps the last command, and the first line processed afterwards
  reports ``'host_stall'`` with how late it was; only a stall longer than
  ``link.host_stall_limit`` writes the safe voltage and disarms. Telemetry the kernel holds
  on its way to the port (the reader waits for the kernel's tty worker thread, starved of
  CPU) is a host stall as well, up to ``link.kernel_hold_limit``. A stall is timed from the
  last check that found the port empty (bytes seen later arrived after it), so a device that
  resumes after a gap is not taken for a host that was stalled through the whole gap. A
  read/write error or a vanished port is reported by the link at once. With a 10 ms timer,
  a silent link is detected within ``stale_after`` + 10 ms = 30 ms.
* Backlog (`on_lines`): lines read together are stamped one firmware period apart (the
  device's own clock: one line per period), update the parser, observer and status, and only
  the newest telemetry line steps the controller and writes: no burst of catch-up commands.
* Resumption: when the loop wrote nothing for ``link.stale_after`` (host stall, telemetry
  gap), the force command moves from the last applied value toward the controller's at most
  ``link.resume_rate`` N/s, with the integral held meanwhile.
* Arming: activation arms. Any link fault, reconnection or firmware restart disarms; while
  disarmed the safe voltage is written on every line and grasp-force commands are ignored
  (counted). Only an explicit `GripperBridge.arm` call re-arms, and arming clears the target
  to 0 N: a command received before or during the fault must never apply force afterwards,
  and a new command alone is not an operator's confirmation that the cell is safe.
* Deactivate/shutdown: the safe voltage is written first, then the driver goes inactive.
* Firmware restart text after telemetry has flowed (``Voltage control``, SimpleFOC init):
  homing invalidated, observer and controller reset, disarmed, counted as a firmware restart,
  also when it arrives on a new connection (the real firmware is silent for ~5.7 s after a
  reset, so the link faults and reconnects first; hardware_protocols §2.3). Restart text
  before the first telemetry line of the process, or repeated before telemetry resumes, is
  the same boot and only counted.
* Every (re)connection first writes a bare newline and the safe voltage in one write, so a
  fragment left in the firmware's buffer cannot merge with a command and the firmware (which
  applies its last value forever) is in a known state. Every command is one write.
* F/T bias (`bias_refusal`): refused while the pads may be loaded — a squeezing target, a
  squeezing command being applied, a finger's biased F/T measuring normal force, or the
  fingers not reopened since they stalled on something while squeezing (or the F/T saw
  contact). A bias taken under load would absorb the load (issue 16).
"""
from __future__ import annotations

import math
import threading
from typing import NamedTuple
from collections.abc import Callable, Sequence

from slip_gripper_driver.core.bridge_params import BridgeParams
from slip_gripper_driver.core.force_control import (BypassReason, ForceLoopInput,
                                                    ForceLoopOutput, GraspForceController)
from slip_gripper_driver.core.grasp_command import GraspCommandGate
from slip_gripper_driver.core.gripper_records import (BridgeDiagnostics, CommandResult,
                                                      GripperStatusSnapshot, LineResult,
                                                      LinkState, MotorCommandRecord,
                                                      WatchdogResult)
from slip_gripper_driver.core.homing import Homing, HomingResult, homing_refusal
from slip_gripper_driver.core.observer import RateObserver
from slip_gripper_driver.core.protocol import (CONNECT_FLUSH, TELEMETRY_PERIOD_S,
                                               CommandError, LineKind, ParsedLine,
                                               TelemetryParser, encode_force_command,
                                               format_voltage_command, voltage_to_force)

_NAN = math.nan

#: The fingers count as released from a contact once they opened this far beyond it [m].
CONTACT_RELEASE_MARGIN_M = 0.002
#: Squeezing with the fingers at rest for this long means they stalled on something [s].
STALL_CONFIRM_S = 0.05

#: Writes one command to the device; returns False when it was not written.
Writer = Callable[[bytes], bool]


class _FtSlot(NamedTuple):
    """Latest F/T sample of one finger, handed over as one immutable object."""

    fz: float  #: bias-removed Fz [N]; NaN if invalid
    stamp: float  #: acquisition stamp [s]; NaN before the first sample
    biased: bool


_NO_FT = _FtSlot(_NAN, _NAN, False)
#: Fingers whose F/T the loop uses, by ``force_control.measurement`` (default: both).
_USED_FINGERS = {'finger_1': (1,), 'finger_2': (2,)}


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
        self._stale_latched = self._stale_safe_written = False
        self._fault_reported = False
        self._stall_fault_reported = False
        self._pending_homing = False
        self._expect_banner = True  # restart text now would be a boot, not a restart
        # host stalls and resumption
        self._lagging = False
        self._pending_stall_s = 0.0
        #: Newest watchdog time [s] at which the port was empty during a telemetry gap (NaN
        #: when none since the last line): bytes seen waiting later arrived after it.
        self._port_empty_t = _NAN
        #: Newest watchdog time [s] at which the kernel held telemetry the device had sent.
        self._kernel_held_t = _NAN
        #: Time of the previous watchdog check, and of the first check after the watchdog
        #: itself was late (the whole driver process did not run) [s].
        self._last_check_t = _NAN
        self._checks_resumed_t = _NAN
        self._ft_backlog_probe: Callable[[int], bool] | None = None
        self._ft_host_lag_steps = 0
        self._last_write_line_t = _NAN
        self._ramp_t = _NAN
        self._ramp_from = 0.0
        # contact seen by F/T or a squeezing stall: motor angle [rad] until the fingers reopen
        self._contact_angle = _NAN
        self._stall_since = _NAN
        # latest values
        self._angle = _NAN
        self._rate = _NAN
        self._voltage_cmd = _NAN
        self._force_cmd = _NAN
        self._last_out: ForceLoopOutput | None = None
        self._gate = GraspCommandGate()
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
        self._host_stalls = 0
        self._last_host_stall_s = 0.0
        self._max_host_stall_s = 0.0
        self._max_watchdog_gap_s = 0.0
        self._catch_up_lines = 0
        self._resume_ramps = 0

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
            self._last_check_t = _NAN  # watchdog gaps count from the first check from now
            self._parser.reset()
            self._observer.reset()
            self._controller.reset()
            self._stale_latched = self._stale_safe_written = False
            self._fault_reported = False
            self._gate.clear(t)
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
            self._gate.clear(t)
            return CommandResult(True, 'armed; target cleared to 0 N')

    def stop(self, t: float) -> bool:
        """Write the safe voltage now and hold it until the next accepted command.

        Returns:
            True when the safe voltage was written.
        """
        with self._lock:
            self._stopped = True
            self._gate.clear(t)
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
            self._last_write_line_t = _NAN
            self._ramp_t = self._stall_since = self._port_empty_t = _NAN
            self._connect_t = self._activate_t = t
            self._gate.rewind(t)
            for i, slot in enumerate(self._ft):
                if math.isfinite(slot.stamp):
                    self._ft[i] = slot._replace(stamp=min(slot.stamp, t))

    # ------------------------------------------------------------------ link events
    def on_connected(self, t: float, port: str = '') -> None:
        """The port was (re)opened at ``t`` [s]: new link session; a newline (ending any
        fragment in the firmware's buffer) and the safe voltage written in one write."""
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
            self._stale_latched = self._stale_safe_written = False
            self._fault_reported = False
            self._new_session('link (re)connected')
            self._voltage_cmd = self._params.actuator.safe_voltage
            self._write(CONNECT_FLUSH + self._safe_command)

    def on_link_lost(self, t: float, reason: str) -> None:
        """The port failed or was dropped at ``t`` [s]: safe state, disarmed, homing void."""
        del t
        with self._lock:
            if self._connected:
                self._link_losses += 1
            self._connected = False
            self._enter_safe(f'link lost: {reason}')
            self._new_session(f'link lost: {reason}')

    def check_watchdog(self, t: float,
                       input_pending: Callable[[], int] | None = None,
                       kernel_holds_input: Callable[[], bool] | None = None
                       ) -> WatchdogResult:
        """Supervise telemetry; call from a timer (≤ 10 ms period) with the current time [s].

        Args:
            t: Current time on the line clock [s].
            input_pending: Bytes received at the port but not yet read by the loop (asked only
                when no line was processed for ``link.stale_after``); None = unknown (0).
            kernel_holds_input: The reader waits for the kernel to hand over bytes the device
                has sent (`SerialLink.kernel_holds_input`; asked like ``input_pending``); then
                the stall is the kernel's, bounded by ``link.kernel_hold_limit``, even with
                bytes at the port; None = never.

        Writes the safe voltage once when no telemetry arrives; disarms and asks for a
        reconnection once when the link faults. Telemetry waiting at the port is a host stall
        (`LinkState.LAGGING`): nothing is written unless the loop stays stuck for
        ``link.host_stall_limit`` while this watchdog keeps checking on time. A pause of the
        whole process (this check itself came more than ``link.stale_after`` after the
        previous one) is not held against the loop: nothing could be written meanwhile, the
        firmware kept the last command, and the loop resumes with the lines waiting. Telemetry
        the kernel has received but not handed to the port yet (its tty worker thread waits
        for a CPU) is a host stall in the same way, up to ``link.kernel_hold_limit``: seen at
        this check or at one within ``link.stale_after`` before it.
        """
        gap = t - self._last_check_t
        if not gap <= self._params.link.stale_after:  # NaN: the first check
            self._checks_resumed_t = t  # this check is late: the process did not run either
            if gap > self._max_watchdog_gap_s:  # (NaN compares False)
                self._max_watchdog_gap_s = gap
        self._last_check_t = t
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
            if age <= p.stale_after:
                return WatchdogResult(LinkState.OK, age, False, 'ok')
            pending = input_pending() if input_pending is not None else 0
            in_kernel = False
            if kernel_holds_input is not None and self._session_lines > 0:
                if kernel_holds_input():
                    self._kernel_held_t = t
                in_kernel = t - self._kernel_held_t <= p.stale_after  # NaN: never seen
            if (pending > 0 or in_kernel) and self._session_lines > 0:
                # Waiting since the port was last seen empty, at most since the last line: a
                # device that resumes after a gap is not a host that stalled all along.
                empty = self._port_empty_t
                waited = age if empty != empty else max(0.0, min(age, t - empty))
                stuck = min(waited, max(0.0, t - self._checks_resumed_t))
                return self._host_lagging(waited, stuck, pending, in_kernel)
            self._port_empty_t = t
            self._lagging = False
            if age > p.fault_after:
                reason = f'no telemetry for {age:.3f} s (fault after {p.fault_after:.3f} s)'
                reconnect = not self._fault_reported
                if reconnect:
                    self._fault_reported = True
                    self._link_faults += 1
                    self._go_stale(reason, disarm=True)
                return WatchdogResult(LinkState.FAULT, age, reconnect, reason, reconnect)
            reason = f'no telemetry for {age:.3f} s (stale after {p.stale_after:.3f} s)'
            self._go_stale(reason, disarm=False)
            return WatchdogResult(LinkState.STALE, age, False, reason,
                                  held=not self._safe())

    def _host_lagging(self, age: float, stuck: float, pending: int,
                      in_kernel: bool = False) -> WatchdogResult:
        """Telemetry waits at the port (or, ``in_kernel``, in the kernel on its way there):
        the host is behind, not the device (lock held).

        ``age``: how long it waited [s]; ``stuck``: the part of it during which this
        watchdog ran on time while the loop did not [s]."""
        self._lagging = True
        link = self._params.link
        if age > link.stale_after:
            self._pending_stall_s = max(self._pending_stall_s, age)
        limit = link.kernel_hold_limit if in_kernel else link.host_stall_limit
        where = ('telemetry the device sent waits in the kernel (its tty worker thread has not '
                 'run: the host is overloaded)' if in_kernel else
                 f'{pending} bytes of telemetry wait unprocessed')
        if stuck <= limit:
            paused = '' if stuck >= age else \
                f'; the driver process did not run for {age - stuck:.3f} s of it'
            return WatchdogResult(LinkState.LAGGING, age, False,
                                  f'{where} for {age:.3f} s (host busy{paused}; the last '
                                  'command stays applied)')
        if in_kernel:
            reason = (f'telemetry the device sent waited in the kernel for {age:.3f} s (its tty '
                      f'worker thread did not run; kernel_hold_limit {limit:.3f} s): the host '
                      'is overloaded')
        else:
            reason = (f'telemetry waited unprocessed for {age:.3f} s, {stuck:.3f} s of it '
                      f'while the rest of the driver ran (host_stall_limit {limit:.3f} s): the '
                      'loop is stuck')
        disarmed = not self._stall_fault_reported
        if disarmed:
            self._stall_fault_reported = True
            self._go_stale(reason, disarm=True)
        return WatchdogResult(LinkState.LAGGING, age, False, reason, disarmed)

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
            result = self._gate.submit(force, t, stamp=stamp, timeout=timeout, source=source,
                                       armed=self._active and self._armed, params=self._params)
            if result.accepted:
                self._stopped = False
            return result

    def set_ft_backlog_probe(self, probe: Callable[[int], bool] | None) -> None:
        """``probe(finger)``: records of that finger's box wait unread at the host (its reader
        is behind). Asked only while a used F/T sample is older than ``ft_fault_after``: with
        records waiting, the old sample is the host's delay, not a silent box, so the loop
        treats it as stale (open loop) rather than as an F/T fault (``safe_hold_force``), up
        to ``link.host_stall_limit``. None (the default, and topic mode): never asked."""
        self._ft_backlog_probe = probe

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

    def on_ft_wrench(self, finger: int, t: float, wrench: Sequence[float] | None) -> None:
        """Store the latest wrench of one finger as the host's F/T path delivers it.

        Args:
            finger: 1 or 2.
            t: Acquisition stamp [s].
            wrench: Bias-removed ``(Fx, Fy, Fz, Tx, Ty, Tz)`` [N, N·m] in the sensor frame,
                or None while that sensor has no bias (the loop then runs open).
        """
        if wrench is None:
            self.on_ft_sample(finger, t, _NAN, False)
        else:
            self.on_ft_sample(finger, t, float(wrench[2]), True)

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

    def adopt_homing(self, t: float, result: HomingResult) -> CommandResult:
        """Take known limits at ``t`` [s] instead of driving against the stops.

        Refused for the same reasons as `start_homing`; the motor is not moved. A simulator
        that knows its limits homes this way.
        """
        with self._lock:
            refusal = self._homing_refusal(t)
            if refusal is not None:
                return CommandResult(False, refusal)
            self._controller.reset()
            self._homing.adopt(result)
            return CommandResult(True, self._homing.message)

    # ------------------------------------------------------------------ the 500 Hz path
    def on_line(self, line: bytes, overflow: bool, t: float) -> LineResult:
        """Process one device line stamped at acquisition time ``t`` [s] and write a command.

        Signature matches `transport.SerialLink`'s ``on_line`` callback.
        """
        with self._lock:
            return self._handle(self._parser.parse(line, overflow), t, True)

    def on_lines(self, lines: Sequence[tuple[bytes, bool]], t: float,
                 period: float = TELEMETRY_PERIOD_S) -> list[LineResult]:
        """Process the lines of one read (``(line, overflow)`` pairs, oldest first).

        The newest line is stamped ``t`` [s] and each earlier one ``period`` [s] before the
        next (the firmware prints one line per period; never before the previous line's
        stamp). Every line updates the parser, observer and status; only the newest telemetry
        line steps the controller (or homing) and writes a command, so a backlog left by a
        host stall produces no burst of commands. A backlog longer than ``link.stale_after``
        is reported as a host stall on that line, unless the watchdog had found the port
        empty meanwhile (then the device was late and the link went stale).
        """
        n = len(lines)
        if n == 1:
            return [self.on_line(lines[0][0], lines[0][1], t)]
        with self._lock:
            parsed = [self._parser.parse(line, overflow) for line, overflow in lines]
            newest = -1
            for i, item in enumerate(parsed):
                if item.kind == LineKind.TELEMETRY:
                    newest = i
            backlog = (n - 1) * period
            # A backlog after the watchdog found the port empty (stale) is a burst from a
            # device that was late, not a host stall: the stale event told that story.
            if backlog > self._params.link.stale_after and self._session_lines > 0 and \
                    not self._stale_latched:
                self._pending_stall_s = max(self._pending_stall_s, backlog)
            floor = self._last_line_t if math.isfinite(self._last_line_t) else -math.inf
            out = []
            for i, item in enumerate(parsed):
                stamp = max(t - (n - 1 - i) * period, floor)
                out.append(self._handle(item, stamp, i == newest))
            return out

    def _handle(self, parsed: ParsedLine, t: float, step: bool) -> LineResult:
        """One parsed line (lock held); ``step``: a telemetry line may step and write."""
        if parsed.kind == LineKind.TELEMETRY:
            return self._on_telemetry(parsed.angle_rad, t, step)
        if parsed.restart and not self._expect_banner:
            # Restart text after telemetry (on this connection or an earlier one): the
            # firmware was reset. Text that follows before telemetry is the same boot.
            self._expect_banner = True
            self._firmware_restarts += 1
            self._session_lines = 0
            self._enter_safe('firmware restart detected')
            self._new_session('firmware restart detected')
            self._voltage_cmd = self._params.actuator.safe_voltage
            written = self._write(self._safe_command)
            return LineResult(t, parsed.kind, self._safe_command, written, None, None,
                              'firmware_restart')
        return LineResult(t, parsed.kind, None, False, None, None, '')

    def _on_telemetry(self, angle: float, t: float, step: bool = True) -> LineResult:
        params = self._params
        a = params.actuator
        self._session_lines += 1
        self._last_line_t = t
        self._port_empty_t = _NAN
        self._stale_latched = self._stale_safe_written = False
        self._fault_reported = False
        self._stall_fault_reported = False
        self._expect_banner = False
        self._angle = angle
        self._rate = self._observer.update(t, angle * a.opening_per_rad).rate
        if not self._active:
            return LineResult(t, LineKind.TELEMETRY, None, False, self._snapshot(t), None, '')
        ft = self._ft_pair()  # one consistent pair for this step
        homing = self._homing
        homing_active = homing.active
        if not homing_active:
            self._track_contact(angle, t, ft)
        if not step:
            self._catch_up_lines += 1
            return LineResult(t, LineKind.TELEMETRY, None, False, self._snapshot(t, ft), None,
                              '')
        event = ''
        if self._pending_stall_s > 0.0:
            stall = self._pending_stall_s
            self._pending_stall_s = 0.0
            self._host_stalls += 1
            self._last_host_stall_s = stall
            self._max_host_stall_s = max(self._max_host_stall_s, stall)
            event = 'host_stall'
        self._lagging = False

        if self._pending_homing:
            self._pending_homing = False
            refusal = self._homing_refusal(t)
            if refusal is None:
                self._controller.reset()
                homing.start(t)
            else:
                homing.message = f'automatic homing refused: {refusal}'
            homing_active = homing.active

        out: ForceLoopOutput | None = None
        force_cmd = _NAN
        if homing_active:
            step_h = homing.step(t, angle)
            if step_h.voltage_v is not None and self._armed:
                command = format_voltage_command(step_h.voltage_v, a.voltage_limit)
                voltage = float(command[1:-1])
            else:
                command, voltage = self._safe_command, a.safe_voltage
            if step_h.finished:
                event = 'homing_done' if homing.homed else 'homing_failed'
            self._force_cmd = voltage_to_force(voltage, a.newton_per_volt)
            self._ramp_t = _NAN
        else:
            safe = self._safe()
            ramping = self._resume_ramp(t, safe)
            out = self._controller.step(self._loop_input(t, ft, ramping))
            self._last_out = out
            command, voltage = self._safe_command, a.safe_voltage
            force_cmd = out.force_cmd
            if not safe:
                if ramping:
                    force_cmd = self._ramped(force_cmd, t)
                fc = params.force_control
                try:
                    command, voltage = encode_force_command(
                        force_cmd, newton_per_volt=a.newton_per_volt,
                        max_close_force_n=fc.max_command_force,
                        max_open_force_n=fc.max_open_force, voltage_limit_v=a.voltage_limit)
                except CommandError as exc:  # cannot happen with finite inputs; stay safe
                    self._enter_safe(f'command encoding failed: {exc}')
            self._force_cmd = force_cmd
        self._voltage_cmd = voltage
        written = self._write(command)
        self._last_write_line_t = t
        # Everything below only reports: it runs after the command left.
        motor = None if out is None else MotorCommandRecord(
            t, out.force_target, force_cmd, voltage, out.measured_force, out.error,
            out.integral, out.gain_scale, out.closed_loop, int(out.bypass_reason))
        return LineResult(t, LineKind.TELEMETRY, command, written, self._snapshot(t, ft), motor,
                          event)

    def _resume_ramp(self, t: float, safe: bool) -> bool:
        """True while the command resumes from the last applied value (lock held).

        Starts when the loop wrote nothing for ``link.stale_after`` (a host stall or a
        telemetry gap; the watchdog may have written the safe voltage meanwhile).
        """
        if safe:
            self._ramp_t = _NAN
            return False
        if t - self._last_write_line_t > self._params.link.stale_after:
            self._ramp_t = t
            self._ramp_from = voltage_to_force(self._voltage_cmd,
                                               self._params.actuator.newton_per_volt)
            self._resume_ramps += 1
        return self._ramp_t == self._ramp_t  # not NaN

    def _ramped(self, force_cmd: float, t: float) -> float:
        """``force_cmd`` [N] limited to ``resume_rate`` from the value applied at the
        resumption; the ramp ends once the controller's command is within reach."""
        reach = self._params.link.resume_rate * (t - self._ramp_t)
        low, high = self._ramp_from - reach, self._ramp_from + reach
        if force_cmd < low:
            return low
        if force_cmd > high:
            return high
        self._ramp_t = _NAN
        return force_cmd

    def _track_contact(self, angle: float, t: float, ft: tuple[_FtSlot, _FtSlot]) -> None:
        """Remember where the pads last touched something (lock held; see `bias_refusal`).

        Contact: a finger's biased, fresh F/T measures at least ``contact_threshold`` of
        normal force, or the fingers rest (``|opening rate| < end_stop_speed``) for
        `STALL_CONFIRM_S` while the command squeezes with at least ``contact_threshold``.
        Released once the motor angle is `CONTACT_RELEASE_MARGIN_M` of opening beyond it.
        """
        p = self._params
        fc = p.force_control
        threshold = fc.contact_threshold
        loaded = False
        for slot in ft:
            if slot.biased and t - slot.stamp <= fc.ft_stale_after and -slot.fz >= threshold:
                loaded = True
        squeezing = -p.actuator.newton_per_volt * self._voltage_cmd >= threshold
        if squeezing and abs(self._rate) < fc.end_stop_speed:
            if self._stall_since != self._stall_since:  # NaN: not resting yet
                self._stall_since = t
            elif t - self._stall_since >= STALL_CONFIRM_S:
                loaded = True
        else:
            self._stall_since = _NAN
        if loaded:
            self._contact_angle = angle
        elif angle > self._contact_angle + CONTACT_RELEASE_MARGIN_M / p.actuator.opening_per_rad:
            self._contact_angle = _NAN

    def bias_refusal(self, t: float) -> str | None:
        """Why an F/T bias must not be taken now at ``t`` [s], or None when the pads are free.

        A bias taken while the pads are loaded absorbs the load: every later force reads low
        by that much and the loop squeezes harder (issue 16: 10 N commanded gave 18.1 N). The
        pads may be loaded while homing runs, while a squeezing target (> 0 N) is active,
        while the applied command squeezes with at least ``contact_threshold``, while a
        finger's biased F/T (no older than ``ft_fault_after``) measures that much normal
        force, or until the fingers reopened by `CONTACT_RELEASE_MARGIN_M` after they last
        touched something (F/T contact or a squeezing stall).
        """
        with self._lock:
            fc = self._params.force_control
            threshold = fc.contact_threshold
            reasons = []
            if self._homing.active:
                reasons.append('homing is running')
            target = self._gate.target.force
            if self._active and self._armed and not self._stopped and target > 0.0:
                reasons.append(f'a squeezing grasp-force target of {target:.1f} N is active')
            applied = voltage_to_force(self._voltage_cmd, self._params.actuator.newton_per_volt)
            if applied >= threshold:
                reasons.append(f'the motor is commanded to squeeze with {applied:.1f} N')
            for finger, slot in enumerate(self._ft_pair(), start=1):
                if slot.biased and t - slot.stamp <= fc.ft_fault_after and -slot.fz >= threshold:
                    reasons.append(f'finger {finger} F/T measures {-slot.fz:.1f} N of normal '
                                   'force')
            if self._contact_angle == self._contact_angle:  # not NaN
                reasons.append(f'the fingers touched something (at motor angle '
                               f'{self._contact_angle:.4f} rad) and have not opened '
                               f'{CONTACT_RELEASE_MARGIN_M * 1e3:.0f} mm since')
            if not reasons:
                return None
            return ('the pads may be loaded: ' + '; '.join(reasons)
                    + ' (open the gripper with a negative grasp force, then bias)')

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
            gate = self._gate
            if not self._connected:
                state = LinkState.DOWN
            elif not self._active:
                state = LinkState.INACTIVE
            elif self._lagging:
                state = LinkState.LAGGING
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
                write_failures=self._write_failures, commands_accepted=gate.accepted,
                commands_rejected=gate.rejected, rejected_by_reason=gate.rejected_by_reason(),
                commands_ignored=gate.ignored, targets_clipped=gate.clipped,
                command_age_s=t - gate.target.stamp, command_source=gate.target.source,
                homed=self._homing.homed, homing_active=self._homing.active,
                homing_message=self._homing.message,
                bypass_reason=out.bypass_reason if out else BypassReason.SAFE_STATE,
                closed_loop=out.closed_loop if out else False,
                saturations=self._controller.saturations,
                skipped_integrations=self._controller.skipped_integrations,
                ft_samples=(self._ft_samples[0], self._ft_samples[1]),
                ft_age_s=(t - ft[0].stamp, t - ft[1].stamp),
                ft_biased=(ft[0].biased, ft[1].biased), host_stalls=self._host_stalls,
                last_host_stall_s=self._last_host_stall_s,
                max_host_stall_s=self._max_host_stall_s,
                max_watchdog_gap_s=self._max_watchdog_gap_s, catch_up_lines=self._catch_up_lines,
                ft_host_lag_steps=self._ft_host_lag_steps,
                resume_ramps=self._resume_ramps, contact_angle=self._contact_angle)

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

    def _enter_safe(self, reason: str) -> None:
        self._armed = False
        self._safe_reason = reason
        self._homing.abort(reason)

    def _new_session(self, reason: str) -> None:
        self._homing.invalidate(reason)
        self._observer.reset()
        self._controller.reset()
        self._rate = _NAN
        # Angles of a new session may count from a new zero (firmware restart).
        self._contact_angle = self._stall_since = self._ramp_t = _NAN
        self._last_write_line_t = _NAN
        self._lagging = False
        self._pending_stall_s = 0.0

    def _go_stale(self, reason: str, disarm: bool) -> None:
        """React once when telemetry stops (lock held).

        A stale link (no line for ``link.stale_after``) is counted once per gap; with
        ``link.stale_action`` ``hold_last`` nothing is written (the firmware keeps the last
        command, as through a host stall), with ``safe_voltage`` the safe voltage is written.
        Homing, which moves open loop, always gets the safe voltage. The loop is clocked by
        telemetry, so it resumes with the next line, rate-limited from the applied value. A
        fault (``link.fault_after``, reconnection follows) writes the safe voltage and disarms:
        after a reconnect nothing is applied until ``arm()``.
        """
        homing = self._homing.active
        if disarm and (self._armed or homing):
            self._enter_safe(reason)
        elif homing:
            self._homing.abort(reason)
        if not self._stale_latched:
            self._stale_latched = True
            self._stale_events += 1
        hold = not disarm and not homing and \
            self._params.link.stale_action == 'hold_last'
        if hold or self._stale_safe_written:
            return
        self._stale_safe_written = True
        self._voltage_cmd = self._params.actuator.safe_voltage
        self._write(self._safe_command)

    def _safe(self) -> bool:
        return not (self._active and self._armed) or self._stopped or self._stale_safe_written

    def _line_age(self, t: float) -> float:
        ref = self._last_line_t
        if not math.isfinite(ref):
            ref = max(self._connect_t, self._activate_t)
        return t - ref if math.isfinite(ref) else math.inf

    def _link_ok(self, t: float) -> bool:
        """Telemetry arrives: recent lines, or lines waiting at the port (host stall)."""
        return self._connected and self._session_lines > 0 and \
            (self._lagging or self._line_age(t) <= self._params.link.stale_after)

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
            target_force=0.0 if self._stopped else self._gate.target.force)

    def _loop_input(self, t: float, ft: tuple[_FtSlot, _FtSlot],
                    hold_integral: bool = False) -> ForceLoopInput:
        result = self._homing.result
        k = self._params.actuator.opening_per_rad
        measurement = self._params.force_control.measurement
        target = self._gate.target
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
            t=t, target=target.force, target_stamp=target.stamp,
            target_timeout=target.timeout, fz_1=ft1.fz, fz_2=ft2.fz,
            ft_stamp_1=ft1.stamp, ft_stamp_2=ft2.stamp, ft_biased=biased,
            homed=result is not None, opening=opening,
            opening_rate=self._rate if result is not None else _NAN, stroke=stroke,
            safe_state=self._safe(), hold_integral=hold_integral,
            ft_host_lag=self._ft_host_lag(t, ft, measurement))

    def _ft_host_lag(self, t: float, ft: tuple[_FtSlot, _FtSlot], measurement: str) -> bool:
        """Every used F/T sample past ``ft_fault_after`` has newer records waiting unread at
        the host, for no longer than ``link.host_stall_limit`` (lock held)."""
        probe = self._ft_backlog_probe
        if probe is None:
            return False
        fault_after = self._params.force_control.ft_fault_after
        limit = self._params.link.host_stall_limit
        lagging = False
        for k in _USED_FINGERS.get(measurement, (1, 2)):
            age = t - ft[k - 1].stamp
            if age <= fault_after:
                continue  # fresh enough: no fault from this finger
            if not age <= limit or not probe(k):  # NaN age: no sample at all
                return False
            lagging = True
        if lagging:
            self._ft_host_lag_steps += 1
        return lagging

    def _snapshot(self, t: float, ft: tuple[_FtSlot, _FtSlot] | None = None
                  ) -> GripperStatusSnapshot:
        parser = self._parser
        result = self._homing.result
        k = self._params.actuator.opening_per_rad
        force, biased, fresh = self._ft_state(t, ft)
        out = self._last_out
        homed = result is not None
        return GripperStatusSnapshot(
            stamp=t, line_count=parser.good, bad_line_count=parser.not_telemetry,
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
