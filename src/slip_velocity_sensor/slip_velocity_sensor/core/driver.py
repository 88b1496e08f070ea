# SPDX-License-Identifier: Apache-2.0
"""One velocity sensor on one port: open, identify, upload, stream, reconnect (ROS-free).

`SensorDriver` is everything the ``velocity_sensor`` node does apart from ROS: it owns the
`SerialLink` (reader thread, acquisition stamps, reopen with back-off), runs the identify
`Handshake` with the calibration upload, claims the sensor name host-wide (`NameClaim`), feeds
every line to the `SensorSession` and hands each sample to a callback **on the reader thread**,
so line arrival to publication never waits for an executor.

Lifecycle::

    driver = SensorDriver(params, calibration, clock=node_clock_s, on_sample=publish)
    driver.connect()   # configure: open, handshake + upload, claim; DriverError names the port
    driver.set_chip_mode(2); driver.reset_pose()   # services
    driver.close()     # cleanup / shutdown: stop threads, close the port, release the name

After `connect` the reader keeps running until `close` (the node gates publication on its
lifecycle state), so a board restart, an unplugged adapter or a foreign name on the port are
handled in every configured state. A **supervisor thread** re-initialises the device whenever
the session needs it (after the link reopened, after a boot banner, after another name
appeared): handshake, calibration upload and the requested chip mode again, retried with
exponential back-off (``reconnect.*``) while diagnostics report ERROR.

Times: ``clock`` (the node clock, seconds) stamps lines and drives the session; ``wait_clock``
(monotonic) only bounds the handshake and back-off waits.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Callable

from slip_cell_common.core.monitors import Level, Report
from slip_cell_common.core.param_schema import flatten
from slip_cell_common.core.serial_transport import (ByteStream, LinkError, ReconnectPolicy,
                                                SerialLink, open_stream)
from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.calibration import SensorCalibration, upload_commands
from slip_velocity_sensor.core.handshake import (Handshake, HandshakeError, HandshakeFailure,
                                                 HandshakeResult, HandshakeRunner)
from slip_velocity_sensor.core.identity import (DuplicateSensorNameError, NameClaim,
                                                default_lock_dir)
from slip_velocity_sensor.core.params import VelocitySensorParams
from slip_velocity_sensor.core.session import Sample, SensorSession

Clock = Callable[[], float]
#: ``(level, message)`` for the node's logger; level is ``'info'``, ``'warn'`` or ``'error'``.
EventCallback = Callable[[str, str], None]

#: Parameter groups used only when the port is opened and the calibration uploaded.
_BOUND_AT_CONFIGURE = ('calibration.', 'reconnect.')


class DriverError(RuntimeError):
    """Configure-time or command failure; the message names the port.

    Attributes:
        retryable: The same attempt may succeed later (port missing or busy, device silent,
            no name reply, re-sync loop, link failure); False for a wrong name, a name claimed
            by another port, or a driver closed while connecting.
    """

    def __init__(self, message: str, *, retryable: bool = False) -> None:
        super().__init__(message)
        self.retryable = retryable


@dataclass(frozen=True)
class DriverStatus:
    """Snapshot of the link and (re)initialisation counters.

    Attributes:
        port: Port path or URL.
        connected: The port is open.
        initialised: Handshake and upload done since the last (re)connection.
        reconnects: Successful reopenings of the port.
        losses: Link losses (read/write errors, unplugged).
        connect_failures: Failed reopen attempts.
        reinit_attempts: Handshakes run by the supervisor (after reconnects or restarts).
        reinit_failures: Those that failed.
        retry_in_s: Seconds until the next reopen or re-initialisation attempt (0 when none).
        last_error: Most recent link or handshake error (names the port), '' when none.
        handshake: Result of the most recent successful handshake.
    """

    port: str
    connected: bool
    initialised: bool
    reconnects: int
    losses: int
    connect_failures: int
    reinit_attempts: int
    reinit_failures: int
    retry_in_s: float
    last_error: str
    handshake: HandshakeResult | None


class SensorDriver:
    """Owns one velocity sensor; see the module docstring.

    Args:
        params: Validated node parameters.
        calibration: Calibration to upload (SI), from `calibration.resolve_calibration`.
        clock: Node clock [s]: line stamps and session time.
        on_sample: Called on the reader thread with every sample (keep it short).
        on_event: Log sink for state changes (reader or supervisor thread).
        opener: `open_stream`-compatible port factory (tests pass in-process streams).
        wait_clock: Monotonic clock for handshake timeouts and back-off.
        read_timeout_s: Serial read timeout [s]; bounds how long stopping the reader takes.
        write_timeout_s: Serial write timeout [s]. Commands are rare and small, so it is
            generous: pyserial reports a timeout when the write call itself was delayed (a
            loaded host), although the bytes went out.
        supervise_period_s: How often the supervisor checks whether to re-initialise [s].
    """

    def __init__(self, params: VelocitySensorParams, calibration: SensorCalibration, *,
                 clock: Clock, on_sample: Callable[[Sample], None] | None = None,
                 on_event: EventCallback | None = None,
                 opener: Callable[..., ByteStream] = open_stream,
                 wait_clock: Clock = time.monotonic, read_timeout_s: float = 0.02,
                 write_timeout_s: float = 0.5, supervise_period_s: float = 0.05) -> None:
        self.params = params
        self.calibration = calibration
        self.port = params.port
        self.session = SensorSession(params.session, port=params.port,
                                     expected_name=params.expected_name)
        self._clock = clock
        self._wait_clock = wait_clock
        self._on_sample = on_sample
        self._on_event = on_event
        self._init_commands = upload_commands(calibration, params.calibration.speed_term)
        self._link = SerialLink(
            params.port, clock=clock, on_line=self._on_line, on_connected=self._on_connected,
            on_lost=self._on_lost, on_error=self._on_link_error, baudrate=params.baudrate,
            read_timeout_s=read_timeout_s, write_timeout_s=write_timeout_s,
            max_line_length=self.session.parser.limits.max_line_bytes,
            reconnect=params.reconnect, opener=opener, wait_clock=wait_clock)
        self._policy = ReconnectPolicy(params.reconnect.initial_delay,
                                       params.reconnect.max_delay, clock=wait_clock)
        self._runner: HandshakeRunner | None = None
        self._claim: NameClaim | None = None
        self._device_lock = threading.Lock()
        self._requested_mode = 0
        self._last_command_t = -float('inf')
        self._handshake: HandshakeResult | None = None
        self._reinit_attempts = 0
        self._reinit_failures = 0
        self._last_error = ''
        self._stop = threading.Event()
        self._closed = False
        self._thread_lock = threading.Lock()  # starting vs joining the reader and supervisor
        self._wake = threading.Event()
        self._supervisor: threading.Thread | None = None
        self._supervise_period_s = supervise_period_s

    # ---------------------------------------------------------------- lifecycle

    def connect(self) -> HandshakeResult:
        """Open the port, identify, upload the calibration, claim the name, start streaming.

        Blocks for at most ``handshake.retries × handshake.timeout`` plus the upload.

        Raises:
            DriverError: Port missing or busy, no or wrong answer, re-sync loop, name already
                claimed by another port, `close` called meanwhile; the message names the port
                and ``retryable`` says whether trying again later makes sense. Nothing stays
                open. A closed driver cannot connect again: make a new one.
        """
        try:
            self._link.open()
            result = self._run_handshake(start_reader=True)
            self._claim_name()
            if self._closed:
                raise LinkError(f'{self.port}: driver closed while connecting')
        except (LinkError, HandshakeError, DuplicateSensorNameError) as exc:
            closed = self._closed
            self.close()
            wrong_name = (isinstance(exc, HandshakeError)
                          and exc.reason is HandshakeFailure.WRONG_NAME)
            retryable = not (closed or wrong_name or isinstance(exc, DuplicateSensorNameError))
            raise DriverError(str(exc), retryable=retryable) from exc
        with self._thread_lock:  # no thread is started after (or joined during) close
            if not self._closed:
                self._initialised(result)
                self._stop.clear()
                self._supervisor = threading.Thread(
                    target=self._supervise, name=f'velocity-sensor supervisor {self.port}',
                    daemon=True)
                self._supervisor.start()
        if self._closed:
            self.close()
            raise DriverError(f'{self.port}: driver closed while connecting')
        return result

    def close(self) -> None:
        """Stop the supervisor and the reader, close the port, release the name (idempotent).

        Safe from another thread while `connect` runs: the handshake fails at once.
        """
        self._closed = True
        self._stop.set()
        self._wake.set()
        runner = self._runner
        if runner is not None:
            runner.on_lost(self._clock(), f'{self.port}: driver closing')
        with self._thread_lock:
            supervisor, self._supervisor = self._supervisor, None
        if supervisor is not None and supervisor is not threading.current_thread():
            supervisor.join(self.params.handshake.timeout + 1.0)
        with self._thread_lock:
            self._link.close()
        if self._claim is not None:
            self._claim.release()
            self._claim = None

    def update_params(self, params: VelocitySensorParams) -> tuple[str, ...]:
        """Apply run-time parameter changes; returns the changed names that need a reconfigure.

        Host processing (``stale_after``, rates, integration, settle and re-sync times),
        ``handshake.*`` and ``command_spacing`` apply at once (the handshake values from the
        next re-initialisation). The calibration values, ``radius`` and ``reconnect.*`` are
        bound to the upload and the link made at configure.
        """
        old = flatten(self.params)
        changed = [name for name, value in flatten(params).items() if old.get(name) != value]
        self.params = params
        self.session.update_params(params.session)
        return tuple(n for n in changed if n == 'radius' or n.startswith(_BOUND_AT_CONFIGURE))

    # ---------------------------------------------------------------- commands

    def set_chip_mode(self, mode: int) -> None:
        """Send ``c<mode>`` (0 fused, 1..3 single chip), spaced from the previous command.

        The mode is also re-applied after every re-initialisation.

        Raises:
            ValueError: ``mode`` not in 0..3.
            DriverError: Link down or re-initialising (try again), or the write failed.
        """
        command = protocol.chip_mode_command(mode)
        if not self._device_lock.acquire(blocking=False):
            raise DriverError(f'{self.port}: the sensor is being re-initialised; try again')
        try:
            if not self._link.connected or self.session.needs_reinitialisation:
                raise DriverError(f'{self.port}: link down or sensor not initialised '
                                  f'({self._last_error or "reconnecting"})')
            self._space_command()
            try:
                self._write(command)
            except OSError as exc:
                raise DriverError(f'write of {command!r} failed: {exc}') from exc
            self._last_command_t = self._wait_clock()
            self._requested_mode = mode
            self.session.chip_mode_sent(mode, self._clock())
        finally:
            self._device_lock.release()

    def reset_pose(self) -> None:
        """Zero the integrated x, y, θ."""
        self.session.reset_pose()

    @property
    def requested_chip_mode(self) -> int:
        """The chip mode last asked for (re-applied after reconnects)."""
        return self._requested_mode

    def stale_marker(self, t: float) -> Sample | None:
        """See `SensorSession.stale_marker` (``t`` on the node clock [s])."""
        return self.session.stale_marker(t)

    # ---------------------------------------------------------------- status

    def status(self) -> DriverStatus:
        """Counter snapshot."""
        link = self._link.stats()
        retry = link.retry_in_s if not link.connected else (
            self._policy.time_until_next() if self.session.needs_reinitialisation else 0.0)
        return DriverStatus(
            port=self.port, connected=link.connected,
            initialised=not self.session.needs_reinitialisation, reconnects=link.reconnects,
            losses=link.losses, connect_failures=link.connect_failures,
            reinit_attempts=self._reinit_attempts, reinit_failures=self._reinit_failures,
            retry_in_s=retry, last_error=self._last_error, handshake=self._handshake)

    def reports(self, t: float) -> dict[str, Report]:
        """Diagnostic tasks ``link``, ``rate``, ``chips``, ``calibration`` at ``t`` [s]."""
        reports = self.session.reports(t)
        st = self.status()
        link = reports['link']
        values = link.values + (
            ('connected', str(st.connected)), ('reconnects', str(st.reconnects)),
            ('losses', str(st.losses)), ('connect_failures', str(st.connect_failures)),
            ('reinit_attempts', str(st.reinit_attempts)),
            ('reinit_failures', str(st.reinit_failures)), ('retry_in_s', f'{st.retry_in_s:.2f}'),
            ('last_error', st.last_error))
        message = link.message
        if link.level is not Level.OK:
            action = ('reopening the port' if not st.connected else 're-initialising')
            message = (f'{message}; {action} (next attempt in {st.retry_in_s:.1f} s, '
                       f'{st.connect_failures + st.reinit_failures} failed so far)')
        reports['link'] = Report(link.level, message, values)
        return reports

    # ---------------------------------------------------------------- reader-thread callbacks

    def _on_line(self, line: bytes, overflow: bool, t: float) -> None:
        runner = self._runner
        if runner is not None:
            runner.on_line(line, overflow, t)
            return
        sample = self.session.handle_line(t, line, overflow)
        if sample is not None and self._on_sample is not None:
            self._on_sample(sample)

    def _on_connected(self, t: float, port: str) -> None:
        del t, port
        self._wake.set()

    def _on_lost(self, t: float, reason: str) -> None:
        self._last_error = reason
        self.session.link_lost(reason)
        runner = self._runner
        if runner is not None:
            runner.on_lost(t, reason)
        if not self._stop.is_set():
            self._event('error', f'link lost: {reason}; reconnecting with back-off')

    def _on_link_error(self, t: float, message: str) -> None:
        del t
        self._last_error = message

    # ---------------------------------------------------------------- internals

    def _event(self, level: str, message: str) -> None:
        if self._on_event is not None:
            self._on_event(level, message)

    def _write(self, command: bytes) -> bool:
        """Write one command; raises OSError with the link's reason (names the port)."""
        if self._link.write(command):
            return True
        raise OSError(self._link.stats().last_error or f'{self.port}: not connected')

    def _space_command(self) -> None:
        wait = self._last_command_t + self.params.command_spacing - self._wait_clock()
        if wait > 0.0:
            time.sleep(wait)

    def _run_handshake(self, start_reader: bool = False) -> HandshakeResult:
        init = list(self._init_commands) + [protocol.chip_mode_command(self._requested_mode)]
        hs = Handshake(self.params.expected_name, self.params.handshake, init_commands=init,
                       command_spacing=self.params.command_spacing, port=self.port)
        runner = HandshakeRunner(hs, self.session.parser)
        self._runner = runner  # route lines to the handshake before the reader delivers any
        if self._closed:
            runner.on_lost(self._clock(), f'{self.port}: driver closing')
        try:
            if start_reader:
                with self._thread_lock:
                    if not self._closed:  # else the handshake fails on the queued loss
                        self._link.start()
            return runner.run(self._write, self._wait_clock)
        finally:
            self._runner = None
            self._last_command_t = self._wait_clock()

    def _claim_name(self) -> None:
        lock_dir = Path(self.params.lock_dir) if self.params.lock_dir else default_lock_dir()
        claim = NameClaim(self.params.expected_name, self.port, lock_dir)
        try:
            claim.acquire()
        except OSError as exc:
            raise LinkError(f'{self.port}: cannot claim sensor name '
                            f'{self.params.expected_name!r} in {lock_dir}: {exc}') from exc
        self._claim = claim

    def _initialised(self, result: HandshakeResult) -> None:
        self._handshake = result
        self._last_error = ''
        self.session.mark_initialised(
            calibration_source=self.calibration.source, calibration_uploaded=True,
            speed_term=self.params.calibration.speed_term, chip_mode=self._requested_mode)
        # The mode command was the last init command: lines already in flight may predate it.
        self.session.chip_mode_sent(self._requested_mode, self._clock())

    def _supervise(self) -> None:
        while not self._stop.is_set():
            self._wake.wait(self._supervise_period_s)
            self._wake.clear()
            if self._stop.is_set():
                return
            if not (self._link.connected and self.session.needs_reinitialisation):
                continue
            if not self._policy.due():
                continue
            with self._device_lock:
                self._reinitialise()

    def _reinitialise(self) -> None:
        self._reinit_attempts += 1
        try:
            result = self._run_handshake()
        except HandshakeError as exc:
            if self._stop.is_set():
                return
            self._reinit_failures += 1
            delay = self._policy.record_failure()
            self._last_error = f're-initialisation failed: {exc}'
            self.session.link_lost(self._last_error)
            self._event('error', f'{self._last_error}; next attempt in {delay:.1f} s')
            return
        self._policy.record_success()
        self._initialised(result)
        self._event('info', f'{self.port}: {result.name} re-initialised (calibration '
                            f'uploaded, chip mode {self._requested_mode})')
