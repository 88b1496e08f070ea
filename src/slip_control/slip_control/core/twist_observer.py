# SPDX-License-Identifier: Apache-2.0
"""Observer of the object's slip twist from the fingers' velocity sensors (filterpy Kalman filter).

Used by the ``model`` HOLD and HINGE laws (`model_hold`, `model_hinge`), which act on the
*state* of the slip, not on single samples: the optical-flow sensors report whole counts
(≈ 1 mm/s per count at 120 Hz, docs/control_and_estimation.md §6.8), so one sample is either 0
or a jump of a count. A constant-velocity Kalman filter per axis of the generalised slip twist
``(v̄x, v̄y, r·ω̄)`` [m/s] (two-finger means in ``gripper_middle``, `signals.combine_twists`)
turns the quantised samples into

* the slip velocity estimate ``v̂`` [m/s] (its norm is the slip speed, its first two components
  the grasp point's translation, the third ``r·ω̂``),
* the slip displacement ``p̂`` [m] since the observer started (third axis ``r·θ``).

Model per axis, state ``(p, v)``, sample interval ``dt`` [s] from the stamps::

    p ← p + v·dt,   v ← v + a·dt,   a ~ white, std ``accel_std`` [m/s²]
    z = v + n,      n ~ white, std ``velocity_noise`` [m/s] (≈ count/√12 plus sensor noise)

A repeated or older stamp skips the prediction. Slip is reported when the estimated translation
speed exceeds ``detect_speed`` or the rotation rate ``detect_rate`` (a slow turn of a small pad
moves its rim less than one count per sample). The LINEAR/ROTATIONAL model laws observe the
progress along the commanded slip instead (`slip_observer`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import KalmanFilter

from slip_control.core.signals import MiddleTwist

#: Axes of the generalised slip twist: x, y [m/s] and r·ω [m/s].
AXES = 3


@dataclass(frozen=True, slots=True)
class TwistObserverConfig:
    """Noise model and detection threshold of the observer (SI).

    Attributes:
        accel_std: Standard deviation of the slip acceleration driving the model [m/s²].
        velocity_noise: Standard deviation of one velocity sample [m/s].
        detect_speed: Estimated translation speed above which slip is reported [m/s].
        detect_rate: Estimated rotation rate above which slip is reported [rad/s].
    """

    accel_std: float = 0.3
    velocity_noise: float = 0.0005
    detect_speed: float = 0.0015
    detect_rate: float = 0.05

    def __post_init__(self) -> None:
        for name in ('accel_std', 'velocity_noise', 'detect_speed', 'detect_rate'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} must be finite and > 0, got {value!r}')


@dataclass(frozen=True, slots=True)
class SlipEstimate:
    """Observer output after one sample (``gripper_middle``, SI).

    Attributes:
        velocity: Estimated ``(v̄x, v̄y, r·ω̄)`` [m/s].
        displacement: Estimated slip ``(x, y, r·θ)`` since the observer started [m].
        speed: ``‖velocity‖`` [m/s].
        translation_speed: ``‖(v̄x, v̄y)‖`` [m/s].
        rotation_rate: Estimated ``ω̄`` [rad/s].
        slipping: ``translation_speed > detect_speed`` or ``|rotation_rate| > detect_rate``.
    """

    velocity: tuple[float, float, float]
    displacement: tuple[float, float, float]
    speed: float
    translation_speed: float
    rotation_rate: float
    slipping: bool


class TwistObserver:
    """Kalman filter of the generalised slip twist (module docstring).

    Args:
        config: Noise model and detection threshold.
        r: Torsional radius [m] that scales ``ω`` into the third axis (> 0).
    """

    def __init__(self, config: TwistObserverConfig, r: float) -> None:
        if not (math.isfinite(r) and r > 0.0):
            raise ValueError(f'r must be finite and > 0, got {r!r}')
        self._cfg = config
        self._r = r
        kf = KalmanFilter(dim_x=2 * AXES, dim_z=AXES)
        kf.x = np.zeros((2 * AXES, 1))
        # Known zero displacement, unknown initial slip velocity (a few counts).
        kf.P = np.diag([1e-12, 1e-5] * AXES)
        kf.H = np.zeros((AXES, 2 * AXES))
        for k in range(AXES):
            kf.H[k, 2 * k + 1] = 1.0
        kf.R = np.eye(AXES) * config.velocity_noise ** 2
        self._kf = kf
        self._last_stamp: float | None = None
        self._estimate = SlipEstimate((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, 0.0, 0.0, False)

    @property
    def estimate(self) -> SlipEstimate:
        """The latest estimate (zero before the first sample)."""
        return self._estimate

    @property
    def r(self) -> float:
        """Torsional radius of the third axis [m]."""
        return self._r

    def reset_time(self) -> None:
        """Forget the last stamp (clock jumped back): the next sample is not predicted to."""
        self._last_stamp = None

    def update(self, twist: MiddleTwist, stamp: float) -> SlipEstimate:
        """Take one two-finger mean twist stamped ``stamp`` [s]; returns the new estimate."""
        kf = self._kf
        last = self._last_stamp
        if last is not None and stamp > last:
            self._predict(stamp - last)
        if last is None or stamp > last:
            self._last_stamp = stamp
        kf.update(np.array([[twist.vx], [twist.vy], [self._r * twist.omega]]))
        x = kf.x[:, 0]
        vel = (float(x[1]), float(x[3]), float(x[5]))
        disp = (float(x[0]), float(x[2]), float(x[4]))
        speed = math.sqrt(vel[0] ** 2 + vel[1] ** 2 + vel[2] ** 2)
        trans = math.hypot(vel[0], vel[1])
        rate = vel[2] / self._r
        cfg = self._cfg
        self._estimate = SlipEstimate(
            velocity=vel, displacement=disp, speed=speed, translation_speed=trans,
            rotation_rate=rate,
            slipping=trans > cfg.detect_speed or abs(rate) > cfg.detect_rate)
        return self._estimate

    def _predict(self, dt: float) -> None:
        f = np.eye(2 * AXES)
        q = np.zeros((2 * AXES, 2 * AXES))
        # Discrete white-noise acceleration: G = (dt²/2, dt), Q = G Gᵀ σ_a².
        g = np.array([0.5 * dt * dt, dt])
        block = np.outer(g, g) * self._cfg.accel_std ** 2
        for k in range(AXES):
            f[2 * k, 2 * k + 1] = dt
            q[2 * k:2 * k + 2, 2 * k:2 * k + 2] = block
        self._kf.predict(F=f, Q=q)
