# SPDX-License-Identifier: Apache-2.0
"""Distributed planar LuGre model with the planar Elasto-Plastic extension (spec §4, §5, §8).

Paper "Planar Friction Modelling with LuGre Dynamics and Limit Surfaces" §4.1-§4.3; thesis
eqs 2.8-2.15. One 2-D bristle ``z_ij`` [m] per active cell (amended units), driven by the cell
sliding velocity of the pad-centre twist ``(vx, vy, ω)``:

    v_ij  = (vx − ω y_ij, vy + ω x_ij),   s_ij = ‖v_ij‖
    g_ij  = μ_C + (μ_S − μ_C)·exp(−(s_ij/v_s)^γ)                         (eq 2.9)
    ż_ij  = v_ij − β_ij·σ0·s_ij·z_ij/g_ij = q − k·z                        (eq 2.8, §5)
    f_ij  = −(σ0 z_ij + σ1 ż_ij + σ2 v_ij)·f_n·p̂_ij                       (eq 2.10)
    F = Σ f_ij,  τ_c = Σ ρ_ij × f_ij,  τ_cop = τ_c − c × F                 (eqs 2.14-2.15)

Elasto-Plastic weight (spec §5): ``β = ε·α`` with ``ε = (1 + v̂·ẑ)/2`` and
``α = (1 − cos πu)/2``, ``u = clip((‖z‖/z_max − r_ba)/(1 − r_ba), 0, 1)``, ``z_max = g/σ0``
(the steady deflection's length at any non-zero speed); this is the spec's
``½ sin(π(‖z‖ − (z_max + z_ba)/2)/(z_max − z_ba)) + ½`` rewritten.

Integration (spec §8, :mod:`.integrators`): the exponential update
``ż̄ = φ(k dt)(q − k z)``, ``z⁺ = z + dt ż̄``, with the force of a step evaluated on the
pre-update ``z`` (or the post-update one, ``force_from``) and the step-mean rate ``ż̄``
(explicit Euler: ``φ ≡ 1``). With the Elasto-Plastic weight frozen over a step the fixed point
is ``z_ss/β``, which a large step can overshoot. The continuous dynamics keep
``‖z‖ ≤ max(‖z₀‖, z_max)``: on the sphere ‖z‖ = z_max, α = 1 and
``d‖z‖²/dt = s‖z‖(cos θ − 1) ≤ 0`` (θ the angle between v and z). The exponential scheme
therefore projects ``z⁺`` back onto that bound; the projection is inactive whenever the
frozen-β step does not overshoot, and it makes the update unconditionally bounded.

Cells with zero pressure carry no bristle (their deflection is zero): a cell that enters the
contact when the pressure map changes starts undeformed, as a newly touching asperity does.

The viscous wrench is summed in closed form, ``Σ p̂ v_ij = (vx − ω c_y, vy + ω c_x)`` and
``Σ p̂ ρ × v_ij = c_x vy − c_y vx + ω Σ p̂ ‖ρ‖²``, which saves two grid sweeps per step.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .integrators import (EULER_STABILITY_LIMIT, ForceFrom, Integrator, UnstableStepError,
                          check_force_from, check_integrator)
from .params import DEFAULT_PARAMS, LuGreParams
from .planar import Frame, Wrench
from .surfaces import ContactSurface

__all__ = ['DistributedPlanarLuGre', 'steady_state_wrenches']

TwistLike = Union[Sequence[float], NDArray[np.float64]]

_TINY = 1e-300
#: |ω| below which bilinear CoR smoothing treats a twist as a pure translation (C++ value).
OMEGA_MIN = 1e-10


def _check_frame(frame: str) -> None:
    if frame not in ('pad', 'cop'):
        raise ValueError(f"frame must be 'pad' or 'cop', got {frame!r}")


def _stribeck(s: NDArray[np.float64], params: LuGreParams) -> NDArray[np.float64]:
    """``g(s) = μ_C + (μ_S − μ_C)·exp(−(s/v_s)^γ)`` (eq 2.9), element-wise."""
    if params.mu_s == params.mu_c:
        return np.full_like(s, params.mu_c)
    return params.mu_c + (params.mu_s - params.mu_c) * np.exp(
        -np.power(s / params.v_s, params.stribeck_exp))


def steady_state_wrenches(surface: ContactSurface, params: LuGreParams,
                          twists: ArrayLike, f_n: float = 1.0, bilinear: bool = False,
                          chunk_elements: int = 200_000) -> NDArray[np.float64]:
    """Steady-state wrenches of the distributed model for many pad-centre twists (spec §4).

    Every cell at its steady deflection (``ż = 0``):
    ``f_ij = −(g_ij v̂_ij + σ2 v_ij)·f_n·p̂_ij``, with the unit vector regularised as
    ``v/√(s² + v_eps²)`` so that a centre of rotation on (or at round-off distance from) a
    cell centre contributes no spurious force (spec §13.6, A16).

    With ``bilinear=True`` (paper §4.4, spec §4) a twist with ``|ω| ≥ 1e-10`` whose centre of
    rotation lies inside the grid's bounding box is replaced by the bilinear blend of the
    steady wrenches of pure rotations with the same ω about the four surrounding cell
    corners. Exact for Coulomb friction; use it for tables and quasi-static queries only.

    Args:
        surface: Contact surface.
        params: Friction law (σ0, σ1, r_ba are irrelevant in steady state).
        twists: (K, 3) or (3,) twists ``(vx, vy, ω)`` at the pad centre [m/s, m/s, rad/s].
        f_n: Normal force [N].
        bilinear: Apply bilinear CoR smoothing.
        chunk_elements: Upper bound on K·cells per vectorised chunk (memory).

    Returns:
        (K, 3) or (3,) wrenches ``(fx, fy, τ)`` on the object about the pad centre.
    """
    tw = np.asarray(twists, dtype=np.float64)
    single = tw.ndim == 1
    tw = np.atleast_2d(tw)
    if tw.shape[-1] != 3:
        raise ValueError(f'twists must have shape (K, 3), got {tw.shape}')
    if not bilinear:
        out = _one_point_steady(surface, params, tw, chunk_elements)
    else:
        out = np.empty_like(tw)
        vx, vy, om = tw[:, 0], tw[:, 1], tw[:, 2]
        rot = np.abs(om) >= OMEGA_MIN
        om_safe = np.where(rot, om, 1.0)
        px = np.where(rot, -vy / om_safe, np.inf)
        py = np.where(rot, vx / om_safe, np.inf)
        x0, y0 = surface.half_extent
        inside = rot & (np.abs(px) <= x0) & (np.abs(py) <= y0)
        outside = ~inside
        if np.any(outside):
            out[outside] = _one_point_steady(surface, params, tw[outside], chunk_elements)
        if np.any(inside):
            ny, nx = surface.shape
            h = surface.cell_size
            # Fractional position on the lattice of cell corners, [j, i] image order.
            fi = px[inside] / h + nx / 2.0
            fj = ny / 2.0 - py[inside] / h
            i0 = np.minimum(np.floor(fi), nx - 1)
            j0 = np.minimum(np.floor(fj), ny - 1)
            di = fi - i0
            dj = fj - j0
            omi = om[inside]
            corner_twists = []
            weights = []
            for ci, cj, w in ((0, 0, (1 - di) * (1 - dj)), (1, 0, di * (1 - dj)),
                              (0, 1, (1 - di) * dj), (1, 1, di * dj)):
                cx = (i0 + ci - nx / 2.0) * h
                cy = (ny / 2.0 - (j0 + cj)) * h
                # Pure rotation about (cx, cy): pad-centre twist ω ẑ × (0 − c).
                corner_twists.append(np.stack((omi * cy, -omi * cx, omi), axis=-1))
                weights.append(w)
            cw = _one_point_steady(surface, params, np.concatenate(corner_twists),
                                   chunk_elements).reshape(4, -1, 3)
            out[inside] = np.einsum('ck,ckd->kd', np.asarray(weights), cw)
    out *= f_n
    return out[0] if single else out


def _one_point_steady(surface: ContactSurface, params: LuGreParams, tw: NDArray[np.float64],
                      chunk_elements: int) -> NDArray[np.float64]:
    """One-point-per-cell steady wrench at the pad centre for f_n = 1, (K, 3) → (K, 3)."""
    x, y, w = surface.x, surface.y, surface.weights
    wx = w * x
    wy = w * y
    eps2 = params.v_eps ** 2
    out = np.empty_like(tw)
    step = max(1, chunk_elements // max(1, x.size))
    for k0 in range(0, tw.shape[0], step):
        t = tw[k0:k0 + step]
        om = t[:, 2:3]
        vxc = t[:, 0:1] - om * y
        vyc = t[:, 1:2] + om * x
        s2 = vxc * vxc + vyc * vyc
        g = _stribeck(np.sqrt(s2), params)
        scale = g / np.sqrt(s2 + eps2)
        if params.sigma2:
            ax = scale * vxc + params.sigma2 * vxc
            ay = scale * vyc + params.sigma2 * vyc
        else:
            ax = scale * vxc
            ay = scale * vyc
        out[k0:k0 + step, 0] = -(ax @ w)
        out[k0:k0 + step, 1] = -(ay @ w)
        out[k0:k0 + step, 2] = -(ay @ wx - ax @ wy)
    return out


class DistributedPlanarLuGre:
    """Distributed planar LuGre / Elasto-Plastic friction model over a contact grid.

    Example::

        model = DistributedPlanarLuGre(square(21, 0.02), LuGreParams(), f_n=1.0)
        w = model.step((0.01, 0.0, 0.5), dt=1e-3)       # twist at the pad centre
        w.fx, w.fy, w.tau, w.tau_cop                     # N, N, N·m (pad), N·m (CoP)

    Args:
        surface: Contact surface (grid + pressure map).
        params: Amended LuGre parameters.
        elasto_plastic: Use the planar Elasto-Plastic weight β (spec §5); plain LuGre if False.
        integrator: ``'exponential'`` (default, unconditionally stable) or
            ``'explicit_euler'`` (reference scheme; raises :class:`UnstableStepError` when a step
            would diverge unless ``rate_limiter`` is on).
        rate_limiter: Reference component-wise rate limiter (explicit Euler only).
        f_n: Initial normal force [N].
        force_from: ``'pre_update'`` (reference; default) or ``'post_update'`` deflection in
            the returned wrench -- use the latter when coupling to a rigid body
            (:mod:`.integrators`).
    """

    def __init__(self, surface: ContactSurface, params: LuGreParams = DEFAULT_PARAMS, *,
                 elasto_plastic: bool = True, integrator: str = 'exponential',
                 rate_limiter: bool = False, f_n: float = 1.0,
                 force_from: str = 'pre_update') -> None:
        self._params = params
        self._force_from: ForceFrom = check_force_from(force_from)
        self._ep = bool(elasto_plastic)
        self._integrator: Integrator = check_integrator(integrator)
        if rate_limiter and self._integrator != 'explicit_euler':
            raise ValueError("rate_limiter applies to integrator='explicit_euler' only")
        self._limiter = bool(rate_limiter)
        self._f_n = 0.0
        self.set_normal_force(f_n)
        self._z = np.zeros((2, 0))
        self._surface = surface
        self._configure(surface, keep_state=False)

    # ------------------------------------------------------------------ configuration
    def _configure(self, surface: ContactSurface, keep_state: bool) -> None:
        """Precompute geometry and allocate all per-step buffers for ``surface``."""
        old_surface, old_z = self._surface, self._z
        m = surface.n_active
        x, y, w = surface.x, surface.y, surface.weights
        self._surface = surface
        self._cop = surface.cop
        self._polar = surface.polar_moment
        # R = [−y; x]: cell velocity = ω R + (vx, vy).
        self._rot = np.ascontiguousarray(np.stack((-y, x)))
        # a (2m,) @ M (2m, 3) = (Σ p̂ a_x, Σ p̂ a_y, Σ p̂ (x a_y − y a_x)).
        mat = np.zeros((2 * m, 3))
        mat[:m, 0] = w
        mat[:m, 2] = -w * y
        mat[m:, 1] = w
        mat[m:, 2] = w * x
        self._sum_matrix = mat
        z = np.zeros((2, m))
        if keep_state and old_surface.shape == surface.shape and old_z.shape[1] > 0:
            old_full = np.zeros((2, old_surface.pressure.size))
            old_full[:, old_surface.active] = old_z
            z[:] = old_full[:, surface.active]
        self._z = z
        self._z_next = np.empty((2, m))
        self._zdot = np.empty((2, m))
        self._v = np.empty((2, m))
        self._t2 = np.empty((2, m))
        self._v_rows = (self._v[0], self._v[1])
        self._t_rows = (self._t2[0], self._t2[1])
        self._a = np.empty((2, m))
        self._s2 = np.empty(m)
        self._s = np.empty(m)
        self._g = np.empty(m)
        self._k = np.empty(m)
        self._zn = np.empty(m)
        self._u = np.empty(m)
        self._c = np.empty(m)
        self._x = np.empty(m)
        self._ph = np.empty(m)

    @property
    def surface(self) -> ContactSurface:
        """The current contact surface."""
        return self._surface

    @property
    def params(self) -> LuGreParams:
        """The friction-law parameters."""
        return self._params

    @property
    def elasto_plastic(self) -> bool:
        """Whether the Elasto-Plastic weight is active."""
        return self._ep

    @property
    def force_from(self) -> ForceFrom:
        """Deflection used by the returned wrench: ``'pre_update'`` or ``'post_update'``."""
        return self._force_from

    @property
    def f_n(self) -> float:
        """Current normal force [N]."""
        return self._f_n

    def reset(self) -> None:
        """Zero every bristle deflection."""
        self._z.fill(0.0)

    def set_normal_force(self, f_n: float) -> None:
        """Set the normal force [N] (≥ 0). Bristle states are untouched (spec §7, A10)."""
        f = float(f_n)
        if not (math.isfinite(f) and f >= 0.0):
            raise ValueError(f'normal force must be finite and >= 0 N, got {f_n!r}')
        self._f_n = f

    def set_pressure(self, surface: ContactSurface | ArrayLike) -> None:
        """Replace the pressure map at run time.

        Cells active in both maps keep their deflection; cells leaving the contact lose it and
        cells entering start undeformed. A different grid shape resets all bristles.

        Args:
            surface: A :class:`ContactSurface`, or a ``[j, i]`` pressure array (any scale) on
                the current cell size.
        """
        if not isinstance(surface, ContactSurface):
            surface = ContactSurface.from_array(surface, self._surface.cell_size,
                                                name=self._surface.name)
        self._configure(surface, keep_state=True)

    @property
    def state(self) -> NDArray[np.float64]:
        """Bristle deflections [m] as a (ny, nx, 2) copy, zero outside the contact."""
        ny, nx = self._surface.shape
        full = np.zeros((2, ny * nx))
        full[:, self._surface.active] = self._z
        return np.moveaxis(full.reshape(2, ny, nx), 0, -1).copy()

    def set_state(self, z: ArrayLike) -> None:
        """Set the bristle deflections from a (ny, nx, 2) array [m] (inactive cells ignored)."""
        self._z[:] = self._compact(z)

    def _compact(self, z: ArrayLike) -> NDArray[np.float64]:
        za = np.asarray(z, dtype=np.float64)
        ny, nx = self._surface.shape
        if za.shape != (ny, nx, 2):
            raise ValueError(f'state must have shape {(ny, nx, 2)}, got {za.shape}')
        return np.ascontiguousarray(np.moveaxis(za, -1, 0).reshape(2, -1)[:, self._surface.active])

    def _pad_twist(self, twist: TwistLike, frame: str) -> tuple[float, float, float]:
        vx, vy, om = float(twist[0]), float(twist[1]), float(twist[2])
        if frame == 'pad':
            return vx, vy, om
        _check_frame(frame)
        cx, cy = self._cop
        # v_pad = v_cop + ω ẑ × (0 − c)
        return vx + om * cy, vy - om * cx, om

    def _wrench(self, fx: float, fy: float, tau: float) -> Wrench:
        cx, cy = self._cop
        return Wrench(fx, fy, tau, tau - (cx * fy - cy * fx))

    # ------------------------------------------------------------------ dynamics
    def _rates(self, vx: float, vy: float, om: float, z: NDArray[np.float64]) -> None:
        """Fill ``_v``, ``_s``, ``_g`` and ``_k`` (the ``ż = v − k z`` rate) for state ``z``."""
        p = self._params
        v, t2, s2, s, g, k = self._v, self._t2, self._s2, self._s, self._g, self._k
        v0, v1 = self._v_rows
        t0, t1 = self._t_rows
        np.multiply(self._rot, om, out=v)
        v0 += vx
        v1 += vy
        np.multiply(v, v, out=t2)
        np.add(t0, t1, out=s2)
        np.sqrt(s2, out=s)
        if p.mu_s != p.mu_c:
            if p.stribeck_exp == 2.0:
                np.multiply(s2, -1.0 / (p.v_s * p.v_s), out=g)
            else:
                np.multiply(s, 1.0 / p.v_s, out=g)
                np.power(g, p.stribeck_exp, out=g)
                np.negative(g, out=g)
            np.exp(g, out=g)
            g *= p.mu_s - p.mu_c
            g += p.mu_c
        else:
            g.fill(p.mu_c)
        np.divide(s, g, out=k)
        if self._ep:
            k *= 0.25 * p.sigma0      # the ¼ of β = (1 − cos πu)(1 + c)/4, see below
            self._apply_ep_weight(z)
        else:
            k *= p.sigma0

    def _apply_ep_weight(self, z: NDArray[np.float64]) -> None:
        """Multiply ``_k`` by ``4β = 4ε·α`` of spec §5; leaves ``‖z‖`` in ``_zn``.

        ``α = (1 − cos πu)/2`` with ``u = (σ0 w − r_ba)/(1 − r_ba)``, ``w = ‖z‖/g`` clipped to
        ``[r_ba/σ0, 1/σ0]`` (so u ∈ [0, 1]); ``ε = (1 + c)/2`` with ``c = v·z/(s‖z‖)``.
        """
        p = self._params
        v, t2, s, g, k, zn, u, c, x = (self._v, self._t2, self._s, self._g, self._k, self._zn,
                                       self._u, self._c, self._x)
        t0, t1 = self._t_rows
        np.multiply(z, z, out=t2)
        np.add(t0, t1, out=zn)
        np.sqrt(zn, out=zn)
        np.divide(zn, g, out=u)
        np.maximum(u, p.r_ba / p.sigma0, out=u)
        np.minimum(u, 1.0 / p.sigma0, out=u)
        band = math.pi / (1.0 - p.r_ba)
        u *= band * p.sigma0
        u -= band * p.r_ba
        np.cos(u, out=u)                            # cos πu
        # Where s‖z‖ = 0 either k = 0 (s = 0) or α = 0 (z = 0), so the value of ε there is
        # irrelevant; clamping the denominator only avoids 0/0.
        np.multiply(v, z, out=t2)
        np.add(t0, t1, out=c)
        np.multiply(s, zn, out=x)
        np.maximum(x, _TINY, out=x)
        np.divide(c, x, out=c)
        np.subtract(1.0, u, out=u)                  # 2α
        c += 1.0                                    # 2ε
        u *= c
        k *= u

    def step(self, twist: TwistLike, dt: float, f_n: float | None = None,
             frame: Frame = 'pad') -> Wrench:
        """Advance the bristles by ``dt`` at a constant twist and return the friction wrench.

        The wrench of a step uses the pre-update deflection (or the post-update one, see
        ``force_from``) and the step-mean bristle rate (spec §4 item 8, §8).

        Args:
            twist: ``(vx, vy, ω)`` of the object relative to the pad [m/s, m/s, rad/s].
            dt: Time step [s] (> 0); any size is stable with the exponential integrator.
            f_n: Normal force [N] for this and later steps (default: keep the current one).
            frame: Reference point of ``twist``: ``'pad'`` (pad centre) or ``'cop'``.

        Returns:
            The wrench on the object, torque about the pad centre and about the CoP.
        """
        if f_n is not None:
            self.set_normal_force(f_n)
        if not dt > 0.0:
            raise ValueError(f'dt must be > 0 s, got {dt!r}')
        p = self._params
        vx, vy, om = self._pad_twist(twist, frame)
        z, zn_next, zd, t2, a, k, x, ph = (self._z, self._z_next, self._zdot, self._t2,
                                           self._a, self._k, self._x, self._ph)
        self._rates(vx, vy, om, z)
        # ż_euler = v − k z; exponential: ż̄ = φ(k dt)·ż_euler (ph holds −φ).
        np.multiply(z, k, out=zd)
        zd -= self._v
        if self._integrator == 'exponential':
            np.multiply(k, dt, out=x)
            np.maximum(x, _TINY, out=x)
            np.negative(x, out=ph)
            np.expm1(ph, out=ph)
            np.divide(ph, x, out=ph)
            zd *= ph
            np.multiply(zd, dt, out=zn_next)
            zn_next += z
            if self._ep:
                self._project(z, zn_next, zd, dt)
        else:
            np.negative(zd, out=zd)
            self._euler_checks(z, zd, dt)
            np.multiply(zd, dt, out=zn_next)
            zn_next += z
        # a = σ0 z + σ1 ż̄ on the pre- (reference) or post-update deflection.
        np.multiply(z if self._force_from == 'pre_update' else zn_next, p.sigma0, out=a)
        if p.sigma1:
            np.multiply(zd, p.sigma1, out=t2)
            a += t2
        fx, fy, tau = a.reshape(-1) @ self._sum_matrix
        self._z, self._z_next = zn_next, z
        return self._finish(fx, fy, tau, vx, vy, om)

    def advance(self, vx: float, vy: float, om: float, dt: float,
                f_n: float) -> tuple[float, float, float, float]:
        """``step((vx, vy, om), dt, f_n)`` for a pad-centre twist given as floats.

        The interface the rigid-body coupling shares with
        :meth:`~friction_models.core.reduced.ReducedPlanarLuGre.advance`.

        Returns:
            The `Wrench` fields ``(fx, fy, τ_pad, τ_cop)`` [N, N, N·m, N·m].
        """
        return self.step((vx, vy, om), dt, f_n)

    def _finish(self, fx: float, fy: float, tau: float, vx: float, vy: float,
                om: float) -> Wrench:
        p = self._params
        fn = self._f_n
        if p.sigma2:
            cx, cy = self._cop
            fx += p.sigma2 * (vx - om * cy)
            fy += p.sigma2 * (vy + om * cx)
            tau += p.sigma2 * (cx * vy - cy * vx + om * self._polar)
        return self._wrench(-fn * float(fx), -fn * float(fy), -fn * float(tau))

    def _project(self, z: NDArray[np.float64], z_next: NDArray[np.float64],
                 zd: NDArray[np.float64], dt: float) -> None:
        """Keep ``‖z⁺‖ ≤ max(‖z‖, z_max)`` per cell (Elasto-Plastic, exponential scheme)."""
        t2, u, c = self._t2, self._u, self._c
        t0, t1 = self._t_rows
        np.multiply(z_next, z_next, out=t2)
        np.add(t0, t1, out=c)                        # ‖z⁺‖²
        np.maximum(c, _TINY, out=c)
        np.divide(self._g, self._params.sigma0, out=u)
        np.maximum(u, self._zn, out=u)               # bound = max(z_max, ‖z‖)
        u *= u
        np.divide(u, c, out=u)                       # (bound/‖z⁺‖)²
        if u.min(initial=1.0) >= 1.0:
            return
        np.minimum(u, 1.0, out=u)
        np.sqrt(u, out=u)
        z_next *= u
        np.subtract(z_next, z, out=zd)
        zd *= 1.0 / dt

    def _euler_checks(self, z: NDArray[np.float64], zd: NDArray[np.float64], dt: float) -> None:
        """Reference rate limiter, or the divergence guard when it is off."""
        if self._limiter:
            p = self._params
            # z_ss = v g/(σ0 s) with the regularised unit vector; |ż_i| ≤ |z_ss,i − z_i|/dt.
            zss = self._t2
            np.multiply(self._s2, 1.0, out=self._x)
            self._x += p.v_eps ** 2
            np.sqrt(self._x, out=self._x)
            np.divide(self._g, self._x, out=self._x)
            self._x *= 1.0 / p.sigma0
            np.multiply(self._v, self._x, out=zss)
            zss -= z
            np.abs(zss, out=zss)
            zss *= 1.0 / dt
            np.minimum(np.abs(zd), zss, out=zss)
            np.copysign(zss, zd, out=zd)
        else:
            kdt = float(self._k.max(initial=0.0)) * dt
            if kdt > EULER_STABILITY_LIMIT:
                raise UnstableStepError(
                    f'explicit Euler step unstable: max k*dt = {kdt:.3g} > 2 (dt = {dt:g} s); '
                    "reduce dt, enable rate_limiter or use integrator='exponential'")

    def derivative(self, z: ArrayLike, twist: TwistLike, frame: Frame = 'pad',
                   ) -> NDArray[np.float64]:
        """Bristle rate ``ż = v − β σ0 ‖v‖ z/g`` for a given state (for SciPy ODE solvers).

        Args:
            z: Deflections, shape (ny, nx, 2) [m].
            twist: ``(vx, vy, ω)`` [m/s, m/s, rad/s] at the ``frame`` point.
            frame: ``'pad'`` or ``'cop'``.

        Returns:
            ż [m/s], shape (ny, nx, 2), zero outside the contact.
        """
        vx, vy, om = self._pad_twist(twist, frame)
        zc = self._compact(z)
        self._rates(vx, vy, om, zc)
        rate = self._v - self._k * zc
        ny, nx = self._surface.shape
        full = np.zeros((2, ny * nx))
        full[:, self._surface.active] = rate
        return np.moveaxis(full.reshape(2, ny, nx), 0, -1)

    def wrench_at(self, z: ArrayLike, twist: TwistLike, f_n: float | None = None,
                  frame: Frame = 'pad') -> Wrench:
        """Wrench for a given state with the instantaneous rate ż (ODE-solver use).

        Args:
            z: Deflections, shape (ny, nx, 2) [m].
            twist: ``(vx, vy, ω)`` at the ``frame`` point.
            f_n: Normal force [N] (default: current).
            frame: ``'pad'`` or ``'cop'``.

        Returns:
            The wrench on the object.
        """
        if f_n is not None:
            self.set_normal_force(f_n)
        vx, vy, om = self._pad_twist(twist, frame)
        zc = self._compact(z)
        self._rates(vx, vy, om, zc)
        a = self._params.sigma0 * zc + self._params.sigma1 * (self._v - self._k * zc)
        fx, fy, tau = a.reshape(-1) @ self._sum_matrix
        return self._finish(fx, fy, tau, vx, vy, om)

    def steady_state(self, twist: TwistLike, frame: Frame = 'pad', bilinear: bool = False,
                     f_n: float | None = None) -> Wrench:
        """Steady sliding wrench for a constant twist (no state; spec §4 "steady-state mode").

        Args:
            twist: ``(vx, vy, ω)`` at the ``frame`` point.
            frame: ``'pad'`` or ``'cop'``.
            bilinear: Bilinear CoR smoothing (paper §4.4; exact for Coulomb friction only).
            f_n: Normal force [N] (default: current; not stored).

        Returns:
            The wrench on the object.
        """
        vx, vy, om = self._pad_twist(twist, frame)
        fn = self._f_n if f_n is None else float(f_n)
        fx, fy, tau = steady_state_wrenches(self._surface, self._params, (vx, vy, om),
                                            f_n=fn, bilinear=bilinear)
        return self._wrench(float(fx), float(fy), float(tau))
