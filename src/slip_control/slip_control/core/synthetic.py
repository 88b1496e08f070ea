# SPDX-License-Identifier: Apache-2.0
"""Synthetic sensor streams with known contact properties (estimator tests and benchmarks).

Kinematic, not dynamic: the slip motion is prescribed and the friction wrench follows the
ellipsoidal limit surface with viscous terms (control_and_estimation §3.1)::

    f_t = (μ_c·v/s + μ_v·v)·f_n,   |τ| = (μ_c·r²·|ω|/s + μ_v·u·|ω|)·f_n,   s = ‖(v, r·ω)‖

while slipping (``s`` above a small threshold); while sticking, the pads carry the static
load (``f_t/f_n`` rising towards ``μ_s`` before breakaway). Optionally the pads also carry a
constant tangential load ``f_t0`` during rotation (gravity), in which case the torque is the
limit-surface capacity ``r·sqrt((μ_c f_n)² − f_t0²)``.

Sensors as in hardware_protocols §3–§5: F/T with Gaussian noise at 500 Hz; slip velocity at
≈ 120 Hz quantised by differencing integer counts of the integrated displacement (0.0079375 mm
per count) and of the angle (0.013/120 rad per count); finger 2's z flipped.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from slip_control.core.signals import SensorSnapshot, TwistSample, WrenchSample
from slip_control.core.trajectory import TrapezoidalTrajectory

COUNT_M = 0.0254 / 3200.0
ANGLE_COUNT = 0.013 / 120.0


@dataclass(frozen=True)
class TrueContact:
    """Ground truth of one pad (SI)."""

    mu_c: float = 0.45
    mu_s: float = 0.50
    mu_v: float = 2.0
    r: float = 0.006
    u: float = 3.6e-5


@dataclass(frozen=True)
class StreamNoise:
    """Sensor noise and rates."""

    force: float = 0.02          # [N] 1-σ per axis
    torque: float = 2e-4         # [N·m] 1-σ
    rate_hz: float = 120.0       # twist rate
    finger_2_delay: float = 0.001  # [s]
    quantise: bool = True


def _quantised_rate(x: NDArray[np.float64], count: float, dt: float,
                    quantise: bool) -> NDArray[np.float64]:
    """Per-sample rate from a sampled position by differencing integer counts."""
    if not quantise:
        return np.diff(x, prepend=x[0]) / dt
    c = np.floor(x / count)
    return np.diff(c, prepend=c[0]) * count / dt


def _friction(tc: TrueContact, f_n: NDArray[np.float64], v: NDArray[np.float64],
              w: NDArray[np.float64], f_t0: float) -> tuple[NDArray[np.float64],
                                                            NDArray[np.float64]]:
    """Tangential force and |torque| of a slipping pad (limit surface + viscous)."""
    aw = np.abs(w)
    s = np.hypot(v, tc.r * aw)
    s_safe = np.maximum(s, 1e-12)
    f_t = (tc.mu_c * v / s_safe + tc.mu_v * v) * f_n
    tau = (tc.mu_c * tc.r ** 2 * aw / s_safe + tc.mu_v * tc.u * aw) * f_n
    if f_t0 > 0.0:
        cap = np.sqrt(np.maximum((tc.mu_c * f_n) ** 2 - f_t0 ** 2, 0.0))
        rot = aw > 1e-9
        tau = np.where(rot, tc.r * cap + tc.mu_v * tc.u * aw * f_n, tau)
        f_t = np.where(rot & (v < 1e-4), f_t0, f_t)
    return f_t, tau


def stream(truth: tuple[TrueContact, TrueContact], t: NDArray[np.float64],
           slip: NDArray[np.float64], angle: NDArray[np.float64], f_n: NDArray[np.float64],
           *, t0: float = 0.0, f_t0: float = 0.0, slip_dir: tuple[float, float] = (0.6, 0.8),
           noise: StreamNoise = StreamNoise(), seed: int = 0,
           stick_mask: NDArray[np.bool_] | None = None) -> list[SensorSnapshot]:
    """Snapshots at the twist rate for a prescribed slip (same motion on both pads).

    Args:
        truth: Ground truth of fingers 1 and 2.
        t: Sample times relative to ``t0`` [s], uniform at ``noise.rate_hz``, shape (n,).
        slip: Slip distance along ``slip_dir`` (sensor xy of each pad) [m], shape (n,).
        angle: Slip angle [rad] (finger 1's z; finger 2 sees ``−angle``), shape (n,).
        f_n: Normal force per pad [N], shape (n,).
        t0: Absolute time of ``t = 0`` [s].
        f_t0: Tangential load carried during rotation [N] (gravity), 0 for none.
        slip_dir: Unit slip direction in each pad's sensor xy.
        noise: Sensor noise and rates.
        seed: RNG seed.
        stick_mask: Samples where the pads stick (``f_t/f_n`` ramps towards ``μ_s``).

    Returns:
        One snapshot per finger-1 twist; finger 2's twist lags by ``finger_2_delay``, the
        wrenches are the latest 500 Hz samples (up to 2 ms older).
    """
    rng = np.random.default_rng(seed)
    dt = 1.0 / noise.rate_hz
    n = t.size
    v_true = np.abs(np.gradient(slip, dt)) if n > 1 else np.zeros(n)
    w_true = np.gradient(angle, dt) if n > 1 else np.zeros(n)
    out_w: list[tuple[NDArray[np.float64], ...]] = []
    out_tw: list[tuple[NDArray[np.float64], ...]] = []
    for k, tc in enumerate(truth, start=1):
        f_t, tau = _friction(tc, f_n, v_true, w_true, f_t0)
        if stick_mask is not None and stick_mask.any():
            ramp = np.cumsum(stick_mask) / max(1, int(stick_mask.sum()))
            f_t = np.where(stick_mask, (0.2 + 0.8 * ramp) * tc.mu_s * f_n, f_t)
        sign = 1.0 if k == 1 else -1.0
        cx, cy = slip_dir
        fx = -f_t * cx + noise.force * rng.standard_normal(n)
        fy = -f_t * cy + noise.force * rng.standard_normal(n)
        fz = -f_n + noise.force * rng.standard_normal(n)
        tz = -sign * np.sign(w_true) * tau + noise.torque * rng.standard_normal(n)
        vx = _quantised_rate(slip * cx, COUNT_M, dt, noise.quantise)
        vy = _quantised_rate(slip * cy, COUNT_M, dt, noise.quantise)
        om = sign * _quantised_rate(angle, ANGLE_COUNT, dt, noise.quantise)
        out_w.append((fx, fy, fz, tz))
        out_tw.append((vx, vy, om))
    ft_lag = rng.uniform(0.0, 0.002, n)
    snaps = []
    snap = SensorSnapshot()
    (a1, b1, c1, d1), (a2, b2, c2, d2) = out_w
    (x1, y1, o1), (x2, y2, o2) = out_tw
    for i in range(n):
        ts = t0 + float(t[i])
        snap = (snap
                .with_wrench(1, WrenchSample(float(a1[i]), float(b1[i]), float(c1[i]),
                                             float(d1[i]), ts - float(ft_lag[i])))
                .with_wrench(2, WrenchSample(float(a2[i]), float(b2[i]), float(c2[i]),
                                             float(d2[i]), ts - float(ft_lag[i])))
                .with_twist(1, TwistSample(float(x1[i]), float(y1[i]), float(o1[i]), ts))
                .with_twist(2, TwistSample(float(x2[i]), float(y2[i]), float(o2[i]),
                                           ts - noise.finger_2_delay)))
        snaps.append(snap)
    return snaps


def exploration_linear(truth: tuple[TrueContact, TrueContact], *, t0: float = 0.0,
                       window: float = 1.0, descent: float = 0.01, descent_time: float = 0.8,
                       f_n: float = 5.0, noise: StreamNoise = StreamNoise(),
                       seed: int = 0) -> list[SensorSnapshot]:
    """Linear exploration of §3.8: the tool descends ``descent`` [m] in ``descent_time`` [s].

    The pads stick for the first 60 ms (load building up to breakaway), then the object
    slides along the trapezoidal descent; ``f_n`` [N] has a 5 % ripple.
    """
    dt = 1.0 / noise.rate_hz
    t = np.arange(0.0, window, dt)
    stick = 0.06
    traj = TrapezoidalTrajectory(descent, descent_time - stick)
    slip, _ = traj.sample_array(t - stick)
    fn = f_n * (1.0 + 0.05 * np.sin(2 * math.pi * 3.0 * t))
    return stream(truth, t, slip, np.zeros_like(t), fn, t0=t0, noise=noise, seed=seed,
                  stick_mask=t < stick)


def exploration_rotational(truth: tuple[TrueContact, TrueContact], *, t0: float = 0.0,
                           twist: float = 0.17453, twist_time: float = 0.5,
                           f_n: float = 5.0, noise: StreamNoise = StreamNoise(),
                           seed: int = 1) -> list[SensorSnapshot]:
    """Rotational exploration of §3.8: twist ``+twist`` [rad] in ``twist_time`` [s] and back."""
    dt = 1.0 / noise.rate_hz
    t = np.arange(0.0, 2.0 * twist_time, dt)
    traj = TrapezoidalTrajectory(twist, twist_time)
    up, _ = traj.sample_array(t)
    down, _ = traj.sample_array(t - twist_time)
    angle = up - down
    fn = f_n * (1.0 + 0.05 * np.sin(2 * math.pi * 2.0 * t))
    return stream(truth, t, np.zeros_like(t), angle, fn, t0=t0, noise=noise, seed=seed)


def controlled_slip(truth: tuple[TrueContact, TrueContact], *, t0: float = 0.0,
                    distance: float = 0.02, angle: float = 0.349, duration: float = 2.0,
                    f_t0: float = 1.0, noise: StreamNoise = StreamNoise(),
                    seed: int = 2) -> list[SensorSnapshot]:
    """A LINEAR slip then a ROTATIONAL slip (trapezoids), as the slip controllers produce.

    ``f_n`` [N] oscillates between ≈ 2.5 and 5 N as under the slip controllers; during the
    rotation the pads carry the tangential load ``f_t0`` [N].
    """
    dt = 1.0 / noise.rate_hz
    t = np.arange(0.0, 2.0 * duration, dt)
    x, _ = TrapezoidalTrajectory(distance, duration).sample_array(t)
    th, _ = TrapezoidalTrajectory(angle, duration).sample_array(t - duration)
    fn = 3.75 + 1.25 * np.sin(2 * math.pi * 2.7 * t)
    return stream(truth, t, x, th, fn, t0=t0, f_t0=f_t0, noise=noise, seed=seed)
