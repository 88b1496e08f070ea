# SPDX-License-Identifier: Apache-2.0
"""Gripper firmware emulator speaking the real serial protocol (for tests and demos).

Plays the ESP32/SimpleFOC firmware of hardware_protocols §2 byte for byte, including what the
published firmware really does where it differs from first assumptions (§8):

* **Telemetry**: one shaft-angle line with four decimals and ``\\r\\n`` per period
  (multi-turn, relative to the power-up position, quantised to the 4096-count encoder). The
  period is timed inside the FOC loop, so a line is late by up to one loop iteration, never
  early: each period lasts ``period`` plus a uniform ``[0, period_jitter]`` (the jitter amount
  is a model parameter, not a measured figure).
* **Command buffer**: host bytes are appended until ``\\n`` and the whole buffer is acted on, so
  a fragment merges with the next command (``T-2.`` then ``T0.00\\n`` applies −2 V). When exactly
  20 characters have arrived without a newline the firmware prints ``Too long`` and starts a
  new buffer, but the old content stays behind: a bare ``\\n`` next re-runs it (any other byte
  starts the new buffer). A line starting with ``T`` sets the q-axis voltage with C ``atof``
  semantics (non-numeric text → **0 V**), clipped to ``voltage_limit`` the way SimpleFOC's
  ``_constrain`` clips (``Tinf`` → the limit, ``Tnan`` stays NaN: **neither is rejected**;
  NaN drives this model with no voltage, the real PWM is undefined). Other lines are ignored.
  The last value is applied forever (no watchdog). `FirmwareEmulator.malformed_commands`
  counts executed ``T`` lines that were not in the host's fixed ``T%.2f`` format (fragments,
  stale buffers, text) and ``nonfinite_commands`` the NaN/inf ones, so tests catch a host that
  leaves fragments or sends non-finite values.
* **Reset**: after a (re)start the firmware is **silent for about 5.7 s** (``boot_time``)
  while ``initFOC`` aligns the rotor, which moves the fingers by about ±5 mm
  (``align_amplitude``); then it prints only ``Voltage control`` and streams angles counted
  from the power-up position, so **the first angle is not 0** (the rotor ends
  ``align_end_offset`` away). Bytes the host writes meanwhile wait in the USB receive buffer
  (``RX_BUFFER_BYTES``, excess dropped) and are parsed after the boot. At construction the
  firmware has just finished booting (``boot=True`` prints ``Voltage control`` first).

Plant (quasi-static, motor inertia neglected; one coordinate, the opening ``x`` [m])::

    D·ẋ = k_FV·V_eff − friction + Σ_contacts k_i·(w_i − x)⁺,
    D   = damping + k_FV·k_e / k_open            (back-EMF acts as damping)
    V_eff = clip(V, ±max_phase_voltage)           (SVPWM ceiling ≈ supply/√3)

with the closed stop as a stiff contact at ``x = 0`` (pads touching), an optional object of
width ``w`` and stiffness ``k``, and a hard open stop at ``stroke``. Stall force is exactly
``k_FV·|V|`` minus friction; the grasp force on the pads is the contact force. Integrated with
implicit Euler (stable for any stiffness). The alignment motion is kinematic (the opening
follows the alignment profile, clamped to ``[0, stroke]``).

Three ways to use it:

* `FirmwareEmulator`: pure, time-stepped (``tick`` → one period); deterministic for a seed.
* `EmulatedFirmwareStream`: a `transport.ByteStream` over it in simulated time.
* `PtyFirmwareEmulator`: a pseudo-terminal whose slave path pyserial opens like a real port,
  at 500 Hz real time, with garbage injection, silence, restarts and ``vanish``/``reappear``
  (the port disappears and comes back under the same symlink, like ``/dev/serial/by-id``).

Run ``python -m slip_gripper_driver.core.firmware_emulator --help`` to try the driver
without hardware.
"""
from __future__ import annotations

import argparse
import fcntl
import json
import math
import os
import re
import resource
import signal
import sys
import termios
import threading
import time
import tty
from array import array
from collections import deque
from dataclasses import asdict, dataclass
from collections.abc import Callable, Sequence

import numpy as np

#: Characters without ``\\n`` after which the firmware prints ``Too long`` (exactly this many).
FIRMWARE_BUFFER_CHARS = 20

#: What the firmware prints when a (re)start has finished (nothing else; §2.3).
BOOT_LINE = 'Voltage control'

#: Reply of the firmware's command reader to ``FIRMWARE_BUFFER_CHARS`` characters.
TOO_LONG_REPLY = 'Too long'

#: ``getrusage`` target of the calling thread (Linux); elsewhere the whole process.
RUSAGE_THREAD = getattr(resource, 'RUSAGE_THREAD', resource.RUSAGE_SELF)

#: Host bytes kept while the firmware boots (USB CDC receive buffer; excess dropped).
RX_BUFFER_BYTES = 256

_ATOF_RE = re.compile(
    r'[ \t\n\v\f\r]*([+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?'
    r'|inf(?:inity)?|nan))', re.IGNORECASE)

#: The host's command format (``T%.2f``); anything else executed is counted as malformed.
_HOST_COMMAND_RE = re.compile(rb'T-?[0-9]{1,2}\.[0-9]{2}')


def atof(text: str) -> float:
    """C ``atof``: the longest numeric prefix after leading whitespace, else 0.0."""
    match = _ATOF_RE.match(text)
    if match is None:
        return 0.0
    return float(match.group(1))


@dataclass(frozen=True)
class GripperModelParams:
    """Motor, transmission, object and firmware timing of the emulated gripper (SI; volts at
    the link)."""

    newton_per_volt: float = 3.9166  #: stall grasp force per volt [N/V]
    opening_per_rad: float = 0.0086751614  #: opening per motor radian [m/rad]
    back_emf: float = 0.4  #: back-EMF constant [V·s/rad] (no-load 2.5 rad/s per V)
    damping: float = 5.0  #: viscous damping of the guides [N·s/m]
    friction: float = 0.3  #: Coulomb friction of the guides [N]
    stroke: float = 0.080  #: open limit [m]
    initial_opening: float = 0.040  #: opening at power-up [m]
    object_width: float = 0.0  #: object between the pads [m]; 0 = none
    object_stiffness: float = 20000.0  #: object stiffness [N/m]
    stop_stiffness: float = 1.0e6  #: pad-to-pad stiffness at the closed stop [N/m]
    voltage_limit: float = 20.0  #: firmware voltage_limit [V]
    max_phase_voltage: float = 20.0 / math.sqrt(3.0)  #: SVPWM ceiling [V]
    counts_per_rev: int = 4096  #: encoder resolution
    period: float = 0.002  #: nominal telemetry period [s]
    period_jitter: float = 40e-6  #: each period is late by up to this much [s] (model value)
    substeps: int = 4  #: physics steps per telemetry period
    boot_time: float = 5.7  #: silence after a reset while initFOC aligns the rotor [s]
    align_amplitude: float = 0.005  #: finger excursion of the alignment [m]
    align_end_offset: float = 0.0012  #: opening change left by the alignment (to mid-stroke) [m]


class GripperPlant:
    """Quasi-static finger model; see the module docstring.

    Args:
        params: Model parameters.
    """

    def __init__(self, params: GripperModelParams) -> None:
        self.params = params
        self.opening = params.initial_opening
        self.rate = 0.0
        p = params
        self._d = p.damping + p.newton_per_volt * p.back_emf / p.opening_per_rad

    def contact_force(self) -> float:
        """Force between the pads and the object (or each other) [N], ≥ 0."""
        return sum(k * (w - self.opening) for w, k in self._contacts(self.opening))

    def _contacts(self, x: float) -> list[tuple[float, float]]:
        p = self.params
        out = [(0.0, p.stop_stiffness)] if x < 0.0 else []
        if p.object_width > 0.0 and x < p.object_width:
            out.append((p.object_width, p.object_stiffness))
        return out

    def step(self, dt: float, voltage_v: float) -> None:
        """Advance by ``dt`` [s] with q-axis voltage ``voltage_v`` [V] (positive opens)."""
        p = self.params
        if math.isnan(voltage_v):
            voltage_v = 0.0  # a NaN target: undefined PWM on the real board; no drive here
        v_eff = min(max(voltage_v, -p.max_phase_voltage), p.max_phase_voltage)
        drive = p.newton_per_volt * v_eff
        drive = math.copysign(max(0.0, abs(drive) - p.friction), drive)
        x0 = self.opening
        x1 = x0
        for _ in range(2):  # re-solve once if the step enters a new contact
            contacts = self._contacts(min(x0, x1))
            k_sum = sum(k for _, k in contacts)
            kw_sum = sum(k * w for w, k in contacts)
            h = dt / self._d
            x1 = (x0 + h * (drive + kw_sum)) / (1.0 + h * k_sum)
            if self._contacts(x1) == contacts:
                break
        x1 = min(x1, p.stroke)
        self.rate = (x1 - x0) / dt
        self.opening = x1

    def place(self, opening: float, dt: float) -> None:
        """Move kinematically to ``opening`` [m] (clamped to the stops) over ``dt`` [s]."""
        x1 = min(max(opening, 0.0), self.params.stroke)
        self.rate = (x1 - self.opening) / dt if dt > 0.0 else 0.0
        self.opening = x1


class FirmwareEmulator:
    """Time-stepped firmware: host bytes in, telemetry and debug lines out.

    Args:
        params: Gripper model and firmware timing.
        seed: Seed of the garbage and period-jitter generators.
        boot: Print ``Voltage control`` before the first line (the firmware has just booted).
    """

    def __init__(self, params: GripperModelParams = GripperModelParams(), seed: int = 0,
                 boot: bool = True) -> None:
        self.params = params
        self.plant = GripperPlant(params)
        self.time_s = 0.0
        self.last_period_s = params.period  #: duration of the newest tick [s]
        self.target_voltage_v = 0.0
        self.output = bytearray()
        self.commands: deque[bytes] = deque(maxlen=10000)
        self.commands_received = 0
        self.nonfinite_commands = 0  #: executed T lines whose value was NaN or ±inf
        self.malformed_commands = 0  #: executed T lines not in the host's T%.2f format
        self.too_long_replies = 0
        self.stale_reruns = 0  #: bare newlines that re-ran the buffer left by ``Too long``
        self.ignored_lines = 0
        self.lines_sent = 0
        self.restarts = 0
        self._buffer = bytearray()
        self._stale = b''
        # The rotor ended the power-up alignment away from where the encoder counted from.
        self._zero_opening = self.plant.opening - self._align_offset(self.plant.opening)
        self._rng = np.random.default_rng(seed)
        self._jitter_rng = np.random.default_rng([seed, 1])
        self._silent_until = -math.inf
        self._boot: tuple[float, float, float] | None = None  # (start, end, opening at reset)
        self._boot_rx = bytearray()
        if boot:
            self._print(BOOT_LINE)

    @property
    def booting(self) -> bool:
        """The firmware is in its reset silence (alignment running)."""
        return self._boot is not None

    # ------------------------------------------------------------------ host → firmware
    def receive(self, data: bytes) -> None:
        """Feed bytes written by the host (any split)."""
        if self._boot is not None:  # the loop does not run yet: bytes wait in the USB buffer
            room = RX_BUFFER_BYTES - len(self._boot_rx)
            self._boot_rx += data[:max(0, room)]
            return
        for byte in data:
            if byte == 0x0A:
                if not self._buffer and self._stale:
                    self.stale_reruns += 1
                    self._handle(self._stale)
                else:
                    self._handle(bytes(self._buffer))
                self._buffer.clear()
                self._stale = b''
                continue
            self._stale = b''
            self._buffer.append(byte)
            if len(self._buffer) == FIRMWARE_BUFFER_CHARS:
                self._stale = bytes(self._buffer)  # not cleared: a bare newline re-runs it
                self._buffer.clear()
                self.too_long_replies += 1
                self._print(TOO_LONG_REPLY)

    def _handle(self, line: bytes) -> None:
        if not line.startswith(b'T'):
            self.ignored_lines += 1
            return
        self.commands.append(line)
        self.commands_received += 1
        if _HOST_COMMAND_RE.fullmatch(line) is None:
            self.malformed_commands += 1
        value = atof(line[1:].decode('latin-1'))
        if not math.isfinite(value):
            self.nonfinite_commands += 1  # accepted, as the firmware does
        limit = self.params.voltage_limit
        # SimpleFOC's _constrain: comparisons with NaN are false, so NaN passes through.
        self.target_voltage_v = -limit if value < -limit else limit if value > limit else value

    # ------------------------------------------------------------------ firmware → host
    def tick(self) -> bytes:
        """Advance one telemetry period; returns (and queues) the bytes printed meanwhile."""
        p = self.params
        period = p.period
        if p.period_jitter > 0.0:
            period += float(self._jitter_rng.uniform(0.0, p.period_jitter))
        self.last_period_s = period
        self.time_s += period
        if self._boot is not None:
            self._boot_step(period)
        else:
            sub = period / p.substeps
            for _ in range(p.substeps):
                self.plant.step(sub, self.target_voltage_v)
            if self.time_s >= self._silent_until:
                self._print(f'{self.angle_rad():.4f}')
                self.lines_sent += 1
        out = bytes(self.output)
        self.output.clear()
        return out

    def _boot_step(self, period: float) -> None:
        assert self._boot is not None
        start, end, x0 = self._boot
        p = self.params
        tau = min(1.0, (self.time_s - start) / (end - start)) if end > start else 1.0
        self.plant.place(x0 + p.align_amplitude * math.sin(2.0 * math.pi * tau)
                         + self._align_offset(x0) * tau, period)
        if self.time_s < end:
            return
        self._boot = None
        self.plant.rate = 0.0
        self._print(BOOT_LINE)
        pending, self._boot_rx = bytes(self._boot_rx), bytearray()
        self.receive(pending)

    def _align_offset(self, x0: float) -> float:
        """Opening change [m] the alignment leaves when it starts at ``x0`` [m] (towards the
        middle of the stroke, so a stop never hides it)."""
        offset = self.params.align_end_offset
        return -offset if x0 > 0.5 * self.params.stroke else offset

    def angle_rad(self) -> float:
        """Encoder-quantised shaft angle relative to the last power-up or reset [rad]."""
        p = self.params
        theta = (self.plant.opening - self._zero_opening) / p.opening_per_rad
        count = 2.0 * math.pi / p.counts_per_rev
        return round(theta / count) * count

    @property
    def grasp_force(self) -> float:
        """Pad contact force [N] (what the F/T sensors measure as −Fz)."""
        return self.plant.contact_force()

    @property
    def opening(self) -> float:
        """True finger separation [m]."""
        return self.plant.opening

    # ------------------------------------------------------------------ fault injection
    def inject(self, data: bytes | str) -> None:
        """Queue raw bytes (garbage, partial lines, debug text) on the output."""
        self.output += data.encode('latin-1') if isinstance(data, str) else data

    def inject_garbage(self, length: int = 12) -> bytes:
        """Queue one line of random bytes (terminators excluded) and return it."""
        raw = self._rng.integers(0, 256, size=length, dtype=np.uint8).tobytes()
        raw = raw.replace(b'\n', b'?').replace(b'\r', b'?')
        self.inject(raw + b'\r\n')
        return raw

    def silence(self, duration_s: float) -> None:
        """Stop printing telemetry for ``duration_s`` [s] of emulator time."""
        self._silent_until = self.time_s + duration_s

    def restart(self, silence_s: float | None = None) -> None:
        """Firmware reset: target 0 V, command buffer lost, silent boot with the alignment
        motion, then ``Voltage control`` and angles counted from the reset position.

        Args:
            silence_s: Boot silence [s]; None = ``params.boot_time`` (5.7 s like the real one).
        """
        self.restarts += 1
        self.target_voltage_v = 0.0
        self._buffer.clear()
        self._stale = b''
        self._boot_rx.clear()
        self._zero_opening = self.plant.opening
        duration = self.params.boot_time if silence_s is None else silence_s
        self._boot = (self.time_s, self.time_s + max(0.0, duration), self.plant.opening)

    def _print(self, text: str) -> None:
        self.output += text.encode('ascii') + b'\r\n'


class EmulatedFirmwareStream:
    """`transport.ByteStream` over a `FirmwareEmulator` in simulated time.

    A read with nothing pending advances the emulator by one period, so a reader sees one
    telemetry line per read and never blocks. `now` gives the matching simulated clock.

    Args:
        emulator: The emulator to drive.
    """

    def __init__(self, emulator: FirmwareEmulator) -> None:
        self.emulator = emulator
        self._pending = bytearray()
        self.closed = False

    def now(self) -> float:
        """Simulated time [s]."""
        return self.emulator.time_s

    @property
    def in_waiting(self) -> int:
        """Bytes already produced."""
        return len(self._pending)

    def read(self, size: int = 1) -> bytes:
        """Return up to ``size`` bytes, ticking the emulator when nothing is pending."""
        if self.closed:
            raise OSError('emulated port closed')
        if not self._pending:
            self._pending += self.emulator.tick()
        out = bytes(self._pending[:size])
        del self._pending[:size]
        return out

    def write(self, data: bytes) -> int:
        """Deliver host bytes to the firmware."""
        if self.closed:
            raise OSError('emulated port closed')
        self.emulator.receive(data)
        return len(data)

    def close(self) -> None:
        """Mark closed."""
        self.closed = True


#: Link gaps kept in `PtyFirmwareEmulator.gap_log` (the longest ones).
GAP_LOG_LENGTH = 20


@dataclass(frozen=True, slots=True)
class SendGap:
    """One link gap of the emulator thread: the wall-clock interval between two sends, and
    where it went.

    Attributes:
        at_s: ``time.monotonic()`` at the end of the gap [s].
        gap_s: Interval since the previous send [s].
        cpu_s: CPU time the thread used meanwhile [s] (``time.thread_time``): close to
            ``gap_s`` = the thread was computing; close to 0 = it was not running.
        involuntary_switches: The thread was preempted this many times meanwhile.
        voluntary_switches: It blocked this many times (its sleep, the GIL, a lock, I/O).
        runqueue_wait_s: Time it was ready to run but waited for a CPU [s] (Linux
            ``schedstat``, with ``kernel.task_delayacct = 1``; NaN otherwise).
        major_faults: Page faults that had to read from storage meanwhile (Linux; -1
            elsewhere).
        overslept_s: How much longer the sleeps until a tick took than asked [s] (late
            wake-ups).
        read_s, tick_s, write_s: Time in reading + parsing host bytes, in the plant ticks
            (lock included) and in the pty write of the send that opened the gap [s].
        clock_s: Time in this record's own counter reads [s] (a ``/proc`` read releases
            the GIL, so a wait for it can end there).

    A wait for the GIL ends in whichever call released it, so it shows as ``overslept_s``,
    ``write_s`` or ``clock_s``; with ``cpu_s`` near 0 the parts add up to about ``gap_s``
    less the asked sleep.
    """

    at_s: float
    gap_s: float
    cpu_s: float
    involuntary_switches: int
    voluntary_switches: int
    runqueue_wait_s: float
    major_faults: int
    overslept_s: float
    read_s: float
    tick_s: float
    write_s: float
    clock_s: float


class _GapClock:
    """Where the emulator thread's time went since its last send (`SendGap` fields); create
    it in the thread it measures."""

    def __init__(self) -> None:
        self._task = _TaskCounters()
        self.restart()

    def restart(self) -> None:
        """Open a new gap (call it at the send that closes the last one)."""
        t0 = time.monotonic()
        self._parts = {'sleep': 0.0, 'read': 0.0, 'tick': 0.0, 'write': 0.0, 'clock': 0.0}
        self._cpu0 = time.thread_time()
        self._switches0 = _context_switches()
        self._wait0, self._faults0 = self._task.read()
        self.add('clock', time.monotonic() - t0)

    def add(self, part: str, seconds: float) -> None:
        self._parts[part] += max(0.0, seconds)

    def gap(self, now: float, gap_s: float) -> SendGap:
        """The record of the gap that ends at ``now`` (monotonic [s]), ``gap_s`` long."""
        p = self._parts
        involuntary, voluntary = _context_switches()
        wait, faults = self._task.read()
        return SendGap(now, gap_s, time.thread_time() - self._cpu0,
                       involuntary - self._switches0[0], voluntary - self._switches0[1],
                       wait - self._wait0, faults - self._faults0 if faults >= 0 else -1,
                       p['sleep'], p['read'], p['tick'], p['write'], p['clock'])

    def close(self) -> None:
        self._task.close()


class _TaskCounters:
    """The calling thread's run-queue wait [s] and major page faults, from
    ``/proc/thread-self`` (opened once; NaN and -1 where there is no such file)."""

    def __init__(self) -> None:
        self._fds: list[int] = []
        for name in ('schedstat', 'stat'):
            try:
                self._fds.append(os.open(f'/proc/thread-self/{name}', os.O_RDONLY))
            except OSError:
                self.close()
                return

    def read(self) -> tuple[float, int]:
        if not self._fds:
            return math.nan, -1
        try:
            schedstat = os.pread(self._fds[0], 128, 0).split()
            stat = os.pread(self._fds[1], 1024, 0).rsplit(b')', 1)[1].split()
            # Both schedstat figures stay 0 while the kernel keeps no per-task delay
            # accounting (sysctl kernel.task_delayacct = 0): then the wait is unknown.
            wait = int(schedstat[1]) * 1e-9 if int(schedstat[0]) > 0 else math.nan
            return wait, int(stat[9])
        except (OSError, IndexError, ValueError):
            return math.nan, -1

    def close(self) -> None:
        for fd in self._fds:
            os.close(fd)
        self._fds = []


def _context_switches() -> tuple[int, int]:
    """``(involuntary, voluntary)`` context switches of the calling thread so far (zeros
    where not available)."""
    try:
        usage = resource.getrusage(RUSAGE_THREAD)
    except (OSError, ValueError):
        return 0, 0
    return int(usage.ru_nivcsw), int(usage.ru_nvcsw)


def _drain(master: int) -> bytes:
    """What the host has written that the pty already holds for the master (non-blocking).

    Reads only what ``FIONREAD`` reports: a read or poll of a pty end with nothing in it
    first waits for the kernel's worker thread to move pending bytes over
    (``tty_buffer_flush_work``), and that normal-priority thread can wait for a CPU for
    seconds on a loaded host. Bytes still pending there are read at a later tick.
    """
    parts = []
    count = array('i', [0])
    while True:
        try:
            fcntl.ioctl(master, termios.FIONREAD, count, True)
        except OSError:  # the pty is gone
            break
        if count[0] <= 0:
            break
        try:
            data = os.read(master, count[0])
        except (BlockingIOError, OSError):  # EIO: the slave is not open
            break
        if not data:
            break
        parts.append(data)
    return b''.join(parts)


class PtyFirmwareEmulator:
    """The emulator behind a pseudo-terminal, in real time (the device side of a fake port).

    Args:
        emulator: Firmware to serve (a default one when None).
        link_path: Optional symlink pointing at the current pty slave; it survives
            `vanish`/`reappear` like a ``/dev/serial/by-id`` path.
        realtime_scale: Emulator seconds per wall-clock second (1.0 = real time).
    """

    def __init__(self, emulator: FirmwareEmulator | None = None, *,
                 link_path: str | None = None, realtime_scale: float = 1.0,
                 on_tick: Callable[[float, float, float], None] | None = None) -> None:
        self.emulator = emulator if emulator is not None else FirmwareEmulator()
        #: ``on_tick(monotonic_s, pad_force_n, voltage_v)`` after each tick, lock held: the
        #: plant's truth for a benchmark (called from the emulator thread).
        self.on_tick = on_tick
        self.link_path = link_path
        self.lock = threading.Lock()
        self.late_ticks = 0
        self.max_send_gap_s = 0.0  #: longest wall-clock interval between two sends [s]
        self.long_gaps = 0  #: sends more than 10 periods after the previous one (link gaps)
        #: The longest link gaps (up to `GAP_LOG_LENGTH`), each a `SendGap`: where the thread
        #: spent the gap, so a benchmark can tell a descheduled emulator from a slow one.
        self.gap_log: list[SendGap] = []
        self.dropped_writes = 0
        self.vanished = 0
        self._scale = realtime_scale
        self._master = -1
        self._slave = -1
        self._slave_name = ''
        self._thread: threading.Thread | None = None
        self._running = False

    @property
    def port(self) -> str:
        """Path for pyserial: the symlink if configured, else the pty slave."""
        return self.link_path or self._slave_name

    def start(self) -> str:
        """Create the pty and start the 500 Hz thread; returns `port`."""
        self._open_pty()
        self._running = True
        self._thread = threading.Thread(target=self._run, name='firmware-emulator',
                                        daemon=True)
        self._thread.start()
        return self.port

    def stop(self) -> None:
        """Stop the thread and close the pty."""
        self._stop_thread()
        self._close_pty()
        if self.link_path and os.path.islink(self.link_path):
            os.unlink(self.link_path)

    def vanish(self) -> None:
        """The USB device disappears: pty closed, symlink removed; the host's reads fail."""
        self.vanished += 1
        self.stop()

    def reappear(self, reboot: bool = True, boot_s: float | None = None) -> str:
        """The device re-enumerates under the same symlink (new pty); optional reboot with
        ``boot_s`` [s] of boot silence (None = the model's ``boot_time``, 5.7 s)."""
        if reboot:
            with self.lock:
                self.emulator.restart(boot_s)
        return self.start()

    def inject(self, data: bytes | str) -> None:
        """Queue raw bytes on the output (thread-safe)."""
        with self.lock:
            self.emulator.inject(data)

    def restart(self, silence_s: float | None = None) -> None:
        """Firmware reset with ``silence_s`` [s] of boot silence, None = the model's
        ``boot_time`` (5.7 s) (thread-safe)."""
        with self.lock:
            self.emulator.restart(silence_s)

    def silence(self, duration_s: float) -> None:
        """No telemetry for ``duration_s`` [s] (thread-safe)."""
        with self.lock:
            self.emulator.silence(duration_s)

    def grasp_force(self) -> float:
        """Pad contact force [N] (thread-safe)."""
        with self.lock:
            return self.emulator.grasp_force

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """Poll ``predicate`` (called with the lock held) until true or the timeout [s]."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self.lock:
                if predicate():
                    return True
            time.sleep(0.002)
        with self.lock:
            return predicate()

    # ------------------------------------------------------------------ internals
    def _open_pty(self) -> None:
        master, slave = os.openpty()
        # Raw line discipline before anyone opens the slave: no echo of telemetry back into
        # the command parser, no CR/LF translation.
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        self._slave_name = os.ttyname(slave)
        if self.link_path:
            tmp = f'{self.link_path}.tmp{os.getpid()}'
            if os.path.lexists(tmp):
                os.unlink(tmp)
            os.symlink(self._slave_name, tmp)
            os.replace(tmp, self.link_path)

    def _close_pty(self) -> None:
        for fd in (self._master, self._slave):
            if fd >= 0:
                os.close(fd)
        self._master = self._slave = -1

    def _stop_thread(self) -> None:
        self._running = False  # the thread sees it within one period
        if self._thread is not None:
            self._thread.join(2.0)
        self._thread = None

    def _run(self) -> None:
        # The thread sleeps on the clock until each tick and then takes what the port holds
        # (`_drain`): a microcontroller's loop never waits for the host. Waiting in select()
        # on the pty master instead stalled this thread for 0.03-2.5 s at a time beside CPU
        # burners (the poll waits for the kernel's tty worker, see `_drain`).
        emulator = self.emulator
        scale = self._scale
        next_tick = time.monotonic() + emulator.params.period / scale
        last_send = math.nan
        master = self._master
        since_send = _GapClock()
        while self._running:
            t_wait = time.monotonic()
            delay = next_tick - t_wait
            if delay > 0.0:
                time.sleep(delay)
                since_send.add('sleep', time.monotonic() - t_wait - delay)
            if not self._running:
                break
            t_read = time.monotonic()
            data = _drain(master)
            if data:
                with self.lock:
                    emulator.receive(data)
            now = time.monotonic()
            since_send.add('read', now - t_read)
            # Every period that has ended produces its line (each period with its own jitter).
            chunks = []
            with self.lock:
                while next_tick <= now:
                    chunks.append(emulator.tick())
                    if self.on_tick is not None:  # stamped with the tick's scheduled time
                        self.on_tick(next_tick, emulator.grasp_force, emulator.target_voltage_v)
                    next_tick += emulator.last_period_s / scale
            since_send.add('tick', time.monotonic() - now)
            if not chunks:
                continue
            self.late_ticks += len(chunks) - 1
            if last_send == last_send:  # not NaN
                gap = now - last_send
                self.max_send_gap_s = max(self.max_send_gap_s, gap)
                if gap > 10.0 * emulator.params.period / scale:
                    self.long_gaps += 1
                    self._log_gap(since_send.gap(now, gap))
            last_send = now
            since_send.restart()  # the next gap starts at `now`: this write is part of it
            t_write = time.monotonic()
            self._send(master, b''.join(chunks))
            since_send.add('write', time.monotonic() - t_write)
        since_send.close()

    def _log_gap(self, gap: SendGap) -> None:
        self.gap_log.append(gap)
        self.gap_log.sort(key=lambda g: -g.gap_s)
        del self.gap_log[GAP_LOG_LENGTH:]

    def _send(self, master: int, data: bytes) -> None:
        try:
            os.write(master, data)
        except BlockingIOError:
            self.dropped_writes += 1  # nobody reads the port: a real CDC device drops too
        except OSError:
            self.dropped_writes += 1


def _build_parser() -> argparse.ArgumentParser:
    d = GripperModelParams()
    parser = argparse.ArgumentParser(
        description='Gripper firmware emulator on a pseudo-terminal (500 Hz angle lines, '
                    'answers T<volts>, reproduces the firmware behaviours listed in the module '
                    'docstring). Point the driver\'s serial.port at the printed path.',
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument('--link', default=None,
                        help='create this symlink to the pty (stable path across reappear)')
    parser.add_argument('--stroke', type=float, default=d.stroke, help='open limit [m]')
    parser.add_argument('--initial-opening', type=float, default=d.initial_opening,
                        help='opening at power-up [m]')
    parser.add_argument('--object-width', type=float, default=0.0,
                        help='object between the pads [m]; 0 = none')
    parser.add_argument('--object-stiffness', type=float, default=d.object_stiffness,
                        help='object stiffness [N/m]')
    parser.add_argument('--boot-time', type=float, default=d.boot_time,
                        help='silence after a firmware reset while the rotor aligns [s]')
    parser.add_argument('--period-jitter', type=float, default=d.period_jitter,
                        help='each telemetry period is late by up to this much [s]')
    parser.add_argument('--garbage-every', type=int, default=0,
                        help='inject a line of random bytes every N telemetry lines')
    parser.add_argument('--netft', action='append', default=[], metavar='HOST:PORT',
                        help='also serve a Net F/T emulator measuring the pad force (repeat '
                             'for finger 1 then finger 2, e.g. 127.0.0.6:49152)')
    parser.add_argument('--duration', type=float, default=0.0,
                        help='stop after this many seconds; 0 = until Ctrl-C')
    parser.add_argument('--stats-json', action='store_true',
                        help='print counters as one JSON line at exit')
    parser.add_argument('--seed', type=int, default=0, help='random seed')
    parser.add_argument('--record-truth', default=None, metavar='FILE',
                        help='at exit, write (monotonic time [s], pad force [N], applied '
                             'voltage [V]) of every tick to FILE as float64 triples: the '
                             'plant\'s truth, for benchmarks')
    parser.add_argument('--priority', type=int, default=0,
                        help='SCHED_FIFO priority of the emulator threads (1-99), so that, like '
                             'real firmware, its 500 Hz timing does not depend on the host load; '
                             '0 = normal scheduling; falls back with a warning when not permitted')
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Console entry point; prints the port path, runs until Ctrl-C or ``--duration``."""
    args = _build_parser().parse_args(argv)
    if args.priority > 0:
        from slip_gripper_driver.core.realtime import set_fifo_priority
        problem = set_fifo_priority(args.priority)  # inherited by every thread started below
        if problem:
            print(f'warning: {problem}; emulator runs with normal scheduling', file=sys.stderr,
                  flush=True)
    model = GripperModelParams(stroke=args.stroke, initial_opening=args.initial_opening,
                               object_width=args.object_width,
                               object_stiffness=args.object_stiffness,
                               boot_time=args.boot_time, period_jitter=args.period_jitter)
    truth = array('d')

    def record(t: float, force: float, voltage: float) -> None:
        truth.extend((t, force, voltage))

    pty_emu = PtyFirmwareEmulator(FirmwareEmulator(model, seed=args.seed), link_path=args.link,
                                  on_tick=record if args.record_truth else None)
    port = pty_emu.start()
    netfts = []
    if args.netft:
        from slip_gripper_driver.core.netft_emulator import NetFTEmulator

        def pad_force(_: float) -> tuple[float, float, float, float, float, float]:
            return (0.0, 0.0, -pty_emu.grasp_force(), 0.0, 0.0, 0.0)

        for k, spec in enumerate(args.netft, start=1):
            host, _, port_text = spec.rpartition(':')
            emu = NetFTEmulator(host=host or '127.0.0.1', port=int(port_text),
                                force_source=pad_force, seed=args.seed + k)
            emu.start()
            netfts.append(emu)
            print(f'Net F/T emulator (finger {k}) on {emu.address[0]}:{emu.address[1]}',
                  flush=True)
    print(f'gripper firmware emulator on {port}', flush=True)
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set())
                for sig in (signal.SIGINT, signal.SIGTERM)}
    start = time.monotonic()
    last_garbage = 0
    try:
        while not stop.wait(0.01):
            if args.duration and time.monotonic() - start >= args.duration:
                break
            if args.garbage_every > 0:
                with pty_emu.lock:
                    sent = pty_emu.emulator.lines_sent
                    if sent - last_garbage >= args.garbage_every:
                        last_garbage = sent
                        pty_emu.emulator.inject_garbage()
    finally:
        pty_emu.stop()
        for emu in netfts:
            emu.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if args.record_truth:
        with open(args.record_truth, 'wb') as out:
            truth.tofile(out)
    if args.stats_json:
        e = pty_emu.emulator
        print(json.dumps({
            'lines_sent': e.lines_sent, 'commands_received': e.commands_received,
            'late_ticks': pty_emu.late_ticks, 'dropped_writes': pty_emu.dropped_writes,
            'max_send_gap_s': pty_emu.max_send_gap_s, 'long_gaps': pty_emu.long_gaps,
            'too_long_replies': e.too_long_replies, 'nonfinite_commands': e.nonfinite_commands,
            'malformed_commands': e.malformed_commands, 'stale_reruns': e.stale_reruns,
            'gap_log': [asdict(g) for g in pty_emu.gap_log],
            'last_voltage_v': e.target_voltage_v, 'model': asdict(model)}), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
