# SPDX-License-Identifier: Apache-2.0
"""Reference scenarios of the paper, shared by the tests, the CLI and the benchmarks (spec §10).

* :func:`twist_profile` -- the 5 s piecewise-linear CoP twist of paper §6.1 / spec §10.1.
* :func:`simulate_stick_slip` -- a mass pulled through a spring over a 1-D amended LuGre
  contact: stick-slip for μ_S > μ_C, steady sliding for μ_S = μ_C.
* :func:`simulate_drift` -- a planar rigid body held by one contact under oscillating
  sub-breakaway loads (paper §6.2 / spec §10.2), for any planar model.

Rigid-body coupling (see :mod:`.integrators`, ``force_from``): with a model that returns the
post-update wrench the body advances as ``x⁺ = x + v dt`` (the velocity the bristles saw) and
then ``v⁺ = v + a dt`` -- symplectic Euler for the contact spring, stable for
``ω_c dt < 2`` with ``ω_c = √(σ0 f_n/m)``. With the reference's pre-update wrench the
reference update ``x⁺ = x + v dt + ½ a dt²``, ``v⁺ = v + a dt`` is used, whose half-step lag
costs ``σ0 f_n dt/2`` of damping (it needs ``dt < 2σ1/σ0``).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal, NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .one_d import AmendedLuGre
from .params import LuGreParams
from .planar import Frame, Wrench

__all__ = [
    'DriftResult',
    'PlanarModel',
    'StickSlipResult',
    'drift_loads',
    'simulate_drift',
    'simulate_stick_slip',
    'twist_profile',
]

FloatArray = NDArray[np.float64]

# Knots of the §10.1 profile: time [s] → (vx [m/s], vy [m/s], ω [rad/s]) at the CoP.
_PROFILE_T = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.3, 2.8, 3.3, 3.8, 4.3, 4.6, 5.0])
_PROFILE_V = np.array([
    [0.0, 0.0, 0.0],        # rest
    [0.0, 0.0, 1.0],        # ω ramps to 1 rad/s (pure rotation about the CoP)
    [0.0, 0.0, 1.0],
    [0.015, 0.0, 1.0],      # vx superposed: the CoR leaves the patch ...
    [0.0, 0.0, 1.0],        # ... and comes back
    [0.0, 0.0, 1.0],
    [0.0, 0.006, 1.0],      # vy together with ω
    [0.0, 0.006, 1.0],
    [0.0, 0.006, 0.0],      # ω ramps down: pure translation
    [0.0, 0.006, 0.0],
    [0.0, 0.0, 0.0],        # everything stops
    [0.0, 0.0, 0.0],
])


def twist_profile(t: ArrayLike) -> FloatArray:
    """Piecewise-linear CoP twist of spec §10.1 at time(s) ``t`` [s].

    ω ramps to 1 rad/s; vx up to 15 mm/s is superposed and removed (the CoR sweeps out of the
    patch and back); then vy = 6 mm/s together with ω; ω ramps down leaving a pure
    translation; then everything stops (5 s in total).

    Args:
        t: Time(s) [s].

    Returns:
        Array of shape ``t.shape + (3,)``: ``(vx, vy, ω)`` [m/s, m/s, rad/s] at the CoP.
    """
    ta = np.asarray(t, dtype=np.float64)
    return np.stack([np.interp(ta, _PROFILE_T, _PROFILE_V[:, c]) for c in range(3)], axis=-1)


class StickSlipResult(NamedTuple):
    """Time series of :func:`simulate_stick_slip` (all arrays of equal length).

    Attributes:
        t: Time [s].
        x: Mass position [m].
        v: Mass velocity [m/s].
        spring_force: Spring force on the mass [N].
        friction: Friction force on the mass [N].
        drive_speed: Speed of the spring's far end [m/s].
    """

    t: FloatArray
    x: FloatArray
    v: FloatArray
    spring_force: FloatArray
    friction: FloatArray
    drive_speed: float

    def stick_phases(self, after: float = 0.0, stuck_fraction: float = 0.1,
                     slip_fraction: float = 3.0, min_stick: float = 0.02) -> int:
        """Count stick→slip cycles after time ``after`` [s].

        A cycle is a stick phase -- ``|v| < stuck_fraction·v_d`` for at least ``min_stick``
        seconds (so contact ringing after a slip does not count) -- followed by a slip with
        ``v > slip_fraction·v_d`` (``v_d`` the drive speed).
        """
        sel = self.t >= after
        v = np.abs(self.v[sel]) / self.drive_speed
        fast = self.v[sel] / self.drive_speed > slip_fraction
        dt = float(self.t[1] - self.t[0]) if self.t.size > 1 else 1.0
        need = max(1, round(min_stick / dt))
        count = 0
        run = 0
        armed = False
        for slow, slip in zip((v < stuck_fraction).tolist(), fast.tolist(), strict=True):
            run = run + 1 if slow else 0
            if run >= need:
                armed = True
            elif armed and slip:
                count += 1
                armed = False
        return count


def simulate_stick_slip(params: LuGreParams, *, f_n: float = 10.0, mass: float = 1.0,
                        stiffness: float = 1e4, drive_speed: float = 1e-3,
                        duration: float = 2.0, dt: float = 1e-4, elasto_plastic: bool = False,
                        ) -> StickSlipResult:
    """Pull a mass through a spring over an amended LuGre contact (classic stick-slip rig).

    The spring's far end moves at ``drive_speed``; ``m ẍ = k_s (v_d t − x) + f_friction``.
    With μ_S > μ_C the falling Stribeck curve makes steady sliding unstable and the mass
    alternately sticks and slips; with μ_S = μ_C it settles to sliding at ``v_d``.

    Args:
        params: Amended LuGre parameters.
        f_n: Normal force [N].
        mass: Mass [kg].
        stiffness: Spring stiffness [N/m].
        drive_speed: Pulling speed [m/s].
        duration: Simulated time [s].
        dt: Step [s].
        elasto_plastic: Use the Elasto-Plastic law.

    Returns:
        The time series.
    """
    steps = round(duration / dt)
    model = AmendedLuGre(params, elasto_plastic=elasto_plastic, force_from='post_update')
    t: FloatArray = np.arange(steps + 1, dtype=np.float64) * dt
    xs = np.zeros(steps + 1)
    vs = np.zeros(steps + 1)
    spring = np.zeros(steps + 1)
    fric = np.zeros(steps + 1)
    x = v = 0.0
    for n in range(steps):
        ff = float(model.step(v, f_n, dt))     # bristles advance with v over the step
        x += v * dt                            # ... and so does the mass (drift)
        fs = stiffness * (drive_speed * t[n + 1] - x)
        spring[n], fric[n] = fs, ff
        v += (fs + ff) / mass * dt             # kick with the end-of-step forces
        xs[n + 1], vs[n + 1] = x, v
    spring[steps] = stiffness * (drive_speed * t[steps] - x)
    fric[steps] = fric[steps - 1] if steps else 0.0
    return StickSlipResult(t, xs, vs, spring, fric, drive_speed)


class PlanarModel(Protocol):
    """What :func:`simulate_drift` needs from a planar model."""

    def step(self, twist: tuple[float, float, float], dt: float, f_n: float | None = None,
             frame: Frame = 'pad') -> Wrench:
        """Advance by dt and return the wrench."""


class DriftResult(NamedTuple):
    """Time series of :func:`simulate_drift`.

    Attributes:
        t: Time [s].
        x: Object displacement along x [m].
        theta: Object rotation [rad].
        f_n: Normal force [N].
    """

    t: FloatArray
    x: FloatArray
    theta: FloatArray
    f_n: FloatArray

    def period_mean(self, t0: float, period: float, series: str = 'x') -> float:
        """Mean of ``series`` over ``[t0, t0 + period)``."""
        data = getattr(self, series)
        sel = (self.t >= t0) & (self.t < t0 + period)
        return float(np.mean(data[sel]))


LoadCase = Literal['tangential', 'normal']


def drift_loads(case: LoadCase, f_n0: float = 9.81,
                ) -> Callable[[float], tuple[float, float, float]]:
    """Load functions of spec §10.2: ``t → (fx [N], τ [N·m], f_n [N])``."""
    def ramp(t: float, t0: float, t1: float) -> float:
        return min(max((t - t0) / (t1 - t0), 0.0), 1.0)

    def tangential(t: float) -> tuple[float, float, float]:
        fx = ramp(t, 0.0, 0.2) + (0.4 * math.sin(6 * math.pi * t) if t >= 1.0 else 0.0)
        tau = 0.03 * ramp(t, 2.8, 3.0) + (0.01 * math.sin(6 * math.pi * t) if t >= 3.0 else 0.0)
        return fx, tau, f_n0

    def normal(t: float) -> tuple[float, float, float]:
        r = ramp(t, 0.0, 0.2)
        fn = f_n0 + (math.sin(6 * math.pi * t) if t >= 1.0 else 0.0)
        return r, 0.03 * r, fn

    if case == 'tangential':
        return tangential
    if case == 'normal':
        return normal
    raise ValueError(f"load case must be 'tangential' or 'normal', got {case!r}")


def simulate_drift(model: PlanarModel, case: LoadCase = 'tangential', *, mass: float = 1.0,
                   inertia: float = 1.25e-3, f_n0: float = 9.81, duration: float = 5.0,
                   dt: float = 1e-4, record_every: int = 1) -> DriftResult:
    """Planar object held by one contact under oscillating sub-breakaway loads (spec §10.2).

    The object's twist is passed directly as the pad-centre twist and the returned friction
    wrench at the pad centre is applied to it, together with the external loads. The body
    update follows the model's ``force_from`` (module docstring).

    Args:
        model: A distributed or reduced planar model.
        case: ``'tangential'`` or ``'normal'`` load case.
        mass: Object mass [kg].
        inertia: Object inertia about z [kg·m²].
        f_n0: Nominal normal force [N].
        duration: Simulated time [s].
        dt: Step [s].
        record_every: Keep every n-th sample.

    Returns:
        Displacement and rotation histories.
    """
    loads = drift_loads(case, f_n0)
    steps = round(duration / dt)
    n_rec = steps // record_every + 1
    ts, xs, ths, fns = (np.zeros(n_rec) for _ in range(4))
    post = getattr(model, 'force_from', 'pre_update') == 'post_update'
    half = 0.0 if post else 0.5 * dt * dt
    x = y = th = vx = vy = om = 0.0
    for n in range(steps):
        t = n * dt
        fx_ext, tau_ext, fn = loads(t)
        w = model.step((vx, vy, om), dt, f_n=fn)
        ax = (fx_ext + w.fx) / mass
        ay = w.fy / mass
        alpha = (tau_ext + w.tau) / inertia
        x += vx * dt + half * ax
        y += vy * dt + half * ay
        th += om * dt + half * alpha
        vx += ax * dt
        vy += ay * dt
        om += alpha * dt
        if (n + 1) % record_every == 0:
            r = (n + 1) // record_every
            ts[r], xs[r], ths[r], fns[r] = (n + 1) * dt, x, th, fn
    return DriftResult(ts, xs, ths, fns)
