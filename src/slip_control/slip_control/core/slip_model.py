# SPDX-License-Identifier: Apache-2.0
"""Friction model of the two pads for the model-based slip laws (docs/model_slip_control.md §2).

Each pad is the project's own reduced planar LuGre model
(`friction_models.core.reduced.ReducedPlanarLuGre`) on the pre-computed limit surface of an
assumed pressure shape (`friction_models.core.limit_surface`), scaled so that its
characteristic radius is the estimated torsional radius ``r``, with the estimated ``μ_c``,
``μ_s`` (``μ_c`` when not estimated), viscous ``σ2 = max(μ_v, 0)`` and the Stribeck velocity
of the parameters. Only its steady sliding wrench is used:

    W_k(ν) = f_n·(g_k(v_n)·h_k(ν) − σ2,k·(vx, vy, J_c ω))      (friction_models §6; per pad)

so everything here is *per unit grasp force* [N/N, N·m/N] and averaged over the two pads (both
carry the same grasp force; the controllers work with two-finger means,
control_and_estimation §1.2). Twists and wrenches are in ``gripper_middle`` axes at the grasp
point (both pads evaluated in those axes: exact for the symmetric maps, an approximation for
the gradient ones), the friction pointing *with* the motion it resists (positive numbers).

The two inverse problems the slip laws need:

* `translation_force` — grasp force at which the pads' friction for a translation at speed
  ``v`` equals a load ``f`` [N per pad]; `slide_force` the same with a torque on the pads
  too (the object turns while it slides, as the limit surface makes it);
* `rotation_force` — grasp force at which a turning slip carries a tangential load ``f`` and a
  torque ``τ`` (per pad) at the same time: the limit surface couples them, so the twist is
  found by bisection on its elevation ``ψ`` (``ψ = 0`` pure rotation about the grasp point,
  ``ψ → π/2`` pure translation) until the wrench direction matches the load's, and the
  translation that comes with the turn (``r·tan ψ`` per radian) is returned with it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from friction_models.core.limit_surface import LimitSurface
from friction_models.core.params import LuGreParams
from friction_models.core.reduced import ReducedPlanarLuGre
from friction_models.core.surfaces import standard_surface

from slip_control.core.contact import ContactProperties, FingerContact

#: Cells per side of the assumed pressure map and its nominal side [m] (the simulator's).
GRID_N = 21
PATCH_SIZE = 0.02
#: Limit-surface segments per quadrant.
N_LS = 20
#: Bisection steps of `ContactModel.rotation_force` (ψ to ~1e-6 rad).
_BISECTIONS = 22


@dataclass(frozen=True, slots=True)
class RotationSolution:
    """Grasp force and twist of a turning slip that carries a given load (per unit turn rate).

    Attributes:
        force: Grasp force [N].
        psi: Twist elevation ``ψ`` [rad] (0 = pure rotation about the grasp point).
        translation_per_rad: Grasp-point translation per radian of turn [m/rad].
    """

    force: float
    psi: float
    translation_per_rad: float


class ContactModel:
    """Steady friction of the two pads per unit grasp force (module docstring).

    Args:
        props: Contact properties (``μ_c`` of both fingers must be finite and > 0; ``μ_s``,
            ``μ_v`` are used when finite; a finger without a valid ``r`` takes the other's, or
            ``fallback_r`` — only rotations depend on it).
        shape: Assumed pressure shape (a `friction_models.core.surfaces.STANDARD_SURFACES`
            name).
        stribeck_velocity: Stribeck velocity ``v_s`` [m/s].
        fallback_r: Torsional radius used when neither finger has one [m].
    """

    def __init__(self, props: ContactProperties, shape: str, stribeck_velocity: float,
                 fallback_r: float = 0.005) -> None:
        radii = [f.r for f in (props.finger_1, props.finger_2)
                 if math.isfinite(f.r) and f.r > 0.0]
        for k in (1, 2):
            f = props.finger(k)
            if not (math.isfinite(f.mu_c) and f.mu_c > 0.0):
                raise ValueError(f'finger {k}: the friction model needs a finite mu_c > 0, '
                                 f'got {f.mu_c!r}')
        base = standard_surface(shape, GRID_N, PATCH_SIZE)
        table = LimitSurface.build(base, N_LS)
        self._surface = base
        self._table = table
        self._v_s = stribeck_velocity
        self._r_valid = len(radii) == 2
        r_default = radii[0] if radii else fallback_r
        fingers = [f if math.isfinite(f.r) and f.r > 0.0 else replace(f, r=r_default)
                   for f in (props.finger_1, props.finger_2)]
        self._pads = tuple(self._make_pad(f) for f in fingers)
        self._r = 0.5 * (fingers[0].r + fingers[1].r)
        self._mu_s = 0.5 * sum(p.params.mu_s for p in self._pads)
        self._mu_c = 0.5 * sum(p.params.mu_c for p in self._pads)
        self._mu_s_r = 0.5 * sum(p.params.mu_s * p.r_a for p in self._pads)

    def _make_pad(self, f: FingerContact) -> ReducedPlanarLuGre:
        mu_c = float(f.mu_c)
        mu_s = float(f.mu_s) if math.isfinite(f.mu_s) and f.mu_s >= mu_c else mu_c
        sigma2 = float(f.mu_v) if math.isfinite(f.mu_v) and f.mu_v > 0.0 else 0.0
        surface = self._surface.scaled(float(f.r) / self._table.r_a)
        params = LuGreParams(mu_c=mu_c, mu_s=mu_s, v_s=self._v_s, sigma2=sigma2)
        return ReducedPlanarLuGre(surface, params, limit_surface=self._table, f_n=1.0)

    # -- views ---------------------------------------------------------------------------

    @property
    def r_valid(self) -> bool:
        """Both fingers had a valid torsional radius."""
        return self._r_valid

    @property
    def r(self) -> float:
        """Mean torsional radius of the pads [m]."""
        return self._r

    @property
    def mu_c(self) -> float:
        """Mean Coulomb coefficient [-]."""
        return self._mu_c

    @property
    def mu_s(self) -> float:
        """Mean static coefficient [-] (``μ_c`` where not estimated)."""
        return self._mu_s

    @property
    def static_torque_per_force(self) -> float:
        """Mean static torsional capacity per unit grasp force ``mean(μ_s·r)`` [N·m/N]."""
        return self._mu_s_r

    # -- forward model ----------------------------------------------------------------------

    def wrench(self, vx: float, vy: float, omega: float) -> tuple[float, float, float]:
        """Mean steady friction of the pads per unit grasp force, against the twist.

        Args:
            vx, vy: Slip velocity of the grasp point [m/s] (``gripper_middle``).
            omega: Slip rate [rad/s].

        Returns:
            ``(fx, fy, τ)`` [N/N, N/N, N·m/N] pointing *with* the motion (the load the friction
            balances); zero for a zero twist.
        """
        fx = fy = tz = 0.0
        for pad in self._pads:
            w = pad.steady_state((vx, vy, omega), frame='pad', f_n=1.0)
            fx -= w.fx
            fy -= w.fy
            tz -= w.tau
        return 0.5 * fx, 0.5 * fy, 0.5 * tz

    def translation_coefficient(self, speed: float) -> float:
        """Mean friction per unit grasp force of a pure translation at ``speed`` [m/s] [-].

        At ``speed ≤ 0`` the static value ``mean(μ_s)`` (the break-away limit).
        """
        if not speed > 0.0:
            return self._mu_s
        return self.wrench(speed, 0.0, 0.0)[0]

    def translation_force(self, load: float, speed: float) -> float:
        """Grasp force [N] at which a translation at ``speed`` [m/s] carries ``load`` [N/pad]."""
        return max(load, 0.0) / self.translation_coefficient(speed)

    def slide_force(self, force: float, torque: float, speed: float) -> float:
        """Grasp force [N] that carries a tangential ``force`` [N/pad] and a ``torque``
        [N·m/pad] while the grasp point slides at ``speed`` [m/s] (the object turning as the
        limit surface makes it: a translation with a torque on the pads is a combined slip).

        ``speed ≤ 0`` evaluates the static end of the Stribeck curve (break-away).
        """
        f = abs(force)
        tau = abs(torque)
        v = max(speed, 1e-7)
        if tau <= 0.0:
            return self.translation_force(f, speed)
        if f <= 0.0:
            return self.rotation_force(0.0, tau, v / self._r).force
        r = self._r
        lo, hi = 1e-6, 0.5 * math.pi - 1e-6
        want = f / tau
        for _ in range(_BISECTIONS):
            psi = 0.5 * (lo + hi)
            fx, _, tz = self.wrench(v, 0.0, v / (r * math.tan(psi)))
            if fx >= want * tz:
                hi = psi
            else:
                lo = psi
        psi = 0.5 * (lo + hi)
        fx, _, tz = self.wrench(v, 0.0, v / (r * math.tan(psi)))
        return f / fx if fx > 0.0 else math.inf

    def rotation_force(self, force: float, torque: float, rate: float) -> RotationSolution:
        """Grasp force that carries a tangential ``force`` [N/pad] and a ``torque`` [N·m/pad]
        while the object turns at ``rate`` [rad/s] (limit-surface coupling, module docstring).

        The translation is taken along the load (normality on a centred limit surface); ``rate
        ≤ 0`` uses a small rate (the static end of the Stribeck curve).
        """
        f = abs(force)
        tau = abs(torque)
        w = max(abs(rate), 1e-6)
        r = self._r
        if tau <= 0.0:
            return RotationSolution(self.translation_force(f, 0.0), 0.5 * math.pi, math.inf)
        lo, hi = 0.0, 0.5 * math.pi
        want = f / tau
        for _ in range(_BISECTIONS):
            psi = 0.5 * (lo + hi)
            v = r * w * math.tan(psi)
            fx, _, tz = self.wrench(v, 0.0, w)
            if fx >= want * tz:
                hi = psi
            else:
                lo = psi
        psi = 0.5 * (lo + hi)
        v = r * w * math.tan(psi)
        fx, _, tz = self.wrench(v, 0.0, w)
        force_needed = tau / tz if tz > 0.0 else math.inf
        return RotationSolution(force_needed, psi, r * math.tan(psi))
