# SPDX-License-Identifier: Apache-2.0
"""Bristle integrators for the linear-in-state form ``ż = q − k·z`` (spec §8).

Every LuGre-type bristle in this package -- 1-D, per distributed cell, or the reduced model's
three states -- obeys, for a velocity and weight held constant over a step,

    ż = q − k·z,      q = drive (velocity),  k = β·σ0·‖v‖/g ≥ 0.

**Exponential update** (default; exact for frozen q and k):

    z⁺ = exp(−k·dt)·z + φ(k·dt)·dt·q,     φ(x) = (1 − exp(−x))/x = −expm1(−x)/x,  φ(0) = 1.

Rewriting ``exp(−x) = 1 − x·φ(x)`` gives the form used throughout the package,

    ż̄ = φ(k·dt)·(q − k·z),     z⁺ = z + dt·ż̄,

i.e. the explicit-Euler rate scaled by φ ∈ (0, 1]. ``ż̄`` is the exact mean rate over the step
and is what the σ1 damping term uses. The update is a convex combination of ``z`` and the fixed
point ``q/k``, so it cannot overshoot or diverge for any dt; ``k = 0`` (sticking, or the
purely elastic band of the Elasto-Plastic law) gives ``z⁺ = z + q·dt`` without a special case,
and it tends to explicit Euler as ``k·dt → 0`` (φ = 1 − k·dt/2 + O(dt²)).

**Explicit Euler** (``ż̄ = q − k·z``) reproduces the reference algorithm step for step for
regression work. It is stable only for ``k·dt < 2`` (monotone for ``k·dt < 1``); the optional
component-wise rate limiter (reference option ``stability``) clips each rate component to
``|ż_i| ≤ |z_ss,i − z_i|/dt`` so one step cannot jump past the steady deflection.

**Which state the force of a step uses** (``force_from``). The reference evaluates the force of
a step on the pre-update deflection, ``f = −(σ0 z + σ1 ż̄ + σ2 v)·f_n`` (``'pre_update'``,
the default, spec §4 item 8). Coupled to a rigid body whose position advances with the same
velocity, that one-step lag of the contact spring acts as a *negative* damping ``σ0 f_n dt``;
it exceeds the bristle damping ``σ1 f_n`` as soon as ``dt > σ1/σ0`` (80 µs for the default set)
and the coupled system then oscillates with growing amplitude whatever the bristle integrator.
``'post_update'`` uses ``σ0 z⁺`` instead; with the body update ``x⁺ = x + v dt`` (the velocity
passed to ``step``) followed by ``v⁺ = v + a dt`` this is the symplectic Euler method for the
contact spring, stable for ``ω_c dt < 2`` with ``ω_c = √(σ0 f_n/m)``. The two differ by
``σ0 f_n ż̄ dt`` per step, i.e. they agree as dt → 0.
"""
from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    'EULER_STABILITY_LIMIT',
    'ForceFrom',
    'Integrator',
    'UnstableStepError',
    'check_force_from',
    'check_integrator',
    'explicit_euler_step',
    'exponential_step',
    'phi',
    'phi_scalar',
    'rate_limit',
]

Integrator = Literal['exponential', 'explicit_euler']
ForceFrom = Literal['pre_update', 'post_update']

#: Explicit Euler on ``ż = q − k z`` diverges for ``k·dt > 2`` (per-step factor ``1 − k dt``).
EULER_STABILITY_LIMIT = 2.0

# Smallest argument passed to expm1(-x)/x; expm1 is exact to round-off down to the denormals,
# so clamping x = 0 to this value yields φ = 1 exactly without a branch.
_TINY = 1e-300


class UnstableStepError(ValueError):
    """Raised when an unlimited explicit-Euler step would diverge (``k·dt > 2``)."""


def check_integrator(integrator: str) -> Integrator:
    """Validate an integrator name.

    Args:
        integrator: ``'exponential'`` or ``'explicit_euler'``.

    Returns:
        The same name, typed.

    Raises:
        ValueError: For any other name.
    """
    if integrator == 'exponential':
        return 'exponential'
    if integrator == 'explicit_euler':
        return 'explicit_euler'
    raise ValueError(f"integrator must be 'exponential' or 'explicit_euler', got {integrator!r}")


def check_force_from(force_from: str) -> ForceFrom:
    """Validate a ``force_from`` option (``'pre_update'`` or ``'post_update'``)."""
    if force_from == 'pre_update':
        return 'pre_update'
    if force_from == 'post_update':
        return 'post_update'
    raise ValueError(f"force_from must be 'pre_update' or 'post_update', got {force_from!r}")


def phi(x: ArrayLike, out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Evaluate ``φ(x) = −expm1(−x)/x`` with ``φ(0) = 1`` (spec §8), element-wise.

    Args:
        x: Non-negative arguments ``k·dt`` (any shape).
        out: Optional float64 buffer of the same shape (may be ``x`` itself).

    Returns:
        φ(x) in (0, 1], same shape as ``x``.
    """
    xa = np.asarray(x, dtype=np.float64)
    if out is None:
        out = np.empty_like(xa)
    np.maximum(xa, _TINY, out=out)
    denominator = out.copy()
    np.negative(out, out=out)
    np.expm1(out, out=out)
    np.negative(out, out=out)
    np.divide(out, denominator, out=out)
    return out


def phi_scalar(x: float) -> float:
    """Scalar ``φ(x) = −expm1(−x)/x`` with ``φ(0) = 1``; see :func:`phi`."""
    if x <= _TINY:
        return 1.0
    return -math.expm1(-x) / x


def exponential_step(z: ArrayLike, q: ArrayLike, k: ArrayLike, dt: float,
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One exact step of ``ż = q − k z`` for frozen ``q`` and ``k`` (spec §8).

    Args:
        z: Current state (any shape; broadcast with ``q`` and ``k``).
        q: Drive term, same units as ż.
        k: Non-negative relaxation rate [1/s].
        dt: Step [s], > 0.

    Returns:
        ``(z_next, zdot_mean)`` where ``zdot_mean = (z_next − z)/dt`` is the mean rate.
    """
    za = np.asarray(z, dtype=np.float64)
    ka = np.asarray(k, dtype=np.float64)
    zdot = phi(ka * dt) * (np.asarray(q, dtype=np.float64) - ka * za)
    return za + dt * zdot, zdot


def rate_limit(zdot: NDArray[np.float64], z: ArrayLike, z_ss: ArrayLike, dt: float,
               out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Reference rate limiter: clip each component to ``|ż_i| ≤ |z_ss,i − z_i|/dt`` (spec §8).

    Component-wise (not a projection), keeping the sign of ``ż_i``; it may therefore rotate a
    2-D/3-D rate and it also caps the σ1 damping force. Kept for regression with the
    reference; the exponential integrator does not need it.

    Args:
        zdot: Unlimited rate.
        z: Current state.
        z_ss: Steady-state deflection at the current velocity.
        dt: Step [s].
        out: Optional output buffer (may be ``zdot``).

    Returns:
        The limited rate.
    """
    bound = np.abs(np.asarray(z_ss, dtype=np.float64) - np.asarray(z, dtype=np.float64)) / dt
    if out is None:
        out = np.empty_like(zdot)
    np.copyto(out, np.copysign(np.minimum(np.abs(zdot), bound), zdot))
    return out


def explicit_euler_step(z: ArrayLike, q: ArrayLike, k: ArrayLike, dt: float,
                        z_ss: ArrayLike | None = None,
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One explicit-Euler step of ``ż = q − k z`` (the reference scheme), optionally limited.

    Args:
        z: Current state.
        q: Drive term.
        k: Relaxation rate [1/s].
        dt: Step [s].
        z_ss: Steady-state deflection; when given, the rate limiter of :func:`rate_limit` is
            applied.

    Returns:
        ``(z_next, zdot)``.

    Raises:
        UnstableStepError: Without the limiter when ``max(k)·dt > 2`` (the step would diverge).
    """
    za = np.asarray(z, dtype=np.float64)
    ka = np.asarray(k, dtype=np.float64)
    zdot = np.asarray(q, dtype=np.float64) - ka * za
    if z_ss is None:
        kdt = float(np.max(ka)) * dt if ka.size else 0.0
        if kdt > EULER_STABILITY_LIMIT:
            raise UnstableStepError(
                f'explicit Euler step unstable: k*dt = {kdt:.3g} > 2; reduce dt, enable the '
                "rate limiter or use integrator='exponential'")
    else:
        zdot = rate_limit(zdot, za, z_ss, dt)
    return za + dt * zdot, zdot
