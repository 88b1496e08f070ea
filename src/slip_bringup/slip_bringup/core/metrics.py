# SPDX-License-Identifier: Apache-2.0
"""Evaluation metrics of control_and_estimation §6.4–6.7, from arrays (bags or simulation).

* §6.4 estimation spread: mean and SD of ``μ_c, μ_s, μ_v, r`` over repeated explorations, with
  validity counts and mean sample counts.
* §6.5 linear slip: final distance by integrating the magnitude of the two-finger mean
  middle-frame velocity ``‖v̄‖`` (reference definition) and, ours, the signed projection
  ``v̄·ê``; tracking errors against the trapezoid.
* §6.6 rotational slip: final angle by integrating ``(ω1 − ω2)/2`` in the raw sensor frames
  (finger 2's z is flipped); tracking errors.
* §6.7 hold and hinge: peak slip distance and angle (largest excursion of the integrated
  mean slip from the start) and the force range; force statistics.
* the final estimate of a run: the last valid value of each quantity (`last_valid`).

Integration is trapezoidal on the sample stamps; intervals with ``dt ≤ 0`` contribute
nothing (CE-6). All inputs are SI.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from slip_cell_common.core.frames import FrameParams, planar_to_middle
from slip_control.core.contact import ContactProperties

FloatArray = NDArray[np.float64]


def cumulative_integral(t: ArrayLike, y: ArrayLike) -> FloatArray:
    """Trapezoidal running integral of ``y`` over stamps ``t`` (shape (n,) or (n, k)).

    Intervals with ``dt ≤ 0`` (duplicates, out-of-order stamps) are skipped. The first
    element is 0.
    """
    ta = np.asarray(t, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    if ta.size == 0:
        return np.zeros_like(ya)
    dt = np.diff(ta)
    dt = np.where(dt > 0.0, dt, 0.0)
    mid = 0.5 * (ya[1:] + ya[:-1])
    if ya.ndim == 2:
        steps = mid * dt[:, None]
        return np.vstack([np.zeros((1, ya.shape[1])), np.cumsum(steps, axis=0)])
    return np.concatenate([[0.0], np.cumsum(mid * dt)])


def to_middle(frames: FrameParams, finger: int, x: ArrayLike, y: ArrayLike,
              z: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Vectorised `frames.planar_to_middle` for a finger's ``(x, y, z)`` series.

    The fixed planar rotation is read off `planar_to_middle` applied to the unit vectors, so
    the frame conventions live in one place.
    """
    ex = planar_to_middle(frames, finger, 1.0, 0.0, 0.0)
    ey = planar_to_middle(frames, finger, 0.0, 1.0, 0.0)
    ez = planar_to_middle(frames, finger, 0.0, 0.0, 1.0)
    xa, ya, za = (np.asarray(a, dtype=np.float64) for a in (x, y, z))
    return (ex[0] * xa + ey[0] * ya, ex[1] * xa + ey[1] * ya, ez[2] * za)


# --- §6.4 -------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class Spread:
    """Mean and sample SD of one quantity over the valid estimates (NaN if none)."""

    mean: float
    sd: float
    n: int


@dataclass(frozen=True, slots=True)
class FingerSpread:
    """Estimation spread of one finger (§6.4)."""

    mu_c: Spread
    mu_s: Spread
    mu_v: Spread
    r: Spread
    n_runs: int
    n_linear_valid: int
    n_rotational_valid: int
    mean_n_linear: float
    mean_n_rotational: float


def spread(values: Sequence[float]) -> Spread:
    """Mean and sample SD of the finite ``values`` (SD NaN below two values)."""
    return _spread(values)


def _spread(values: Sequence[float]) -> Spread:
    a = np.asarray([v for v in values if math.isfinite(v)], dtype=np.float64)
    if a.size == 0:
        return Spread(math.nan, math.nan, 0)
    sd = float(a.std(ddof=1)) if a.size > 1 else math.nan
    return Spread(float(a.mean()), sd, int(a.size))


def estimation_spread(sets: Sequence[ContactProperties]) -> tuple[FingerSpread, FingerSpread]:
    """Spread of repeated estimates per finger (§6.4).

    ``μ_c, μ_s`` use the ``linear_valid`` estimates, ``μ_v`` the ``viscous_valid`` ones, ``r``
    the ``rotational_valid`` ones.
    """
    out = []
    for k in (1, 2):
        fs = [s.finger(k) for s in sets]
        lin = [f for f in fs if f.linear_valid]
        out.append(FingerSpread(
            mu_c=_spread([f.mu_c for f in lin]), mu_s=_spread([f.mu_s for f in lin]),
            mu_v=_spread([f.mu_v for f in fs if f.viscous_valid]),
            r=_spread([f.r for f in fs if f.rotational_valid]), n_runs=len(fs),
            n_linear_valid=len(lin), n_rotational_valid=sum(f.rotational_valid for f in fs),
            mean_n_linear=float(np.mean([f.n_linear for f in fs])) if fs else math.nan,
            mean_n_rotational=float(np.mean([f.n_rotational for f in fs])) if fs else math.nan))
    return out[0], out[1]


# --- §6.5 -------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class LinearSlipDistance:
    """Final linear slip (§6.5).

    Attributes:
        magnitude: ``∫‖v̄‖ dt`` [m] (reference definition; counts noise and reversals as
            progress).
        signed: ``∫ v̄·ê dt`` [m].
        direction: ``ê`` used (given, or the direction of the net displacement).
    """

    magnitude: float
    signed: float
    direction: tuple[float, float]


def linear_slip_distance(t: ArrayLike, v1_middle: ArrayLike, v2_middle: ArrayLike,
                         direction: tuple[float, float] | None = None) -> LinearSlipDistance:
    """Final slip distance from both fingers' middle-frame velocities (§6.5).

    Args:
        t: Stamps [s], shape (n,).
        v1_middle: Finger-1 velocity in ``gripper_middle`` xy [m/s], shape (n, 2).
        v2_middle: Finger-2 velocity in ``gripper_middle`` xy [m/s], shape (n, 2).
        direction: Slip direction ``ê`` (normalised here); ``None`` uses the net displacement.
    """
    vm = 0.5 * (np.asarray(v1_middle, dtype=np.float64) + np.asarray(v2_middle,
                                                                     dtype=np.float64))
    mag = cumulative_integral(t, np.hypot(vm[:, 0], vm[:, 1]))
    disp = cumulative_integral(t, vm)
    if direction is None:
        net = disp[-1]
        n = float(np.hypot(net[0], net[1]))
        e = (float(net[0] / n), float(net[1] / n)) if n > 0.0 else (1.0, 0.0)
    else:
        n = math.hypot(direction[0], direction[1])
        if not n > 0.0:
            raise ValueError('direction must be non-zero')
        e = (direction[0] / n, direction[1] / n)
    signed = float(disp[-1, 0] * e[0] + disp[-1, 1] * e[1])
    return LinearSlipDistance(float(mag[-1]), signed, e)


@dataclass(frozen=True, slots=True)
class TrackingErrors:
    """Errors of a slip trajectory against its trapezoid (§6.5, §6.6), SI.

    Attributes:
        pos_rms: RMS of ``x_d − x`` [m | rad].
        pos_max: Max ``|x_d − x|``.
        vel_rms: RMS of ``v_d − v`` [m/s | rad/s].
        vel_max: Max ``|v_d − v|``.
        final_error: Last ``x_d − x``.
    """

    pos_rms: float
    pos_max: float
    vel_rms: float
    vel_max: float
    final_error: float


def tracking_errors(ref_pos: ArrayLike, meas_pos: ArrayLike, ref_vel: ArrayLike,
                    meas_vel: ArrayLike) -> TrackingErrors:
    """RMS and maximum tracking errors of a ``slip_control/tracking`` series."""
    ep = np.asarray(ref_pos, dtype=np.float64) - np.asarray(meas_pos, dtype=np.float64)
    ev = np.asarray(ref_vel, dtype=np.float64) - np.asarray(meas_vel, dtype=np.float64)
    if ep.size == 0:
        nan = math.nan
        return TrackingErrors(nan, nan, nan, nan, nan)
    return TrackingErrors(float(np.sqrt(np.mean(ep ** 2))), float(np.max(np.abs(ep))),
                          float(np.sqrt(np.mean(ev ** 2))), float(np.max(np.abs(ev))),
                          float(ep[-1]))


# --- §6.6 -------------------------------------------------------------------------------------

def rotational_slip_angle(t: ArrayLike, omega1_raw: ArrayLike, omega2_raw: ArrayLike) -> float:
    """Final rotation [rad]: ``∫ (ω1 − ω2)/2 dt`` with raw-frame rates (§6.6)."""
    w = 0.5 * (np.asarray(omega1_raw, dtype=np.float64)
               - np.asarray(omega2_raw, dtype=np.float64))
    return float(cumulative_integral(t, w)[-1])


# --- §6.7 -------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class HoldMetrics:
    """Hold/hinge disturbance metrics (§6.7).

    Attributes:
        peak_slip_distance: Largest ``‖∫v̄ dt‖`` from the start [m].
        peak_slip_angle: Largest ``|∫ω̄ dt|`` from the start [rad].
        final_slip_distance: ``‖∫v̄ dt‖`` at the end [m].
        force_min: Minimum grasp force [N].
        force_max: Maximum grasp force [N].
    """

    peak_slip_distance: float
    peak_slip_angle: float
    final_slip_distance: float
    force_min: float
    force_max: float

    @property
    def force_range(self) -> float:
        """``force_max − force_min`` [N]."""
        return self.force_max - self.force_min


def hold_metrics(t: ArrayLike, v_middle: ArrayLike, omega_middle: ArrayLike,
                 force: ArrayLike) -> HoldMetrics:
    """Peak slip and force range under disturbance (§6.7).

    Args:
        t: Stamps [s], shape (n,).
        v_middle: Two-finger mean slip velocity ``v̄`` in ``gripper_middle`` [m/s], (n, 2).
        omega_middle: Two-finger mean rate ``ω̄`` [rad/s], shape (n,).
        force: Grasp force (measured or commanded) [N], shape (n,).
    """
    disp = cumulative_integral(t, v_middle)
    dist = np.hypot(disp[:, 0], disp[:, 1])
    ang = cumulative_integral(t, omega_middle)
    f = np.asarray(force, dtype=np.float64)
    return HoldMetrics(float(dist.max()), float(np.abs(ang).max()), float(dist[-1]),
                       float(f.min()), float(f.max()))


@dataclass(frozen=True, slots=True)
class ForceStats:
    """Statistics of a grasp-force series [N] (finite samples only; NaN when none)."""

    min: float
    max: float
    mean: float
    sd: float
    n: int

    @property
    def span(self) -> float:
        """``max − min`` [N] (§6.7)."""
        return self.max - self.min


def force_stats(force: ArrayLike) -> ForceStats:
    """Min, max, mean and sample SD of the finite samples of ``force`` [N]."""
    f = np.asarray(force, dtype=np.float64)
    f = f[np.isfinite(f)]
    if f.size == 0:
        return ForceStats(math.nan, math.nan, math.nan, math.nan, 0)
    sd = float(f.std(ddof=1)) if f.size > 1 else math.nan
    return ForceStats(float(f.min()), float(f.max()), float(f.mean()), sd, int(f.size))


# --- §6.4: the final estimate ----------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class FinalValue:
    """One quantity of the final estimate and where it came from.

    Attributes:
        value: The last valid, finite value (NaN when no estimate has it).
        std: Its 1-sigma uncertainty as published with it (NaN if unknown).
        index: Index of the estimate it was taken from (−1: none).
    """

    value: float
    std: float
    index: int


def last_valid(values: Sequence[float], stds: Sequence[float],
               valid: Sequence[bool]) -> FinalValue:
    """The final estimate of one quantity: the last one that is valid and finite.

    Estimates arrive in stages (the linear phase publishes ``μ_c`` with ``r`` still NaN, the
    rotational phase completes the set), so the final value is the last complete one — never
    a mean over partial sets, where one NaN would hide a good estimate.
    """
    for i in range(len(values) - 1, -1, -1):
        v = float(values[i])
        if valid[i] and math.isfinite(v):
            s = float(stds[i])
            return FinalValue(v, s if math.isfinite(s) else math.nan, i)
    return FinalValue(math.nan, math.nan, -1)
