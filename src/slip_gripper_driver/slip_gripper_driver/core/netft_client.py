# SPDX-License-Identifier: Apache-2.0
"""RDT client of one ATI Net F/T box over UDP: one socket, one reader thread (ROS-free).

A box serves one RDT client: a second start redirects its stream, so exactly one process
owns each box (HW-13). Records are validated (size, sequence), converted to SI with the box's
scale and handed to a callback in order (HW-7, §4.6). What a real box does and the client
handles (hardware_protocols §4.3, §4.7):

* every start request opens a new stream numbered from 1: its first record is accepted at once
  (`SequenceTracker`), nothing is dropped as "out of order";
* a device bias (0x0042) may stop the stream: the start request is re-sent right after it;
* any stream that falls silent for ``restart_after_s`` (at least ten record periods) gets a
  start request from the reader thread at once, then with exponential back-off — not after a
  receive timeout polled by a timer;
* a box restart shows as ``ft_sequence`` going backwards, or as a latched monitor bit cleared
  without a latch-reset request: the sample carries ``device_restart`` (the bias is lost).
"""
from __future__ import annotations

import fcntl
import math
import select
import socket
import struct
import termios
import threading
import time
from collections import deque
from dataclasses import dataclass
from collections.abc import Callable

from slip_cell_common.core.monitors import Level
from slip_cell_common.core.serial_transport import ReconnectPolicy
from slip_gripper_driver.core import udp_arrival
from slip_gripper_driver.core.ft_scale import ForceTorqueScale, Wrench
from slip_gripper_driver.core.netft_status import STATUS_MONITOR_BIT, decode_status
from slip_gripper_driver.core.rdt_codec import (RDT_PORT, DatagramError, RdtCommand,
                                                decode_datagram, encode_request)
from slip_gripper_driver.core.rdt_sequence import SeqVerdict, SequenceTracker

Clock = Callable[[], float]


class NetFTError(RuntimeError):
    """Net F/T failure; the message names the box address."""


@dataclass(frozen=True, slots=True)
class FtSample:
    """One accepted record in SI.

    Attributes:
        stamp: Acquisition time: when the datagram reached the host, on the injected clock
            [s] (the kernel's arrival stamp where available, else the time it was read).
        rdt_sequence: RDT record counter.
        ft_sequence: Device measurement counter.
        status: Status word.
        wrench: (Fx, Fy, Fz [N], Tx, Ty, Tz [N·m]) in the sensor frame, as measured.
        new_stream: First record of a new stream (numbering restarted).
        device_restart: The box restarted before this record (its device bias is gone).
    """

    stamp: float
    rdt_sequence: int
    ft_sequence: int
    status: int
    wrench: Wrench
    new_stream: bool = False
    device_restart: bool = False


@dataclass(frozen=True)
class NetFTStats:
    """Counters and state of a `NetFTClient`."""

    address: str
    streaming: bool
    datagrams: int
    records: int
    bad_datagrams: int
    accepted: int
    lost: int
    duplicates: int
    out_of_order: int
    resyncs: int
    ft_stalls: int
    ft_restarts: int
    restarts: int  #: start requests re-sent to a silent stream
    new_streams: int  #: streams whose numbering restarted (accepted at once)
    device_restarts: int  #: box restarts seen (ft_sequence backwards, latch cleared)
    bias_restarts: int  #: start requests sent right after a device bias
    socket_errors: int
    status: int
    status_level: Level
    status_text: str
    latched_status: int
    rate_hz: float
    last_stamp: float
    last_error: str
    arrival_stamps: bool = False  #: records are stamped with the kernel's arrival time
    longest_wait_s: float = 0.0  #: longest a datagram waited unread in the socket [s]


class RateEstimator:
    """Events per second over a sliding window of stamps.

    Args:
        window_s: Window length [s].
    """

    def __init__(self, window_s: float = 1.0) -> None:
        self.window_s = window_s
        self._stamps: deque[float] = deque()

    def tick(self, t: float) -> None:
        """Record one event at ``t`` [s]."""
        self._stamps.append(t)
        while self._stamps and self._stamps[0] < t - self.window_s:
            self._stamps.popleft()

    def rate(self, now: float) -> float:
        """Rate [Hz] over the window ending at ``now`` [s] (0 without events)."""
        while self._stamps and self._stamps[0] < now - self.window_s:
            self._stamps.popleft()
        return len(self._stamps) / self.window_s


SampleCallback = Callable[[FtSample], None]


class NetFTClient:
    """RDT client of one Net F/T box: one UDP socket, one reader thread.

    The reader thread wakes when a datagram is pending, drains **every** pending datagram,
    stamps each with the time it reached the host on the injected clock (the kernel's arrival
    stamp, `udp_arrival`: a reader held up by a busy host does not make old records look
    fresh), validates it (size, sequence), converts accepted records to SI and calls
    ``on_sample`` for each, in order (HW-7, §4.6).

    Args:
        address: Box IP or host name.
        scale: Counts → SI conversion (from parameters or `fetch_netft_config`).
        clock: Node clock [s] used for stamps.
        on_sample: Called on the reader thread for every accepted record (must not block).
        port: Box RDT port.
        buffered: Use buffered streaming (0x0003) instead of real-time (0x0002).
        start_retries: Start requests before giving up.
        start_wait_s: Wait for data after each start request [s].
        bind_address: Local address to bind (ephemeral port).
        resync_after: See `SequenceTracker`.
        restart_after_s: Silence after which the reader thread re-sends the start request at
            once [s]; never below ten periods of ``expected_rate_hz``.
        expected_rate_hz: Record rate of the box [Hz].
        restart_initial_s: Delay before the next start request when the first re-sent one
            brought no data [s].
        restart_max_s: Largest such delay [s] (exponential back-off in between).
        thread_setup: Called first on the reader thread (scheduling priority, see
            `realtime.ThreadTuning.apply`); an exception there is recorded in ``last_error``.
        wall_clock: ``CLOCK_REALTIME`` [s] (``time.time``), the clock of the kernel's
            arrival stamps; only differences of it are used (how long a datagram waited).
        arrival_stamps: Use the kernel's arrival stamps where the platform has them.
    """

    def __init__(self, address: str, *, scale: ForceTorqueScale, clock: Clock,
                 on_sample: SampleCallback | None = None, port: int = RDT_PORT,
                 buffered: bool = False, start_retries: int = 10, start_wait_s: float = 0.1,
                 bind_address: str = '', resync_after: int = 16, restart_after_s: float = 0.02,
                 expected_rate_hz: float = 1000.0, restart_initial_s: float = 0.5,
                 restart_max_s: float = 5.0,
                 thread_setup: Callable[[], object] | None = None,
                 wall_clock: Clock = time.time, arrival_stamps: bool = True) -> None:
        self.address = address
        self._wall_clock = wall_clock
        self._want_arrival_stamps = arrival_stamps
        self._arrival_stamps = False
        self._longest_wait_s = 0.0
        self._last_arrival = -math.inf
        self._thread_setup = thread_setup
        self.port = port
        self.scale = scale
        self._clock = clock
        self._on_sample = on_sample
        self._buffered = buffered
        self._start_retries = max(1, start_retries)
        self._start_wait_s = start_wait_s
        self._bind_address = bind_address
        self._tracker = SequenceTracker(resync_after)
        self._restart_policy = ReconnectPolicy(restart_initial_s, restart_max_s, clock=clock)
        self._silence_s = max(restart_after_s, 10.0 / max(expected_rate_hz, 1e-3))
        self._last_start = -math.inf
        self._restarts = 0
        self._bias_restarts = 0
        self._device_restarts = 0
        self._monitor_latched = False
        self._latch_reset_sent = False
        self._rate = RateEstimator()
        self._lock = threading.Lock()
        self._first_data = threading.Event()
        self._sock: socket.socket | None = None
        self._wake_r: socket.socket | None = None
        self._wake_w: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._running = False
        self._streaming = False
        self._latest: FtSample | None = None
        self._datagrams = 0
        self._records = 0
        self._bad = 0
        self._socket_errors = 0
        self._status = 0
        self._latched = 0
        self._last_error = ''

    @property
    def name(self) -> str:
        """``address:port``."""
        return f'{self.address}:{self.port}'

    # ------------------------------------------------------------------ lifecycle
    def open(self) -> None:
        """Create the socket (configure). Receives only from the box.

        Raises:
            NetFTError: The address cannot be resolved or the socket cannot be created.
        """
        if self._sock is not None:
            return
        try:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.bind((self._bind_address, 0))
            sock.connect((self.address, self.port))
            sock.setblocking(False)
            self._arrival_stamps = self._want_arrival_stamps and udp_arrival.enable(sock)
        except OSError as exc:
            raise NetFTError(f'Net F/T {self.name}: cannot open UDP socket: {exc}') from exc
        self._sock = sock
        self._wake_r, self._wake_w = socket.socketpair()
        self._running = True
        self._thread = threading.Thread(target=self._run, name=f'netft-reader {self.name}',
                                        daemon=True)
        self._thread.start()

    def start(self) -> None:
        """Request streaming and wait for the first record (activate).

        Sends the start command up to ``start_retries`` times, waiting ``start_wait_s`` for
        data after each.

        Raises:
            NetFTError: No data after all retries (the message names the box).
        """
        if self._sock is None:
            self.open()
        self._first_data.clear()
        for _ in range(self._start_retries):
            self._send_start()
            if self._first_data.wait(self._start_wait_s):
                self._restart_policy.record_success()
                self._streaming = True
                return
        raise NetFTError(f'Net F/T {self.name}: no RDT data after {self._start_retries} start '
                         f'requests ({self._start_wait_s:.2f} s each)'
                         + (f'; last error: {self._last_error}' if self._last_error else ''))

    def stop(self) -> None:
        """Send the stop command (deactivate); the socket stays open."""
        if self._sock is not None:
            self._send(encode_request(RdtCommand.STOP, 0))
        self._streaming = False

    def close(self) -> None:
        """Stop streaming, end the reader thread and close the socket (cleanup/shutdown)."""
        if self._sock is None:
            return
        self.stop()
        self._running = False
        if self._wake_w is not None:
            try:
                self._wake_w.send(b'x')
            except OSError:
                pass  # the thread also exits on its own when the socket closes
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(1.0)
        self._thread = None
        for s in (self._sock, self._wake_r, self._wake_w):
            if s is not None:
                s.close()
        self._sock = self._wake_r = self._wake_w = None

    def supervise(self, now: float, receive_timeout_s: float = 0.1) -> bool:
        """Whether a started stream is live at ``now`` [s] (a record within
        ``receive_timeout_s``).

        The restart itself needs no timer: the reader thread re-sends the start request as
        soon as the stream has been silent for ``restart_after_s`` (box rebooted, cable
        replugged, stream stopped by a device bias), then with exponential back-off. UDP has
        no connection to lose, so this is the reconnection.
        """
        if not self._streaming or self._sock is None:
            return False
        latest = self._latest
        return latest is not None and now - latest.stamp <= receive_timeout_s

    def set_device_bias(self) -> None:
        """Command the box's software bias (0x0042; affects every client of the box).

        A real box may stop streaming after it (hardware_protocols §4.7), so the start request
        follows at once; the new stream is numbered from 1 and accepted as such.
        """
        self._send(encode_request(RdtCommand.SET_BIAS, 0))
        if self._streaming:
            with self._lock:
                self._bias_restarts += 1
            self._send_start()

    def reset_latch(self) -> None:
        """Reset the box's threshold latch (0x0041) and the client's latched status."""
        with self._lock:
            self._latched = 0
            self._latch_reset_sent = True
        self._send(encode_request(RdtCommand.RESET_LATCH, 0))

    def input_pending(self) -> int:
        """Bytes of the next datagram waiting unread in the socket (0: none or closed): the
        box has sent records this client's reader has not taken yet."""
        sock = self._sock
        if sock is None:
            return 0
        try:
            buf = fcntl.ioctl(sock.fileno(), termios.FIONREAD, b'\0\0\0\0')
        except (OSError, ValueError):  # closed meanwhile
            return 0
        return int(struct.unpack('i', buf)[0])

    # ------------------------------------------------------------------ outputs
    def latest(self) -> FtSample | None:
        """Newest accepted sample."""
        return self._latest

    def stats(self, now: float | None = None) -> NetFTStats:
        """Counter snapshot; ``now`` [s] for the rate (defaults to the injected clock)."""
        t = self._clock() if now is None else now
        with self._lock:
            tr = self._tracker
            info = decode_status(self._status)
            latest = self._latest
            return NetFTStats(
                address=self.name, streaming=self._streaming, datagrams=self._datagrams,
                records=self._records, bad_datagrams=self._bad, accepted=tr.accepted,
                lost=tr.lost, duplicates=tr.duplicates, out_of_order=tr.out_of_order,
                resyncs=tr.resyncs, ft_stalls=tr.ft_stalls, ft_restarts=tr.ft_restarts,
                restarts=self._restarts, new_streams=tr.new_streams,
                device_restarts=self._device_restarts, bias_restarts=self._bias_restarts,
                socket_errors=self._socket_errors, status=self._status,
                status_level=info.level, status_text=info.text, latched_status=self._latched,
                rate_hz=self._rate.rate(t),
                last_stamp=latest.stamp if latest is not None else math.nan,
                last_error=self._last_error, arrival_stamps=self._arrival_stamps,
                longest_wait_s=self._longest_wait_s)

    # ------------------------------------------------------------------ internals
    def _send_start(self) -> None:
        """Send the start request; the box numbers the new stream from 1."""
        command = RdtCommand.START_BUFFERED if self._buffered else RdtCommand.START_REALTIME
        with self._lock:
            self._tracker.expect_new_stream()
            self._last_start = self._clock()
        self._send(encode_request(command, 0))

    def _restart_if_silent(self) -> None:
        """Reader thread: re-send the start request to a stream silent for ``_silence_s``."""
        if not self._streaming:
            return
        latest = self._latest
        last = max(latest.stamp if latest is not None else -math.inf, self._last_start)
        if self._clock() - last < self._silence_s or not self._restart_policy.due():
            return
        self._restart_policy.record_failure()
        with self._lock:
            self._restarts += 1
        self._send_start()

    def _send(self, data: bytes) -> None:
        sock = self._sock
        if sock is None:
            return
        try:
            sock.send(data)
        except OSError as exc:
            with self._lock:
                self._socket_errors += 1
                self._last_error = f'send to {self.name} failed: {exc}'

    def _run(self) -> None:
        sock, wake = self._sock, self._wake_r
        assert sock is not None and wake is not None
        if self._thread_setup is not None:
            try:
                self._thread_setup()
            except Exception as exc:
                with self._lock:
                    self._last_error = f'{self.name}: thread setup failed: {exc}'
        while self._running:
            timeout = self._silence_s if self._streaming else 1.0
            try:
                ready, _, _ = select.select([sock, wake], [], [], timeout)
            except (OSError, ValueError):
                break  # socket closed under us: shutting down
            if wake in ready:
                break
            if sock in ready:
                self._drain(sock)
            self._restart_if_silent()

    def _drain(self, sock: socket.socket) -> None:
        arrival_stamps = self._arrival_stamps
        while True:
            try:
                if arrival_stamps:
                    data, waited = udp_arrival.receive(sock, 65536, self._wall_clock)
                else:
                    data, waited = sock.recv(65536), None
            except BlockingIOError:
                return
            except ConnectionRefusedError as exc:
                # ICMP port unreachable from an earlier send: nothing listens at the box port.
                with self._lock:
                    self._socket_errors += 1
                    self._last_error = f'{self.name}: {exc}'
                continue
            except OSError as exc:
                with self._lock:
                    self._socket_errors += 1
                    self._last_error = f'receive from {self.name} failed: {exc}'
                return
            stamp = self._clock()
            if waited is not None:
                if waited > self._longest_wait_s:
                    self._longest_wait_s = waited
                stamp -= waited
            # Never before the previous datagram: read-time stamps (before the kernel's stamping
            # is on) and arrival stamps must not interleave backwards.
            if stamp < self._last_arrival:
                stamp = self._last_arrival
            self._last_arrival = stamp
            self._handle(data, stamp)

    def _handle(self, data: bytes, stamp: float) -> None:
        samples: list[FtSample] = []
        tracker = self._tracker
        with self._lock:
            self._datagrams += 1
            try:
                records = decode_datagram(data)
            except DatagramError as exc:
                self._bad += 1
                self._last_error = f'{self.name}: {exc}'
                return
            for rec in records:
                self._records += 1
                verdict = tracker.update(rec.rdt_sequence, rec.ft_sequence)
                if verdict in (SeqVerdict.DUPLICATE, SeqVerdict.OLD):
                    continue
                restarted = tracker.restarted or self._latch_lost(rec.status)
                if restarted:
                    self._device_restarts += 1
                self._status = rec.status
                self._latched |= rec.status
                sample = FtSample(stamp, rec.rdt_sequence, rec.ft_sequence, rec.status,
                                  self.scale.to_si(rec.counts),
                                  verdict == SeqVerdict.NEW_STREAM, restarted)
                self._latest = sample
                self._rate.tick(stamp)
                samples.append(sample)
        if samples:
            self._first_data.set()
            if self._restart_policy.failures:
                self._restart_policy.record_success()
        callback = self._on_sample
        if callback is not None:
            for sample in samples:
                callback(sample)

    def _latch_lost(self, status: int) -> bool:
        """A latched monitor bit disappeared without a reset request: the box restarted
        (lock held)."""
        latched = bool(status & STATUS_MONITOR_BIT)
        lost = self._monitor_latched and not latched and not self._latch_reset_sent
        if not latched:
            self._latch_reset_sent = False
        self._monitor_latched = latched
        return lost

