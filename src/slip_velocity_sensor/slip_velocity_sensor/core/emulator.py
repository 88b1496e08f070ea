# SPDX-License-Identifier: Apache-2.0
"""Firmware emulator of the optical velocity sensor, in-process or on a pseudo-terminal.

The emulator plays the ESP32 firmware of hardware_protocols §3 at the byte level, so the
host code under test is the real parser, handshake and session. What it reproduces of the
shipped firmware (the behaviour observed on it wins where the spec says otherwise):

* **Two tasks.** A sensor task polls the three chips every ``chip.poll_period`` (≈ 1.7 ms): the
  true twist of the surface relative to the sensor (a motion callback ``t → (vx, vy, ω)``, SI,
  sensor frame) gives each chip's true velocity through the rigid-body model; the chips read
  low by the true calibration (`SensorCalibration`, raw = b·v/(1 − a·|v|)), and
  `CountQuantizer` turns motion into 3200-CPI counts with carried remainders and ±127
  saturation per poll. A serial task takes the counts, converts them to mm/s with its own dt,
  applies the device calibration ``v_raw/(b + a·v_raw)`` (signed v_raw like the shipped
  firmware, or |v_raw|), fuses with outlier rejection (`RigidBodyFusion` built with the
  uploaded radius), prints ``v/t%.4f/t%.4f/t%.4f`` and handles at most one command.
* **Serial period.** ``vTaskDelay(6)`` plus printing and scheduling: every period is drawn
  uniformly from 6–8 ms (125–167 Hz; ``output_period`` 7 ms ± ``period_jitter`` 1/7).
* **Chip re-sync.** When a chip does not answer its product-ID read (`set_chip_blind`,
  `inject_resync`), the sensor task prints ``n/tresynch`` and then the three product IDs as
  signed decimals separated by spaces (``0 49 49``: chip 1 holds its data line low; ``-1``: the
  line is pulled high) *before* it re-syncs, and repeats this on every pass (every
  ``resync_pass_period``, ≈ 6 ms) while the chip stays out. No chip is read meanwhile, so the
  serial task keeps printing ``v/t0.0000/t0.0000/t0.0000`` lines; the first line after the
  chip answers again covers part of the re-sync (reads low). Nothing marks the end: the notices
  just stop.
* **Commands.** ``n`` (name), ``c<k>`` (chip mode; single-chip lines carry chip k's raw
  chip-frame speeds and a stale ω), ``k<i><j><value>`` (radius in mm, per-chip a in 1/(mm/s)
  and b, with free-text replies); a 256-byte receive buffer; malformed commands are ignored.
* **Restart.** ESP32 ROM boot banner, silence for ``boot_duration``, calibration and chip mode
  back to the firmware defaults (a = 0, b = 1, radius 20.3 mm, fused).

Fault injection beyond the firmware: chips off the surface, count noise, garbage lines,
silence (a hung board), ``resync_on_identify`` (a transient re-sync that also loses the name
reply of an ``n`` command, to exercise the host's re-ask path; the real firmware would still
answer) and, on a pty, vanishing (unplugged).

`FirmwareEmulator` is time-driven (``advance(t)``), so tests can run it in virtual time.
`EmulatorStream` exposes it as an in-process byte stream; `PtyEmulator` serves it on a
pseudo-terminal whose slave path pyserial opens like a USB-UART. Emulators play the device and
may use real time.
"""
from __future__ import annotations

import argparse
import errno
import math
import os
import select
import signal
import sys
import threading
import time
import tty
from collections import deque
from dataclasses import dataclass, field, replace
from collections.abc import Callable, Sequence

import numpy as np

from slip_velocity_sensor.core import calibration as cal_mod
from slip_velocity_sensor.core import protocol
from slip_velocity_sensor.core.calibration import SensorCalibration, SpeedTerm
from slip_velocity_sensor.core.chip_model import ChipModelParams, CountQuantizer
from slip_velocity_sensor.core.fusion import (DEFAULT_CHIP_ANGLES, FusionParams, RigidBodyFusion,
                                              model_matrix)

#: Motion callback: time [s] → true twist (vx [m/s], vy [m/s], ω [rad/s]) of the surface
#: relative to the sensor, in the sensor frame.
MotionFn = Callable[[float], tuple[float, float, float]]

_UART_RX_BYTES = 256  # ESP32 Arduino default RX buffer: commands beyond it are lost


def still(t: float) -> tuple[float, float, float]:
    """No motion."""
    return (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ConstantTwist:
    """Constant twist motion (vx, vy [m/s], omega [rad/s])."""

    vx: float = 0.0
    vy: float = 0.0
    omega: float = 0.0

    def __call__(self, t: float) -> tuple[float, float, float]:
        """Twist at time ``t`` [s]."""
        return (self.vx, self.vy, self.omega)


@dataclass(frozen=True)
class SineTwist:
    """Sinusoidal twist ``amplitude · sin(2π f t)`` per component (SI)."""

    vx: float = 0.0
    vy: float = 0.0
    omega: float = 0.0
    frequency: float = 0.5

    def __call__(self, t: float) -> tuple[float, float, float]:
        """Twist at time ``t`` [s]."""
        s = math.sin(2.0 * math.pi * self.frequency * t)
        return (self.vx * s, self.vy * s, self.omega * s)


@dataclass(frozen=True)
class EmulatorParams:
    """Emulated sensor board (SI; device units only where the firmware has them).

    Attributes:
        name: Name compiled into the firmware (reply to ``n``).
        output_period: Mean serial task period [s] (7 ms: ``vTaskDelay(6)`` plus printing).
        period_jitter: Uniform jitter of each output period, fraction of the period (1/7:
            every period in 6–8 ms, 125–167 Hz, like the firmware).
        radius: Physical chip radius [m] (what the chips really see).
        chip_angles: Physical chip angles [rad].
        default_radius: Radius the firmware uses until ``k00`` sets it [m] (20.3 mm).
        outlier_threshold: Residual ratio above which the firmware drops the slowest chip.
        firmware_speed_term: Device law: ``signed_compat`` (shipped firmware) or ``abs``.
        truth: True chip behaviour: raw = b·v/(1 − a·term(v)) per chip axis.
        truth_speed_term: How ``truth.a`` enters (``abs``: direction-symmetric chips).
        chip: Counter model (resolution, saturation, poll period, count noise).
        chips_off: Chips (1..3) initially off the surface (read no motion).
        garbage_probability: Probability per output line of also emitting a garbage line.
        resync_on_identify: Number of ``n`` commands that start a transient re-sync and lose
            their name reply (injected fault; see the module docstring).
        resync_duration: How long a transient chip loss (`inject_resync`,
            ``resync_on_identify``) lasts [s].
        resync_pass_period: Time of one failing sensor pass (print the notice, re-sync) [s]:
            the notices repeat at this period.
        resync_chip: Chip (1..3) that drops out in a transient re-sync.
        resync_product_id: What that chip reads meanwhile: 0 (data line low) or -1 (high).
        boot_duration: Time from a restart's boot banner to the first line [s].
        reply_to_commands: Print free-text replies to ``k`` commands.
        seed: Seed of the emulator's random generator (jitter, noise, garbage).
    """

    name: str = 'sensor_1'
    output_period: float = 0.007
    period_jitter: float = 1.0 / 7.0
    radius: float = 0.0243
    chip_angles: tuple[float, ...] = DEFAULT_CHIP_ANGLES
    default_radius: float = 0.0203
    outlier_threshold: float = 0.2
    firmware_speed_term: str = SpeedTerm.SIGNED_COMPAT.value
    truth: SensorCalibration = field(default_factory=SensorCalibration)
    truth_speed_term: str = SpeedTerm.ABS.value
    chip: ChipModelParams = field(default_factory=ChipModelParams)
    chips_off: tuple[int, ...] = ()
    garbage_probability: float = 0.0
    resync_on_identify: int = 0
    resync_duration: float = 0.05
    resync_pass_period: float = 0.006
    resync_chip: int = 1
    resync_product_id: int = 0
    boot_duration: float = 0.3
    reply_to_commands: bool = True
    seed: int = 0

    def validate(self) -> None:
        """Raise ValueError on an unusable configuration."""
        if self.output_period * (1.0 - self.period_jitter) <= self.chip.poll_period:
            raise ValueError('output_period must exceed the chip poll period')
        if not 0.0 <= self.period_jitter < 0.5:
            raise ValueError('period_jitter must be in [0, 0.5)')
        if self.firmware_speed_term not in (SpeedTerm.SIGNED_COMPAT.value, SpeedTerm.ABS.value):
            raise ValueError('firmware_speed_term must be signed_compat or abs')
        if any(c not in (1, 2, 3) for c in self.chips_off):
            raise ValueError('chips_off entries must be 1..3')
        if self.resync_chip not in (1, 2, 3):
            raise ValueError('resync_chip must be 1..3')
        if self.resync_product_id == protocol.EXPECTED_PRODUCT_ID:
            raise ValueError('resync_product_id must differ from a healthy chip ID')
        if not self.resync_pass_period > 0.0 or self.resync_duration < 0.0:
            raise ValueError('resync_pass_period must be > 0 s and resync_duration >= 0 s')
        self.truth.validate()


class FirmwareEmulator:
    """Time-driven model of the sensor firmware (see the module docstring).

    Args:
        params: Board model.
        motion: True motion of the surface relative to the sensor; `still` when omitted.
    """

    def __init__(self, params: EmulatorParams | None = None,
                 motion: MotionFn | None = None) -> None:
        self.params = params if params is not None else EmulatorParams()
        self.params.validate()
        p = self.params
        self._motion: MotionFn = motion if motion is not None else still
        self._rng = np.random.default_rng(p.seed)
        self._a_true = model_matrix(p.radius, p.chip_angles)
        truth = p.truth
        self._truth_a = np.array([truth.axis(c, ax).a for c in (1, 2, 3) for ax in ('x', 'y')])
        self._truth_b = np.array([truth.axis(c, ax).b for c in (1, 2, 3) for ax in ('x', 'y')])
        self._quantizer = CountQuantizer(6, p.chip, self._rng)
        self._m_per_count = p.chip.metres_per_count
        self._rx = protocol.LineSplitter(64)
        self._commands: deque[bytes] = deque()
        self._rx_bytes = 0
        self._off = np.zeros(6, dtype=bool)
        for chip in p.chips_off:
            self._off[2 * (chip - 1):2 * chip] = True
        self._silent = False
        self._resyncs_left = p.resync_on_identify
        self._blind: dict[int, int] = {}            # chip -> product ID it reads
        self._transient_until: float | None = None  # end of an injected chip loss [s]
        self._next_pass: float | None = None        # next failing-pass check [s]
        self._busy_until = -math.inf                # chips not read before this [s]
        self._t_now = 0.0
        self._boot_end: float | None = None
        self._boot_announce = False
        self._started = False
        self._t_next = 0.0
        self._t_poll = 0.0
        self._t_take = 0.0
        self._acc = np.zeros(6, dtype=np.int64)
        self._restart_requested = False
        self._lock = threading.RLock()  # controls may be called from another thread
        self.received: list[tuple[float, bytes]] = []
        self.velocity_lines = 0
        self.garbage_lines = 0
        self.resync_notices = 0
        self._factory_reset()

    # ---------------------------------------------------------------- device state

    def _factory_reset(self) -> None:
        """Firmware defaults after power-up: fused mode, a = 0, b = 1, default radius."""
        self.chip_mode = 0
        self._last_omega = 0.0
        self.device_radius = self.params.default_radius
        self.device_a_per_mm_s = np.zeros(6)
        self.device_b = np.ones(6)
        self._fusion = self._device_fusion()
        self._commands.clear()
        self._rx.clear()
        self._rx_bytes = 0

    def _device_fusion(self) -> RigidBodyFusion:
        return RigidBodyFusion(FusionParams(radius=self.device_radius,
                                            chip_angles=self.params.chip_angles,
                                            outlier_threshold=self.params.outlier_threshold))

    @property
    def name(self) -> str:
        """Name the firmware answers to ``n``."""
        return self.params.name

    # ---------------------------------------------------------------- controls

    def set_motion(self, motion: MotionFn) -> None:
        """Replace the motion callback."""
        with self._lock:
            self._motion = motion

    def set_chip_off(self, chip: int, off: bool = True) -> None:
        """Lift chip 1..3 off the surface (reads no motion) or put it back."""
        if chip not in (1, 2, 3):
            raise ValueError(f'chip must be 1..3, got {chip!r}')
        with self._lock:
            self._off[2 * (chip - 1):2 * chip] = off

    def set_silent(self, silent: bool = True) -> None:
        """Stop (or resume) all output and command handling, like a hung board."""
        with self._lock:
            self._silent = silent

    def inject_resync(self, duration: float | None = None) -> None:
        """Let chip ``resync_chip`` drop out for ``duration`` [s] (``resync_duration``) from now.

        The sensor task prints ``n/tresynch`` and the product IDs on every pass until the chip
        answers again.
        """
        with self._lock:
            d = self.params.resync_duration if duration is None else duration
            self._start_transient(self._t_now, d)

    def set_chip_blind(self, chip: int, blind: bool = True, product_id: int = 0) -> None:
        """Make chip 1..3 stop answering (reads ``product_id``: 0 line low, -1 line high).

        The firmware then re-syncs on every pass until `set_chip_blind` (chip, False).
        """
        if chip not in (1, 2, 3):
            raise ValueError(f'chip must be 1..3, got {chip!r}')
        if product_id == protocol.EXPECTED_PRODUCT_ID:
            raise ValueError('a blind chip must read another ID than a healthy one')
        with self._lock:
            if blind:
                self._blind[chip] = product_id
                self._schedule_pass(self._t_now)
            else:
                self._blind.pop(chip, None)

    @property
    def resyncing(self) -> bool:
        """True while the sensor task re-syncs (the chips are not read)."""
        with self._lock:
            return self._next_pass is not None

    def restart(self) -> None:
        """Reset the board at the next serial iteration: boot banner, then firmware defaults.

        The uploaded calibration and chip mode are lost, as on the real board.
        """
        with self._lock:
            self._restart_requested = True

    # ---------------------------------------------------------------- I/O

    def receive(self, t: float, data: bytes) -> None:
        """Bytes from the host at ``t`` [s] (complete lines are queued as commands)."""
        with self._lock:
            if self._boot_end is not None:
                return  # a booting board drops what it receives
            self._receive_lines(t, data)

    def _receive_lines(self, t: float, data: bytes) -> None:
        for line, overflow in self._rx.feed(data):
            if overflow:
                continue
            if self._rx_bytes + len(line) + 1 > _UART_RX_BYTES:
                continue  # RX buffer full: lost, like on the device
            self._commands.append(line.rstrip(b'\r'))
            self._rx_bytes += len(line) + 1
            self.received.append((t, line.rstrip(b'\r')))

    def next_output_time(self) -> float:
        """Time of the next serial iteration [s]."""
        return self._t_next

    def advance(self, t: float) -> bytes:
        """Run the firmware up to time ``t`` [s]; return the bytes it printed."""
        with self._lock:
            if not self._started:
                self._started = True
                self._t_poll = self._t_take = t
                self._t_next = t + self._period()
            out = bytearray()
            while True:
                t_pass = self._next_pass if self._next_pass is not None else math.inf
                if min(t_pass, self._t_next) > t:
                    break
                if t_pass <= self._t_next:  # the two tasks run on two cores: time order
                    out += self._sensor_pass(t_pass)
                else:
                    out += self._serial_iteration(self._t_next)
                    self._t_next += self._period()
            self._t_now = max(self._t_now, t)
            return bytes(out)

    # ---------------------------------------------------------------- internals

    def _period(self) -> float:
        p = self.params
        if p.period_jitter <= 0.0:
            return p.output_period
        return p.output_period * (1.0 + self._rng.uniform(-p.period_jitter, p.period_jitter))

    def _poll_chips(self, until: float) -> None:
        p = self.params
        dt = p.chip.poll_period
        booting = self._boot_end is not None
        while self._t_poll + dt <= until:
            mid = self._t_poll + 0.5 * dt
            self._t_poll += dt
            if booting or self._t_poll <= self._busy_until:  # re-syncing: chips not read
                continue
            v_true = self._a_true @ np.asarray(self._motion(mid), dtype=np.float64)
            v_raw = self._truth_b * v_true / (1.0 - self._truth_a * self._truth_term(v_true))
            v_raw[self._off] = 0.0
            self._acc += self._quantizer.read(v_raw * dt)

    def _truth_term(self, v: np.ndarray) -> np.ndarray:
        if self.params.truth_speed_term == SpeedTerm.SIGNED_COMPAT.value:
            return v
        if self.params.truth_speed_term == SpeedTerm.ZERO.value:
            return np.zeros_like(v)
        magnitude: np.ndarray = np.abs(v)
        return magnitude

    def _serial_iteration(self, t: float) -> bytes:
        out = bytearray()
        if self._restart_requested:
            self._restart_requested = False
            self._factory_reset()
            self._boot_announce = True
            self._boot_end = t + self.params.boot_duration
        if self._boot_announce:
            self._boot_announce = False
            out += (b'ESP-ROM:esp32s3-emulated\r\n'
                    b'rst:0x1 (POWERON),boot:0x8 (SPI_FAST_FLASH_BOOT)\r\n')
        if self._boot_end is not None:
            if t < self._boot_end:
                self._t_poll = self._t_take = t
                return bytes(out)
            self._boot_end = None
            self._quantizer.reset()
            if self._blind or self._transient_until is not None:
                self._schedule_pass(t)  # the sensor task starts with a product-ID check
        self._poll_chips(t)
        counts = self._acc.copy()
        self._acc[:] = 0
        dt = t - self._t_take
        self._t_take = t
        if self._silent:
            return bytes(out)
        out += self._velocity_line(counts, dt)
        if self.params.garbage_probability > 0.0 and \
                self._rng.random() < self.params.garbage_probability:
            out += self._garbage()
        if self._commands:
            out += self._handle(t, self._commands.popleft())
        return bytes(out)

    # ---------------------------------------------------------------- chip re-sync

    def _start_transient(self, t: float, duration: float) -> None:
        end = t + duration
        self._transient_until = max(end, self._transient_until or end)
        self._schedule_pass(t)

    def _schedule_pass(self, t: float) -> None:
        """Check the product IDs at the next chip poll after ``t`` [s]."""
        if self._next_pass is None:
            dt = self.params.chip.poll_period
            self._next_pass = max(self._t_poll, t - dt) + dt

    def _chip_ids(self, t: float) -> tuple[int, int, int]:
        ids = [protocol.EXPECTED_PRODUCT_ID] * protocol.N_CHIPS
        for chip, pid in self._blind.items():
            ids[chip - 1] = pid
        if self._transient_until is not None:
            if t < self._transient_until:
                ids[self.params.resync_chip - 1] = self.params.resync_product_id
            else:
                self._transient_until = None
        return ids[0], ids[1], ids[2]

    def _sensor_pass(self, t: float) -> bytes:
        """One sensor-task pass while re-syncing: check the IDs; notice and re-sync if bad."""
        self._next_pass = None
        if self._boot_end is not None:
            return b''  # the board is restarting; the check resumes with the task
        self._poll_chips(t)  # everything read before this pass counts
        ids = self._chip_ids(t)
        if all(pid == protocol.EXPECTED_PRODUCT_ID for pid in ids):
            self._quantizer.reset()  # the chips were reset: carried sub-counts are gone
            return b''
        period = self.params.resync_pass_period
        self._busy_until = t + period
        self._next_pass = t + period
        self.resync_notices += 1
        if self._silent:
            return b''
        return f'n/tresynch\r\n{ids[0]} {ids[1]} {ids[2]}\r\n'.encode('ascii')

    def _velocity_line(self, counts: np.ndarray, dt: float) -> bytes:
        mm_per_count = self._m_per_count * protocol.MM_PER_M
        v_raw_mm_s = counts * (mm_per_count / dt)
        self.velocity_lines += 1
        if self.chip_mode:
            k = self.chip_mode - 1
            return protocol.format_velocity_line(v_raw_mm_s[2 * k], v_raw_mm_s[2 * k + 1],
                                                 self._last_omega)
        if self.params.firmware_speed_term == SpeedTerm.ABS.value:
            term = np.abs(v_raw_mm_s)
        else:
            term = v_raw_mm_s
        v_mm_s = v_raw_mm_s / (self.device_b + self.device_a_per_mm_s * term)
        fused = self._fusion.fuse(v_mm_s / protocol.MM_PER_M)
        self._last_omega = fused.omega
        return protocol.format_velocity_line(fused.vx * protocol.MM_PER_M,
                                             fused.vy * protocol.MM_PER_M, fused.omega)

    def _garbage(self) -> bytes:
        self.garbage_lines += 1
        kind = int(self._rng.integers(0, 6))
        if kind == 0:  # random bytes, may contain newlines
            return bytes(self._rng.integers(0, 256, int(self._rng.integers(1, 48)),
                                            dtype=np.uint8))
        if kind == 1:
            return b'v\t1.0000\t2.0000\t0.0100\r\n'  # TAB instead of "/t"
        if kind == 2:
            return b'v/ t1.0000/ t2.0000/ t0.0100\r\n'
        if kind == 3:
            return b'v/tnan/t0.0000/t0.0000\r\n'
        if kind == 4:
            return b'v/t12.34'  # truncated: merges with the next line
        return b'debug: \xff\xfe chip poll overrun\r\n'

    def _handle(self, t: float, command: bytes) -> bytes:
        self._rx_bytes = max(0, self._rx_bytes - len(command) - 1)
        text = command.decode('ascii', 'replace').strip()
        if text == 'n':
            if self._resyncs_left > 0:  # injected fault: a chip drops out, the reply is lost
                self._resyncs_left -= 1
                self._start_transient(t, self.params.resync_duration)
                return b''
            return f'n/t{self.params.name}\r\n'.encode('ascii')
        if len(text) == 2 and text[0] == 'c' and text[1] in '0123':
            self.chip_mode = int(text[1])
            return b''
        if len(text) >= 4 and text[0] == 'k' and text[1] in '0123' and text[2] in '0123':
            return self._set_calibration(int(text[1]), int(text[2]), text[3:])
        return b''

    def _set_calibration(self, i: int, j: int, value_text: str) -> bytes:
        try:
            value = float(value_text)
        except ValueError:
            return b''
        if not math.isfinite(value):
            return b''
        reply = ''
        if i == 0:
            if value <= 0.0:
                return b''
            self.device_radius = value / protocol.MM_PER_M
            self._fusion = self._device_fusion()
            reply = f'radius is updated to: {value:.2f}'
        else:
            axis = 2 * (i - 1) + (0 if j < 2 else 1)
            if j in (0, 2):
                self.device_a_per_mm_s[axis] = value
                reply = f'a in filter updated to: {value:.6f}'
            else:
                self.device_b[axis] = value
                reply = f'b in filter updated to: {value:.4f}'
        if not self.params.reply_to_commands:
            return b''
        return (reply + '\r\n').encode('ascii')

    def device_calibration(self) -> SensorCalibration:
        """The calibration currently in the device, converted to SI (for tests)."""
        chips = []
        for c in range(3):
            axes = [cal_mod.AxisCalibration(a=float(self.device_a_per_mm_s[2 * c + k])
                                            * protocol.MM_PER_M,
                                            b=float(self.device_b[2 * c + k])) for k in (0, 1)]
            chips.append(cal_mod.ChipCalibration(x=axes[0], y=axes[1]))
        return SensorCalibration(sensor=self.params.name, radius=self.device_radius,
                                 chips=tuple(chips), source='device')


class EmulatorStream:
    """In-process byte stream over a `FirmwareEmulator` (read/write/close like pyserial).

    Emulator time is ``clock() − clock()`` at construction. With a fake ``clock``/``sleep``
    pair the whole exchange runs in virtual time.

    Args:
        emulator: The firmware model.
        clock: Time source [s].
        sleep: Blocking wait [s] used while ``read`` waits for data.
        timeout: Read timeout [s] (like pyserial's ``timeout``).
        port: Name reported in errors.
    """

    def __init__(self, emulator: FirmwareEmulator, *, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep, timeout: float = 0.02,
                 port: str = 'emulator://') -> None:
        self.emulator = emulator
        self.timeout = timeout
        self.port = port
        self._clock = clock
        self._sleep = sleep
        self._t0 = clock()
        self._buf = bytearray()
        self._closed = False
        self._vanished = False
        self._lock = threading.Lock()

    def _now(self) -> float:
        return self._clock() - self._t0

    def _check(self) -> None:
        if self._vanished:
            raise OSError(errno.EIO, f'{self.port}: emulated device unplugged')
        if self._closed:
            raise OSError(errno.EBADF, f'{self.port}: stream closed')

    def _pump(self) -> None:
        self._buf += self.emulator.advance(self._now())

    @property
    def in_waiting(self) -> int:
        """Bytes readable without blocking."""
        with self._lock:
            self._check()
            self._pump()
            return len(self._buf)

    def read(self, size: int = 1) -> bytes:
        """Read up to ``size`` bytes, waiting at most ``timeout`` for the first."""
        deadline = self._clock() + self.timeout
        while True:
            with self._lock:
                self._check()
                self._pump()
                if self._buf:
                    data = bytes(self._buf[:size])
                    del self._buf[:size]
                    return data
                wait = min(deadline - self._clock(),
                           self.emulator.next_output_time() - self._now())
            if self._clock() >= deadline:
                return b''
            self._sleep(max(wait, 1e-4))

    def write(self, data: bytes) -> int:
        """Send bytes to the emulated firmware."""
        with self._lock:
            self._check()
            self.emulator.receive(self._now(), bytes(data))
        return len(data)

    def reset_input_buffer(self) -> None:
        """Discard unread output."""
        with self._lock:
            self._pump()
            self._buf.clear()

    def close(self) -> None:
        """Close the stream."""
        self._closed = True

    def vanish(self) -> None:
        """Unplug: every later read or write raises ``OSError(EIO)``."""
        self._vanished = True


class PtyEmulator:
    """Serve a `FirmwareEmulator` on a pseudo-terminal in a background thread.

    Open `port` (the slave path) with pyserial like a USB-UART. `vanish` closes the master side,
    which is what unplugging the adapter looks like to the host (reads fail with EIO).

    Args:
        emulator: The firmware model.
        clock: Real-time source [s] (the emulator plays the device in real time).
        record_write_times: Keep the clock time at which each velocity line was written
            (`write_times`, for latency benchmarks).
    """

    def __init__(self, emulator: FirmwareEmulator, *,
                 clock: Callable[[], float] = time.monotonic,
                 record_write_times: bool = False) -> None:
        self.emulator = emulator
        self._clock = clock
        self._record = record_write_times
        self.write_times: list[float] = []
        self.bytes_dropped = 0
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.port = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._fd_lock = threading.Lock()
        self._t0 = 0.0

    def start(self) -> PtyEmulator:
        """Start serving; returns self."""
        if self._thread is None:
            self._t0 = self._clock()
            self._thread = threading.Thread(target=self._run, name=f'pty-emulator {self.port}',
                                            daemon=True)
            self._thread.start()
        return self

    def now(self) -> float:
        """Emulator time [s]."""
        return self._clock() - self._t0

    def stop(self) -> None:
        """Stop serving and close the pseudo-terminal."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(2.0)
        self._close_fds()

    def vanish(self) -> None:
        """Unplug: close the pty at once; the host's next read fails with EIO."""
        self._stop.set()
        self._close_fds()

    def _close_fds(self) -> None:
        with self._fd_lock:
            for name in ('_master', '_slave'):
                fd = getattr(self, name)
                if fd >= 0:
                    os.close(fd)
                    setattr(self, name, -1)

    def __enter__(self) -> PtyEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _run(self) -> None:
        em = self.emulator
        while not self._stop.is_set():
            # The fds are only used under the lock, so vanish() never closes one mid-call and a
            # recycled descriptor number is never polled.
            with self._fd_lock:
                master = self._master
                if master < 0:
                    return
                out = em.advance(self.now())
                if out:
                    self._write(master, out)
                timeout = min(max(em.next_output_time() - self.now(), 0.0), 0.01)
                ready, _, _ = select.select([master], [], [], timeout)
                data = self._read(master) if ready else b''
            if data is None:  # EIO: no slave side open at the moment; do not spin
                self._stop.wait(0.005)
            elif data:
                em.receive(self.now(), data)

    @staticmethod
    def _read(master: int) -> bytes | None:
        try:
            return os.read(master, 4096)
        except BlockingIOError:
            return b''
        except OSError:
            return None

    def _write(self, master: int, data: bytes) -> None:
        try:
            written = os.write(master, data)
        except BlockingIOError:
            written = 0
        except OSError:
            return
        if written < len(data):  # nobody reads the port: a UART drops what it cannot send
            self.bytes_dropped += len(data) - written
        if self._record:
            t = self._clock()
            self.write_times.extend([t] * data[:written].count(b'v/t'))


# --------------------------------------------------------------------------- command line


def _parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    defaults = EmulatorParams()
    parser = argparse.ArgumentParser(
        prog='velocity_sensor_emulator',
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
        description='Emulate one optical velocity sensor on a pseudo-terminal, with the '
                    'firmware\'s timing and chip re-sync output (see the module docstring of '
                    'slip_velocity_sensor.core.emulator). Prints the port path (open it as the '
                    'node\'s "port" parameter); Ctrl-C or SIGTERM stops.')
    add = parser.add_argument
    add('--name', default=defaults.name, help='name answered to "n"')
    add('--rate', type=float, default=round(1.0 / defaults.output_period, 3),
        help='mean output rate [Hz] (the firmware: about 143 Hz, periods of 6-8 ms)')
    add('--jitter', type=float, default=round(defaults.period_jitter, 4),
        help='uniform jitter of each output period, as a fraction of the mean period '
             '(0.1429 at 143 Hz: 6-8 ms like the firmware; 0: a fixed period)')
    add('--truth', default='',
        help='calibration YAML describing how the emulated chips read low ("": ideal chips)')
    add('--motion', choices=('still', 'constant', 'sine'), default='still',
        help='true motion of the surface relative to the sensor')
    add('--vx', type=float, default=0.0, help='[m/s] (amplitude for sine)')
    add('--vy', type=float, default=0.0, help='[m/s] (amplitude for sine)')
    add('--omega', type=float, default=0.0, help='[rad/s] (amplitude for sine)')
    add('--frequency', type=float, default=0.5, help='sine frequency [Hz]')
    add('--chip-off', type=int, action='append', default=[], choices=(1, 2, 3),
        help='chip lifted off the surface: reads no motion (repeatable)')
    add('--blind-chip', type=int, action='append', default=[], choices=(1, 2, 3),
        help='chip that does not answer at all: the firmware prints its re-sync notices on '
             'every pass and zero velocity lines (repeatable)')
    add('--blind-id', type=int, default=0, choices=(0, -1),
        help='product ID a blind chip reads: 0 (data line low) or -1 (pulled high)')
    add('--noise', type=float, default=0.0, help='count noise std per poll [counts]')
    add('--garbage', type=float, default=0.0, help='probability per line of a garbage line')
    add('--resync-on-identify', type=int, default=0,
        help='the first N "n" commands start a transient chip re-sync and lose their reply '
             '(injected fault)')
    add('--resync-duration', type=float, default=defaults.resync_duration,
        help='length of a transient chip re-sync [s]')
    add('--firmware-speed-term', default='signed_compat', choices=('signed_compat', 'abs'),
        help='how the device applies the calibration a-term (shipped firmware: signed_compat)')
    add('--duration', type=float, default=0.0, help='stop after [s]; 0 = never')
    add('--link', default='', help='also create this symlink to the pty ("": none)')
    add('--seed', type=int, default=0, help='seed of the emulator\'s random generator')
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point (``velocity_sensor_emulator``)."""
    args = _parse_args(argv)
    truth = cal_mod.load_calibration(args.truth) if args.truth else SensorCalibration()
    chip = replace(ChipModelParams(), count_noise_std=args.noise)
    params = EmulatorParams(name=args.name, output_period=1.0 / args.rate,
                            period_jitter=args.jitter, truth=truth,
                            radius=truth.radius, chip=chip, chips_off=tuple(args.chip_off),
                            garbage_probability=args.garbage,
                            resync_on_identify=args.resync_on_identify,
                            resync_duration=args.resync_duration,
                            firmware_speed_term=args.firmware_speed_term, seed=args.seed)
    motion: MotionFn = still
    if args.motion == 'constant':
        motion = ConstantTwist(args.vx, args.vy, args.omega)
    elif args.motion == 'sine':
        motion = SineTwist(args.vx, args.vy, args.omega, args.frequency)
    stop = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: stop.set())
    emulator = FirmwareEmulator(params, motion)
    for blind in args.blind_chip:
        emulator.set_chip_blind(blind, product_id=args.blind_id)
    pty_emulator = PtyEmulator(emulator)
    if args.link:
        if os.path.lexists(args.link):
            os.remove(args.link)
        os.symlink(pty_emulator.port, args.link)
    sys.stdout.write(f'{pty_emulator.port}\n')
    sys.stdout.flush()
    pty_emulator.start()
    try:
        stop.wait(args.duration if args.duration > 0.0 else None)
    finally:
        pty_emulator.stop()
        if args.link and os.path.islink(args.link):
            os.remove(args.link)
    return 0


if __name__ == '__main__':
    sys.exit(main())
