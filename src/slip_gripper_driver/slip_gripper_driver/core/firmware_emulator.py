# SPDX-License-Identifier: Apache-2.0
"""Gripper firmware emulator speaking the real serial protocol (for tests and demos).

Plays the ESP32/SimpleFOC firmware of hardware_protocols §2 byte for byte:

* every 2 ms one shaft-angle line with four decimals and ``\\r\\n`` (multi-turn, relative to
  the power-up position, quantised to the 4096-count encoder);
* host lines are collected up to ``\\n``; more than 20 characters without a newline →
  ``Too long in read`` and the buffer is dropped; a line starting with ``T`` sets the q-axis
  voltage with C ``atof`` semantics (non-numeric text → **0 V**); other lines are ignored; the
  last value is applied forever (no watchdog);
* ``Voltage control`` and SimpleFOC-style init text at (re)start, with the angle zeroed.

Plant (quasi-static, motor inertia neglected; one coordinate, the opening ``x`` [m])::

    D·ẋ = k_FV·V_eff − friction + Σ_contacts k_i·(w_i − x)⁺,
    D   = damping + k_FV·k_e / k_open            (back-EMF acts as damping)
    V_eff = clip(V, ±max_phase_voltage)           (SVPWM ceiling ≈ supply/√3)

with the closed stop as a stiff contact at ``x = 0`` (pads touching), an optional object of
width ``w`` and stiffness ``k``, and a hard open stop at ``stroke``. Stall force is exactly
``k_FV·|V|`` minus friction; the grasp force on the pads is the contact force. Integrated with
implicit Euler (stable for any stiffness).

Three ways to use it:

* `FirmwareEmulator`: pure, time-stepped (``tick`` → one line); fully deterministic.
* `EmulatedFirmwareStream`: a `transport.ByteStream` over it in simulated time.
* `PtyFirmwareEmulator`: a pseudo-terminal whose slave path pyserial opens like a real port,
  at 500 Hz real time, with garbage injection, silence, restarts and ``vanish``/``reappear``
  (the port disappears and comes back under the same symlink, like ``/dev/serial/by-id``).

Run ``python -m slip_gripper_driver.core.firmware_emulator --help`` to try the driver
without hardware.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import select
import signal
import sys
import threading
import time
import tty
from collections import deque
from dataclasses import asdict, dataclass
from typing import Callable, Sequence

import numpy as np

#: Firmware command buffer length: one more character without ``\\n`` → ``Too long in read``.
FIRMWARE_BUFFER_CHARS = 20

_ATOF_RE = re.compile(
    r'[ \t\n\v\f\r]*([+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?'
    r'|inf(?:inity)?|nan))', re.IGNORECASE)

#: What the emulated firmware prints while booting (SimpleFOC-style; last line is the sketch's).
BOOT_BANNER: tuple[str, ...] = (
    'MOT: Init', 'MOT: Enable driver.', 'MOT: Align sensor.', 'MOT: sensor_direction==CW',
    'MOT: PP check: OK!', 'MOT: Zero elec. angle: 2.18', 'MOT: No current sense.',
    'MOT: Ready.', 'Voltage control')


def atof(text: str) -> float:
    """C ``atof``: the longest numeric prefix after leading whitespace, else 0.0."""
    match = _ATOF_RE.match(text)
    if match is None:
        return 0.0
    return float(match.group(1))


@dataclass(frozen=True)
class GripperModelParams:
    """Motor, transmission and object of the emulated gripper (SI; volts at the link)."""

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
    period: float = 0.002  #: telemetry period [s]
    substeps: int = 4  #: physics steps per telemetry period


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


class FirmwareEmulator:
    """Time-stepped firmware: host bytes in, telemetry and debug lines out.

    Args:
        params: Gripper model.
        seed: Seed of the garbage generator.
        boot: Print the boot banner before the first line.
    """

    def __init__(self, params: GripperModelParams = GripperModelParams(), seed: int = 0,
                 boot: bool = True) -> None:
        self.params = params
        self.plant = GripperPlant(params)
        self.time_s = 0.0
        self.target_voltage_v = 0.0
        self.output = bytearray()
        self.commands: deque[bytes] = deque(maxlen=10000)
        self.commands_received = 0
        self.nonfinite_commands = 0
        self.too_long_replies = 0
        self.ignored_lines = 0
        self.lines_sent = 0
        self.restarts = 0
        self._buffer = bytearray()
        self._zero_opening = self.plant.opening
        self._rng = np.random.default_rng(seed)
        self._silent_until = -math.inf
        if boot:
            self._print_banner()

    # ------------------------------------------------------------------ host → firmware
    def receive(self, data: bytes) -> None:
        """Feed bytes written by the host (any split)."""
        for byte in data:
            if byte == 0x0A:
                self._handle(bytes(self._buffer))
                self._buffer.clear()
                continue
            self._buffer.append(byte)
            if len(self._buffer) > FIRMWARE_BUFFER_CHARS:
                self._buffer.clear()
                self.too_long_replies += 1
                self._print('Too long in read')

    def _handle(self, line: bytes) -> None:
        if not line.startswith(b'T'):
            self.ignored_lines += 1
            return
        self.commands.append(line)
        self.commands_received += 1
        value = atof(line[1:].decode('latin-1'))
        if math.isnan(value):
            # SimpleFOC would propagate NaN into the PWM; the emulator releases instead.
            self.nonfinite_commands += 1
            value = 0.0
        limit = self.params.voltage_limit
        self.target_voltage_v = min(max(value, -limit), limit)

    # ------------------------------------------------------------------ firmware → host
    def tick(self) -> bytes:
        """Advance one telemetry period; returns (and queues) the bytes printed meanwhile."""
        p = self.params
        sub = p.period / p.substeps
        for _ in range(p.substeps):
            self.plant.step(sub, self.target_voltage_v)
        self.time_s += p.period
        if self.time_s >= self._silent_until:
            self._print(f'{self.angle_rad():.4f}')
            self.lines_sent += 1
        out = bytes(self.output)
        self.output.clear()
        return out

    def angle_rad(self) -> float:
        """Encoder-quantised shaft angle relative to the last (re)start [rad]."""
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

    def restart(self, silence_s: float = 0.0) -> None:
        """Firmware reset: target 0 V, angle re-zeroed, boot banner, optional silence [s]."""
        self.restarts += 1
        self.target_voltage_v = 0.0
        self._buffer.clear()
        self._zero_opening = self.plant.opening
        self._silent_until = self.time_s + silence_s
        self._print_banner()

    def _print(self, text: str) -> None:
        self.output += text.encode('ascii') + b'\r\n'

    def _print_banner(self) -> None:
        for text in BOOT_BANNER:
            self._print(text)


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


class PtyFirmwareEmulator:
    """The emulator behind a pseudo-terminal, in real time (the device side of a fake port).

    Args:
        emulator: Firmware to serve (a default one when None).
        link_path: Optional symlink pointing at the current pty slave; it survives
            `vanish`/`reappear` like a ``/dev/serial/by-id`` path.
        realtime_scale: Emulator seconds per wall-clock second (1.0 = real time).
    """

    def __init__(self, emulator: FirmwareEmulator | None = None, *,
                 link_path: str | None = None, realtime_scale: float = 1.0) -> None:
        self.emulator = emulator if emulator is not None else FirmwareEmulator()
        self.link_path = link_path
        self.lock = threading.Lock()
        self.late_ticks = 0
        self.dropped_writes = 0
        self.vanished = 0
        self._scale = realtime_scale
        self._master = -1
        self._slave = -1
        self._slave_name = ''
        self._thread: threading.Thread | None = None
        self._running = False
        self._wake_r, self._wake_w = -1, -1

    @property
    def port(self) -> str:
        """Path for pyserial: the symlink if configured, else the pty slave."""
        return self.link_path or self._slave_name

    def start(self) -> str:
        """Create the pty and start the 500 Hz thread; returns `port`."""
        self._open_pty()
        self._running = True
        self._wake_r, self._wake_w = os.pipe()
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

    def reappear(self, reboot: bool = True) -> str:
        """The device re-enumerates under the same symlink (new pty); optional reboot."""
        if reboot:
            with self.lock:
                self.emulator.restart()
        return self.start()

    def inject(self, data: bytes | str) -> None:
        """Queue raw bytes on the output (thread-safe)."""
        with self.lock:
            self.emulator.inject(data)

    def restart(self, silence_s: float = 0.2) -> None:
        """Firmware restart with ``silence_s`` [s] of boot time (thread-safe)."""
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
        self._running = False
        if self._wake_w >= 0:
            os.write(self._wake_w, b'x')
        if self._thread is not None:
            self._thread.join(2.0)
        self._thread = None
        for fd in (self._wake_r, self._wake_w):
            if fd >= 0:
                os.close(fd)
        self._wake_r = self._wake_w = -1

    def _run(self) -> None:
        period = self.emulator.params.period / self._scale
        next_tick = time.monotonic() + period
        master, wake = self._master, self._wake_r
        while self._running:
            timeout = max(0.0, next_tick - time.monotonic())
            ready, _, _ = select.select([master, wake], [], [], timeout)
            if wake in ready:
                break
            if master in ready:
                try:
                    data = os.read(master, 4096)
                except BlockingIOError:
                    data = b''
                except OSError:  # EIO: no process has the slave open; nothing to read
                    data = b''
                if data:
                    with self.lock:
                        self.emulator.receive(data)
            now = time.monotonic()
            if now < next_tick:
                continue
            due = int((now - next_tick) / period) + 1
            self.late_ticks += due - 1
            next_tick += due * period
            with self.lock:
                out = b''.join(self.emulator.tick() for _ in range(due))
            self._send(master, out)

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
                    'answers T<volts>). Point the driver\'s serial.port at the printed path.')
    parser.add_argument('--link', default=None,
                        help='create this symlink to the pty (stable path across reappear)')
    parser.add_argument('--stroke', type=float, default=d.stroke, help='open limit [m]')
    parser.add_argument('--initial-opening', type=float, default=d.initial_opening,
                        help='opening at power-up [m]')
    parser.add_argument('--object-width', type=float, default=0.0,
                        help='object between the pads [m]; 0 = none')
    parser.add_argument('--object-stiffness', type=float, default=d.object_stiffness,
                        help='object stiffness [N/m]')
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
                               object_stiffness=args.object_stiffness)
    pty_emu = PtyFirmwareEmulator(FirmwareEmulator(model, seed=args.seed), link_path=args.link)
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
    if args.stats_json:
        e = pty_emu.emulator
        print(json.dumps({
            'lines_sent': e.lines_sent, 'commands_received': e.commands_received,
            'late_ticks': pty_emu.late_ticks, 'dropped_writes': pty_emu.dropped_writes,
            'too_long_replies': e.too_long_replies, 'nonfinite_commands': e.nonfinite_commands,
            'last_voltage_v': e.target_voltage_v, 'model': asdict(model)}), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
