# SPDX-License-Identifier: Apache-2.0
"""ATI Net F/T box emulator: RDT over UDP with the real codecs (for tests and demos).

Serves the 8-byte requests and streams 36-byte big-endian records (`rdt_codec`) from a UDP
socket, by default on ``127.0.0.1`` with an ephemeral port. Device behaviours it reproduces
(hardware_protocols §4):

* one client per box: a new start request redirects the stream to its sender;
* **every start request opens a new stream numbered from 1** (``rdt_sequence``), while
  ``ft_sequence`` keeps counting across streams until the box restarts (§4.3);
* ``sample_count``, real-time (0x0002) and buffered (0x0003) streaming, stop (0x0000);
* the device bias (0x0042) subtracts the current reading inside the box and **stops the
  stream** until the next start request (``stop_on_bias``, on by default; §4.7);
* latch reset (0x0041) clears the status word;
* status words on demand (`set_status`, e.g. ``0x80020000``: the box keeps streaming at its
  rate with the error bits set) and values beyond the measuring range (`inject`
  ``out_of_range``; the range is served as ``cfgmr``) (§4.5);
* a reboot (`reboot`): streaming stops, the client is forgotten, both counters restart, the
  status word and the device bias are lost, requests are ignored while it boots (§4.7);
* a stream that stops on its own (`stop_stream`), as after a device bias;
* ``/netftapi2.xml`` over HTTP (``cfgcpf``, ``cfgcpt``, units, ``cfgmr``, ``comrdtrate``,
  ``setbias``) on a chosen or ephemeral port (§4.1, §4.4).

Faults for tests: dropped, duplicated, reordered, truncated and garbage datagrams, sequence
numbers near the 32-bit wrap, pauses.

The wrench comes from ``force_source(t)`` (N, N·m, sensor frame; ``t`` = seconds since
start) plus offsets and Gaussian noise, converted with the box's counts per unit.

Run ``python -m slip_gripper_driver.core.netft_emulator --help``.
"""
from __future__ import annotations

import argparse
import http.server
import math
import select
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Sequence

import numpy as np

from slip_gripper_driver.core.ft_scale import (ForceTorqueScale, force_unit_factor,
                                               torque_unit_factor)
from slip_gripper_driver.core.rdt_codec import (RDT_PORT, DatagramError, RdtCommand,
                                                decode_request, encode_record)

ForceSource = Callable[[float], Sequence[float]]

#: Measuring range of a Mini40 (SI-40-2): |Fx|, |Fy|, |Fz| [N], |Tx|, |Ty|, |Tz| [N·m].
MINI40_RANGE = (40.0, 40.0, 120.0, 2.0, 2.0, 2.0)


def config_xml(scale: ForceTorqueScale, rate_hz: float, address: str,
               measuring_range: Sequence[float] = MINI40_RANGE,
               bias_counts: Sequence[int] = (0,) * 6) -> str:
    """A ``netftapi2.xml`` document describing the emulated box (range given in N, N·m)."""
    f = force_unit_factor(scale.force_unit)
    m = torque_unit_factor(scale.torque_unit)
    cfgmr = [v / f for v in measuring_range[:3]] + [v / m for v in measuring_range[3:]]
    tags = {
        'setserial': 'EMU00001', 'cfgcpf': f'{scale.counts_per_force:g}',
        'cfgcpt': f'{scale.counts_per_torque:g}', 'scfgfu': scale.force_unit,
        'scfgtu': scale.torque_unit, 'cfgmr': ';'.join(f'{v:g}' for v in cfgmr),
        'setbias': ';'.join(str(int(v)) for v in bias_counts),
        'comrdte': 'true', 'comrdtrate': f'{rate_hz:g}', 'runstat': '0', 'netip': address}
    body = ''.join(f'<{k}>{v}</{k}>' for k, v in tags.items())
    return f'<?xml version="1.0"?><netft>{body}</netft>'


class NetFTEmulator:
    """One emulated box; see the module docstring.

    Args:
        host: Address to bind.
        port: UDP port (0 = ephemeral; the real box uses 49152).
        rate_hz: Record rate [Hz].
        scale: Counts per unit and units of the box (1e6 counts per N and per N·m default).
        force_source: ``t [s] → (Fx, Fy, Fz, Tx, Ty, Tz)`` in N and N·m; zero when None.
        offsets: Constant offset added to the wrench (what biasing removes).
        noise_std: Standard deviation of Gaussian noise per component.
        seed: Noise/garbage seed.
        buffer_size: Records per datagram in buffered mode.
        serve_http: Also serve ``/netftapi2.xml`` over HTTP.
        http_port: Its port (0 = ephemeral; the real box uses 80).
        rdt_sequence_start: First ``rdt_sequence`` of every stream (the box: 1; near 2³² to
            test the wrap).
        ft_sequence_start: ``ft_sequence`` after power-up.
        stop_on_bias: A device bias (0x0042) stops the stream until the next start request.
        measuring_range: ``cfgmr`` in N, N·m (|Fx|, |Fy|, |Fz|, |Tx|, |Ty|, |Tz|).
    """

    def __init__(self, *, host: str = '127.0.0.1', port: int = 0, rate_hz: float = 1000.0,
                 scale: ForceTorqueScale = ForceTorqueScale(1.0e6, 1.0e6, 'N', 'N-m'),
                 force_source: ForceSource | None = None,
                 offsets: Sequence[float] = (0.0,) * 6, noise_std: float = 0.0, seed: int = 0,
                 buffer_size: int = 4, serve_http: bool = False, http_port: int = 0,
                 rdt_sequence_start: int = 1, ft_sequence_start: int = 0,
                 stop_on_bias: bool = True,
                 measuring_range: Sequence[float] = MINI40_RANGE) -> None:
        if rate_hz <= 0.0:
            raise ValueError('rate_hz must be > 0')
        if len(measuring_range) != 6:
            raise ValueError('measuring_range needs six values')
        self.scale = scale
        self.stop_on_bias = stop_on_bias
        self.measuring_range = tuple(float(v) for v in measuring_range)
        self._rdt_start = rdt_sequence_start
        self._ft_start = ft_sequence_start
        self._http_port_wanted = http_port
        self.rate_hz = rate_hz
        self.force_source = force_source
        self.offsets = tuple(float(v) for v in offsets)
        self.noise_std = noise_std
        self.buffer_size = max(1, buffer_size)
        self.lock = threading.Lock()
        self._rng = np.random.default_rng(seed)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.bind((host, port))
        self._sock.setblocking(False)
        self._serve_http = serve_http
        self._http: http.server.ThreadingHTTPServer | None = None
        self._http_thread: threading.Thread | None = None
        self._thread: threading.Thread | None = None
        self._wake_r, self._wake_w = socket.socketpair()
        self._running = False
        self._t0 = 0.0
        # stream state (guarded by lock)
        self.client: tuple[str, int] | None = None
        self._streaming = False
        self._buffered = False
        self._remaining = 0
        self._next_due = 0.0
        self._rdt_seq = rdt_sequence_start
        self._ft_seq = ft_sequence_start
        self._status = 0
        self._bias_counts: tuple[int, ...] = (0,) * 6
        self._paused = False
        self._booting_until = -math.inf
        self._held: bytes | None = None
        self._pending_batch: list[bytes] = []
        # injections: counts of upcoming records to affect
        self._drop = 0
        self._duplicate = 0
        self._reorder = 0
        self._truncate = 0
        self._garbage = 0
        self._out_of_range = 0
        # counters
        self.requests = 0
        self.bad_requests = 0
        self.ignored_requests = 0
        self.starts = 0
        self.stops = 0
        self.biases = 0
        self.latch_resets = 0
        self.reboots = 0
        self.records_sent = 0
        self.datagrams_sent = 0

    @property
    def address(self) -> tuple[str, int]:
        """Bound ``(host, port)``."""
        host, port = self._sock.getsockname()[:2]
        return host, port

    @property
    def http_port(self) -> int:
        """HTTP port of ``/netftapi2.xml`` (0 when not served)."""
        return self._http.server_address[1] if self._http is not None else 0

    @property
    def streaming(self) -> bool:
        """True while a client is being streamed to."""
        return self._streaming

    def start(self) -> tuple[str, int]:
        """Start the server thread (and the HTTP server); returns `address`."""
        self._running = True
        self._t0 = time.monotonic()
        self._thread = threading.Thread(target=self._run, name='netft-emulator', daemon=True)
        self._thread.start()
        if self._serve_http:
            emulator = self

            class Handler(http.server.BaseHTTPRequestHandler):
                def do_GET(self) -> None:
                    if self.path.split('?')[0] != '/netftapi2.xml':
                        self.send_error(404)
                        return
                    with emulator.lock:
                        bias = emulator._bias_counts
                    xml = config_xml(emulator.scale, emulator.rate_hz, emulator.address[0],
                                     emulator.measuring_range, bias).encode()
                    self.send_response(200)
                    self.send_header('Content-Type', 'text/xml')
                    self.send_header('Content-Length', str(len(xml)))
                    self.end_headers()
                    self.wfile.write(xml)

                def log_message(self, format: str, *args: object) -> None:
                    del format, args  # quiet

            self._http = http.server.ThreadingHTTPServer(
                (self.address[0], self._http_port_wanted), Handler)
            self._http_thread = threading.Thread(target=self._http.serve_forever,
                                                 kwargs={'poll_interval': 0.02},
                                                 name='netft-emulator-http', daemon=True)
            self._http_thread.start()
        return self.address

    def stop(self) -> None:
        """Stop the threads and close the sockets."""
        self._running = False
        try:
            self._wake_w.send(b'x')
        except OSError:
            pass  # already closed
        if self._thread is not None:
            self._thread.join(2.0)
            self._thread = None
        if self._http is not None:
            self._http.shutdown()
            self._http.server_close()
            self._http = None
        for s in (self._sock, self._wake_r, self._wake_w):
            s.close()

    # ------------------------------------------------------------------ fault injection
    def inject(self, *, drop: int = 0, duplicate: int = 0, reorder: int = 0, truncate: int = 0,
               garbage: int = 0, out_of_range: int = 0) -> None:
        """Affect the next records: drop, send twice, swap with the following one, send
        truncated (20 bytes), send a garbage datagram (random length) before them, or report
        Fz at 1.5 times the measuring range (status word unchanged)."""
        with self.lock:
            self._drop += drop
            self._duplicate += duplicate
            self._reorder += reorder
            self._truncate += truncate
            self._garbage += garbage
            self._out_of_range += out_of_range

    def set_status(self, status: int) -> None:
        """Status word of the following records."""
        with self.lock:
            self._status = status & 0xFFFFFFFF

    def pause(self, paused: bool = True) -> None:
        """Stop/resume sending without ending the stream (the sequence keeps counting)."""
        with self.lock:
            self._paused = paused

    def reboot(self, boot_time_s: float = 0.0) -> None:
        """The box restarts: streaming stops, the client is forgotten, both counters restart,
        the status word and the device bias are lost; requests are ignored for
        ``boot_time_s`` [s]."""
        with self.lock:
            self.reboots += 1
            self._streaming = False
            self.client = None
            self._rdt_seq = self._rdt_start
            self._ft_seq = self._ft_start
            self._status = 0
            self._bias_counts = (0,) * 6
            self._pending_batch = []
            self._booting_until = time.monotonic() + boot_time_s

    def stop_stream(self) -> None:
        """Stop sending until the next start request, as a box may after a device bias."""
        with self.lock:
            self._streaming = False
            self._pending_batch = []

    @property
    def bias_counts(self) -> tuple[int, ...]:
        """Device bias in counts (``setbias``)."""
        with self.lock:
            return self._bias_counts

    def set_sequences(self, rdt_sequence: int, ft_sequence: int) -> None:
        """Jump the sequence counters (e.g. to just below 2³², or back to 0 = box reset)."""
        with self.lock:
            self._rdt_seq = rdt_sequence
            self._ft_seq = ft_sequence

    # ------------------------------------------------------------------ internals
    def _wrench_counts(self, t: float) -> tuple[int, ...]:
        wrench = self.force_source(t) if self.force_source is not None else (0.0,) * 6
        values = [float(wrench[i]) + self.offsets[i] for i in range(6)]
        if self.noise_std > 0.0:
            values = [v + self.noise_std * float(self._rng.standard_normal()) for v in values]
        counts = self.scale.to_counts(values)
        return tuple(c - b for c, b in zip(counts, self._bias_counts))

    def _run(self) -> None:
        period = 1.0 / self.rate_hz
        while self._running:
            with self.lock:
                due = self._next_due if self._streaming else math.inf
            timeout = min(0.05, max(0.0, due - time.monotonic()))
            ready, _, _ = select.select([self._sock, self._wake_r], [], [], timeout)
            if self._wake_r in ready:
                break
            if self._sock in ready:
                self._serve_requests()
            now = time.monotonic()
            with self.lock:
                if not self._streaming or now < self._next_due:
                    continue
                n_due = min(int((now - self._next_due) / period) + 1, 50)
                self._next_due += n_due * period
                if now - self._next_due > 0.1:  # far behind: skip ahead rather than burst
                    self._next_due = now + period
                out = self._produce(n_due, now - self._t0)
            for datagram in out:
                self._sendto(datagram)

    def _serve_requests(self) -> None:
        while True:
            try:
                data, peer = self._sock.recvfrom(2048)
            except BlockingIOError:
                return
            except OSError:
                return
            with self.lock:
                self.requests += 1
                if time.monotonic() < self._booting_until:
                    self.ignored_requests += 1
                    continue
                try:
                    command, count = decode_request(data)
                except DatagramError:
                    self.bad_requests += 1
                    continue
                self._command(command, count, peer)

    def _command(self, command: int, count: int, peer: tuple[str, int]) -> None:
        if command in (RdtCommand.START_REALTIME, RdtCommand.START_BUFFERED):
            self.starts += 1
            self.client = peer  # a new start redirects the stream (one client per box)
            self._streaming = True
            self._buffered = command == RdtCommand.START_BUFFERED
            self._remaining = count
            self._next_due = time.monotonic()
            self._pending_batch = []
            self._rdt_seq = self._rdt_start  # every stream is numbered from 1
            self._held = None
        elif command == RdtCommand.STOP:
            self.stops += 1
            self._streaming = False
        elif command == RdtCommand.SET_BIAS:
            self.biases += 1
            self._bias_counts = (0,) * 6
            self._bias_counts = self._wrench_counts(time.monotonic() - self._t0)
            if self.stop_on_bias:
                self._streaming = False
                self._pending_batch = []
        elif command == RdtCommand.RESET_LATCH:
            self.latch_resets += 1
            self._status = 0
        else:
            self.bad_requests += 1

    def _produce(self, n: int, t: float) -> list[bytes]:
        """Datagrams for ``n`` due records (lock held)."""
        out: list[bytes] = []
        for _ in range(n):
            if not self._streaming:
                break
            counts = self._wrench_counts(t)
            if self._out_of_range > 0:
                self._out_of_range -= 1
                beyond = self.scale.to_counts((0.0, 0.0, 1.5 * max(self.measuring_range[2], 1.0),
                                               0.0, 0.0, 0.0))
                counts = (*counts[:2], beyond[2], *counts[3:])
            record = encode_record(self._rdt_seq, self._ft_seq, self._status, counts)
            self._rdt_seq = (self._rdt_seq + 1) & 0xFFFFFFFF
            self._ft_seq = (self._ft_seq + 1) & 0xFFFFFFFF
            if self._remaining > 0:
                self._remaining -= 1
                if self._remaining == 0:
                    self._streaming = False
            if self._paused:
                continue
            if self._garbage > 0:
                self._garbage -= 1
                length = int(self._rng.integers(1, 100))
                if length % 36 == 0:
                    length += 1
                out.append(self._rng.integers(0, 256, size=length, dtype=np.uint8).tobytes())
            if self._drop > 0:
                self._drop -= 1
                continue
            if self._truncate > 0:
                self._truncate -= 1
                out.append(record[:20])
                continue
            if self._reorder > 0 and self._held is None:
                self._reorder -= 1
                self._held = record
                continue
            copies = 1
            if self._duplicate > 0:
                self._duplicate -= 1
                copies = 2
            for _ in range(copies):
                out.extend(self._emit(record))
            if self._held is not None:
                out.extend(self._emit(self._held))
                self._held = None
        return out

    def _emit(self, record: bytes) -> list[bytes]:
        self.records_sent += 1
        if not self._buffered:
            return [record]
        self._pending_batch.append(record)
        if len(self._pending_batch) < self.buffer_size:
            return []
        batch, self._pending_batch = self._pending_batch, []
        return [b''.join(batch)]

    def _sendto(self, datagram: bytes) -> None:
        client = self.client
        if client is None:
            return
        try:
            self._sock.sendto(datagram, client)
            self.datagrams_sent += 1
        except OSError:
            pass  # the client went away; UDP has no connection to report it on


def main(argv: Sequence[str] | None = None) -> int:
    """Console entry point: serve one emulated box until Ctrl-C or ``--duration``."""
    parser = argparse.ArgumentParser(
        description='ATI Net F/T RDT emulator on UDP (real 8/36-byte codecs): streams numbered '
                    'from 1 per start request, device bias stops the stream, error status '
                    'words and reboots on demand.',
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument('--host', default='127.0.0.1', help='address to bind')
    parser.add_argument('--port', type=int, default=RDT_PORT, help='RDT UDP port (0 = any)')
    parser.add_argument('--rate', type=float, default=1000.0, help='record rate [Hz]')
    parser.add_argument('--counts-per-force', type=float, default=1.0e6,
                        help='cfgcpf [counts/N]')
    parser.add_argument('--counts-per-torque', type=float, default=1.0e6,
                        help='cfgcpt [counts/N-m]')
    parser.add_argument('--range', type=float, nargs=6, default=list(MINI40_RANGE),
                        metavar=('FX', 'FY', 'FZ', 'TX', 'TY', 'TZ'),
                        help='measuring range cfgmr [N, N-m]')
    parser.add_argument('--fz', type=float, default=0.0, help='constant Fz [N]')
    parser.add_argument('--offset-fz', type=float, default=0.0,
                        help='Fz offset that a bias removes [N]')
    parser.add_argument('--noise', type=float, default=0.0,
                        help='Gaussian noise std per component [N, N-m]')
    parser.add_argument('--status', type=lambda text: int(text, 0), default=0,
                        help='status word of every record, e.g. 0x80020000 (saturation)')
    parser.add_argument('--stop-on-bias', action=argparse.BooleanOptionalAction, default=True,
                        help='a device bias (0x0042) stops the stream until the next start')
    parser.add_argument('--reboot-every', type=float, default=0.0,
                        help='reboot the box every this many seconds (bias lost, numbering '
                             'restarts); 0 = never')
    parser.add_argument('--http', action='store_true', help='serve /netftapi2.xml')
    parser.add_argument('--http-port', type=int, default=0,
                        help='HTTP port of /netftapi2.xml (0 = any; the box uses 80)')
    parser.add_argument('--duration', type=float, default=0.0,
                        help='seconds to run; 0 = until Ctrl-C')
    args = parser.parse_args(argv)
    fz = args.fz
    emu = NetFTEmulator(
        host=args.host, port=args.port, rate_hz=args.rate,
        scale=ForceTorqueScale(args.counts_per_force, args.counts_per_torque, 'N', 'N-m'),
        force_source=lambda _t: (0.0, 0.0, fz, 0.0, 0.0, 0.0),
        offsets=(0.0, 0.0, args.offset_fz, 0.0, 0.0, 0.0), noise_std=args.noise,
        serve_http=args.http, http_port=args.http_port, stop_on_bias=args.stop_on_bias,
        measuring_range=args.range)
    emu.set_status(args.status)
    host, port = emu.start()
    print(f'Net F/T emulator on {host}:{port}'
          + (f', http://{host}:{emu.http_port}/netftapi2.xml' if args.http else ''), flush=True)
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set())
                for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        deadline = time.monotonic() + args.duration if args.duration > 0.0 else math.inf
        next_reboot = time.monotonic() + args.reboot_every if args.reboot_every > 0 else math.inf
        while not stop.is_set() and time.monotonic() < deadline:
            stop.wait(max(0.0, min(deadline, next_reboot, time.monotonic() + 1.0)
                          - time.monotonic()))
            if time.monotonic() >= next_reboot:
                emu.reboot()
                emu.set_status(args.status)
                next_reboot += args.reboot_every
    finally:
        emu.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    print(f'records sent: {emu.records_sent}, starts: {emu.starts}, stops: {emu.stops}, '
          f'biases: {emu.biases}, reboots: {emu.reboots}', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
