# SPDX-License-Identifier: Apache-2.0
"""Keep opening a Net F/T box that could not be opened at configure (ROS-free).

A box that is still booting, unplugged or unreachable when ``gripper_driver`` configures must
not leave the driver dead until someone reconfigures it. `FtOpener` repeats the channel's
``open`` (read ``netftapi2.xml`` if asked, open the socket, start the stream) on a thread of
its own, with exponential back-off (``reconnect.initial_delay`` doubling up to
``reconnect.max_delay``), until it succeeds or `FtOpener.stop` is called. Until then that
finger has no F/T data, so no bias can be taken (``gripper/bias_ft`` is refused) and the loop
runs open loop, as it does before any bias. The back-off is timed with a monotonic clock;
nothing here touches the device's stamps.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from slip_cell_common.core.serial_transport import ReconnectPolicy
from slip_gripper_driver.core.netft_client import NetFTError

#: ``(level, message)`` log sink; level is ``'info'``, ``'warn'`` or ``'error'``.
EventSink = Callable[[str, str], None]


class Openable(Protocol):
    """What `FtOpener` needs of a channel."""

    @property
    def name(self) -> str:
        """The box as ``address:port`` (messages)."""
        ...

    def open(self) -> None:
        """Open the box; raises `NetFTError` (any exception counts as a failed attempt)."""
        ...


@dataclass(frozen=True)
class OpenerStatus:
    """Snapshot of the open attempts.

    Attributes:
        running: Attempts are still being made.
        opened: An attempt succeeded.
        attempts: Attempts made, the failed one at configure included.
        last_error: Why the newest attempt failed.
        retry_in_s: Seconds until the next attempt (0 while one runs or none is due).
    """

    running: bool
    opened: bool
    attempts: int
    last_error: str
    retry_in_s: float


class FtOpener:
    """Retry ``channel.open()`` on a thread with back-off; see the module docstring.

    Args:
        channel: The channel to open.
        first_error: Why the attempt at configure failed (counted as attempt 1).
        initial_s: First delay [s].
        max_s: Largest delay [s].
        on_event: Log sink (every failure, and the success).
        wait_clock: Monotonic clock of the back-off [s].
    """

    def __init__(self, channel: Openable, first_error: str, initial_s: float, max_s: float,
                 on_event: EventSink | None = None,
                 wait_clock: Callable[[], float] = time.monotonic) -> None:
        self._channel = channel
        self._on_event = on_event
        self._clock = wait_clock
        self._policy = ReconnectPolicy(initial_s, max_s, clock=wait_clock)
        self._policy.record_failure()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._attempts = 1
        self._last_error = first_error
        self._opened = False
        self._thread = threading.Thread(target=self._run, name=f'netft open {channel.name}',
                                        daemon=True)
        self._thread.start()

    def status(self) -> OpenerStatus:
        """The attempts so far."""
        with self._lock:
            running = self._thread.is_alive() and not self._opened
            return OpenerStatus(running, self._opened, self._attempts, self._last_error,
                                self._policy.time_until_next() if running else 0.0)

    def stop(self, timeout_s: float = 10.0) -> None:
        """End the attempts; an attempt in progress finishes first (the channel refuses to
        keep what it opens after its `close`)."""
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout_s)

    def _say(self, level: str, message: str) -> None:
        if self._on_event is not None:
            self._on_event(level, message)

    def _run(self) -> None:
        channel = self._channel
        while not self._stop.wait(self._policy.time_until_next()):
            try:
                channel.open()
            except Exception as exc:  # a half-booted box can fail in many ways
                text = str(exc) if isinstance(exc, NetFTError) else \
                    f'{type(exc).__name__}: {exc}'
                with self._lock:
                    self._attempts += 1
                    self._last_error = text
                    delay = self._policy.record_failure()
                if not self._stop.is_set():
                    self._say('warn', f'{channel.name}: Net F/T still not open (attempt '
                                      f'{self._attempts}: {text}); next attempt in '
                                      f'{delay:.2f} s')
                continue
            with self._lock:
                self._attempts += 1
                self._opened = True
                self._policy.record_success()
            self._say('info', f'{channel.name}: Net F/T open and streaming after '
                              f'{self._attempts} attempts')
            return
