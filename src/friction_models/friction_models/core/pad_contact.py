# SPDX-License-Identifier: Apache-2.0
"""One pad on the object: a planar LuGre model plus what the plant's implicit coupling needs.

ROS-free and deterministic. Pad k's contact frame is ``vel_sensor_k``; twists and wrenches go
between ``gripper_middle`` and the pad frame through the shared
:func:`~slip_cell_common.core.frames.planar_from_middle` / ``planar_to_middle``, evaluated once
into a constant 3×3 matrix ``P_k``. In the elastic (sticking) regime the model's post-update
wrench is linear in the twist of the step, ``W(ν) = W_s − D ν`` (spring ``W_s = −σ0 f_n z``,
stick damping ``D``, see :mod:`.plant`); a pad that slides is linearised about its slip
direction (`PadContact.sliding_terms`). Both are what :class:`~.plant.Plant` assembles into
its implicit solve.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Union

import numpy as np

from slip_cell_common.core.frames import FrameParams, planar_from_middle, planar_to_middle
from slip_cell_common.core.param_schema import ranged_field as _f

from .distributed import DistributedPlanarLuGre
from .limit_surface import LimitSurfaceCache, characteristic_radius
from .params import LuGreParams
from .presets import ContactPreset
from .reduced import ReducedPlanarLuGre
from .surfaces import ContactSurface, standard_surface

__all__ = [
    'FrictionModel',
    'FrictionSettings',
    'PadContact',
]

FrictionModel = Union[ReducedPlanarLuGre, DistributedPlanarLuGre]


@dataclass(frozen=True)
class FrictionSettings:
    """Friction-law settings shared by both pads (parameter group ``friction``).

    μ_c, μ_s, σ2 (= max(μ_v, 0)) and the contact size come from the object preset; the rest
    is here. σ0 is the bristle (pad shear) stiffness per newton of normal force: 1e5 1/m gives
    a pre-sliding displacement μ/σ0 of a few µm, i.e. a stiff pad well below one velocity
    sensor count (7.9 µm).
    """

    sigma0: float = _f(1.0e5, '1/m', 1.0e2, 1.0e8, 'normalised bristle stiffness')
    sigma1: float = _f(40.0, 's/m', 0.0, 1.0e4, 'normalised bristle damping')
    v_s: float = _f(1.0e-3, 'm/s', 1.0e-6, 1.0, 'Stribeck velocity')
    stribeck_exp: float = _f(2.0, '-', 0.1, 10.0, 'Stribeck exponent (gamma)')
    r_ba: float = _f(0.9, '-', 0.0, 0.999, 'elasto-plastic breakaway ratio z_ba/z_max')
    elasto_plastic: bool = field(default=True, metadata={
        'description': 'planar elasto-plastic weight (no creep under constant load)'})
    limit_surface: bool = field(default=True, metadata={
        'description': 'reduced model: pre-computed limit surface (False: ellipsoid)'})
    n_ls: int = field(default=20, metadata={
        'unit': '-', 'range': (2, 200), 'description': 'limit-surface segments per quadrant'})
    patch_size: float = _f(0.02, 'm', 1.0e-3, 0.2,
                           'nominal pad patch side before scaling r_a to the preset r')


def _mat_from(fn: object, frames: FrameParams, finger: int) -> tuple[float, ...]:
    """3×3 matrix (row-major) of the linear map ``fn(frames, finger, x, y, z)``."""
    cols = [fn(frames, finger, *e) for e in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0),  # type: ignore
                                             (0.0, 0.0, 1.0))]
    return tuple(cols[j][i] for i in range(3) for j in range(3))


def _mm(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, ...]:
    """Row-major 3×3 product."""
    return tuple(sum(a[3 * i + k] * b[3 * k + j] for k in range(3))
                 for i in range(3) for j in range(3))


def _tr(a: tuple[float, ...]) -> tuple[float, ...]:
    return (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])



class PadContact:
    """One pad: a friction model in the pad frame plus what the implicit coupling needs.

    The model's surface is the preset's shape scaled so that its characteristic radius equals
    the preset's torsional radius ``r``.

    Args:
        finger: 1 or 2.
        frames: Frame constants (pad orientation in ``gripper_middle``).
        contact: Friction of this pad on the object.
        surface_name: Pad pressure shape.
        settings: Friction-law settings.
        model: ``'reduced'`` or ``'distributed'``.
        integrator: ``'exponential'`` or ``'explicit_euler'``.
        grid_n: Cells per side of the pressure grid.
        dt: Physics step [s] (enters the stick damping ``σ0 dt``).
        cache: Limit-surface cache (tables are shared between presets of the same shape).
    """

    def __init__(self, finger: int, frames: FrameParams, contact: ContactPreset,
                 surface_name: str, settings: FrictionSettings, model: str, integrator: str,
                 grid_n: int, dt: float, cache: LimitSurfaceCache) -> None:
        self.finger = finger
        self.contact = contact
        base = standard_surface(surface_name, grid_n, settings.patch_size)
        params = LuGreParams(mu_c=contact.mu_c, mu_s=max(contact.mu_s, contact.mu_c),
                             v_s=settings.v_s, stribeck_exp=settings.stribeck_exp,
                             sigma0=settings.sigma0, sigma1=settings.sigma1,
                             sigma2=max(contact.mu_v, 0.0), r_ba=settings.r_ba)
        self.params = params
        self._neg_sigma0 = -params.sigma0
        if model == 'reduced' and settings.limit_surface:
            table = cache.get(base, settings.n_ls)
            surface = base.scaled(contact.r / table.r_a)
            self.model: FrictionModel = ReducedPlanarLuGre(
                surface, params, limit_surface=table, elasto_plastic=settings.elasto_plastic,
                integrator=integrator, force_from='post_update', f_n=0.0)
        else:
            surface = base.scaled(contact.r / characteristic_radius(base, bilinear=True))
            if model == 'reduced':
                self.model = ReducedPlanarLuGre(
                    surface, params, limit_surface=False,
                    elasto_plastic=settings.elasto_plastic, integrator=integrator,
                    force_from='post_update', f_n=0.0)
            else:
                self.model = DistributedPlanarLuGre(
                    surface, params, elasto_plastic=settings.elasto_plastic,
                    integrator=integrator, force_from='post_update', f_n=0.0)
        self.surface: ContactSurface = surface
        self.reduced = isinstance(self.model, ReducedPlanarLuGre)
        self.r_a = contact.r
        cx, cy = surface.cop
        self.cx, self.cy = float(cx), float(cy)
        self.cop = (self.cx, self.cy)   #: centre of pressure in the pad frame [m]
        j_c = float(surface.second_moment)
        self.j_c = j_c
        # middle -> pad (P) and pad -> middle (P^T, checked against planar_to_middle).
        self.p_mid_to_pad = _mat_from(planar_from_middle, frames, finger)
        to_mid = _mat_from(planar_to_middle, frames, finger)
        if max(abs(a - b) for a, b in zip(to_mid, _tr(self.p_mid_to_pad))) > 1e-12:
            raise ValueError('planar_to_middle is not the transpose of planar_from_middle')
        # Per unit f_n, about the CoP: stick damping (σ0 dt + σ1 + σ2, ...) and viscous part.
        s0, s1, s2 = params.sigma0, params.sigma1, params.sigma2
        a = s0 * dt + s1 + s2
        b = ((s0 * dt + s1) * self.r_a * self.r_a + s2 * j_c) if self.reduced else a * j_c
        self._d_stick_cop = (a, b)
        self._d_visc_cop = (s2, s2 * j_c)
        # Lever transport T (pad-centre twist -> CoP twist).
        self._t = (1.0, 0.0, -self.cy, 0.0, 1.0, self.cx, 0.0, 0.0, 1.0)
        self.lever = self._t   #: T: pad-centre twist -> CoP twist (row-major)
        self.d_stick_pad = self._pad_matrix(*self._d_stick_cop)
        self.d_visc_pad = self._pad_matrix(*self._d_visc_cop)
        self._sym_stick = _sym6(self.d_stick_pad)
        if not self.reduced:
            w = surface.pressure
            xs, ys = surface.cell_centres()
            self._dist_w = (w, w * xs, w * ys)
        self.w = (0.0, 0.0, 0.0)   #: last wrench on the object, pad frame, pad centre [N, N·m]
        self.f_n = 0.0             #: normal force of the last step [N]
        self.nu = (0.0, 0.0, 0.0)  #: last twist of the object relative to the pad (pad frame)

    def _pad_matrix(self, a: float, b: float) -> tuple[float, ...]:
        """``Tᵀ diag(a, a, b) T``: a CoP-diagonal damping seen at the pad centre."""
        t = self._t
        d = (a, 0.0, 0.0, 0.0, a, 0.0, 0.0, 0.0, b)
        return _mm(_tr(t), _mm(d, t))

    def world_matrices(self, phi: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """``Q_k(φ)`` (world axes → pad) and ``Q_kᵀ D Q_k`` for the stick damping D."""
        c, s = math.cos(phi), math.sin(phi)
        p = self.p_mid_to_pad
        # Q = P · diag(R(φ)ᵀ, 1): world -> middle -> pad (columns 0, 1 rotate).
        q = (p[0] * c - p[1] * s, p[0] * s + p[1] * c, p[2],
             p[3] * c - p[4] * s, p[3] * s + p[4] * c, p[5],
             p[6] * c - p[7] * s, p[6] * s + p[7] * c, p[8])
        return q, _congruence(q, self._sym_stick)

    def spring(self, f_n: float) -> tuple[float, float, float]:
        """Bristle spring wrench ``−σ0 f_n z`` at the pad centre, pad frame [N, N, N·m]."""
        k = self._neg_sigma0 * f_n
        model = self.model
        if isinstance(model, ReducedPlanarLuGre):
            z0, z1, z2 = model.state_tuple
            fx, fy = k * z0, k * z1
            return fx, fy, k * z2 + self.cx * fy - self.cy * fx
        z = model.state
        w, wx, wy = self._dist_w
        zx, zy = z[..., 0], z[..., 1]
        return (k * float(np.sum(w * zx)), k * float(np.sum(w * zy)),
                k * float(np.sum(wx * zy - wy * zx)))

    def stribeck(self, vx: float, vy: float, om: float) -> float:
        """Friction coefficient g(v_n) at the generalised CoP speed of a pad-centre twist."""
        p = self.params
        vcx = vx - om * self.cy
        vcy = vy + om * self.cx
        vn = math.sqrt(vcx * vcx + vcy * vcy + (self.r_a * om) ** 2)
        x = vn / p.v_s
        e = x * x if p.stribeck_exp == 2.0 else x ** p.stribeck_exp
        return p.mu_c + (p.mu_s - p.mu_c) * math.exp(-e)

    def load_ratio(self, fx: float, fy: float, tau: float, f_n: float) -> float:
        """``λ = √((f_t/f_n)² + (τ_c/(r_a f_n))²)`` of a pad-centre wrench (CoP torque)."""
        tc = tau - (self.cx * fy - self.cy * fx)
        return math.sqrt(fx * fx + fy * fy + (tc / self.r_a) ** 2) / f_n

    def reset(self) -> None:
        """Zero the bristles and the stored wrench."""
        self.model.reset()
        self.w = (0.0, 0.0, 0.0)
        self.f_n = 0.0
        self.nu = (0.0, 0.0, 0.0)

    def sliding_terms(self, q: tuple[float, ...], f_n: float,
                      pred: tuple[float, float, float] | None, lam: float
                      ) -> tuple[tuple[float, float, float], tuple[float, ...]]:
        """Linearised friction of a pad that slides in this step (world axes).

        Steady sliding friction in generalised CoP coordinates (``ν̃ = (v_x, v_y, r_a ω)``,
        ``W̃ = (F_x, F_y, τ_c/r_a)``) is ``W̃ = −f_n g(v) n + viscous`` with ``n = ν̃/‖ν̃‖``:
        along ``n`` it barely depends on the speed, across ``n`` it turns with the twist, i.e.
        acts as the damping ``D̃_⊥ = f_n g/‖ν̃‖ (I − n nᵀ)``, which enters the implicit solve
        (explicitly it would be unstable for ``f_n g dt/(m ‖ν̃‖) > 2``), as does the viscous
        part. The constant part:

        * continuing a slide (``pred`` is None): the model's own wrench of the previous step,
          rescaled to the current f_n, so the direction follows the model's LuGre dynamics;
        * starting (or reversing) a slide in this step: the stick-predicted wrench ``pred``
          (world axes) projected onto the kinetic limit ``g(v) f_n``; the slip direction
          opposes it.

        Returns:
            ``(W_w, D̂_w)``: the wrench at the gripper centre and the damping per newton of
            normal force, both in world axes.
        """
        p = self.params
        g = self.stribeck(*self.nu)
        ra, cx, cy = self.r_a, self.cx, self.cy
        vx, vy, om = self.nu
        n0, n1, n2 = vx - om * cy, vy + om * cx, ra * om
        speed = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        if pred is None:
            k = f_n / self.f_n
            wx, wy, wt = self.w
            w = (k * (q[0] * wx + q[3] * wy + q[6] * wt),
                 k * (q[1] * wx + q[4] * wy + q[7] * wt),
                 k * (q[2] * wx + q[5] * wy + q[8] * wt))
            n0, n1, n2 = n0 / speed, n1 / speed, n2 / speed
        else:
            r = g / lam
            w = (pred[0] * r, pred[1] * r, pred[2] * r)
            # Pad-frame CoP wrench of the prediction; the slip opposes it.
            wx = q[0] * w[0] + q[1] * w[1] + q[2] * w[2]
            wy = q[3] * w[0] + q[4] * w[1] + q[5] * w[2]
            wt = q[6] * w[0] + q[7] * w[1] + q[8] * w[2]
            m0, m1, m2 = -wx, -wy, -(wt - (cx * wy - cy * wx)) / ra
            norm = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
            if norm == 0.0:
                return w, self.d_visc_pad
            n0, n1, n2 = m0 / norm, m1 / norm, m2 / norm
        c = g / max(speed, 1e-3 * p.v_s)
        # D_c = S D̃ S with S = diag(1, 1, r_a), D̃ = c (I − n nᵀ) (symmetric).
        a00 = c * (1.0 - n0 * n0)
        a01 = -c * n0 * n1
        a02 = -c * ra * n0 * n2
        a11 = c * (1.0 - n1 * n1)
        a12 = -c * ra * n1 * n2
        a22 = c * ra * ra * (1.0 - n2 * n2)
        if cx or cy:
            # Tᵀ D_c T with T = [[1, 0, −c_y], [0, 1, c_x], [0, 0, 1]]
            b02 = -cy * a00 + cx * a01 + a02
            b12 = -cy * a01 + cx * a11 + a12
            a22 = -cy * b02 + cx * b12 + (-cy * a02 + cx * a12 + a22)
            a02, a12 = b02, b12
        v = self.d_visc_pad
        return w, _congruence(q, (a00 + v[0], a01 + v[1], a02 + v[2], a11 + v[4], a12 + v[5],
                                  a22 + v[8]))

    def twist_reversed(self, q: tuple[float, ...], n0: float, n1: float, n2: float) -> bool:
        """True when the pad's new relative twist (world ``ν_w``) no longer continues the
        slide of the previous step: reversed (negative generalised dot product) or ~0."""
        v0 = q[0] * n0 + q[1] * n1 + q[2] * n2
        v1 = q[3] * n0 + q[4] * n1 + q[5] * n2
        v2 = q[6] * n0 + q[7] * n1 + q[8] * n2
        ra, cx, cy = self.r_a, self.cx, self.cy
        a0, a1, a2 = v0 - v2 * cy, v1 + v2 * cx, ra * v2
        px, py, pw = self.nu
        b0, b1, b2 = px - pw * cy, py + pw * cx, ra * pw
        slow = 1e-6 * self.params.v_s
        return a0 * b0 + a1 * b1 + a2 * b2 <= 0.0 or a0 * a0 + a1 * a1 + a2 * a2 < slow * slow


def _sym6(d: tuple[float, ...]) -> tuple[float, float, float, float, float, float]:
    """Upper triangle ``(d00, d01, d02, d11, d12, d22)`` of a symmetric row-major 3×3."""
    return (d[0], d[1], d[2], d[4], d[5], d[8])


def _congruence(q: tuple[float, ...], d: tuple[float, float, float, float, float, float]
                ) -> tuple[float, ...]:
    """``qᵀ D q`` for a symmetric ``D`` given as ``(d00, d01, d02, d11, d12, d22)``."""
    d00, d01, d02, d11, d12, d22 = d
    q0, q1, q2, q3, q4, q5, q6, q7, q8 = q
    # m = D q (rows of D times the columns of q)
    m0 = d00 * q0 + d01 * q3 + d02 * q6
    m1 = d00 * q1 + d01 * q4 + d02 * q7
    m2 = d00 * q2 + d01 * q5 + d02 * q8
    m3 = d01 * q0 + d11 * q3 + d12 * q6
    m4 = d01 * q1 + d11 * q4 + d12 * q7
    m5 = d01 * q2 + d11 * q5 + d12 * q8
    m6 = d02 * q0 + d12 * q3 + d22 * q6
    m7 = d02 * q1 + d12 * q4 + d22 * q7
    m8 = d02 * q2 + d12 * q5 + d22 * q8
    r00 = q0 * m0 + q3 * m3 + q6 * m6
    r01 = q0 * m1 + q3 * m4 + q6 * m7
    r02 = q0 * m2 + q3 * m5 + q6 * m8
    r11 = q1 * m1 + q4 * m4 + q7 * m7
    r12 = q1 * m2 + q4 * m5 + q7 * m8
    r22 = q2 * m2 + q5 * m5 + q8 * m8
    return (r00, r01, r02, r01, r11, r12, r02, r12, r22)
