# SPDX-License-Identifier: Apache-2.0
"""Sensor models and sensor events of the simulated gripper cell (ROS-free, seeded).

Conventions of hardware_protocols §5.2, stamps are sim time of acquisition [s]:

* **F/T** (one per finger, ``ft_sensor_k``, ≈ 1 kHz): the wrench on the **pad**, i.e. minus the
  friction on the object for ``(Fx, Fy, Tz)``; ``Fz = −f_n`` (squeezing is negative on both
  sensors). ``Tx, Ty`` are the moments of that force about the sensor origin, which lies
  ``pad_offset`` behind the pad surface: with the normal force at the CoP ``(c_x, c_y)``,
  ``Tx = c_y·Fz − d·Fy``, ``Ty = d·Fx − c_x·Fz``. Each sensor adds a constant offset (unknown to
  the controller, so biasing matters) and white Gaussian noise.
* **Velocity sensor** (one per finger, ``vel_sensor_k``, ≈ 120 Hz): velocity of the object
  surface relative to the pad. The plant integrates the relative twist in ``gripper_middle``
  axes; a sample is the mean twist over its output period, rotated into the pad frame.
  ``ideal`` reports that mean; ``chips`` reproduces the device chain of hardware_protocols §3.4
  with the sensor package's own models: per-chip displacements through the rigid-body model
  matrix (:func:`~slip_velocity_sensor.core.fusion.model_matrix`, 3 chips at 240/120/0°,
  d = 24.3 mm), chips reading low by their gain ``b`` (raw = b·true), 3200-CPI counts with
  carried remainders (:class:`~slip_velocity_sensor.core.chip_model.CountQuantizer`), the device
  correction ``v = v_raw / b`` and least-squares fusion with outlier rejection
  (:class:`~slip_velocity_sensor.core.fusion.RigidBodyFusion`). One count per period is
  ≈ 0.95 mm/s raw, ≈ 0.013 rad/s in ω.
* **Motor encoder**: 4096 counts per revolution; the firmware prints the angle with four
  decimals (hardware_protocols §2.3).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TypeAlias, Union
from collections.abc import Iterator

import numpy as np

from slip_cell_common.core.param_schema import ranged_field as _f
from slip_gripper_driver.core.gripper_records import LineResult
from slip_velocity_sensor.core.chip_model import ChipModelParams, CountQuantizer
from slip_velocity_sensor.core.fusion import FusionParams, RigidBodyFusion

__all__ = [
    'FtSample',
    'FtSensor',
    'FtSensorParams',
    'MotorEncoder',
    'RateParams',
    'SimEvents',
    'TelemetrySample',
    'VelocitySample',
    'VelocitySensor',
    'VelocitySensorParams',
]

Vector6 = tuple[float, float, float, float, float, float]

#: Chip gains b (measured/true speed) per chip axis (x1, y1, x2, y2, x3, y3) of the two finger
#: sensors in use (hardware_protocols §3.6).
CHIP_GAINS_1: tuple[float, ...] = (0.8847, 0.9066, 0.8852, 0.8831, 0.9313, 0.9284)
CHIP_GAINS_2: tuple[float, ...] = (0.7086, 0.7029, 0.8573, 0.8800, 0.8861, 0.9008)


@dataclass(frozen=True)
class FtSensorParams:
    """F/T sensor model (parameter group ``ft``). Offsets are (Fx, Fy, Fz, Tx, Ty, Tz)."""

    offset_1: tuple[float, ...] = _f((0.35, -0.22, 1.10, 0.012, -0.008, 0.0021), 'N, N·m',
                                     -100.0, 100.0, 'constant offset of finger 1 sensor')
    offset_2: tuple[float, ...] = _f((-0.41, 0.18, 0.85, -0.006, 0.010, -0.0015), 'N, N·m',
                                     -100.0, 100.0, 'constant offset of finger 2 sensor')
    noise_std: float = _f(0.02, 'N', 0.0, 10.0, 'white noise of each force component')
    torque_noise_std: float = _f(2.5e-4, 'N·m', 0.0, 1.0,
                                 'white noise of each torque component')
    bias_duration: float = _f(0.1, 's', 0.001, 10.0, 'host-side bias averaging window')
    bias_min_samples: int = field(default=50, metadata={
        'unit': '-', 'range': (1, 100000), 'description': 'fewest samples in a bias average'})


@dataclass(frozen=True)
class VelocitySensorParams:
    """Velocity sensor model (parameter group ``velocity_sensor``)."""

    model: str = field(default='chips', metadata={
        'choices': ('ideal', 'chips'), 'description': 'ideal mean twist or quantised chips'})
    rate: float = _f(120.0, 'Hz', 1.0, 2000.0, 'output rate per finger')
    phase_2: float = _f(0.37, '-', 0.0, 1.0,
                        'finger 2 output phase as a fraction of the period')
    radius: float = _f(0.0243, 'm', 0.001, 0.5, 'chip distance from the sensor centre')
    chip_gains_1: tuple[float, ...] = _f(CHIP_GAINS_1, '-', 0.05, 5.0,
                                         'finger 1 chip gains b (x1, y1, x2, y2, x3, y3)')
    chip_gains_2: tuple[float, ...] = _f(CHIP_GAINS_2, '-', 0.05, 5.0,
                                         'finger 2 chip gains b (x1, y1, x2, y2, x3, y3)')
    count_noise_std: float = _f(0.0, 'counts', 0.0, 100.0,
                                'extra counts per output period per chip axis (chips model)')
    poll_period: float = _f(0.0017, 's', 1.0e-4, 0.1,
                            'chip poll period (sets the ±127-count saturation per poll)')


@dataclass(frozen=True)
class RateParams:
    """Sensor rates (parameter group ``rates``)."""

    telemetry: float = _f(500.0, 'Hz', 1.0, 10000.0, 'gripper telemetry and inner loop')
    ft: float = _f(1000.0, 'Hz', 1.0, 10000.0, 'F/T records per sensor')


# ---------------------------------------------------------------------------- events
#: One gripper telemetry line as the driver's bridge handled it: the status after the line,
#: the controller step (None while homing) and the command written (`GripperBridge.on_line`).
TelemetrySample: TypeAlias = LineResult


@dataclass(frozen=True, slots=True)
class FtSample:
    """One F/T record of one finger (``ft_sensor_k`` frame, SI).

    Attributes:
        stamp: Acquisition time [s].
        finger: 1 or 2.
        raw: ``(Fx, Fy, Fz, Tx, Ty, Tz)`` as measured [N, N·m] (offset and noise included).
        biased: ``raw`` minus the host-side bias (the driver's), or None before the first
            bias completed.
    """

    stamp: float
    finger: int
    raw: Vector6
    biased: Vector6 | None


@dataclass(frozen=True, slots=True)
class VelocitySample:
    """One velocity-sensor line of one finger (``vel_sensor_k`` frame, SI).

    Attributes:
        stamp: Acquisition time [s].
        finger: 1 or 2.
        vx: Object velocity relative to the pad, x [m/s].
        vy: Same, y [m/s].
        omega: Rotation rate about the pad z [rad/s].
        valid: Fused sample usable (always True in the simulation's fused mode).
    """

    stamp: float
    finger: int
    vx: float
    vy: float
    omega: float
    valid: bool = True


SimEvent = Union[TelemetrySample, FtSample, VelocitySample]


@dataclass
class SimEvents:
    """Sensor events of one `SimCell.advance` call, each list in time order.

    Iterating yields all events merged by stamp; at equal stamps F/T comes first, then
    velocity, then telemetry (the order in which the cell produced them).
    """

    telemetry: list[TelemetrySample] = field(default_factory=list)
    ft: list[FtSample] = field(default_factory=list)
    velocity: list[VelocitySample] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.telemetry) + len(self.ft) + len(self.velocity)

    def __iter__(self) -> Iterator[SimEvent]:
        keyed: list[tuple[float, int, int, SimEvent]] = \
            [(e.stamp, 0, i, e) for i, e in enumerate(self.ft)]
        keyed += [(e.stamp, 1, i, e) for i, e in enumerate(self.velocity)]
        keyed += [(e.stamp, 2, i, e) for i, e in enumerate(self.telemetry)]
        keyed.sort(key=lambda k: (k[0], k[1], k[2]))
        return (k[3] for k in keyed)

    def extend(self, other: SimEvents) -> None:
        """Append another batch (which must be later in time)."""
        self.telemetry.extend(other.telemetry)
        self.ft.extend(other.ft)
        self.velocity.extend(other.velocity)


# ---------------------------------------------------------------------------- F/T
class FtSensor:
    """Both F/T sensors: offsets plus white noise drawn in blocks from a seeded generator.

    Args:
        params: Sensor model.
        pad_offset: Distance from the sensor origin to the pad surface [m].
        rng: Random generator (consumed only by this object).
        block: Noise rows drawn at a time.
    """

    def __init__(self, params: FtSensorParams, pad_offset: float, rng: np.random.Generator,
                 block: int = 4096) -> None:
        self.params = params
        self.pad_offset = pad_offset
        self._rng = rng
        self._block = block
        std = np.array([params.noise_std] * 3 + [params.torque_noise_std] * 3)
        self._std = std
        self._offsets = (np.asarray(params.offset_1, dtype=np.float64),
                         np.asarray(params.offset_2, dtype=np.float64))
        self._rows: list[list[list[float]]] = [[], []]
        self._idx = [0, 0]

    def _refill(self, k: int) -> None:
        rows = self._offsets[k] + self._std * self._rng.standard_normal((self._block, 6))
        self._rows[k] = rows.tolist()
        self._idx[k] = 0

    def sample(self, finger: int, wrench: tuple[float, float, float], f_n: float,
               cop: tuple[float, float]) -> Vector6:
        """Raw reading of one sensor.

        Args:
            finger: 1 or 2.
            wrench: Friction on the object ``(fx, fy, τ)`` in the pad frame, about the pad
                centre [N, N, N·m].
            f_n: Normal force between pad and object (or the other pad) [N], ≥ 0.
            cop: Centre of pressure in the pad frame [m].

        Returns:
            ``(Fx, Fy, Fz, Tx, Ty, Tz)`` [N, N·m] in ``ft_sensor_k``.
        """
        k = finger - 1
        i = self._idx[k]
        if i >= len(self._rows[k]):
            self._refill(k)
            i = 0
        n = self._rows[k][i]
        self._idx[k] = i + 1
        fx, fy, fz = -wrench[0], -wrench[1], -f_n
        d = self.pad_offset
        cx, cy = cop
        return (fx + n[0], fy + n[1], fz + n[2], cy * fz - d * fy + n[3],
                d * fx - cx * fz + n[4], -wrench[2] + n[5])


# ---------------------------------------------------------------------------- velocity
class VelocitySensor:
    """One finger's velocity sensor fed by the plant's slip integral (module docstring).

    Args:
        finger: 1 or 2.
        params: Sensor model.
        mid_to_pad: Row-major 3×3 map from ``gripper_middle`` to the pad frame (twists).
        rng: Random generator for count noise.
    """

    def __init__(self, finger: int, params: VelocitySensorParams,
                 mid_to_pad: tuple[float, ...], rng: np.random.Generator) -> None:
        self.finger = finger
        self.params = params
        self.period = 1.0 / params.rate
        self._p = mid_to_pad
        self._chips = params.model == 'chips'
        gains = params.chip_gains_1 if finger == 1 else params.chip_gains_2
        if len(gains) != 6:
            raise ValueError(f'velocity_sensor.chip_gains_{finger} needs 6 values '
                             f'(x1, y1, x2, y2, x3, y3), got {len(gains)}')
        self._gains = tuple(float(b) for b in gains)
        self._fusion = RigidBodyFusion(FusionParams(radius=params.radius))
        # Per chip axis: model-matrix row (twist -> chip reading) and gain b.
        self._axes = tuple((a0, a1, a2, b) for (a0, a1, a2), b in
                           zip(self._fusion.matrix.tolist(), self._gains, strict=True))
        polls = max(1, int(round(self.period / params.poll_period)))
        chip = ChipModelParams(max_counts=127 * polls, count_noise_std=params.count_noise_std,
                               poll_period=params.poll_period)
        self._m_per_count = chip.metres_per_count
        self._quantizer = CountQuantizer(6, chip, rng if params.count_noise_std > 0 else None)
        self._last = (0.0, 0.0, 0.0)
        self._last_t = math.nan

    def reset(self, t: float) -> None:
        """Restart at ``t`` [s] with a zero slip integral (scene reset)."""
        self._last = (0.0, 0.0, 0.0)
        self._last_t = t
        self._quantizer.reset()

    def sample(self, t: float, slip_integral: list[float]) -> VelocitySample:
        """The sample at ``t`` [s] from the plant's ``∫ν dt`` in ``gripper_middle`` axes."""
        a0, a1, a2 = slip_integral
        l0, l1, l2 = self._last
        self._last = (a0, a1, a2)
        dt = t - self._last_t if math.isfinite(self._last_t) else self.period
        self._last_t = t
        d0, d1, d2 = a0 - l0, a1 - l1, a2 - l2
        p = self._p
        x = p[0] * d0 + p[1] * d1 + p[2] * d2       # pad-frame displacement over the period
        y = p[3] * d0 + p[4] * d1 + p[5] * d2
        th = p[6] * d0 + p[7] * d1 + p[8] * d2
        if dt <= 0.0:
            return VelocitySample(t, self.finger, 0.0, 0.0, 0.0, False)
        if not self._chips:
            return VelocitySample(t, self.finger, x / dt, y / dt, th / dt, True)
        counts = self._read_counts(x, y, th)
        if not any(counts):
            return VelocitySample(t, self.finger, 0.0, 0.0, 0.0, True)
        k = self._m_per_count / dt
        fused = self._fusion.fuse([c * k / b for c, b in zip(counts, self._gains)])
        return VelocitySample(t, self.finger, fused.vx, fused.vy, fused.omega, True)

    def _read_counts(self, x: float, y: float, th: float) -> list[int]:
        """Counts of the six chip axes for a pad-frame displacement ``(x, y, θ)`` [m, m, rad]:
        the raw chip displacements ``b·A·(x, y, θ)`` through the sensor package's counter."""
        return self._quantizer.read_counts(
            [b * (a0 * x + a1 * y + a2 * th) for a0, a1, a2, b in self._axes])


class MotorEncoder:
    """Motor angle as printed by the firmware: encoder counts, then four decimals.

    Args:
        counts_per_rev: Encoder counts per motor revolution.
    """

    def __init__(self, counts_per_rev: int) -> None:
        self._q = 2.0 * math.pi / counts_per_rev

    def read(self, angle_rad: float) -> float:
        """Reported angle [rad] for a true angle [rad]."""
        return round(math.floor(angle_rad / self._q + 0.5) * self._q, 4)
