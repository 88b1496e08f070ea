# SPDX-License-Identifier: Apache-2.0
"""One-dimensional friction laws (thesis §2.1, spec §2), vectorised over any batch shape.

Sign convention: every function and ``step`` returns the friction force **on the object**,
which opposes the sliding velocity ``v`` (object relative to the surface) [N]. ``f_n ≥ 0`` is
the normal force [N].

Static laws:

* Coulomb (eq 2.1): sliding ``f = −μ_C f_n sgn(v)``; sticking: the force balances the applied
  tangential load up to ``μ_C f_n``.
* Stribeck (eq 2.2): ``f = −(μ_C + (μ_S − μ_C) exp(−(|v|/v_s)^γ) + μ_v |v|)·f_n·sgn(v)``.

Dynamic (bristle) laws, all of the form ``ż = v − k·z`` with ``k ≥ 0``:

* Dahl (eqs 2.3-2.4): ``k = σ0|v|/f_c``, ``f_c = μ_C f_n``; ``f = −σ0 z`` (σ0 in N/m).
* LuGre (eqs 2.5-2.7): ``k = σ0|v|/g(v)``, ``g = f_c + (f_s − f_c) exp(−|v/v_s|^γ)``;
  ``f = −(σ0 z + σ1 ż + σ2 v)``.
* Amended LuGre (eqs 2.8-2.10): ``g`` dimensionless (``μ_C + (μ_S − μ_C)·exp(...)``), σ0 in
  1/m, ``f = −(σ0 z + σ1 ż + σ2 v)·f_n``; a time-varying ``f_n`` needs no state rescaling.
* Elasto-Plastic (eqs 2.11-2.13): amended LuGre with ``k`` multiplied by
  ``α(z, v)`` (:func:`ep_weight`): 0 when unloading (``sgn v ≠ sgn z``) or inside the elastic
  band ``|z| ≤ z_ba = r_ba·z_max``, 1 beyond ``z_max = g/σ0``, a smooth sine blend between.
  Inside the band ``ż = v`` exactly, so oscillating sub-breakaway loads cause no creep.

Integration: :mod:`.integrators` (exponential by default; the force uses the pre-update ``z``
-- or the post-update one with ``force_from='post_update'`` for rigid-body coupling -- and the
step-mean rate). For the Elasto-Plastic law the exponential step additionally keeps
``|z⁺| ≤ max(|z|, z_max)``, the bound the continuous dynamics obey.
"""
from __future__ import annotations

import math
from typing import Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .integrators import (EULER_STABILITY_LIMIT, ForceFrom, Integrator, UnstableStepError,
                          check_force_from, check_integrator)
from .params import (DEFAULT_PARAMS, ClassicLuGreParams, DahlParams, LuGreParams,
                     StribeckParams)

__all__ = [
    'AmendedLuGre',
    'Coulomb',
    'Dahl',
    'ElastoPlastic',
    'LuGre',
    'Stribeck',
    'ep_weight',
    'lugre_steady_state',
    'stribeck_curve',
]

FloatArray = NDArray[np.float64]
_TINY = 1e-300
#: Floor of the friction bound g [N or -] so that k = σ0|v|/g stays finite at f_n = 0.
_G_FLOOR = 1e-12
# Frozen (immutable) instances, safe as default arguments.
_CLASSIC_DEFAULT = ClassicLuGreParams()
_DAHL_DEFAULT = DahlParams()
_STRIBECK_DEFAULT = StribeckParams()


def stribeck_curve(v: ArrayLike, mu_c: float, mu_s: float, v_s: float,
                   stribeck_exp: float) -> FloatArray:
    """``g(v) = μ_C + (μ_S − μ_C)·exp(−(|v|/v_s)^γ)`` (eqs 2.2/2.9), element-wise, even in v.

    Args:
        v: Sliding speed(s) [m/s].
        mu_c: Coulomb coefficient.
        mu_s: Static coefficient.
        v_s: Stribeck velocity [m/s].
        stribeck_exp: Exponent γ.

    Returns:
        g(v) [-].
    """
    x = np.abs(np.asarray(v, dtype=np.float64)) / v_s
    return mu_c + (mu_s - mu_c) * np.exp(-np.power(x, stribeck_exp))


def lugre_steady_state(v: ArrayLike, f_n: ArrayLike, params: LuGreParams) -> FloatArray:
    """Steady sliding force of the amended LuGre law (spec A1): ``−(g(v) sgn v + σ2 v)·f_n``.

    Args:
        v: Sliding velocity [m/s].
        f_n: Normal force [N].
        params: Amended LuGre parameters.

    Returns:
        Force on the object [N].
    """
    va = np.asarray(v, dtype=np.float64)
    g = stribeck_curve(va, params.mu_c, params.mu_s, params.v_s, params.stribeck_exp)
    return -(g * np.sign(va) + params.sigma2 * va) * np.asarray(f_n, dtype=np.float64)


def ep_weight(z: ArrayLike, v: ArrayLike, z_max: ArrayLike, r_ba: float) -> FloatArray:
    """One-dimensional Elasto-Plastic weight α(z, v) (thesis eq 2.13, spec §2).

    Args:
        z: Bristle deflection [m].
        v: Sliding velocity [m/s].
        z_max: Steady deflection ``g(v)/σ0`` at the current speed [m] (> 0).
        r_ba: Elastic band ratio ``z_ba/z_max`` in [0, 1).

    Returns:
        α ∈ [0, 1]: 0 when ``sgn v ≠ sgn z`` or ``|z| ≤ z_ba``, 1 when ``|z| ≥ z_max``, and
        ``½ sin(π(|z| − (z_max + z_ba)/2)/(z_max − z_ba)) + ½`` in between.
    """
    za = np.asarray(z, dtype=np.float64)
    va = np.asarray(v, dtype=np.float64)
    u = (np.abs(za) / np.asarray(z_max, dtype=np.float64) - r_ba) / (1.0 - r_ba)
    alpha = np.sin(0.5 * math.pi * np.clip(u, 0.0, 1.0)) ** 2
    return np.where(np.sign(va) == np.sign(za), alpha, 0.0)


class Coulomb:
    """Coulomb friction (eq 2.1) with a sticking branch.

    Args:
        mu_c: Friction coefficient [-].
        v_eps: Speeds with ``|v| ≤ v_eps`` [m/s] count as sticking.
    """

    def __init__(self, mu_c: float, v_eps: float = 1e-9) -> None:
        if not (math.isfinite(mu_c) and mu_c >= 0.0):
            raise ValueError(f'mu_c must be finite and >= 0, got {mu_c!r}')
        self.mu_c = float(mu_c)
        self.v_eps = float(v_eps)

    def force(self, v: ArrayLike, f_n: ArrayLike, f_applied: ArrayLike = 0.0) -> FloatArray:
        """Friction force on the object [N].

        Args:
            v: Sliding velocity [m/s].
            f_n: Normal force [N].
            f_applied: Other tangential load on the object [N] (used while sticking).

        Returns:
            ``−μ f_n sgn v`` when sliding; ``−clip(f_applied, ±μ f_n)`` when sticking.
        """
        va = np.asarray(v, dtype=np.float64)
        bound = self.mu_c * np.asarray(f_n, dtype=np.float64)
        stick = -np.clip(np.asarray(f_applied, dtype=np.float64), -bound, bound)
        return np.where(np.abs(va) > self.v_eps, -bound * np.sign(va), stick)


class Stribeck:
    """Static Stribeck friction (eq 2.2) with a sticking branch bounded by μ_S f_n.

    Args:
        params: Stribeck parameters.
    """

    def __init__(self, params: StribeckParams = _STRIBECK_DEFAULT) -> None:
        self.params = params

    def coefficient(self, v: ArrayLike) -> FloatArray:
        """Friction coefficient ``μ(v) = g(v) + μ_v |v|`` [-] (even in v)."""
        p = self.params
        va = np.asarray(v, dtype=np.float64)
        return stribeck_curve(va, p.mu_c, p.mu_s, p.v_s, p.stribeck_exp) + p.mu_v * np.abs(va)

    def force(self, v: ArrayLike, f_n: ArrayLike, f_applied: ArrayLike = 0.0) -> FloatArray:
        """Friction force on the object [N] (odd in v; sticking for ``|v| ≤ v_eps``)."""
        p = self.params
        va = np.asarray(v, dtype=np.float64)
        fn = np.asarray(f_n, dtype=np.float64)
        bound = p.mu_s * fn
        stick = -np.clip(np.asarray(f_applied, dtype=np.float64), -bound, bound)
        return np.where(np.abs(va) > p.v_eps, -self.coefficient(va) * fn * np.sign(va), stick)


class _Bristle1D:
    """Shared state handling and integration of ``ż = v − k z`` for the 1-D bristle laws."""

    def __init__(self, shape: tuple[int, ...], integrator: str, rate_limiter: bool,
                 force_from: str = 'pre_update') -> None:
        self._force_from: ForceFrom = check_force_from(force_from)
        self._integrator: Integrator = check_integrator(integrator)
        if rate_limiter and self._integrator != 'explicit_euler':
            raise ValueError("rate_limiter applies to integrator='explicit_euler' only")
        self._limiter = bool(rate_limiter)
        self._z: FloatArray = np.zeros(shape)

    @property
    def z(self) -> FloatArray:
        """Bristle deflection(s) [m] (copy)."""
        return self._z.copy()

    def set_state(self, z: ArrayLike) -> None:
        """Set the deflection(s) [m] (broadcast to the model's shape)."""
        self._z = np.array(np.broadcast_to(np.asarray(z, dtype=np.float64), self._z.shape))

    def reset(self) -> None:
        """Zero the deflection(s)."""
        self._z = np.zeros_like(self._z)

    @property
    def force_from(self) -> ForceFrom:
        """Deflection used by the returned force: ``'pre_update'`` or ``'post_update'``."""
        return self._force_from

    def _force_state(self, z_pre: FloatArray) -> FloatArray:
        return z_pre if self._force_from == 'pre_update' else self._z

    def _advance(self, v: FloatArray, k: FloatArray, z_ss: FloatArray, dt: float,
                 z_bound: FloatArray | None) -> FloatArray:
        """Integrate one step, store ``z⁺`` and return the step-mean rate ``ż̄``.

        Args:
            v: Drive velocity [m/s].
            k: Relaxation rate [1/s].
            z_ss: Steady deflection (limiter only) [m].
            dt: Step [s].
            z_bound: When given, ``|z⁺|`` is limited to ``max(|z|, z_bound)`` (EP).
        """
        if not dt > 0.0:
            raise ValueError(f'dt must be > 0 s, got {dt!r}')
        z = self._z
        rate = v - k * z
        if self._integrator == 'exponential':
            x = np.maximum(k * dt, _TINY)
            rate = rate * (-np.expm1(-x) / x)
            z_new = z + dt * rate
            if z_bound is not None:
                bound = np.maximum(np.abs(z), z_bound)
                over = np.abs(z_new) > bound
                if np.any(over):
                    z_new = np.where(over, np.copysign(bound, z_new), z_new)
                    rate = (z_new - z) / dt
        else:
            if self._limiter:
                lim = np.abs(z_ss - z) / dt
                rate = np.copysign(np.minimum(np.abs(rate), lim), rate)
            else:
                kdt = float(np.max(k)) * dt if k.size else 0.0
                if kdt > EULER_STABILITY_LIMIT:
                    raise UnstableStepError(
                        f'explicit Euler step unstable: k*dt = {kdt:.3g} > 2; reduce dt, '
                        "enable rate_limiter or use integrator='exponential'")
            z_new = z + dt * rate
        self._z = z_new
        return rate


class Dahl(_Bristle1D):
    """Dahl friction (eqs 2.3-2.4): ``ż = v − σ0|v| z/f_c``, ``f = −σ0 z``; no Stribeck effect.

    Args:
        params: Dahl parameters (σ0 in N/m).
        shape: Batch shape of the state (``()`` for one contact).
        integrator: ``'exponential'`` or ``'explicit_euler'``.
        rate_limiter: Reference limiter (explicit Euler only).
        force_from: ``'pre_update'`` (reference) or ``'post_update'`` deflection in the
            returned force; use the latter for rigid-body coupling (:mod:`.integrators`).
    """

    def __init__(self, params: DahlParams = _DAHL_DEFAULT, shape: tuple[int, ...] = (),
                 integrator: str = 'exponential', rate_limiter: bool = False,
                 force_from: str = 'pre_update') -> None:
        super().__init__(shape, integrator, rate_limiter, force_from)
        self.params = params

    def step(self, v: ArrayLike, f_n: ArrayLike, dt: float) -> FloatArray:
        """Advance by ``dt`` at velocity ``v`` [m/s]; return the force on the object [N]."""
        p = self.params
        va = np.asarray(v, dtype=np.float64)
        f_c = np.maximum(p.mu_c * np.asarray(f_n, dtype=np.float64), _G_FLOOR)
        z = self._z
        k = p.sigma0 * np.abs(va) / f_c
        self._advance(va, k, np.sign(va) * f_c / p.sigma0, dt, None)
        return -p.sigma0 * self._force_state(z)


class LuGre(_Bristle1D):
    """Classic force-valued LuGre friction (eqs 2.5-2.7).

    ``ż = v − σ0|v| z/g(v)``, ``g = f_c + (f_s − f_c) exp(−|v/v_s|^γ)``, ``f_c = μ_C f_n``,
    ``f = −(σ0 z + σ1 ż + σ2 v)``. The deflection is a length, so a normal-force change is
    felt only through g (see :class:`AmendedLuGre` for the normalised form).

    Args:
        params: Classic LuGre parameters (σ0 N/m, σ1 N·s/m, σ2 N·s/m).
        shape: Batch shape.
        integrator: ``'exponential'`` or ``'explicit_euler'``.
        rate_limiter: Reference limiter (explicit Euler only).
        force_from: ``'pre_update'`` (reference) or ``'post_update'`` deflection in the
            returned force; use the latter for rigid-body coupling (:mod:`.integrators`).
    """

    def __init__(self, params: ClassicLuGreParams = _CLASSIC_DEFAULT,
                 shape: tuple[int, ...] = (), integrator: str = 'exponential',
                 rate_limiter: bool = False, force_from: str = 'pre_update') -> None:
        super().__init__(shape, integrator, rate_limiter, force_from)
        self.params = params

    def step(self, v: ArrayLike, f_n: ArrayLike, dt: float) -> FloatArray:
        """Advance by ``dt`` at velocity ``v`` [m/s]; return the force on the object [N]."""
        p = self.params
        va = np.asarray(v, dtype=np.float64)
        fn = np.asarray(f_n, dtype=np.float64)
        g = np.maximum(fn * stribeck_curve(va, p.mu_c, p.mu_s, p.v_s, p.stribeck_exp), _G_FLOOR)
        z = self._z
        k = p.sigma0 * np.abs(va) / g
        rate = self._advance(va, k, np.sign(va) * g / p.sigma0, dt, None)
        return -(p.sigma0 * self._force_state(z) + p.sigma1 * rate + p.sigma2 * va)

    def steady_state(self, v: ArrayLike, f_n: ArrayLike) -> FloatArray:
        """Steady sliding force ``−(g(v) sgn v + σ2 v)`` [N]."""
        p = self.params
        va = np.asarray(v, dtype=np.float64)
        g = np.asarray(f_n, dtype=np.float64) * stribeck_curve(va, p.mu_c, p.mu_s, p.v_s,
                                                               p.stribeck_exp)
        return -(g * np.sign(va) + p.sigma2 * va)


class AmendedLuGre(_Bristle1D):
    """Amended (normal-force-normalised) LuGre friction (eqs 2.8-2.10), optionally EP.

    With ``elasto_plastic=True`` this is the Elasto-Plastic law of eqs 2.11-2.13.

    Args:
        params: Amended LuGre parameters (σ0 1/m, σ1 s/m, σ2 s/m).
        shape: Batch shape.
        elasto_plastic: Apply the Elasto-Plastic weight α (:func:`ep_weight`).
        integrator: ``'exponential'`` or ``'explicit_euler'``.
        rate_limiter: Reference limiter (explicit Euler only).
        force_from: ``'pre_update'`` (reference) or ``'post_update'`` deflection in the
            returned force; use the latter for rigid-body coupling (:mod:`.integrators`).
    """

    def __init__(self, params: LuGreParams = DEFAULT_PARAMS, shape: tuple[int, ...] = (),
                 elasto_plastic: bool = False, integrator: str = 'exponential',
                 rate_limiter: bool = False, force_from: str = 'pre_update') -> None:
        super().__init__(shape, integrator, rate_limiter, force_from)
        self.params = params
        self.elasto_plastic = bool(elasto_plastic)

    def _g(self, v: FloatArray) -> FloatArray:
        p = self.params
        return np.maximum(stribeck_curve(v, p.mu_c, p.mu_s, p.v_s, p.stribeck_exp), _G_FLOOR)

    def derivative(self, z: ArrayLike, v: ArrayLike) -> FloatArray:
        """Bristle rate ``ż = v − α σ0 |v| z/g`` [m/s] for a given state (ODE solvers)."""
        p = self.params
        va = np.asarray(v, dtype=np.float64)
        za = np.asarray(z, dtype=np.float64)
        g = self._g(va)
        k = p.sigma0 * np.abs(va) / g
        if self.elasto_plastic:
            k = k * ep_weight(za, va, g / p.sigma0, p.r_ba)
        return va - k * za

    def step(self, v: ArrayLike, f_n: ArrayLike, dt: float) -> FloatArray:
        """Advance by ``dt`` at velocity ``v`` [m/s] with normal force ``f_n`` [N].

        Returns:
            Force on the object ``−(σ0 z + σ1 ż̄ + σ2 v)·f_n`` [N] with the pre-update z
            (post-update with ``force_from='post_update'``).
        """
        p = self.params
        va = np.asarray(v, dtype=np.float64)
        g = self._g(va)
        z = self._z
        z_max = g / p.sigma0
        k = p.sigma0 * np.abs(va) / g
        if self.elasto_plastic:
            k = k * ep_weight(z, va, z_max, p.r_ba)
        rate = self._advance(va, k, np.sign(va) * z_max, dt,
                             z_max if self.elasto_plastic else None)
        zf = self._force_state(z)
        return -(p.sigma0 * zf + p.sigma1 * rate + p.sigma2 * va) * np.asarray(f_n,
                                                                              dtype=np.float64)

    def steady_state(self, v: ArrayLike, f_n: ArrayLike) -> FloatArray:
        """Steady sliding force ``−(g(v) sgn v + σ2 v)·f_n`` [N] (spec A1)."""
        return lugre_steady_state(v, f_n, self.params)


class ElastoPlastic(AmendedLuGre):
    """Elasto-Plastic friction (eqs 2.11-2.13): :class:`AmendedLuGre` with the weight α on.

    Args:
        params: Amended LuGre parameters (``r_ba`` sets the elastic band).
        shape: Batch shape.
        integrator: ``'exponential'`` or ``'explicit_euler'``.
        rate_limiter: Reference limiter (explicit Euler only).
        force_from: ``'pre_update'`` (reference) or ``'post_update'`` deflection in the
            returned force; use the latter for rigid-body coupling (:mod:`.integrators`).
    """

    def __init__(self, params: LuGreParams = DEFAULT_PARAMS, shape: tuple[int, ...] = (),
                 integrator: str = 'exponential', rate_limiter: bool = False,
                 force_from: str = 'pre_update') -> None:
        super().__init__(params, shape, elasto_plastic=True, integrator=integrator,
                         rate_limiter=rate_limiter, force_from=force_from)


OneDModel = Union[Dahl, LuGre, AmendedLuGre]
