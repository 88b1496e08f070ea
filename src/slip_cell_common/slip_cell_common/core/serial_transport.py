# SPDX-License-Identifier: Apache-2.0
"""Serial transport: byte-stream seam, line splitting, reader thread and reconnection.

The port is opened with pyserial's ``serial_for_url``, so a ``/dev/serial/by-id/...`` path, a
``socket://host:port`` URL, ``loop://`` or the slave path of a pseudo-terminal all work
unchanged (HW-8). One `SerialLink` owns one port: a single reader thread reads, stamps every
line with an injected clock when its bytes arrive (HW-11), hands it to a callback, and after a
link error (pyserial's "device reports readiness to read but returned no data", any
``SerialException``/``OSError``) reports the loss and reopens the same URL with exponential
back-off (`ReconnectPolicy`), without ever spinning (HW-6).

The reader thread uses ``time.monotonic`` only to bound its blocking waits (back-off delays);
every stamp handed to callers comes from the injected clock.
"""
from __future__ import annotations

import errno
import fcntl
import os
import re
import select
import struct
import termios
import threading
import time
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol, runtime_checkable
from collections.abc import Callable

import serial

try:  # POSIX ports get a direct descriptor path for the 500 Hz loop (see SerialLink)
    from serial.serialposix import Serial as _PosixSerial
except ImportError:  # pragma: no cover - non-POSIX platforms use pyserial's read/write only
    _PosixSerial = None

from slip_cell_common.core.tty_worker import wait_channel, waiting_for_tty_worker
from slip_cell_common.core.validation import validate_fields

#: A clock returning seconds (the node passes its ROS clock; tests pass a fake).
Clock = Callable[[], float]

_TERMINATOR_RE = re.compile(rb'[\r\n]')

#: Largest chunk read at once [bytes]; far above a 500 Hz line rate, bounds each read.
_MAX_CHUNK = 4096

#: errno values of a non-blocking descriptor that has nothing to give or take right now.
_RETRY_ERRNOS = frozenset({errno.EAGAIN, errno.EWOULDBLOCK, errno.EINTR})


class _DirectIO(NamedTuple):
    """Descriptors of an open POSIX pyserial port (read/write without pyserial's wrappers)."""

    fd: int
    abort_r: int


@runtime_checkable
class ByteStream(Protocol):
    """The I/O seam: what the driver needs from a serial port (pyserial ``Serial`` fits)."""

    def read(self, size: int = 1) -> bytes:
        """Read up to ``size`` bytes; returns fewer (possibly none) on timeout."""

    def write(self, data: bytes) -> int | None:
        """Write all of ``data``."""

    def close(self) -> None:
        """Release the port."""


class LinkError(RuntimeError):
    """A port could not be opened or failed; the message always names the port."""


def describe_link_error(port: str, exc: BaseException) -> str:
    """One-line description of a serial failure, naming the port.

    pyserial's "device reports readiness to read but returned no data" means the device was
    unplugged (USB re-enumeration) or another process took the port.
    """
    text = str(exc)
    if 'readiness to read but returned no data' in text:
        return (f'{port}: device disconnected or port taken by another process '
                f'(readable but returned no data)')
    return f'{port}: {type(exc).__name__}: {text}'


def open_stream(url: str, baudrate: int, timeout_s: float, *,
                write_timeout_s: float = 0.05, exclusive: bool = True) -> ByteStream:
    """Open a serial port or pyserial URL.

    Args:
        url: ``/dev/serial/by-id/...`` path, pty slave path, or pyserial URL (``socket://``,
            ``loop://``).
        baudrate: Baud rate [Bd] (ignored by USB CDC devices).
        timeout_s: Read timeout [s]; bounds how long a read blocks.
        write_timeout_s: Write timeout [s]; a wedged port raises instead of blocking. pyserial
            checks it after ``os.write`` returns, so a thread that waited for the GIL can see a
            "timeout" for bytes already sent; a long timeout, on the other hand, lets a
            blocked write
            outlast the link supervision. Nodes pass a value suited to their link parameters.
        exclusive: Take an exclusive lock on POSIX ports (one owner per device, HW-13).

    Returns:
        The open stream.

    Raises:
        LinkError: The port does not exist, is busy, or the URL is invalid (message names it).
    """
    if not url:
        raise LinkError('serial port is not set (empty path/URL)')
    try:
        port: ByteStream = serial.serial_for_url(
            url, baudrate=baudrate, timeout=timeout_s, write_timeout=write_timeout_s,
            exclusive=exclusive)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise LinkError(f'cannot open serial port {url!r}: {exc}') from exc
    return port


class LineReader:
    """Splits a byte stream into lines at CR and/or LF, with a bounded line length.

    Empty lines (for example between the CR and LF of ``\\r\\n``) are dropped. A line longer
    than ``max_line_length`` is truncated, reported once with ``overflow=True`` and the rest of
    it discarded up to the next terminator, so memory stays bounded whatever arrives.

    With ``resync`` the bytes before the first terminator are discarded: after (re)opening a
    port the first bytes may be the tail of a line (``416`` of ``3.1416``), which must never be
    mistaken for a complete angle. A stream that stayed quiet since the reset is at a line
    boundary (`quiet`): its next bytes start a line and are kept (a firmware that is silent
    while it boots prints its first line then, e.g. the gripper's ``Voltage control``).

    Args:
        max_line_length: Longest accepted line [bytes], ≥ 1.
        resync: Discard up to the first terminator.
    """

    def __init__(self, max_line_length: int = 128, resync: bool = True) -> None:
        if max_line_length < 1:
            raise ValueError('max_line_length must be >= 1')
        self.max_line_length = max_line_length
        self.discarded_bytes = 0
        self.overflows = 0
        self._buf = bytearray()
        self._overflow = False
        self._skipping = resync
        self._fed_since_reset = False

    def reset(self, resync: bool = True) -> None:
        """Forget any partial line (call after reopening the port)."""
        self._buf.clear()
        self._overflow = False
        self._skipping = resync
        self._fed_since_reset = False

    def quiet(self) -> None:
        """The stream delivered nothing for a while: if nothing arrived since the reset, the
        next byte starts a line, so stop resynchronising."""
        if self._skipping and not self._fed_since_reset:
            self._skipping = False

    def feed(self, data: bytes) -> list[tuple[bytes, bool]]:
        """Add received bytes and return the completed lines.

        Args:
            data: Bytes as read from the port (any split, including mid-line).

        Returns:
            ``(line, overflow)`` pairs, terminators removed, in arrival order.
        """
        out: list[tuple[bytes, bool]] = []
        if data:
            self._fed_since_reset = True
        start = 0
        for match in _TERMINATOR_RE.finditer(data):
            end = match.start()
            self._append(data, start, end)
            self._complete(out)
            start = end + 1
        if start < len(data):
            self._append(data, start, len(data))
        return out

    def _append(self, data: bytes, start: int, end: int) -> None:
        if end <= start:
            return
        if self._skipping:
            self.discarded_bytes += end - start
            return
        if self._overflow:
            return
        room = self.max_line_length - len(self._buf)
        if end - start > room:
            self._buf += data[start:start + room]
            self._overflow = True
            self.overflows += 1
        else:
            self._buf += data[start:end]

    def _complete(self, out: list[tuple[bytes, bool]]) -> None:
        if self._skipping:
            self._skipping = False
            return
        if self._buf or self._overflow:
            out.append((bytes(self._buf), self._overflow))
            self._buf.clear()
            self._overflow = False


class ReconnectPolicy:
    """Exponential back-off between reconnection attempts.

    After a loss the first attempt is due ``initial_s`` later; each failed attempt multiplies
    the delay by ``factor`` up to ``max_s``; a success resets it.

    Args:
        initial_s: First delay [s], > 0.
        max_s: Largest delay [s], ≥ ``initial_s``.
        clock: Time source [s] (injected so the policy is testable with a fake clock).
        factor: Growth per failure, ≥ 1.
    """

    def __init__(self, initial_s: float, max_s: float, *, clock: Clock,
                 factor: float = 2.0) -> None:
        if not 0.0 < initial_s <= max_s:
            raise ValueError(f'need 0 < initial_s <= max_s, got {initial_s}, {max_s}')
        if factor < 1.0:
            raise ValueError(f'factor must be >= 1, got {factor}')
        self.initial_s = initial_s
        self.max_s = max_s
        self.factor = factor
        self._clock = clock
        self._next_delay = initial_s
        self._due_at = float('-inf')
        self.failures = 0

    @property
    def next_delay(self) -> float:
        """Delay [s] that the next `record_failure` will schedule."""
        return self._next_delay

    def record_failure(self) -> float:
        """Register a loss or a failed attempt; returns the delay [s] until the next attempt."""
        delay = self._next_delay
        self._due_at = self._clock() + delay
        self._next_delay = min(delay * self.factor, self.max_s)
        self.failures += 1
        return delay

    def record_success(self) -> None:
        """Register a successful (re)connection: the next loss starts at ``initial_s`` again."""
        self._next_delay = self.initial_s
        self._due_at = float('-inf')
        self.failures = 0

    def due(self) -> bool:
        """True when an attempt may be made now."""
        return self._clock() >= self._due_at

    def time_until_next(self) -> float:
        """Seconds until the next attempt is due (0 when due)."""
        return max(0.0, self._due_at - self._clock())


@dataclass(frozen=True)
class SerialParams:
    """Serial port of the gripper firmware (parameter group ``serial``)."""

    port: str = field(default='', metadata={
        'read_only': True, 'required': True,
        'description': '/dev/serial/by-id/... path or pyserial URL (socket://, loop://)'})
    baudrate: int = field(default=115200, metadata={
        'unit': 'Bd', 'range': (300, 4000000), 'read_only': True,
        'description': 'baud rate (ignored by USB CDC)'})
    protocol: str = field(default='plain', metadata={
        'choices': ('plain',), 'read_only': True,
        'description': 'line protocol; only the plain firmware protocol is implemented'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        validate_fields(self)


@dataclass(frozen=True)
class ReconnectParams:
    """Back-off of link reconnection (parameter group ``reconnect``)."""

    initial_delay: float = field(default=0.5, metadata={
        'unit': 's', 'range': (0.01, 60.0), 'description': 'first reconnect delay'})
    max_delay: float = field(default=5.0, metadata={
        'unit': 's', 'range': (0.01, 600.0), 'description': 'largest reconnect delay'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        validate_fields(self, [] if self.initial_delay <= self.max_delay else [
            f'initial_delay {self.initial_delay} s exceeds max_delay {self.max_delay} s'])


@dataclass(frozen=True)
class LinkStats:
    """Snapshot of a `SerialLink`'s state and counters."""

    port: str
    connected: bool
    reconnects: int  #: successful reopenings after a loss
    losses: int  #: link losses (read/write errors, requested drops)
    connect_failures: int  #: failed reopen attempts
    bytes_read: int
    bytes_written: int
    write_errors: int
    writes_dropped: int  #: writes attempted while disconnected
    discarded_bytes: int  #: bytes dropped while resynchronising to a line start
    overflows: int  #: over-long lines
    callback_errors: int  #: exceptions raised by callbacks (a bug; see last_error)
    last_error: str
    retry_in_s: float  #: seconds until the next reopen attempt (0 when connected)


LineCallback = Callable[[bytes, bool, float], None]
#: ``(lines, t)``: every line completed by one read, oldest first, as ``(line, overflow)``.
ChunkCallback = Callable[[list[tuple[bytes, bool]], float], None]
EventCallback = Callable[[float, str], None]


class SerialLink:
    """Owns one serial device: open, reader thread, stamped lines, reconnection.

    Callbacks run on the reader thread (except the first ``on_connected``, which runs in
    `open`) and must not block:

    * ``on_line(line, overflow, t)``: one line without terminator; ``t`` = ``clock()`` taken
      when its last bytes were read [s]. With ``on_chunk`` the lines of one read arrive
      together instead (``on_chunk(lines, t)``), so a consumer can tell a backlog (lines that
      waited while the reader was descheduled) from lines that arrived one by one.
    * ``on_connected(t, port)``: the stream is open (initially and after each reconnection).
    * ``on_lost(t, reason)``: the link failed or a drop was requested; the reason names the
      port. Reconnection attempts follow with back-off.
    * ``on_error(t, message)``: a reopen attempt failed or a callback raised.

    Descriptor lifetime: only the reader thread reads the descriptors, and a stream is closed
    only when no reader uses it: `close` closes at once when the reader has ended, otherwise
    the reader closes the stream itself on its way out (a stream closed under a thread that
    still selects or reads on its descriptor numbers would let that thread touch whatever
    the process opens next under the same numbers). Cancelling a read writes to pyserial's
    abort pipe under the same lock that guards closing.

    Latency (the 500 Hz loop writes its command from ``on_line``): on a POSIX port opened by
    pyserial the reader waits with one ``select`` on the port and pyserial's abort pipe, reads
    with one ``os.read`` and `write` is one ``os.write`` on the non-blocking descriptor. That
    is what pyserial does underneath, without its per-call ``in_waiting`` ioctl, timeout
    bookkeeping and the extra ``select`` after every write (each also a GIL release another
    thread can take over). A write the descriptor cannot take at once (``EAGAIN``, partial)
    goes through pyserial's ``write`` with its timeout, as before; every other stream (URLs,
    fakes) always uses ``read``/``write``.

    Args:
        url: Port path or pyserial URL.
        clock: Stamp source [s] (the node clock).
        on_line: Line callback.
        on_connected: Connection callback.
        on_lost: Loss callback.
        on_error: Error callback (for diagnostics/logging).
        baudrate: Baud rate [Bd].
        read_timeout_s: Read timeout [s]; bounds how long `stop` waits for the thread.
        write_timeout_s: Write timeout [s].
        max_line_length: Longest accepted line [bytes].
        reconnect: Back-off parameters.
        opener: ``open_stream``-compatible factory (tests inject fakes here).
        wait_clock: Monotonic clock used only to time back-off waits.
        thread_setup: Called first on the reader thread (scheduling priority, see
            `realtime.ThreadTuning.apply`); its exceptions are counted like a callback's.
        on_chunk: Receives the lines of each read together instead of ``on_line``.
    """

    def __init__(self, url: str, *, clock: Clock, on_line: LineCallback,
                 on_connected: EventCallback | None = None, on_lost: EventCallback | None = None,
                 on_error: EventCallback | None = None, baudrate: int = 115200,
                 read_timeout_s: float = 0.02, write_timeout_s: float = 0.05,
                 max_line_length: int = 128, reconnect: ReconnectParams = ReconnectParams(),
                 opener: Callable[..., ByteStream] = open_stream,
                 wait_clock: Clock = time.monotonic,
                 thread_setup: Callable[[], object] | None = None,
                 on_chunk: ChunkCallback | None = None) -> None:
        self.url = url
        self._on_chunk = on_chunk
        self._reader_tid: int | None = None  # native id of the reader thread while it runs
        self._last_read = float('nan')
        self._reading = False
        self._exit_lock = threading.Lock()  # hands the close over to an exiting reader
        self._reader_running = False
        self._close_on_exit = False
        self._thread_setup = thread_setup
        self._direct: _DirectIO | None = None
        self._clock = clock
        self._on_line = on_line
        self._on_connected = on_connected
        self._on_lost = on_lost
        self._on_error = on_error
        self._baudrate = baudrate
        self._read_timeout_s = read_timeout_s
        self._write_timeout_s = write_timeout_s
        self._opener = opener
        self._policy = ReconnectPolicy(reconnect.initial_delay, reconnect.max_delay,
                                       clock=wait_clock)
        self._lines = LineReader(max_line_length)
        self._write_lock = threading.Lock()
        self._stream: ByteStream | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._drop_reason: str | None = None
        self._reconnects = 0
        self._losses = 0
        self._connect_failures = 0
        self._bytes_read = 0
        self._bytes_written = 0
        self._write_errors = 0
        self._writes_dropped = 0
        self._callback_errors = 0
        self._last_error = ''
        self._ever_connected = False

    # ------------------------------------------------------------------ lifecycle
    def open(self) -> None:
        """Open the port now (configure); calls ``on_connected``.

        Raises:
            LinkError: The port cannot be opened; the message names it.
        """
        if self._stream is not None:
            return
        stream = self._opener(self.url, self._baudrate, self._read_timeout_s,
                              write_timeout_s=self._write_timeout_s)
        self._install(stream)

    def start(self, open_retry: bool = False) -> None:
        """Start the reader thread (activate).

        Args:
            open_retry: Allow a start before any successful `open`: the reader then opens the
                port with back-off (``reconnect.*``) until it succeeds or `stop` is called,
                reporting each failed attempt through ``on_error``. Otherwise the port must
                have been opened once.

        Raises:
            LinkError: Not opened yet and ``open_retry`` is False.
        """
        thread = self._thread
        if thread is not None and thread.is_alive():
            if not self._stop.is_set():
                return
            thread.join(5.0)  # a reader still on its way out of an earlier stop: never two
            if thread.is_alive():
                raise LinkError(f'{self.url}: the previous reader thread has not ended')
        if not self._ever_connected and not open_retry:
            raise LinkError(f'{self.url}: start() before a successful open()')
        with self._exit_lock:
            self._close_on_exit = False
            self._reader_running = True
        self._stop.clear()
        self._lines.reset(resync=True)
        self._flush_input()
        self._thread = threading.Thread(target=self._run, name=f'serial-reader {self.url}',
                                        daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 1.0) -> None:
        """Stop the reader thread (deactivate); the port stays open if it is.

        Args:
            timeout_s: Longest wait for the thread [s].
        """
        self._stop.set()
        self._cancel_read()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout_s)
        if thread is None or not thread.is_alive():
            self._thread = None

    def close(self, timeout_s: float = 1.0) -> None:
        """Stop the thread and close the port (cleanup/shutdown).

        When the reader has not ended within ``timeout_s`` [s] (`stop`) it closes the stream
        itself as it exits: a descriptor is never closed under a thread that may still use it.
        """
        self.stop(timeout_s)
        with self._exit_lock:
            if self._reader_running and self._thread is not threading.current_thread():
                self._close_on_exit = True
                return
        self._close_stream()

    @property
    def last_read_stamp(self) -> float:
        """``clock()`` of the newest read that completed a line [s] (NaN before the first): the
        stamp its lines are handed over with, set before the callbacks run."""
        return self._last_read

    @property
    def read_in_progress(self) -> bool:
        """The reader has taken bytes off the port and not yet recorded their lines
        (`last_read_stamp`); only on the direct POSIX path."""
        return self._reading

    def kernel_holds_input(self) -> bool:
        """The reader waits for the kernel's tty worker to hand over bytes the device has sent
        (`slip_cell_common.core.tty_worker`): data is arriving that the process cannot see
        yet because the host is overloaded. Thread-safe; False where it cannot be told."""
        return waiting_for_tty_worker(self._reader_tid)

    def reader_wait_channel(self) -> str:
        """Where in the kernel the reader thread sleeps ('' while it runs or where it cannot
        be told); for log messages."""
        return wait_channel(self._reader_tid)

    def input_pending(self) -> int:
        """Bytes the port has received that the reader has not read yet (0 when closed or
        unknown). Thread-safe; tells a silent device from a reader that fell behind."""
        with self._write_lock:
            stream = self._stream
            direct = self._direct
            if stream is None:
                return 0
            try:
                if direct is not None:
                    raw = fcntl.ioctl(direct.fd, termios.TIOCINQ, struct.pack('I', 0))
                    return int(struct.unpack('I', raw)[0])
                return int(getattr(stream, 'in_waiting', 0) or 0)
            except (OSError, ValueError, TypeError, serial.SerialException):
                return 0

    @property
    def connected(self) -> bool:
        """True while a stream is open."""
        return self._stream is not None

    @property
    def running(self) -> bool:
        """True while the reader thread runs."""
        return self._thread is not None and self._thread.is_alive()

    def stats(self) -> LinkStats:
        """Counter snapshot."""
        return LinkStats(
            port=self.url, connected=self.connected, reconnects=self._reconnects,
            losses=self._losses, connect_failures=self._connect_failures,
            bytes_read=self._bytes_read, bytes_written=self._bytes_written,
            write_errors=self._write_errors, writes_dropped=self._writes_dropped,
            discarded_bytes=self._lines.discarded_bytes, overflows=self._lines.overflows,
            callback_errors=self._callback_errors, last_error=self._last_error,
            retry_in_s=0.0 if self.connected else self._policy.time_until_next())

    # ------------------------------------------------------------------ I/O
    def write(self, data: bytes) -> bool:
        """Write bytes if connected; thread-safe.

        Returns:
            True when written. False when disconnected or the write failed (a failure also
            requests a reconnection).
        """
        with self._write_lock:
            stream = self._stream
            if stream is None:
                self._writes_dropped += 1
                return False
            try:
                direct = self._direct
                if direct is not None:
                    done = self._write_direct(direct.fd, data)
                    if done == len(data):
                        self._bytes_written += done
                        return True
                    stream.write(data[done:])  # the rest waits (with timeout) in pyserial
                else:
                    stream.write(data)
            except (serial.SerialException, OSError) as exc:
                self._write_errors += 1
                reason = describe_link_error(self.url, exc)
                self._last_error = f'write failed: {reason}'
            else:
                self._bytes_written += len(data)
                return True
        self.request_reconnect(f'write failed: {reason}')
        return False

    def request_reconnect(self, reason: str) -> None:
        """Ask the reader thread to close the port and reconnect (e.g. telemetry timeout).

        Safe from any thread; the reader acts within one read timeout.
        """
        if self._stream is None:
            return
        self._drop_reason = reason
        self._cancel_read()

    # ------------------------------------------------------------------ internals
    @staticmethod
    def _write_direct(fd: int, data: bytes) -> int:
        """Bytes of ``data`` the non-blocking descriptor took at once (0 when it is full)."""
        try:
            return os.write(fd, data)
        except OSError as exc:
            if exc.errno in _RETRY_ERRNOS:
                return 0
            raise serial.SerialException(f'write failed: {exc}') from exc

    @staticmethod
    def _direct_io(stream: ByteStream) -> _DirectIO | None:
        if _PosixSerial is None or not isinstance(stream, _PosixSerial):
            return None
        fd = getattr(stream, 'fd', None)
        abort_r = getattr(stream, 'pipe_abort_read_r', None)
        if not isinstance(fd, int) or not isinstance(abort_r, int) or fd < 0 or abort_r < 0:
            return None
        return _DirectIO(fd, abort_r)

    def _read(self, stream: ByteStream) -> bytes:
        """Up to `_MAX_CHUNK` bytes, or b'' after the read timeout or a cancel."""
        direct = self._direct
        if direct is None:
            waiting = getattr(stream, 'in_waiting', 0) or 0
            return stream.read(min(max(1, int(waiting)), _MAX_CHUNK))
        ready, _, _ = select.select(direct, (), (), self._read_timeout_s)
        if not ready:
            return b''
        if direct.abort_r in ready:  # cancel_read(): drain the abort pipe like pyserial
            os.read(direct.abort_r, 1000)
            return b''
        # From here until the lines are recorded the bytes are neither waiting at the port
        # nor handed over; a thread that waits for the GIL meanwhile must not look silent.
        self._reading = True
        try:
            chunk = os.read(direct.fd, _MAX_CHUNK)
        except OSError as exc:
            if exc.errno in _RETRY_ERRNOS:
                return b''
            raise serial.SerialException(f'read failed: {exc}') from exc
        if not chunk:
            raise serial.SerialException(
                'device reports readiness to read but returned no data '
                '(device disconnected or multiple access on port?)')
        return chunk

    def _install(self, stream: ByteStream) -> None:
        with self._write_lock:
            self._stream = stream
            self._direct = self._direct_io(stream)
        self._ever_connected = True
        self._drop_reason = None
        self._policy.record_success()
        self._lines.reset(resync=True)
        self._flush_input()
        if self._on_connected is not None:
            self._call(self._on_connected, self._clock(), self.url)

    def _flush_input(self) -> None:
        stream = self._stream
        flush = getattr(stream, 'reset_input_buffer', None)
        if callable(flush):
            try:
                flush()
            except (serial.SerialException, OSError) as exc:
                self._last_error = describe_link_error(self.url, exc)

    def _cancel_read(self) -> None:
        # Under the write lock: `_close_stream` takes the stream out under it before closing,
        # so the abort pipe written here is still open (never a recycled descriptor number).
        with self._write_lock:
            cancel = getattr(self._stream, 'cancel_read', None)
            if callable(cancel):
                try:
                    cancel()
                except (serial.SerialException, OSError, AttributeError, TypeError):
                    pass  # the stream is closing; the read timeout bounds the wait anyway

    def _close_stream(self) -> None:
        with self._write_lock:
            stream, self._stream = self._stream, None
            self._direct = None
        if stream is not None:
            try:
                stream.close()
            except (serial.SerialException, OSError) as exc:
                self._last_error = describe_link_error(self.url, exc)

    def _call(self, callback: Callable[..., object], *args: object) -> None:
        try:
            callback(*args)
        except Exception as exc:
            self._callback_errors += 1
            self._last_error = f'callback {getattr(callback, "__name__", callback)!r} raised ' \
                               f'{type(exc).__name__}: {exc}'
            if self._on_error is not None and callback is not self._on_error:
                try:
                    self._on_error(self._clock(), self._last_error)
                except Exception:
                    self._callback_errors += 1

    def _lose(self, reason: str) -> None:
        self._close_stream()
        self._losses += 1
        self._last_error = reason
        self._policy.record_failure()
        if self._on_lost is not None:
            self._call(self._on_lost, self._clock(), reason)

    def _run(self) -> None:
        try:
            self._read_loop()
        finally:
            self._reader_tid = None
            with self._exit_lock:
                self._reader_running = False
                close = self._close_on_exit
            if close:  # close() came while this thread was still running
                self._close_stream()

    def _read_loop(self) -> None:
        self._reader_tid = threading.get_native_id()
        if self._thread_setup is not None:
            self._call(self._thread_setup)
        while not self._stop.is_set():
            stream = self._stream
            if stream is None:
                self._reconnect_once()
                continue
            reason = self._drop_reason
            if reason is not None:
                self._lose(reason)
                continue
            try:
                chunk = self._read(stream)
            except (serial.SerialException, OSError, TypeError, ValueError) as exc:
                self._reading = False
                # TypeError/ValueError: pyserial on a descriptor that vanished under it.
                if self._stop.is_set():
                    break
                self._lose(describe_link_error(self.url, exc))
                continue
            if not chunk:  # read timeout (or a cancel): the stream was quiet
                self._reading = False
                self._lines.quiet()
                continue
            stamp = self._clock()
            self._bytes_read += len(chunk)
            lines = self._lines.feed(chunk)
            if lines:
                self._last_read = stamp
            self._reading = False
            if self._on_chunk is not None:
                if lines:
                    self._call(self._on_chunk, lines, stamp)
                continue
            for line, overflow in lines:
                self._call(self._on_line, line, overflow, stamp)

    def _reconnect_once(self) -> None:
        if self._stop.wait(self._policy.time_until_next()):
            return
        try:
            stream = self._opener(self.url, self._baudrate, self._read_timeout_s,
                                  write_timeout_s=self._write_timeout_s)
        except LinkError as exc:
            self._connect_failures += 1
            self._last_error = str(exc)
            self._policy.record_failure()
            if self._on_error is not None:
                self._call(self._on_error, self._clock(), str(exc))
            return
        if self._ever_connected:  # the first successful open of a start retry is no reconnect
            self._reconnects += 1
        self._install(stream)
