# SPDX-License-Identifier: Apache-2.0
"""Start a velocity-sensor driver, retrying a failed start with back-off (ROS-free).

A sensor that is not plugged in, still booting or re-syncing when the node starts must not
stay dead until someone reconfigures the node. `DriverStarter` runs start attempts (open the
port, identify, upload, claim the name: `driver.SensorDriver.connect`) on a thread:

* an attempt that fails with a retryable `driver.DriverError` (port missing or busy, no
  answer, no name reply, re-sync loop, link failure) is repeated after an exponential back-off
  (``reconnect.initial_delay`` doubling up to ``reconnect.max_delay``);
* a wrong name or a name claimed by another port stops the attempts (retrying cannot fix a
  wrong port or two boards flashed alike);
* `stop` ends the attempts at once, also one in progress (its driver is closed);
* every failure and the final start are reported through ``on_event`` with the port, the
  attempt number and the next delay.

Times: ``wait_clock`` (monotonic) only times the back-off.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from collections.abc import Callable

from slip_cell_common.core.serial_transport import ReconnectParams, ReconnectPolicy
from slip_velocity_sensor.core.driver import DriverError, SensorDriver
from slip_velocity_sensor.core.handshake import HandshakeResult

#: ``(level, message)`` log sink; level is ``'info'``, ``'warn'`` or ``'error'``.
EventCallback = Callable[[str, str], None]
#: Called on the starter thread with the started driver and its handshake result.
StartedCallback = Callable[[SensorDriver, HandshakeResult], None]


@dataclass(frozen=True)
class StarterStatus:
    """Snapshot of the start attempts.

    Attributes:
        port: Port path or URL.
        running: Attempts are being made (between `DriverStarter.start` and a start, a
            permanent failure or `DriverStarter.stop`).
        started: A driver was started and handed over.
        gave_up: A permanent failure ended the attempts.
        attempts: Start attempts made.
        last_error: Why the newest attempt failed ('' when none failed).
        retry_in_s: Seconds until the next attempt (0 when none is scheduled).
    """

    port: str
    running: bool
    started: bool
    gave_up: bool
    attempts: int
    last_error: str
    retry_in_s: float


class DriverStarter:
    """Make start attempts on a thread until one succeeds; see the module docstring.

    Args:
        port: Port path or URL (messages).
        make_driver: Builds a fresh, unconnected driver for each attempt.
        reconnect: Back-off between attempts.
        on_started: Receives the connected driver (the starter no longer touches it).
        on_event: Log sink.
        wait_clock: Monotonic clock of the back-off.
    """

    def __init__(self, port: str, make_driver: Callable[[], SensorDriver],
                 reconnect: ReconnectParams, *, on_started: StartedCallback,
                 on_event: EventCallback | None = None,
                 wait_clock: Callable[[], float] = time.monotonic) -> None:
        self.port = port
        self._make_driver = make_driver
        self._policy = ReconnectPolicy(reconnect.initial_delay, reconnect.max_delay,
                                       clock=wait_clock)
        self._on_started = on_started
        self._on_event = on_event
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._pending: SensorDriver | None = None
        self._attempts = 0
        self._last_error = ''
        self._started = False
        self._gave_up = False

    def record_failure(self, error: DriverError) -> None:
        """Count a failed attempt made by the caller (the first one, made in configure)."""
        with self._lock:
            self._attempts += 1
            self._last_error = str(error)
            self._gave_up = not error.retryable
        if error.retryable:
            self._policy.record_failure()

    def start(self) -> None:
        """Begin (or resume) the attempts on a thread; the first one is due after the back-off
        of failures already recorded. No effect once started, after a permanent failure or
        while running."""
        with self._lock:
            if self._started or self._gave_up:
                return
            if self._thread is not None and self._thread.is_alive():
                return
            self._stop.clear()
            self._thread = threading.Thread(target=self._run,
                                            name=f'velocity-sensor start {self.port}',
                                            daemon=True)
            self._thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        """End the attempts (closing an attempt in progress); the thread is joined."""
        self._stop.set()
        with self._lock:
            pending, thread = self._pending, self._thread
        if pending is not None:
            pending.close()
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout_s)
        with self._lock:
            self._thread = None

    def status(self) -> StarterStatus:
        """Snapshot of the attempts."""
        with self._lock:
            running = self._thread is not None and self._thread.is_alive()
            return StarterStatus(
                port=self.port, running=running, started=self._started,
                gave_up=self._gave_up, attempts=self._attempts, last_error=self._last_error,
                retry_in_s=self._policy.time_until_next() if running else 0.0)

    def _event(self, level: str, message: str) -> None:
        if self._on_event is not None:
            self._on_event(level, message)

    def _run(self) -> None:
        while not self._stop.is_set():
            wait = self._policy.time_until_next()
            if wait > 0.0 and self._stop.wait(wait):
                return
            driver = self._make_driver()
            with self._lock:
                self._pending = driver
                self._attempts += 1
                attempt = self._attempts
            if self._stop.is_set():
                driver.close()
                return
            try:
                result = driver.connect()
            except DriverError as exc:
                with self._lock:
                    self._pending = None
                    self._last_error = str(exc)
                if self._stop.is_set():
                    return
                if not exc.retryable:
                    with self._lock:
                        self._gave_up = True
                    self._event('error', f'start attempt {attempt} failed: {exc}; not retrying '
                                         '(fix the port or the sensor name, then reconfigure)')
                    return
                delay = self._policy.record_failure()
                self._event('error', f'start attempt {attempt} failed: {exc}; retrying in '
                                     f'{delay:.1f} s')
                continue
            with self._lock:
                self._pending = None
                stopped = self._stop.is_set()
                if not stopped:
                    self._started = True
                    self._last_error = ''
            if stopped:
                driver.close()
                return
            self._policy.record_success()
            self._event('info', f'{self.port}: {result.name} started at attempt {attempt}')
            self._on_started(driver, result)
            return
