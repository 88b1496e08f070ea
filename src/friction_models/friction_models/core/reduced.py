# SPDX-License-Identifier: Apache-2.0
"""Reduced planar LuGre model: three bristle states and a pre-computed limit surface (spec §6).

Paper §5 (C++ variant, used for the paper's figures). The distributed bristles are replaced by
one 3-D bristle ``z = (z_x, z_y, z_τ)`` [m] acting on the generalised velocity at the centre of
pressure c, ``ṽ = (vx, vy, r_a ω)``; the force-torque coupling of the actual pressure map comes
from the normalised limit surface ``h = LS(v; r_a)`` (:mod:`.limit_surface`). Per step:

    v     = v_pad + ω ẑ × c                                       (twist at the CoP)
    v_n   = √(vx² + vy² + r_a² ω²)
    w     = −S h,   S = diag(1, 1, r_a)                            (h opposes the motion)
    g     = μ_C + (μ_S − μ_C)·exp(−(v_n/v_s)^γ)
    ż     = (w − β σ0 z/g)·v_n  =  q − k z,   q = w v_n,  k = β σ0 v_n/g
    (Fx, Fy, τ_c) = −(σ0 z + σ1 ż + σ2 (vx, vy, J_c ω))·f_n       (J_c = Σ p̂‖ρ − c‖²)
    τ_pad = τ_c + c × F

``J_c ω`` equals the spec's ``s_v,3 r_a² ω`` with ``s_v = (1, 1, J_c/r_a²)``: the viscous torque
of the distributed model about the CoP (spec §6.3, §13.8). The Elasto-Plastic weight β
(spec §5) is evaluated on the rescaled vectors ``S⁻¹z``, ``S⁻¹z_ss = −h g/σ0`` and the drive
direction ``−h``. In steady sliding ``F = g f_n h_xy`` and ``τ_c = g f_n r_a h_τ``: the Coulomb
limit surface scaled by the Stribeck factor. With ``limit_surface=False`` the direction is the
ellipsoid ``h = −ṽ/v_n`` (paper §5.1), exact only at pure translation and pure rotation about
the CoP. At ``v_n = 0`` the state freezes and the force is the spring ``−σ0 z f_n`` (spec §6.6).

Integration and its unconditional bound are those of :mod:`.distributed` (exponential update
with the step-mean rate; Elasto-Plastic overshoot projected onto ``‖S⁻¹z‖ ≤ max(‖S⁻¹z₀‖,
z_max)``). Size changes of the same pressure shape only rescale r_a, c and J_c (spec §6.5); a
new shape re-builds (or fetches from a :class:`LimitSurfaceCache`) the table.

:class:`ReducedPlanarLuGre` steps one contact with a scalar fast path (plain floats, no numpy
per step); :class:`ReducedPlanarLuGreBatch` steps N independent contacts as arrays.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .integrators import (EULER_STABILITY_LIMIT, ForceFrom, Integrator, UnstableStepError,
                          check_force_from, check_integrator)
from .limit_surface import (LimitSurface, LimitSurfaceCache, ProgressCallback,
                            characteristic_radius, lookup_arrays, lookup_scalar)
from .params import DEFAULT_PARAMS, LuGreParams
from .planar import BatchWrench, Frame, Wrench
from .surfaces import ContactSurface

__all__ = ['ReducedPlanarLuGre', 'ReducedPlanarLuGreBatch']

TwistLike = Union[Sequence[float], NDArray[np.float64]]
LimitSurfaceOption = Union[bool, LimitSurface]

_TINY = 1e-300


class _ContactGeometry(NamedTuple):
    """What the reduced model needs of one contact: surface, table (None: ellipsoid), r_a [m].

    ``r_a`` is the table's bilinear radius rescaled to the surface's cell size (spec §6.5).
    """

    surface: ContactSurface
    table: LimitSurface | None
    r_a: float

    @property
    def cx(self) -> float:
        """CoP x [m]."""
        return self.surface.cop[0]

    @property
    def cy(self) -> float:
        """CoP y [m]."""
        return self.surface.cop[1]

    @property
    def second_moment(self) -> float:
        """``J_c = Σ p̂‖ρ − c‖²`` [m²]."""
        return self.surface.second_moment


def _resolve_geometry(surface: ContactSurface, limit_surface: LimitSurfaceOption, n_ls: int,
                      cache: LimitSurfaceCache | None, progress: ProgressCallback | None,
                      previous: _ContactGeometry | None = None) -> _ContactGeometry:
    """Table and radius for ``surface``; reuse ``previous`` when only the size changed."""
    if previous is not None and previous.surface.same_shape_as(surface):
        ratio = surface.cell_size / previous.surface.cell_size
        return _ContactGeometry(surface, previous.table, previous.r_a * ratio)
    if isinstance(limit_surface, LimitSurface):
        given = limit_surface
        if given.shape_key != surface.shape_key():
            raise ValueError(f'the limit surface was built for another pressure shape '
                             f'(grid {given.source_shape}) than surface {surface.name!r}')
        return _ContactGeometry(surface, given, given.r_a * surface.cell_size / given.cell_size)
    if limit_surface:
        table = (cache.get(surface, n_ls, progress) if cache is not None
                 else LimitSurface.build(surface, n_ls, progress=progress))
        return _ContactGeometry(surface, table, table.r_a)
    return _ContactGeometry(surface, None, characteristic_radius(surface, bilinear=True))


class ReducedPlanarLuGre:
    """Reduced planar LuGre / Elasto-Plastic model of one contact (paper §5, spec §6).

    Example::

        model = ReducedPlanarLuGre(circle(21, 0.02), LuGreParams(), limit_surface=True)
        w = model.step((0.01, 0.0, 0.5), dt=1e-3, f_n=2.0)   # twist at the pad centre
        w.fx, w.fy, w.tau                                      # N, N, N·m at the pad centre

    Args:
        surface: Contact surface (pressure shape, CoP, size).
        params: Amended LuGre parameters.
        limit_surface: ``True`` builds (or fetches from ``cache``) the pre-computed limit
            surface; a :class:`LimitSurface` uses that table; ``False`` selects the ellipsoid
            approximation (paper §5.1).
        elasto_plastic: Planar Elasto-Plastic weight (spec §5).
        integrator: ``'exponential'`` (default) or ``'explicit_euler'`` (reference scheme).
        rate_limiter: Reference component-wise limiter (explicit Euler only).
        n_ls: Limit-surface segments per quadrant when the table is built here.
        cache: Optional shared :class:`LimitSurfaceCache`.
        f_n: Initial normal force [N].
        progress: Build-progress callback (see :meth:`LimitSurface.build`).
        force_from: ``'pre_update'`` (reference; default) or ``'post_update'`` state in the
            returned wrench -- use the latter when coupling to a rigid body
            (:mod:`.integrators`).
    """

    def __init__(self, surface: ContactSurface, params: LuGreParams = DEFAULT_PARAMS, *,
                 limit_surface: LimitSurfaceOption = True, elasto_plastic: bool = True,
                 integrator: str = 'exponential', rate_limiter: bool = False, n_ls: int = 20,
                 cache: LimitSurfaceCache | None = None, f_n: float = 1.0,
                 progress: ProgressCallback | None = None,
                 force_from: str = 'pre_update') -> None:
        self._params = params
        self._force_from: ForceFrom = check_force_from(force_from)
        self._post = self._force_from == 'post_update'
        self._ep = bool(elasto_plastic)
        self._integrator: Integrator = check_integrator(integrator)
        if rate_limiter and self._integrator != 'explicit_euler':
            raise ValueError("rate_limiter applies to integrator='explicit_euler' only")
        self._limiter = bool(rate_limiter)
        self._use_ls = bool(limit_surface)
        self._n_ls = int(n_ls)
        self._cache = cache
        self._progress = progress
        self._f_n = 0.0
        self.set_normal_force(f_n)
        self._z = [0.0, 0.0, 0.0]
        self._geo = _resolve_geometry(surface, limit_surface, self._n_ls, cache, progress)
        self._bind()

    def _bind(self) -> None:
        """Copy hot per-step constants into plain attributes (scalar fast path)."""
        p = self._params
        geo = self._geo
        self._cx, self._cy, self._r_a, self._j = geo.cx, geo.cy, geo.r_a, geo.second_moment
        self._flat = geo.table.flat if geo.table is not None else []
        self._n = geo.table.n_ls if geo.table is not None else 0
        self._dmu = p.mu_s - p.mu_c
        self._inv_vs = 1.0 / p.v_s
        self._inv_band = 1.0 / (1.0 - p.r_ba)
        self._sigma0, self._sigma1, self._sigma2 = p.sigma0, p.sigma1, p.sigma2
        self._exponential = self._integrator == 'exponential'

    # ------------------------------------------------------------------ properties
    @property
    def params(self) -> LuGreParams:
        """The friction-law parameters."""
        return self._params

    @property
    def surface(self) -> ContactSurface:
        """The current contact surface."""
        return self._geo.surface

    @property
    def limit_surface(self) -> LimitSurface | None:
        """The limit-surface table, or ``None`` for the ellipsoid variant."""
        return self._geo.table

    @property
    def r_a(self) -> float:
        """Current characteristic radius [m] (bilinear reference value, spec §6.1)."""
        return self._r_a

    @property
    def viscous_scale(self) -> tuple[float, float, float]:
        """``s_v = (1, 1, J_c/r_a²)`` (spec §6.3)."""
        return (1.0, 1.0, self._j / (self._r_a * self._r_a))

    @property
    def f_n(self) -> float:
        """Current normal force [N]."""
        return self._f_n

    @property
    def force_from(self) -> ForceFrom:
        """State used by the returned wrench: ``'pre_update'`` or ``'post_update'``."""
        return self._force_from

    @property
    def state(self) -> NDArray[np.float64]:
        """Bristle state ``(z_x, z_y, z_τ)`` [m] (copy; ``z_τ`` carries a factor r_a)."""
        return np.array(self._z)

    @property
    def state_tuple(self) -> tuple[float, float, float]:
        """Bristle state ``(z_x, z_y, z_τ)`` [m] as plain floats (no array; per-step use)."""
        z0, z1, z2 = self._z
        return z0, z1, z2

    def set_state(self, z: ArrayLike) -> None:
        """Set the bristle state (3,) [m]."""
        za = np.asarray(z, dtype=np.float64).reshape(3)
        self._z = [float(za[0]), float(za[1]), float(za[2])]

    def reset(self) -> None:
        """Zero the bristle state."""
        self._z = [0.0, 0.0, 0.0]

    def set_normal_force(self, f_n: float) -> None:
        """Set the normal force [N] (≥ 0); the state is untouched (spec §7, A10)."""
        f = float(f_n)
        if not (math.isfinite(f) and f >= 0.0):
            raise ValueError(f'normal force must be finite and >= 0 N, got {f_n!r}')
        self._f_n = f

    def set_pressure(self, surface: ContactSurface | ArrayLike) -> None:
        """Replace the pressure map (spec §6.5).

        Same normalised shape: only r_a, the CoP and J_c are rescaled. A new shape rebuilds
        the limit surface (through the cache when one was given). The state is kept.

        Args:
            surface: A :class:`ContactSurface`, or a ``[j, i]`` pressure array (any scale) on
                the current cell size.
        """
        if not isinstance(surface, ContactSurface):
            surface = ContactSurface.from_array(surface, self._geo.surface.cell_size,
                                                name=self._geo.surface.name)
        option: LimitSurfaceOption = self._use_ls
        self._geo = _resolve_geometry(surface, option, self._n_ls, self._cache, self._progress,
                                      previous=self._geo)
        self._bind()

    # ------------------------------------------------------------------ kernel pieces
    def _direction(self, vx: float, vy: float, om: float,
                   vn: float) -> tuple[float, float, float]:
        """Normalised limit-surface wrench ``h`` (against the motion) for a CoP twist."""
        if self._flat:
            return lookup_scalar(self._flat, self._n, vx, vy, om, self._r_a)
        inv = 1.0 / vn
        return (-vx * inv, -vy * inv, -self._r_a * om * inv)

    def _stribeck(self, vn: float) -> float:
        p = self._params
        if self._dmu == 0.0:
            return p.mu_c
        x = vn * self._inv_vs
        e = x * x if p.stribeck_exp == 2.0 else x ** p.stribeck_exp
        return p.mu_c + self._dmu * math.exp(-e)

    def _beta(self, hx: float, hy: float, ht: float, g: float, z0: float, z1: float,
              z2: float) -> float:
        """Elasto-Plastic weight β = ε·α on the rescaled vectors (spec §5, §6.3 item 7)."""
        p = self._params
        y2 = z2 / self._r_a
        yn = math.sqrt(z0 * z0 + z1 * z1 + y2 * y2)
        hn = math.sqrt(hx * hx + hy * hy + ht * ht)
        y_max = hn * g / p.sigma0
        if yn <= p.r_ba * y_max:
            return 0.0
        if hn == 0.0:      # no drive direction (cannot happen for a non-zero twist)
            return 1.0
        if yn >= y_max:
            alpha = 1.0
        else:
            u = (yn / y_max - p.r_ba) * self._inv_band
            s = math.sin(0.5 * math.pi * u)
            alpha = s * s
        # Drive direction in rescaled space is −h; ε = (1 + (−ĥ)·ŷ)/2.
        eps = 0.5 * (1.0 - (hx * z0 + hy * z1 + ht * y2) / (hn * yn))
        return alpha * eps

    # ------------------------------------------------------------------ public API
    def _cop_twist(self, twist: TwistLike, frame: str) -> tuple[float, float, float]:
        vx, vy, om = float(twist[0]), float(twist[1]), float(twist[2])
        if frame == 'pad':
            return vx - om * self._cy, vy + om * self._cx, om
        if frame == 'cop':
            return vx, vy, om
        raise ValueError(f"frame must be 'pad' or 'cop', got {frame!r}")

    def step(self, twist: TwistLike, dt: float, f_n: float | None = None,
             frame: Frame = 'pad') -> Wrench:
        """Advance the three bristle states by ``dt`` and return the friction wrench.

        The wrench uses the pre-update state (or the post-update one, see ``force_from``)
        and the step-mean rate (spec §6.3, §8).

        Args:
            twist: ``(vx, vy, ω)`` of the object relative to the pad [m/s, m/s, rad/s].
            dt: Time step [s] (> 0).
            f_n: Normal force [N] for this and later steps (default: keep).
            frame: Reference point of ``twist``: ``'pad'`` (pad centre) or ``'cop'``.

        Returns:
            The wrench on the object (torque about the pad centre and about the CoP).
        """
        if f_n is not None:
            self.set_normal_force(f_n)
        if not dt > 0.0:
            raise ValueError(f'dt must be > 0 s, got {dt!r}')
        vx, vy, om = self._cop_twist(twist, frame)
        return Wrench._make(self._advance_cop(vx, vy, om, dt))

    def advance(self, vx: float, vy: float, om: float, dt: float,
                f_n: float) -> tuple[float, float, float, float]:
        """`step` without argument checks, for a rigid-body coupling that steps every dt.

        Same numbers as ``step((vx, vy, om), dt, f_n)`` with ``frame='pad'``; the caller
        guarantees plain floats, ``dt > 0`` and a finite ``f_n ≥ 0``.

        Args:
            vx, vy, om: Twist of the object relative to the pad at the pad centre
                [m/s, m/s, rad/s].
            dt: Time step [s].
            f_n: Normal force [N] for this and later steps.

        Returns:
            The `Wrench` fields ``(fx, fy, τ_pad, τ_cop)`` [N, N, N·m, N·m] as a plain tuple.
        """
        self._f_n = f_n
        return self._advance_cop(vx - om * self._cy, vy + om * self._cx, om, dt)

    def _advance_cop(self, vx: float, vy: float, om: float,
                     dt: float) -> tuple[float, float, float, float]:
        """The step kernel for a CoP twist (module docstring); returns the `Wrench` fields."""
        r_a = self._r_a
        z0, z1, z2 = self._z
        vn = math.sqrt(vx * vx + vy * vy + r_a * r_a * om * om)
        if vn > 0.0:
            flat = self._flat
            if flat:
                hx, hy, ht = lookup_scalar(flat, self._n, vx, vy, om, r_a)
            else:
                hx, hy, ht = self._direction(vx, vy, om, vn)
            g = self._stribeck(vn)
            k = self._sigma0 * vn / g
            if self._ep:
                k *= self._beta(hx, hy, ht, g, z0, z1, z2)
            # ż = q − k z with q = w v_n, w = −S h.
            d0 = -hx * vn - k * z0
            d1 = -hy * vn - k * z1
            d2 = -r_a * ht * vn - k * z2
            if self._exponential:
                x = k * dt
                if x > _TINY:      # φ(x) = −expm1(−x)/x; φ(0) = 1 (sticking: no scaling)
                    ph = -math.expm1(-x) / x
                    d0 *= ph
                    d1 *= ph
                    d2 *= ph
                n0, n1, n2 = z0 + dt * d0, z1 + dt * d1, z2 + dt * d2
                if self._ep:
                    # Elasto-Plastic bound ‖S⁻¹z⁺‖ ≤ max(‖S⁻¹z‖, z_max) (module docstring).
                    y_new = math.sqrt(n0 * n0 + n1 * n1 + (n2 / r_a) ** 2)
                    bound = max(math.sqrt(z0 * z0 + z1 * z1 + (z2 / r_a) ** 2),
                                math.sqrt(hx ** 2 + hy ** 2 + ht ** 2) * g / self._sigma0)
                    if y_new > bound:
                        f = bound / y_new
                        n0, n1, n2 = n0 * f, n1 * f, n2 * f
                        d0, d1, d2 = (n0 - z0) / dt, (n1 - z1) / dt, (n2 - z2) / dt
            else:
                d0, d1, d2 = self._euler_rate((hx, hy, ht), g, k, d0, d1, d2, dt)
                n0, n1, n2 = z0 + dt * d0, z1 + dt * d1, z2 + dt * d2
            self._z = [n0, n1, n2]
            if self._post:
                z0, z1, z2 = n0, n1, n2
        else:
            d0 = d1 = d2 = 0.0
        fn = self._f_n
        sig0, sig1, sig2 = self._sigma0, self._sigma1, self._sigma2
        fx = -(sig0 * z0 + sig1 * d0 + sig2 * vx) * fn
        fy = -(sig0 * z1 + sig1 * d1 + sig2 * vy) * fn
        tc = -(sig0 * z2 + sig1 * d2 + sig2 * self._j * om) * fn
        return (fx, fy, tc + self._cx * fy - self._cy * fx, tc)

    def _euler_rate(self, h: tuple[float, float, float], g: float, k: float, d0: float,
                    d1: float, d2: float, dt: float) -> tuple[float, float, float]:
        """Explicit-Euler rate: reference limiter, or the divergence guard."""
        z0, z1, z2 = self._z
        if self._limiter:
            c = g / self._params.sigma0
            b0 = abs(-h[0] * c - z0) / dt
            b1 = abs(-h[1] * c - z1) / dt
            b2 = abs(-self._r_a * h[2] * c - z2) / dt
            return (math.copysign(min(abs(d0), b0), d0), math.copysign(min(abs(d1), b1), d1),
                    math.copysign(min(abs(d2), b2), d2))
        if k * dt > EULER_STABILITY_LIMIT:
            raise UnstableStepError(
                f'explicit Euler step unstable: k*dt = {k * dt:.3g} > 2 (dt = {dt:g} s); '
                "reduce dt, enable rate_limiter or use integrator='exponential'")
        return d0, d1, d2

    def derivative(self, z: ArrayLike, twist: TwistLike, frame: Frame = 'pad',
                   ) -> NDArray[np.float64]:
        """Bristle rate ``ż = (w − β σ0 z/g)·v_n`` for a given state (SciPy solvers).

        Args:
            z: State (3,) [m].
            twist: ``(vx, vy, ω)`` at the ``frame`` point.
            frame: ``'pad'`` or ``'cop'``.

        Returns:
            ż (3,) [m/s].
        """
        za = np.asarray(z, dtype=np.float64).reshape(3)
        vx, vy, om = self._cop_twist(twist, frame)
        vn = math.sqrt(vx * vx + vy * vy + (self._r_a * om) ** 2)
        if vn == 0.0:
            return np.zeros(3)
        h = self._direction(vx, vy, om, vn)
        g = self._stribeck(vn)
        k = self._params.sigma0 * vn / g
        if self._ep:
            k *= self._beta(*h, g, float(za[0]), float(za[1]), float(za[2]))
        w = np.array([-h[0], -h[1], -self._r_a * h[2]])
        return w * vn - k * za

    def steady_state(self, twist: TwistLike, frame: Frame = 'pad',
                     f_n: float | None = None) -> Wrench:
        """Steady sliding wrench (``z = z_ss``, ``ż = 0``) for a constant twist.

        Args:
            twist: ``(vx, vy, ω)`` at the ``frame`` point.
            frame: ``'pad'`` or ``'cop'``.
            f_n: Normal force [N] (default: current; not stored).

        Returns:
            The wrench on the object.
        """
        p = self._params
        vx, vy, om = self._cop_twist(twist, frame)
        fn = self._f_n if f_n is None else float(f_n)
        vn = math.sqrt(vx * vx + vy * vy + (self._r_a * om) ** 2)
        hx = hy = ht = 0.0
        g = p.mu_c
        if vn > 0.0:
            hx, hy, ht = self._direction(vx, vy, om, vn)
            g = self._stribeck(vn)
        fx = (g * hx - p.sigma2 * vx) * fn
        fy = (g * hy - p.sigma2 * vy) * fn
        tc = (g * self._r_a * ht - p.sigma2 * self._j * om) * fn
        return Wrench(fx, fy, tc + self._cx * fy - self._cy * fx, tc)


class ReducedPlanarLuGreBatch:
    """N independent reduced contacts stepped together with array arithmetic (spec §6).

    Intended for Monte-Carlo studies and the simulator's two pads. All contacts share the
    friction law and integrator; each has its own surface (hence CoP, r_a, J_c and table),
    normal force and state. Results equal N :class:`ReducedPlanarLuGre` steps to round-off.

    Example::

        pads = ReducedPlanarLuGreBatch([circle(), circle()], LuGreParams())
        w = pads.step(np.array([[0.01, 0, 0.2], [0.01, 0, -0.2]]), dt=1e-3, f_n=[2.0, 2.0])
        w.fx, w.tau                # arrays of shape (2,)

    Args:
        surfaces: One surface per contact, or a single surface shared by ``n`` contacts.
        params: Amended LuGre parameters.
        n: Number of contacts when ``surfaces`` is a single surface.
        limit_surface: ``True`` (pre-computed tables), ``False`` (ellipsoid).
        elasto_plastic: Planar Elasto-Plastic weight.
        integrator: ``'exponential'`` or ``'explicit_euler'``.
        rate_limiter: Reference limiter (explicit Euler only).
        n_ls: Limit-surface segments per quadrant.
        cache: Optional :class:`LimitSurfaceCache` (identical surfaces share a table anyway).
        f_n: Initial normal force(s) [N], scalar or (N,).
        force_from: ``'pre_update'`` (default) or ``'post_update'`` (rigid-body coupling).
        scalar_threshold: Up to this many contacts each is stepped by the scalar kernel of
            :class:`ReducedPlanarLuGre` (numpy's per-call overhead dominates small arrays);
            larger batches use the vectorised path. Both give the same numbers.
    """

    def __init__(self, surfaces: ContactSurface | Sequence[ContactSurface],
                 params: LuGreParams = DEFAULT_PARAMS, *, n: int | None = None,
                 limit_surface: bool = True, elasto_plastic: bool = True,
                 integrator: str = 'exponential', rate_limiter: bool = False, n_ls: int = 20,
                 cache: LimitSurfaceCache | None = None,
                 f_n: float | ArrayLike = 1.0, scalar_threshold: int = 16,
                 force_from: str = 'pre_update') -> None:
        if isinstance(surfaces, ContactSurface):
            if n is None:
                raise ValueError('give n when a single surface is shared by all contacts')
            surface_list = [surfaces] * int(n)
        else:
            surface_list = list(surfaces)
            if n is not None and n != len(surface_list):
                raise ValueError(f'n = {n} but {len(surface_list)} surfaces given')
        if not surface_list:
            raise ValueError('at least one contact is needed')
        self._params = params
        self._force_from: ForceFrom = check_force_from(force_from)
        self._ep = bool(elasto_plastic)
        self._integrator: Integrator = check_integrator(integrator)
        if rate_limiter and self._integrator != 'explicit_euler':
            raise ValueError("rate_limiter applies to integrator='explicit_euler' only")
        self._limiter = bool(rate_limiter)
        self._use_ls = bool(limit_surface)
        self._n_ls = int(n_ls)
        self._cache = cache if cache is not None else LimitSurfaceCache()
        self._size = len(surface_list)
        self._geos = self._resolve(surface_list)
        self._pack()
        self._z = np.zeros((3, self._size))
        self._f_n = np.zeros(self._size)
        self._scalar: list[ReducedPlanarLuGre] | None = None
        if self._size <= scalar_threshold:
            self._scalar = [self._scalar_model(g) for g in self._geos]
        self.set_normal_force(f_n)

    def _scalar_model(self, geo: _ContactGeometry) -> ReducedPlanarLuGre:
        """A single-contact model sharing ``geo``'s table (no rebuild)."""
        option: LimitSurfaceOption = geo.table if geo.table is not None else False
        return ReducedPlanarLuGre(geo.surface, self._params, limit_surface=option,
                                  elasto_plastic=self._ep, integrator=self._integrator,
                                  rate_limiter=self._limiter, n_ls=self._n_ls,
                                  force_from=self._force_from)

    def _resolve(self, surfaces: Sequence[ContactSurface]) -> list[_ContactGeometry]:
        by_id: dict[int, _ContactGeometry] = {}
        geos = []
        for s in surfaces:
            geo = by_id.get(id(s))
            if geo is None:
                geo = _resolve_geometry(s, self._use_ls, self._n_ls, self._cache, None)
                by_id[id(s)] = geo
            geos.append(geo)
        return geos

    def _pack(self) -> None:
        """Stack per-contact geometry and tables into arrays."""
        geos = self._geos
        self._cx = np.array([g.cx for g in geos])
        self._cy = np.array([g.cy for g in geos])
        self._r_a = np.array([g.r_a for g in geos])
        self._j = np.array([g.second_moment for g in geos])
        if self._use_ls:
            tables: list[LimitSurface] = []
            index: dict[str, int] = {}
            tid = np.empty(self._size, dtype=np.intp)
            for c, g in enumerate(geos):
                if g.table is None:
                    raise RuntimeError('limit-surface batch without a table')   # invariant
                if g.table.key not in index:
                    index[g.table.key] = len(tables)
                    tables.append(g.table)
                tid[c] = index[g.table.key]
            n = self._n_ls
            rows = (4 * n + 1) * (n + 1)
            self._rows = np.ascontiguousarray(np.concatenate([t.table.reshape(-1, 3)
                                                              for t in tables]))
            self._base = tid * rows
        self._h = np.empty((3, self._size))

    # ------------------------------------------------------------------ properties
    @property
    def size(self) -> int:
        """Number of contacts N."""
        return self._size

    @property
    def params(self) -> LuGreParams:
        """The friction-law parameters."""
        return self._params

    @property
    def r_a(self) -> NDArray[np.float64]:
        """Characteristic radii [m], (N,) copy."""
        return self._r_a.copy()

    @property
    def state(self) -> NDArray[np.float64]:
        """Bristle states [m], (N, 3) copy."""
        if self._scalar is not None:
            return np.array([m._z for m in self._scalar])
        return self._z.T.copy()

    def set_state(self, z: ArrayLike) -> None:
        """Set all bristle states from an (N, 3) array [m]."""
        za = np.asarray(z, dtype=np.float64).reshape(self._size, 3)
        if self._scalar is not None:
            for model, row in zip(self._scalar, za, strict=True):
                model.set_state(row)
        else:
            self._z[:] = za.T

    def reset(self, which: ArrayLike | None = None) -> None:
        """Zero the states of all contacts, or of the contacts selected by ``which``."""
        z = self.state
        if which is None:
            z.fill(0.0)
        else:
            z[np.asarray(which)] = 0.0
        self.set_state(z)

    @property
    def f_n(self) -> NDArray[np.float64]:
        """Normal forces [N], (N,) copy."""
        return self._f_n.copy()

    def set_normal_force(self, f_n: float | ArrayLike) -> None:
        """Set the normal force(s) [N], scalar or (N,), all ≥ 0; states are untouched."""
        f = np.broadcast_to(np.asarray(f_n, dtype=np.float64), (self._size,))
        if not (np.all(np.isfinite(f)) and np.all(f >= 0.0)):
            raise ValueError('normal forces must be finite and >= 0 N')
        self._f_n[:] = f
        if self._scalar is not None:
            for model, value in zip(self._scalar, self._f_n.tolist(), strict=True):
                model._f_n = value

    def set_pressure(self, index: int, surface: ContactSurface) -> None:
        """Replace the pressure map of contact ``index`` (size-only changes just rescale)."""
        geo = _resolve_geometry(surface, self._use_ls, self._n_ls, self._cache, None,
                                previous=self._geos[index])
        self._geos[index] = geo
        self._pack()
        if self._scalar is not None:
            state = self._scalar[index]._z
            self._scalar[index] = self._scalar_model(geo)
            self._scalar[index]._z = state

    # ------------------------------------------------------------------ stepping
    def _cop_twists(self, twists: ArrayLike, frame: str,
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        tw = np.asarray(twists, dtype=np.float64)
        if tw.shape != (self._size, 3):
            raise ValueError(f'twists must have shape ({self._size}, 3), got {tw.shape}')
        vx, vy, om = tw[:, 0], tw[:, 1], tw[:, 2]
        if frame == 'pad':
            return vx - om * self._cy, vy + om * self._cx, om.copy()
        if frame == 'cop':
            return vx.copy(), vy.copy(), om.copy()
        raise ValueError(f"frame must be 'pad' or 'cop', got {frame!r}")

    def _directions(self, vx: NDArray[np.float64], vy: NDArray[np.float64],
                    om: NDArray[np.float64], vn: NDArray[np.float64]) -> NDArray[np.float64]:
        """(3, N) normalised limit-surface wrenches h (zero columns where v_n = 0)."""
        h = self._h
        if self._use_ls:
            lookup_arrays(self._rows, self._base, self._n_ls, vx, vy, om, self._r_a, h)
        else:
            inv = np.divide(-1.0, vn, out=np.zeros_like(vn), where=vn > 0.0)
            np.multiply(vx, inv, out=h[0])
            np.multiply(vy, inv, out=h[1])
            np.multiply(om * self._r_a, inv, out=h[2])
        return h

    def _stribeck(self, vn: NDArray[np.float64]) -> NDArray[np.float64]:
        p = self._params
        if p.mu_s == p.mu_c:
            return np.full_like(vn, p.mu_c)
        x = vn * (1.0 / p.v_s)
        e = x * x if p.stribeck_exp == 2.0 else np.power(x, p.stribeck_exp)
        np.negative(e, out=e)
        np.exp(e, out=e)
        e *= p.mu_s - p.mu_c
        e += p.mu_c
        return e

    def _beta(self, h: NDArray[np.float64], g: NDArray[np.float64],
              z: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                               NDArray[np.float64]]:
        """β = ε·α on rescaled vectors; also returns ‖S⁻¹z‖ and ‖h‖."""
        p = self._params
        y2 = z[2] / self._r_a
        yn = np.sqrt(z[0] * z[0] + z[1] * z[1] + y2 * y2)
        hn = np.sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2])
        y_max = hn * g * (1.0 / p.sigma0)
        u = np.divide(yn, y_max, out=np.zeros_like(yn), where=y_max > 0.0)
        u -= p.r_ba
        u *= 1.0 / (1.0 - p.r_ba)
        np.clip(u, 0.0, 1.0, out=u)
        u *= 0.5 * math.pi
        np.sin(u, out=u)
        u *= u
        den = hn * yn
        np.maximum(den, _TINY, out=den)
        c = (h[0] * z[0] + h[1] * z[1] + h[2] * y2) / den
        u *= 0.5 * (1.0 - c)
        return u, yn, hn

    def step(self, twists: ArrayLike, dt: float, f_n: float | ArrayLike | None = None,
             frame: Frame = 'pad') -> BatchWrench:
        """Advance all N contacts by ``dt``.

        Args:
            twists: (N, 3) twists ``(vx, vy, ω)`` [m/s, m/s, rad/s] at each contact's
                ``frame`` point.
            dt: Time step [s] (> 0).
            f_n: Normal forces [N] (scalar or (N,)) for this and later steps (default: keep).
            frame: ``'pad'`` or ``'cop'``.

        Returns:
            Fresh (N,) arrays of forces and torques (pad centre and CoP).
        """
        if f_n is not None:
            self.set_normal_force(f_n)
        if not dt > 0.0:
            raise ValueError(f'dt must be > 0 s, got {dt!r}')
        if self._scalar is not None:
            return self._step_scalar(twists, dt, frame)
        p = self._params
        vx, vy, om = self._cop_twists(twists, frame)
        r_a = self._r_a
        z = self._z
        rw = r_a * om
        vn = np.sqrt(vx * vx + vy * vy + rw * rw)
        h = self._directions(vx, vy, om, vn)
        g = self._stribeck(vn)
        k = (p.sigma0 * vn) / g
        if self._ep:
            beta, yn, hn = self._beta(h, g, z)
            k *= beta
        # q = w v_n with w = −S h.
        q = h * (-vn)
        q[2] *= r_a
        zd = q - k * z
        if self._integrator == 'exponential':
            x = np.maximum(k * dt, _TINY)
            ph = np.expm1(-x)
            ph /= -x
            zd *= ph
            z_new = z + dt * zd
            if self._ep:
                self._project(z, z_new, zd, yn, hn, g, dt)
        else:
            if self._limiter:
                zss = h * (-g / p.sigma0)
                zss[2] *= r_a
                bound = np.abs(zss - z) / dt
                zd = np.copysign(np.minimum(np.abs(zd), bound), zd)
            else:
                kdt = float(k.max()) * dt
                if kdt > EULER_STABILITY_LIMIT:
                    raise UnstableStepError(
                        f'explicit Euler step unstable: max k*dt = {kdt:.3g} > 2; reduce dt, '
                        "enable rate_limiter or use integrator='exponential'")
            z_new = z + dt * zd
        out = np.empty((4, self._size))
        fn = self._f_n
        a = (z if self._force_from == 'pre_update' else z_new) * p.sigma0
        if p.sigma1:
            a += p.sigma1 * zd
        if p.sigma2:
            a[0] += p.sigma2 * vx
            a[1] += p.sigma2 * vy
            a[2] += p.sigma2 * (self._j * om)
        np.multiply(a, -fn, out=out[:3])
        # out rows: fx, fy, τ_cop → τ_pad = τ_cop + c × F
        out[3] = out[2]
        out[2] += self._cx * out[1] - self._cy * out[0]
        self._z = z_new
        return BatchWrench(out[0], out[1], out[2], out[3])

    def _step_scalar(self, twists: ArrayLike, dt: float, frame: Frame) -> BatchWrench:
        """Small-N path: the scalar kernel per contact."""
        tw = np.asarray(twists, dtype=np.float64)
        if tw.shape != (self._size, 3):
            raise ValueError(f'twists must have shape ({self._size}, 3), got {tw.shape}')
        assert self._scalar is not None
        rows = [m.step(t, dt, frame=frame)
                for m, t in zip(self._scalar, tw.tolist(), strict=True)]
        out = np.array(rows).T
        return BatchWrench(out[0], out[1], out[2], out[3])

    def _project(self, z: NDArray[np.float64], z_new: NDArray[np.float64],
                 zd: NDArray[np.float64], y_old: NDArray[np.float64],
                 hn: NDArray[np.float64], g: NDArray[np.float64], dt: float) -> None:
        """Elasto-Plastic bound ``‖S⁻¹z⁺‖ ≤ max(‖S⁻¹z‖, z_max)``, in place."""
        y2 = z_new[2] / self._r_a
        y_new = np.sqrt(z_new[0] * z_new[0] + z_new[1] * z_new[1] + y2 * y2)
        bound = np.maximum(y_old, hn * g * (1.0 / self._params.sigma0))
        over = y_new > bound
        if not np.any(over):
            return
        f = np.where(over, bound / np.maximum(y_new, _TINY), 1.0)
        z_new *= f
        np.subtract(z_new, z, out=zd)
        zd *= 1.0 / dt

    def steady_state(self, twists: ArrayLike, frame: Frame = 'pad') -> BatchWrench:
        """Steady sliding wrenches (``z = z_ss``) for (N, 3) constant twists."""
        p = self._params
        vx, vy, om = self._cop_twists(twists, frame)
        vn = np.sqrt(vx * vx + vy * vy + (self._r_a * om) ** 2)
        h = self._directions(vx, vy, om, vn).copy()
        g = self._stribeck(vn)
        fn = self._f_n
        fx = (g * h[0] - p.sigma2 * vx) * fn
        fy = (g * h[1] - p.sigma2 * vy) * fn
        tc = (g * self._r_a * h[2] - p.sigma2 * self._j * om) * fn
        return BatchWrench(fx, fy, tc + self._cx * fy - self._cy * fx, tc)
