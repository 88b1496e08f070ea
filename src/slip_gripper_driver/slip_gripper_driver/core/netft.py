# SPDX-License-Identifier: Apache-2.0
"""ATI Net F/T Raw Data Transfer (RDT) over UDP: codecs, scaling, bias and a client.

Protocol (hardware_protocols spec §4), big-endian:

* Request, host → box port 49152, 8 bytes ``'>HHI'``: header 0x1234, command, sample count
  (0 = until stopped). Commands: 0x0000 stop, 0x0002 start real-time streaming, 0x0003 start
  buffered streaming, 0x0041 reset the threshold latch, 0x0042 set the software bias (inside
  the box, for every client).
* Record, box → host, 36 bytes ``'>IIIiiiiii'``: rdt_sequence, ft_sequence, status, then
  Fx, Fy, Fz, Tx, Ty, Tz in counts. A datagram holds one record (real-time) or several
  (buffered); any size that is not a positive multiple of 36 is rejected.
* Scaling: ``F = counts / cfgcpf`` in the box's force unit (``scfgfu``), ``T = counts /
  cfgcpt`` in its torque unit (``scfgtu``); converted to N and N·m here. Never assume the
  counts per unit: read ``netftapi2.xml`` or take them as parameters (HW-7).

Both sequence numbers are 32-bit and wrap; `SequenceTracker` compares them modulo 2³².
A box serves one RDT client: a second start redirects its stream, so exactly one process
owns each box (HW-13).
"""
from __future__ import annotations

import math
import select
import socket
import struct
import threading
import urllib.error
import urllib.request
import xml.etree.ElementTree as ET
from collections import deque
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Callable, NamedTuple, Sequence

from slip_cell_common.core.monitors import Level
from slip_cell_common.core.serial_transport import ReconnectPolicy
from slip_cell_common.core.validation import validate_fields

RDT_PORT = 49152
REQUEST_HEADER = 0x1234
REQUEST = struct.Struct('>HHI')
RECORD = struct.Struct('>IIIiiiiii')
RECORD_SIZE = RECORD.size  # 36
_SEQ_MOD = 1 << 32
_SEQ_HALF = 1 << 31

#: A wrench: (Fx, Fy, Fz [N], Tx, Ty, Tz [N·m]) in the sensor frame.
Wrench = tuple[float, float, float, float, float, float]
Clock = Callable[[], float]


class RdtCommand(IntEnum):
    """RDT request commands."""

    STOP = 0x0000
    START_REALTIME = 0x0002
    START_BUFFERED = 0x0003
    RESET_LATCH = 0x0041
    SET_BIAS = 0x0042


class NetFTError(RuntimeError):
    """Net F/T failure; the message names the box address."""


class DatagramError(ValueError):
    """A datagram that is not a whole number of RDT records."""


# ---------------------------------------------------------------------- codecs
def encode_request(command: int, sample_count: int = 0) -> bytes:
    """8-byte RDT request.

    Args:
        command: `RdtCommand` value.
        sample_count: Records to send (0 = until stopped), < 2³².
    """
    return REQUEST.pack(REQUEST_HEADER, int(command), sample_count)


def decode_request(data: bytes) -> tuple[int, int]:
    """``(command, sample_count)`` of a request (the emulator's side).

    Raises:
        DatagramError: Wrong size or header.
    """
    if len(data) != REQUEST.size:
        raise DatagramError(f'request of {len(data)} bytes, expected {REQUEST.size}')
    header, command, count = REQUEST.unpack(data)
    if header != REQUEST_HEADER:
        raise DatagramError(f'request header 0x{header:04X}, expected 0x{REQUEST_HEADER:04X}')
    return command, count


class RdtRecord(NamedTuple):
    """One RDT record as received (counts).

    Attributes:
        rdt_sequence: Record counter (loss/reorder detection).
        ft_sequence: Device measurement counter (stall/restart detection).
        status: Status word (`decode_status`).
        counts: (Fx, Fy, Fz, Tx, Ty, Tz) [counts].
    """

    rdt_sequence: int
    ft_sequence: int
    status: int
    counts: tuple[int, int, int, int, int, int]


def encode_record(rdt_sequence: int, ft_sequence: int, status: int,
                  counts: Sequence[int]) -> bytes:
    """36-byte record; sequences and status are reduced modulo 2³²."""
    c = [int(v) for v in counts]
    if len(c) != 6:
        raise ValueError(f'need 6 counts, got {len(c)}')
    return RECORD.pack(rdt_sequence % _SEQ_MOD, ft_sequence % _SEQ_MOD, status % _SEQ_MOD, *c)


def decode_datagram(data: bytes) -> list[RdtRecord]:
    """Records of one datagram.

    Raises:
        DatagramError: Empty or not a multiple of 36 bytes (truncated or foreign datagram).
    """
    n = len(data)
    if n == 0 or n % RECORD_SIZE:
        raise DatagramError(f'datagram of {n} bytes is not a multiple of {RECORD_SIZE}')
    return [RdtRecord(v[0], v[1], v[2], (v[3], v[4], v[5], v[6], v[7], v[8]))
            for v in RECORD.iter_unpack(data)]


# ---------------------------------------------------------------------- sequences
class SeqVerdict(IntEnum):
    """How a record's ``rdt_sequence`` relates to the previous accepted one."""

    FIRST = 0
    NEW = 1  #: newer (possibly after a gap)
    DUPLICATE = 2
    OLD = 3  #: older: reordered or late; dropped
    RESYNC = 4  #: accepted after many OLD records in a row (the box restarted its counter)


class SequenceTracker:
    """Wrap-safe tracking of ``rdt_sequence`` and ``ft_sequence``.

    ``d = (seq − last) mod 2³²``: 0 is a duplicate, ``0 < d < 2³¹`` is newer (``d − 1``
    records lost), otherwise older (out of order, dropped). A record that arrives late is
    thus counted once as lost (when the gap appears) and once as out of order. After
    ``resync_after`` consecutive older records the tracker follows the new numbering (a box
    reset restarts its counter). ``ft_sequence`` not advancing between accepted records is a
    stall; going backwards is a device restart.

    Args:
        resync_after: Consecutive older records that force a resynchronisation.
    """

    def __init__(self, resync_after: int = 16) -> None:
        self.resync_after = resync_after
        self.reset()

    def reset(self) -> None:
        """Forget the last sequence numbers and zero the counters."""
        self._last: int | None = None
        self._last_ft: int | None = None
        self._old_run = 0
        self.accepted = 0
        self.lost = 0
        self.duplicates = 0
        self.out_of_order = 0
        self.resyncs = 0
        self.ft_stalls = 0
        self.ft_restarts = 0

    def update(self, rdt_sequence: int, ft_sequence: int) -> SeqVerdict:
        """Classify one record; only FIRST, NEW and RESYNC records should be used."""
        last = self._last
        if last is None:
            verdict = SeqVerdict.FIRST
        else:
            d = (rdt_sequence - last) % _SEQ_MOD
            if d == 0:
                self.duplicates += 1
                return SeqVerdict.DUPLICATE
            if d < _SEQ_HALF:
                self.lost += d - 1
                verdict = SeqVerdict.NEW
            else:
                self._old_run += 1
                if self._old_run < self.resync_after:
                    self.out_of_order += 1
                    return SeqVerdict.OLD
                self.resyncs += 1
                verdict = SeqVerdict.RESYNC
        self._old_run = 0
        self._last = rdt_sequence
        if self._last_ft is not None and verdict != SeqVerdict.RESYNC:
            dft = (ft_sequence - self._last_ft) % _SEQ_MOD
            if dft == 0:
                self.ft_stalls += 1
            elif dft >= _SEQ_HALF:
                self.ft_restarts += 1
        self._last_ft = ft_sequence
        self.accepted += 1
        return verdict


# ---------------------------------------------------------------------- status
STATUS_MONITOR_LATCHED = 0x80010000
STATUS_ERROR_SUMMARY = 0x80000000
_STATUS_BITS: tuple[tuple[int, str], ...] = (
    (0x00020000, 'transducer saturation or A/D error'),
    (0x00100000, 'RDT communication error'),
)


class StatusInfo(NamedTuple):
    """Decoded status word: diagnostic level and text."""

    level: Level
    text: str


def decode_status(status: int) -> StatusInfo:
    """Map a status word to a level (§4.5): 0 OK, 0x80010000 WARN, anything else ERROR."""
    if status == 0:
        return StatusInfo(Level.OK, 'healthy')
    if status == STATUS_MONITOR_LATCHED:
        return StatusInfo(Level.WARN, 'monitor condition latched (0x80010000)')
    parts = [text for bit, text in _STATUS_BITS if status & bit]
    if status & STATUS_ERROR_SUMMARY:
        parts.append('error summary')
    known = STATUS_ERROR_SUMMARY | sum(bit for bit, _ in _STATUS_BITS)
    if status & ~known:
        parts.append('other bits set')
    return StatusInfo(Level.ERROR, f'{", ".join(parts)} (0x{status:08X})')


# ---------------------------------------------------------------------- units
FORCE_UNITS_TO_N: dict[str, float] = {
    'lbf': 4.4482216152605, 'klbf': 4448.2216152605, 'kgf': 9.80665, 'kn': 1000.0, 'n': 1.0}
TORQUE_UNITS_TO_NM: dict[str, float] = {
    'lbfin': 0.1129848290276167, 'lbfft': 1.3558179483314004, 'nmm': 0.001,
    'kgfcm': 0.0980665, 'knm': 1000.0, 'nm': 1.0}


def normalise_unit(unit: str) -> str:
    """Lower-case a unit and drop separators: ``'N-m'``, ``'N m'``, ``'Nm'`` → ``'nm'``."""
    return ''.join(ch for ch in unit.strip().lower() if ch.isalnum())


def force_unit_factor(unit: str) -> float:
    """Newtons per box force unit.

    Raises:
        ValueError: Unknown unit (the message lists the known ones).
    """
    key = normalise_unit(unit)
    if key not in FORCE_UNITS_TO_N:
        raise ValueError(f'unknown force unit {unit!r}; known: lbf, klbf, kgf, kN, N')
    return FORCE_UNITS_TO_N[key]


def torque_unit_factor(unit: str) -> float:
    """N·m per box torque unit.

    Raises:
        ValueError: Unknown unit (the message lists the known ones).
    """
    key = normalise_unit(unit)
    if key not in TORQUE_UNITS_TO_NM:
        raise ValueError(f'unknown torque unit {unit!r}; known: lbf-in, lbf-ft, N-mm, kgf-cm, '
                         f'kN-m, N-m')
    return TORQUE_UNITS_TO_NM[key]


@dataclass(frozen=True)
class ForceTorqueScale:
    """Counts → SI conversion of one box.

    Attributes:
        counts_per_force: ``cfgcpf`` [counts per force unit], > 0.
        counts_per_torque: ``cfgcpt`` [counts per torque unit], > 0.
        force_unit: ``scfgfu`` (e.g. ``'N'``, ``'lbf'``).
        torque_unit: ``scfgtu`` (e.g. ``'N-m'``, ``'Nm'``, ``'lbf-in'``).
    """

    counts_per_force: float
    counts_per_torque: float
    force_unit: str = 'N'
    torque_unit: str = 'N-m'

    def __post_init__(self) -> None:
        for name in ('counts_per_force', 'counts_per_torque'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} must be finite and > 0, got {value!r}')
        force_unit_factor(self.force_unit)
        torque_unit_factor(self.torque_unit)

    @property
    def newton_per_count(self) -> float:
        """[N/count]."""
        return force_unit_factor(self.force_unit) / self.counts_per_force

    @property
    def newton_metre_per_count(self) -> float:
        """[N·m/count]."""
        return torque_unit_factor(self.torque_unit) / self.counts_per_torque

    def to_si(self, counts: Sequence[int]) -> Wrench:
        """Wrench in N and N·m from six counts."""
        f = self.newton_per_count
        m = self.newton_metre_per_count
        return (counts[0] * f, counts[1] * f, counts[2] * f,
                counts[3] * m, counts[4] * m, counts[5] * m)

    def to_counts(self, wrench: Sequence[float]) -> tuple[int, int, int, int, int, int]:
        """Six counts (rounded) from a wrench in N and N·m (the emulator's side)."""
        f = self.newton_per_count
        m = self.newton_metre_per_count
        return (round(wrench[0] / f), round(wrench[1] / f), round(wrench[2] / f),
                round(wrench[3] / m), round(wrench[4] / m), round(wrench[5] / m))


# ---------------------------------------------------------------------- netftapi2.xml
@dataclass(frozen=True)
class NetFTConfig:
    """What the driver needs from ``netftapi2.xml``.

    Attributes:
        scale: Counts per unit and units.
        rdt_rate_hz: ``comrdtrate`` [Hz]; NaN if absent.
        rdt_enabled: ``comrdte``; None if absent.
        values: Every tag with its raw text (``runstat``, ``setbias``, ``cfgmr``, ``netip``…).
    """

    scale: ForceTorqueScale
    rdt_rate_hz: float
    rdt_enabled: bool | None
    values: dict[str, str] = field(default_factory=dict)


def parse_netft_config(xml_text: str | bytes) -> NetFTConfig:
    """Parse the box's ``netftapi2.xml``.

    Raises:
        ValueError: Not XML, or ``cfgcpf``/``cfgcpt``/``scfgfu``/``scfgtu`` missing or invalid.
    """
    try:
        root = ET.fromstring(xml_text)
    except ET.ParseError as exc:
        raise ValueError(f'netftapi2.xml is not valid XML: {exc}') from exc
    values = {child.tag.strip().lower(): (child.text or '').strip() for child in root.iter()
              if child is not root}
    missing = [k for k in ('cfgcpf', 'cfgcpt', 'scfgfu', 'scfgtu') if not values.get(k)]
    if missing:
        raise ValueError(f'netftapi2.xml lacks {", ".join(missing)}')
    try:
        cpf = float(values['cfgcpf'])
        cpt = float(values['cfgcpt'])
    except ValueError as exc:
        raise ValueError(f'netftapi2.xml counts per unit not numeric: {exc}') from exc
    scale = ForceTorqueScale(cpf, cpt, values['scfgfu'], values['scfgtu'])
    try:
        rate = float(values.get('comrdtrate', 'nan'))
    except ValueError:
        rate = math.nan
    enabled_text = values.get('comrdte', '').lower()
    enabled = {'true': True, '1': True, 'false': False, '0': False}.get(enabled_text)
    return NetFTConfig(scale, rate, enabled, values)


def fetch_netft_config(address: str, *, http_port: int = 80,
                       timeout_s: float = 2.0) -> NetFTConfig:
    """Download and parse ``http://<address>:<http_port>/netftapi2.xml``.

    Raises:
        NetFTError: Unreachable box or invalid document (the message names the address).
    """
    url = f'http://{address}:{http_port}/netftapi2.xml'
    try:
        with urllib.request.urlopen(url, timeout=timeout_s) as response:  # noqa: S310
            body = response.read()
    except (urllib.error.URLError, OSError) as exc:
        raise NetFTError(f'cannot read {url}: {exc}') from exc
    try:
        return parse_netft_config(body)
    except ValueError as exc:
        raise NetFTError(f'{url}: {exc}') from exc


# ---------------------------------------------------------------------- bias
class BiasState(IntEnum):
    """Host-side bias procedure state."""

    IDLE = 0
    COLLECTING = 1
    DONE = 2
    FAILED = 3


class BiasAccumulator:
    """Host-side tare (hardware_protocols §4.7): average a window of wrenches.

    After `start`, the first ``settle_samples`` samples are skipped, then every sample whose
    stamp lies within ``duration_s`` of the first averaged one is averaged. The window closes
    with the first sample past it; with fewer than ``min_samples`` the bias fails (the previous
    offsets stay). Without samples, `poll` fails it after ``duration_s + timeout_s``.

    Args:
        duration_s: Averaging window [s] (0.1 s).
        min_samples: Fewest samples for a valid bias (50).
        settle_samples: Samples skipped first (2).
        timeout_s: Extra time allowed for samples to arrive [s].
    """

    def __init__(self, duration_s: float = 0.1, min_samples: int = 50, settle_samples: int = 2,
                 timeout_s: float = 0.5) -> None:
        if duration_s <= 0.0 or min_samples < 1 or settle_samples < 0:
            raise ValueError('need duration_s > 0, min_samples >= 1, settle_samples >= 0')
        self.duration_s = duration_s
        self.min_samples = min_samples
        self.settle_samples = settle_samples
        self.timeout_s = timeout_s
        self._lock = threading.Lock()
        self.offsets: Wrench | None = None
        self.state = BiasState.IDLE
        self.message = 'not biased'
        self._start = math.nan
        self._first = math.nan
        self._skipped = 0
        self._count = 0
        self._sum = [0.0] * 6

    @property
    def biased(self) -> bool:
        """True once valid offsets exist."""
        return self.offsets is not None

    def start(self, t: float) -> None:
        """Begin collecting at ``t`` [s]."""
        with self._lock:
            self.state = BiasState.COLLECTING
            self.message = 'collecting'
            self._start = t
            self._first = math.nan
            self._skipped = 0
            self._count = 0
            self._sum = [0.0] * 6

    def clear(self) -> None:
        """Drop the offsets (unbiased)."""
        with self._lock:
            self.offsets = None
            self.state = BiasState.IDLE
            self.message = 'not biased'

    def add(self, t: float, wrench: Sequence[float]) -> Wrench | None:
        """Feed one raw wrench (N, N·m) stamped ``t`` [s]; returns it bias-removed or None."""
        with self._lock:
            if self.state == BiasState.COLLECTING:
                self._collect(t, wrench)
            off = self.offsets
        if off is None:
            return None
        return (wrench[0] - off[0], wrench[1] - off[1], wrench[2] - off[2],
                wrench[3] - off[3], wrench[4] - off[4], wrench[5] - off[5])

    def poll(self, t: float) -> BiasState:
        """Fail a collection that received too few samples by time ``t`` [s]."""
        with self._lock:
            if self.state == BiasState.COLLECTING and \
                    t - self._start > self.duration_s + self.timeout_s:
                self._finish()
            return self.state

    def _collect(self, t: float, wrench: Sequence[float]) -> None:
        if not all(math.isfinite(v) for v in wrench):
            return
        if self._skipped < self.settle_samples:
            self._skipped += 1
            return
        if math.isnan(self._first):
            self._first = t
        if t - self._first > self.duration_s:
            self._finish()
            return
        self._count += 1
        for i in range(6):
            self._sum[i] += wrench[i]

    def _finish(self) -> None:
        if self._count >= self.min_samples:
            n = self._count
            s = self._sum
            self.offsets = (s[0] / n, s[1] / n, s[2] / n, s[3] / n, s[4] / n, s[5] / n)
            self.state = BiasState.DONE
            self.message = f'biased with {n} samples'
        else:
            self.state = BiasState.FAILED
            self.message = f'bias failed: {self._count} samples, {self.min_samples} required'


# ---------------------------------------------------------------------- client
@dataclass(frozen=True, slots=True)
class FtSample:
    """One accepted record in SI.

    Attributes:
        stamp: Acquisition time (injected clock when the datagram arrived) [s].
        rdt_sequence: RDT record counter.
        ft_sequence: Device measurement counter.
        status: Status word.
        wrench: (Fx, Fy, Fz [N], Tx, Ty, Tz [N·m]) in the sensor frame, as measured.
    """

    stamp: float
    rdt_sequence: int
    ft_sequence: int
    status: int
    wrench: Wrench


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
    restarts: int  #: start requests re-sent by `NetFTClient.supervise`
    socket_errors: int
    status: int
    status_level: Level
    status_text: str
    latched_status: int
    rate_hz: float
    last_stamp: float
    last_error: str


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
    stamps each with the injected clock, validates it (size, sequence), converts accepted
    records to SI and calls ``on_sample`` for each, in order (HW-7, §4.6).

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
        restart_initial_s: First delay between start requests re-sent by `supervise` [s].
        restart_max_s: Largest such delay [s] (exponential back-off in between).
        thread_setup: Called first on the reader thread (scheduling priority, see
            `realtime.ThreadTuning.apply`); an exception there is recorded in ``last_error``.
    """

    def __init__(self, address: str, *, scale: ForceTorqueScale, clock: Clock,
                 on_sample: SampleCallback | None = None, port: int = RDT_PORT,
                 buffered: bool = False, start_retries: int = 10, start_wait_s: float = 0.1,
                 bind_address: str = '', resync_after: int = 16, restart_initial_s: float = 0.5,
                 restart_max_s: float = 5.0,
                 thread_setup: Callable[[], object] | None = None) -> None:
        self.address = address
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
        self._restarts = 0
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
        command = RdtCommand.START_BUFFERED if self._buffered else RdtCommand.START_REALTIME
        for _ in range(self._start_retries):
            self._send(encode_request(command, 0))
            if self._first_data.wait(self._start_wait_s):
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
        """Keep a started stream alive; call from a timer with the current time [s].

        When no record arrived for ``receive_timeout_s`` (box rebooted, cable replugged, or
        another client took the stream), the start request is re-sent with exponential
        back-off. UDP has no connection to lose, so this is the reconnection.

        Returns:
            True when the stream is live (a record within ``receive_timeout_s``).
        """
        if not self._streaming or self._sock is None:
            return False
        latest = self._latest
        if latest is not None and now - latest.stamp <= receive_timeout_s:
            self._restart_policy.record_success()
            return True
        if self._restart_policy.due():
            self._restart_policy.record_failure()
            with self._lock:
                self._restarts += 1
            command = RdtCommand.START_BUFFERED if self._buffered else RdtCommand.START_REALTIME
            self._send(encode_request(command, 0))
        return False

    def set_device_bias(self) -> None:
        """Command the box's software bias (0x0042; affects every client of the box)."""
        self._send(encode_request(RdtCommand.SET_BIAS, 0))

    def reset_latch(self) -> None:
        """Reset the box's threshold latch (0x0041) and the client's latched status."""
        self._send(encode_request(RdtCommand.RESET_LATCH, 0))
        with self._lock:
            self._latched = 0

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
                restarts=self._restarts, socket_errors=self._socket_errors, status=self._status,
                status_level=info.level, status_text=info.text, latched_status=self._latched,
                rate_hz=self._rate.rate(t),
                last_stamp=latest.stamp if latest is not None else math.nan,
                last_error=self._last_error)

    # ------------------------------------------------------------------ internals
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
            except Exception as exc:  # noqa: BLE001 - tuning is optional; keep receiving
                with self._lock:
                    self._last_error = f'{self.name}: thread setup failed: {exc}'
        while self._running:
            try:
                ready, _, _ = select.select([sock, wake], [], [], 1.0)
            except (OSError, ValueError):
                break  # socket closed under us: shutting down
            if wake in ready:
                break
            if sock in ready:
                self._drain(sock)

    def _drain(self, sock: socket.socket) -> None:
        while True:
            try:
                data = sock.recv(65536)
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
            self._handle(data, self._clock())

    def _handle(self, data: bytes, stamp: float) -> None:
        samples: list[FtSample] = []
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
                verdict = self._tracker.update(rec.rdt_sequence, rec.ft_sequence)
                if verdict in (SeqVerdict.DUPLICATE, SeqVerdict.OLD):
                    continue
                self._status = rec.status
                self._latched |= rec.status
                sample = FtSample(stamp, rec.rdt_sequence, rec.ft_sequence, rec.status,
                                  self.scale.to_si(rec.counts))
                self._latest = sample
                self._rate.tick(stamp)
                samples.append(sample)
        if samples:
            self._first_data.set()
        callback = self._on_sample
        if callback is not None:
            for sample in samples:
                callback(sample)


# ---------------------------------------------------------------------- parameters
@dataclass(frozen=True)
class FtFinger1Params:
    """Box of finger 1 (parameter group ``ft.finger_1``)."""

    address: str = field(default='192.168.56.6', metadata={
        'read_only': True, 'description': 'Net F/T box IP address of finger 1'})


@dataclass(frozen=True)
class FtFinger2Params:
    """Box of finger 2 (parameter group ``ft.finger_2``)."""

    address: str = field(default='192.168.56.5', metadata={
        'read_only': True, 'description': 'Net F/T box IP address of finger 2'})


@dataclass(frozen=True)
class FtParams:
    """Both Net F/T boxes (parameter group ``ft``)."""

    mode: str = field(default='embedded', metadata={
        'choices': ('embedded', 'topic'), 'read_only': True,
        'description': 'embedded UDP clients, or consume finger_k/ft/wrench'})
    # One class per finger: the schema rebuilds nested groups from their class defaults.
    finger_1: FtFinger1Params = field(default_factory=FtFinger1Params)
    finger_2: FtFinger2Params = field(default_factory=FtFinger2Params)
    port: int = field(default=RDT_PORT, metadata={
        'range': (1, 65535), 'read_only': True, 'description': 'RDT UDP port'})
    read_config: bool = field(default=True, metadata={
        'read_only': True, 'description': 'read netftapi2.xml on configure'})
    counts_per_force: float = field(default=0.0, metadata={
        'unit': 'counts/unit', 'range': (0.0, 1.0e12), 'read_only': True,
        'description': 'cfgcpf; required when read_config is false'})
    counts_per_torque: float = field(default=0.0, metadata={
        'unit': 'counts/unit', 'range': (0.0, 1.0e12), 'read_only': True,
        'description': 'cfgcpt; required when read_config is false'})
    force_unit: str = field(default='N', metadata={
        'read_only': True, 'description': 'box force unit (lbf, klbf, kgf, kN, N)'})
    torque_unit: str = field(default='N-m', metadata={
        'read_only': True,
        'description': 'box torque unit (lbf-in, lbf-ft, N-mm, kgf-cm, kN-m, N-m)'})
    expected_rate: float = field(default=1000.0, metadata={
        'unit': 'Hz', 'range': (1.0, 10000.0), 'description': 'RDT rate for diagnostics'})
    rate_tolerance: float = field(default=0.1, metadata={
        'unit': '-', 'range': (0.0, 1.0), 'description': 'relative rate tolerance'})
    publish_decimation: int = field(default=2, metadata={
        'range': (1, 100), 'description': 'publish every n-th wrench'})
    publish_raw: bool = field(default=False, metadata={
        'description': 'also publish finger_k/ft/raw'})
    start_retries: int = field(default=10, metadata={
        'range': (1, 100), 'read_only': True, 'description': 'start requests before failing'})
    start_wait: float = field(default=0.1, metadata={
        'unit': 's', 'range': (0.01, 5.0), 'read_only': True,
        'description': 'wait for data after each start request'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field and combination."""
        extra: list[str] = []
        if not self.read_config and (self.counts_per_force <= 0.0
                                     or self.counts_per_torque <= 0.0):
            extra.append('ft.counts_per_force and ft.counts_per_torque are required (> 0) when '
                         'ft.read_config is false')
        for name, check in (('force_unit', force_unit_factor),
                            ('torque_unit', torque_unit_factor)):
            try:
                check(getattr(self, name))
            except ValueError as exc:
                extra.append(str(exc))
        validate_fields(self, extra)

    def scale(self) -> ForceTorqueScale:
        """Scale from the parameters (when ``read_config`` is false)."""
        return ForceTorqueScale(self.counts_per_force, self.counts_per_torque,
                                self.force_unit, self.torque_unit)


@dataclass(frozen=True)
class BiasParams:
    """F/T bias procedure (parameter group ``bias``)."""

    mode: str = field(default='host', metadata={
        'choices': ('host', 'device'), 'description': 'host-side average or box command 0x0042'})
    duration: float = field(default=0.1, metadata={
        'unit': 's', 'range': (0.01, 10.0), 'description': 'averaging window'})
    min_samples: int = field(default=50, metadata={
        'range': (1, 100000), 'description': 'fewest samples for a valid bias'})
    settle_samples: int = field(default=2, metadata={
        'range': (0, 1000), 'description': 'samples skipped before averaging'})
    on_activate: bool = field(default=False, metadata={
        'description': 'bias automatically on activation'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        validate_fields(self)

    def accumulator(self, timeout_s: float = 0.5) -> BiasAccumulator:
        """A `BiasAccumulator` with these settings."""
        return BiasAccumulator(self.duration, self.min_samples, self.settle_samples, timeout_s)
