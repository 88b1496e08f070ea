# SPDX-License-Identifier: Apache-2.0
"""Identify handshake and calibration upload as a time-driven state machine (ROS-free).

The reference host sent ``n`` and read until a name arrived: a ``resynch`` reply made it skip
the port for good, and a silent port hung it forever (hardware_protocols §3.5, HW-6).
`Handshake` instead is driven by the caller with explicit time and parsed lines::

    hs = Handshake('sensor_1', HandshakeParams(), init_commands=cmds, port=url)
    hs.start(t)
    while not hs.done:
        write(hs.poll(now()))              # 0 or 1 command, spaced >= command_spacing
        for line in read_lines(): hs.on_line(now(), line)
    hs.result / hs.error

Behaviour:

* ``n`` is sent; an attempt lasts ``timeout`` seconds; after ``retries`` attempts without the
  expected name the handshake fails with `HandshakeFailure.NO_ANSWER` (nothing received) or
  `HandshakeFailure.NO_NAME` (data, but no name reply: wrong baud rate or firmware).
* ``n/tresynch``: the firmware is re-syncing a chip. A name reply is still accepted; without one,
  wait until the re-sync ended (a velocity line after a serial period free of notices, see
  `resync.ResyncTracker`; the firmware prints no end line) or the attempt timed out, and ask
  again. Each re-ask is a new attempt, so a sensor whose reply never comes while it re-syncs
  fails with `HandshakeFailure.RESYNC_LOOP`.
* An ESP32 boot banner (the board restarted, e.g. on port open): wait until it streams again
  (or the attempt timeout), then ask again as a new attempt. During the upload it restarts the
  handshake this way, because the device lost the values already sent.
* A different name fails at once with `HandshakeFailure.WRONG_NAME` (names are compiled in).
* After the name matched, ``init_commands`` (calibration upload, chip mode) are sent one by
  one, ``command_spacing`` apart (the firmware handles at most one command per ~8 ms loop);
  the handshake is done one spacing after the last command.
"""
from __future__ import annotations

import queue
from dataclasses import dataclass, field
from enum import Enum
from collections.abc import Callable, Iterable, Sequence

from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.protocol import (BadLine, BootLine, LineParser, NameLine,
                                                ParsedLine, ProductIdLine, ResyncLine, TextLine,
                                                VelocityLine)
from slip_velocity_sensor.core.resync import ResyncTracker


@dataclass(frozen=True)
class HandshakeParams:
    """Handshake timing (node parameters ``handshake.*``)."""

    timeout: float = field(default=2.0, metadata={
        'unit': 's', 'range': (0.05, 60.0), 'description': 'wait for a name reply per attempt'})
    retries: int = field(default=3, metadata={
        'unit': '-', 'range': (1, 100), 'description': 'identify attempts before giving up'})


class HandshakeState(str, Enum):
    """Phase of the handshake."""

    IDLE = 'idle'
    IDENTIFYING = 'identifying'
    WAITING_RESYNC = 'waiting_resync'
    WAITING_BOOT = 'waiting_boot'
    UPLOADING = 'uploading'
    DONE = 'done'
    FAILED = 'failed'


class HandshakeFailure(str, Enum):
    """Why a handshake failed."""

    NO_ANSWER = 'no_answer'
    NO_NAME = 'no_name'
    WRONG_NAME = 'wrong_name'
    RESYNC_LOOP = 'resync_loop'
    LINK_ERROR = 'link_error'


class HandshakeError(RuntimeError):
    """A failed handshake; ``str()`` names the port and says what was (not) received.

    Attributes:
        port: Port path or URL.
        reason: Machine-readable cause.
        name: The name the device answered (for `HandshakeFailure.WRONG_NAME`), else ''.
    """

    def __init__(self, port: str, reason: HandshakeFailure, detail: str, name: str = '') -> None:
        super().__init__(f'velocity sensor on {port or "<unnamed port>"}: {detail}')
        self.port = port
        self.reason = reason
        self.name = name


@dataclass(frozen=True)
class HandshakeResult:
    """Outcome of a successful handshake.

    Attributes:
        name: Name the sensor answered.
        port: Port path or URL.
        attempts: ``n`` attempts used (1 = first try).
        resyncs: Chip re-syncs seen (a run of ``resynch`` notices counts once).
        boots: Boot banners seen.
        commands_sent: Commands written, including every ``n``.
        init_commands: Number of initialisation commands uploaded.
        text_replies: Free-text lines received during the upload (firmware acknowledgements).
        started: Time of `Handshake.start` [s].
        finished: Time the handshake completed [s].
    """

    name: str
    port: str
    attempts: int
    resyncs: int
    boots: int
    commands_sent: int
    init_commands: int
    text_replies: int
    started: float
    finished: float


_WAITING = (HandshakeState.IDENTIFYING, HandshakeState.WAITING_RESYNC,
            HandshakeState.WAITING_BOOT)


class Handshake:
    """Identify (``n``) and initialise one velocity sensor; see the module docstring.

    Args:
        expected_name: Name the sensor must answer (``sensor_1``); '' accepts any name
            (port discovery: the answered name is then in `HandshakeResult.name`).
        params: Timeout and retries.
        init_commands: Commands sent after a successful identify (calibration upload, ``c0``).
        command_spacing: Minimum time between two commands [s] (spec: >= 0.010).
        port: Port path or URL, used in error messages.
    """

    def __init__(self, expected_name: str, params: HandshakeParams | None = None, *,
                 init_commands: Sequence[bytes] = (), command_spacing: float = 0.010,
                 port: str = '') -> None:
        if command_spacing < 0.0:
            raise ValueError('command_spacing must be >= 0 s')
        self.expected_name = expected_name
        self.params = params if params is not None else HandshakeParams()
        self.init_commands = tuple(init_commands)
        self.command_spacing = command_spacing
        self.port = port
        self.state = HandshakeState.IDLE
        self.error: HandshakeError | None = None
        self.result: HandshakeResult | None = None
        self._reset_progress(0.0)
        self._attempt = 0

    def _reset_progress(self, t: float) -> None:
        self._name = self.expected_name
        self._queue: list[bytes] = []
        self._last_sent: float | None = None
        self._deadline = t + self.params.timeout
        self._started = t
        self._attempt = 1
        self._sent = 0
        self._lines = 0
        self._velocity_lines = 0
        self._bad_lines = 0
        self._resync = ResyncTracker()
        self._boots = 0
        self._text_replies = 0

    # ---------------------------------------------------------------- status

    @property
    def done(self) -> bool:
        """True once the handshake succeeded or failed."""
        return self.state in (HandshakeState.DONE, HandshakeState.FAILED)

    @property
    def attempt(self) -> int:
        """Current identify attempt (1-based; 0 before `start`)."""
        return self._attempt

    def wait_hint(self, t: float) -> float:
        """Longest the caller may block before calling `poll` again [s] (>= 0)."""
        if self.done or self.state is HandshakeState.IDLE:
            return 0.0
        waits = [self._deadline - t] if self.state in _WAITING else []
        if self._queue or self.state is HandshakeState.UPLOADING:
            waits.append(0.0 if self._last_sent is None
                         else self._last_sent + self.command_spacing - t)
        return max(0.0, min(waits)) if waits else 0.0

    # ---------------------------------------------------------------- driving

    def start(self, t: float) -> None:
        """Begin (or restart) the handshake at time ``t`` [s]."""
        self.state = HandshakeState.IDENTIFYING
        self.error = None
        self.result = None
        self._reset_progress(t)
        self._queue = [protocol.identify_command()]

    def step(self, t: float, lines: Iterable[ParsedLine] = ()) -> list[bytes]:
        """Feed lines received up to ``t`` [s], then `poll`; returns the commands to write."""
        for line in lines:
            self.on_line(t, line)
        return self.poll(t)

    def poll(self, t: float) -> list[bytes]:
        """Advance timers to ``t`` [s]; return the command due now (at most one)."""
        if self.done or self.state is HandshakeState.IDLE:
            return []
        if self.state in _WAITING and t >= self._deadline:
            if not self._next_attempt(t, self._timeout_failure()):
                return []
        if self.state in (HandshakeState.WAITING_RESYNC, HandshakeState.WAITING_BOOT):
            return []
        if self._queue and (self._last_sent is None
                            or t - self._last_sent >= self.command_spacing):
            self._last_sent = t
            self._sent += 1
            return [self._queue.pop(0)]
        if (self.state is HandshakeState.UPLOADING and not self._queue
                and (self._last_sent is None or t - self._last_sent >= self.command_spacing)):
            self._finish(t)
        return []

    def link_failed(self, reason: str) -> None:
        """The port failed (read/write error, unplugged): fail with the reason (names the port)."""
        if not self.done:
            self._fail(HandshakeFailure.LINK_ERROR, f'link failed during the handshake: {reason}')

    def on_line(self, t: float, line: ParsedLine) -> None:
        """Handle one parsed line received at ``t`` [s]."""
        if self.done or self.state is HandshakeState.IDLE:
            return
        self._lines += 1
        if isinstance(line, VelocityLine):
            self._velocity_lines += 1
            resync_over = self._resync.on_velocity_line(t)
            if self.state is HandshakeState.WAITING_BOOT:
                self._next_attempt(t, HandshakeFailure.NO_NAME)
            elif self.state is HandshakeState.WAITING_RESYNC and resync_over:
                self._next_attempt(t, HandshakeFailure.RESYNC_LOOP)
        elif isinstance(line, NameLine):
            self._on_name(line.name)
        elif isinstance(line, ResyncLine):
            self._resync.on_notice(t)
            if self.state is HandshakeState.IDENTIFYING:
                self.state = HandshakeState.WAITING_RESYNC
                self._queue.clear()
        elif isinstance(line, ProductIdLine):
            self._resync.on_product_ids(line.ids)
        elif isinstance(line, BootLine):
            self._boots += 1
            if self.state is HandshakeState.UPLOADING:
                self._deadline = t + self.params.timeout  # values sent so far are lost
            self.state = HandshakeState.WAITING_BOOT
            self._queue.clear()
        elif isinstance(line, TextLine):
            if self.state is HandshakeState.UPLOADING:
                self._text_replies += 1
        elif isinstance(line, BadLine):
            self._bad_lines += 1

    # ---------------------------------------------------------------- internals

    def _on_name(self, name: str) -> None:
        if not self.expected_name and self.state in _WAITING:
            self._name = name
        if name == self._name:
            if self.state in _WAITING:
                self.state = HandshakeState.UPLOADING
                self._queue = list(self.init_commands)
            return
        self._fail(HandshakeFailure.WRONG_NAME,
                   f'answered {name!r}, expected {self.expected_name!r} (wrong port for this '
                   'finger, or two boards flashed with the same name?)', name=name)

    def _ask_again(self, t: float) -> None:
        self.state = HandshakeState.IDENTIFYING
        self._queue = [protocol.identify_command()]
        self._deadline = t + self.params.timeout

    def _next_attempt(self, t: float, failure: HandshakeFailure) -> bool:
        """Start the next attempt; fail with ``failure`` when none is left."""
        if self._attempt >= self.params.retries:
            self._fail(failure, self._failure_detail(failure))
            return False
        self._attempt += 1
        self._ask_again(t)
        return True

    def _timeout_failure(self) -> HandshakeFailure:
        if self.state is HandshakeState.WAITING_RESYNC or self._resync.episodes > 0:
            return HandshakeFailure.RESYNC_LOOP
        return HandshakeFailure.NO_NAME if self._lines else HandshakeFailure.NO_ANSWER

    def _failure_detail(self, failure: HandshakeFailure) -> str:
        tried = (f'after {self._attempt} attempt(s) of {self.params.timeout:g} s '
                 f'({self._sent} command(s) sent)')
        if failure is HandshakeFailure.RESYNC_LOOP:
            return (f'no name reply {tried}: the sensor kept re-syncing '
                    f'({self._resync.notices} resynch notices); a chip is missing, unplugged '
                    'or dirty')
        if failure is HandshakeFailure.NO_ANSWER:
            return (f'no answer to "n" {tried}; nothing was received: is the sensor powered, '
                    'the port right and the baud rate 115200?')
        return (f'no name reply {tried}; received {self._lines} line(s) ({self._velocity_lines} '
                f'velocity, {self._bad_lines} bad, {self._boots} boot banner(s)): '
                'wrong baud rate or firmware without the "n" command?')

    def _fail(self, reason: HandshakeFailure, detail: str, name: str = '') -> None:
        self.state = HandshakeState.FAILED
        self._queue.clear()
        self.error = HandshakeError(self.port, reason, detail, name=name)

    def _finish(self, t: float) -> None:
        self.state = HandshakeState.DONE
        self.result = HandshakeResult(
            name=self._name, port=self.port, attempts=self._attempt,
            resyncs=self._resync.episodes, boots=self._boots, commands_sent=self._sent,
            init_commands=len(self.init_commands), text_replies=self._text_replies,
            started=self._started, finished=t)


class HandshakeRunner:
    """Run a `Handshake` on lines delivered by a reader thread, blocking the calling thread.

    The reader thread (``slip_cell_common.core.serial_transport.SerialLink``) calls `on_line` and
    `on_lost`; the configuring thread calls `run`, which returns when the handshake is done.
    Total blocking is bounded by ``retries × timeout`` plus command spacing.

    Args:
        handshake: The state machine to drive.
        parser: Line parser (pass the session's parser so its counters include these lines).
    """

    def __init__(self, handshake: Handshake, parser: LineParser | None = None) -> None:
        self.handshake = handshake
        self.parser = parser if parser is not None else LineParser()
        self._inbox: queue.Queue[tuple[bytes, bool] | str] = queue.Queue()

    def on_line(self, line: bytes, overflow: bool, t: float) -> None:
        """Line callback for the reader thread (``SerialLink`` signature); ``t`` is unused."""
        self._inbox.put((line, overflow))

    def on_lost(self, t: float, reason: str) -> None:
        """Loss callback for the reader thread: the handshake fails with ``reason``."""
        self._inbox.put(reason)

    def run(self, write: Callable[[bytes], object], clock: Callable[[], float],
            max_block: float = 0.05) -> HandshakeResult:
        """Start the handshake and drive it to completion.

        Args:
            write: Writes one command; returning ``False`` or raising ``OSError`` is a failure.
            clock: Seconds, used for the handshake timers (a monotonic clock for hardware).
            max_block: Longest single wait for a line [s].

        Returns:
            The result of the successful handshake.

        Raises:
            HandshakeError: On timeout, wrong name, re-sync loop or link failure.
        """
        hs = self.handshake
        hs.start(clock())
        while not hs.done:
            self._drain(clock())
            if hs.done:
                break
            for command in hs.poll(clock()):
                try:
                    ok = write(command)
                except OSError as exc:
                    hs.link_failed(f'write of {command!r} failed: {exc}')
                    break
                if ok is False:
                    hs.link_failed(f'write of {command!r} failed (port disconnected?)')
            if hs.done:
                break
            wait = min(hs.wait_hint(clock()), max_block)
            try:
                item = self._inbox.get(timeout=max(wait, 0.0005))
            except queue.Empty:
                continue
            self._handle(clock(), item)
        if hs.error is not None:
            raise hs.error
        if hs.result is None:  # unreachable: done without error means a result
            raise RuntimeError('handshake finished without a result')
        return hs.result

    def _drain(self, t: float) -> None:
        while True:
            try:
                item = self._inbox.get_nowait()
            except queue.Empty:
                return
            self._handle(t, item)

    def _handle(self, t: float, item: tuple[bytes, bool] | str) -> None:
        if isinstance(item, str):
            self.handshake.link_failed(item)
        else:
            self.handshake.on_line(t, self.parser.parse(item[0], item[1]))
