# SPDX-License-Identifier: Apache-2.0
"""Physics of the simulated gripper cell: object, two LuGre pads, table, arm and actuator.

ROS-free and deterministic: time is passed in, nothing reads a clock, nothing is random here
(sensor noise lives in :mod:`.sensors`).

Frames and signs
----------------
* **World**: the vertical plane that contains the ``gripper_middle`` xy plane; X horizontal,
  Y up, Z out of the plane = the grasp axis (``gripper_middle`` z, finger 1 → finger 2).
  Gravity is ``(0, −g)`` at the object's CoM.
* **Gripper**: pose ``(X_g, Y_g, φ)``: the origin of ``gripper_middle`` (the grasp centre,
  where both pad centres project onto the plane) and its rotation about the grasp axis;
  ``φ = 0`` means ``gripper_middle`` +y points up. ``R(φ)`` maps ``gripper_middle`` xy to
  world XY.
* **Pads**: pad k's contact frame is ``vel_sensor_k``. Twists and wrenches go between
  ``gripper_middle`` and the pad frames with the shared
  :func:`~slip_cell_common.core.frames.planar_from_middle` / ``planar_to_middle`` (finger 2's
  ω and τ flip); the plant evaluates them once into constant 3×3 matrices ``P_k``.
* **Object**: rigid, CoM at ``X = (X, Y)``, angle ``θ`` (0 = upright), generalised velocity
  ``u = (V_X, V_Y, Ω)``, mass matrix ``M = diag(m, m, I)`` (I about the CoM).

Relative twist and friction (friction_models spec §1, §7, §14)
--------------------------------------------------------------
With ``d = C_g − X`` the lever from the CoM to the gripper centre, the object material point
at the gripper centre moves with ``(V_X − Ω d_y, V_Y + Ω d_x)``; relative to the gripper, in
world axes at the gripper centre,

    ν_w = L u − b,    L = [[1, 0, −d_y], [0, 1, d_x], [0, 0, 1]],    b = (Ẋ_g, Ẏ_g, φ̇),

and pad k sees ``ν_k = Q_k ν_w`` with ``Q_k = P_k · diag(R(φ)ᵀ, 1)``. Pad k's friction wrench
``W_k`` (on the object, pad frame, about the pad centre) acts on the body as the generalised
force ``Lᵀ Q_kᵀ W_k`` (force at the gripper centre, torque ``τ + d × F`` about the CoM). Both
pads carry the grasp normal force ``f_n``; each is a
:class:`~friction_models.core.reduced.ReducedPlanarLuGre` (elasto-plastic, exponential
integrator, ``force_from='post_update'``) or, for validation, a
:class:`~friction_models.core.distributed.DistributedPlanarLuGre`.

Time stepping: linearly implicit, stick/slide active set
--------------------------------------------------------
The bristles are a stiff spring ``σ0 f_n`` per pad (``ω_c = √(σ0 f_n,total/m)`` is 10³–10⁴
rad/s), so an explicit coupling would bound the step by ``ω_c dt < 2``. In the elastic
(sticking) regime the library's post-update wrench is *linear* in the twist of the step:
``z⁺ = z + dt q(ν)``, ``W(ν) = W_s − D ν`` with the spring ``W_s = −σ0 f_n z`` and, about the
CoP,

    D = f_n · diag(σ0 dt + σ1 + σ2,  σ0 dt + σ1 + σ2,  (σ0 dt + σ1) r_a² + σ2 J_c)

(reduced model; the distributed one has ``(σ0 dt + σ1 + σ2) J_c`` in the last entry). Each step
therefore solves, for the end-of-step velocity ``u⁺`` (backward Euler in the contact spring),

    (M/dt + Lᵀ D_w L + H_table) u⁺ = M u/dt + Q_ext + Lᵀ (W_s,w + D_w b) + r_table,

then checks every pad's predicted wrench against its static limit surface (ellipsoid,
``(f_t/(μ_s f_n))² + (τ_c/(μ_s r_a f_n))² ≤ 1``). A pad that cannot hold is switched to
*sliding* for this step: its friction is linearised about the slip direction ``n`` — a
constant part (the predicted wrench projected onto the kinetic limit ``g(v)·f_n`` when the
slide starts, the model's own previous wrench while it continues) plus the implicit direction
damping ``f_n g/‖ν̃‖ (I − n nᵀ)`` and viscous part — and the system is solved again. The
active set is warm-started from the last step (a sliding pad keeps sliding unless its twist
reverses or vanishes, then the stick prediction decides again); within a step elements only
turn from stick to slide, so the iteration is short. The velocity found is the twist passed
to the library models, whose exact (nonlinear) wrenches then give the final velocity

    (M/dt + H_table) u⁺ = M u/dt + Q_ext + r_table + Lᵀ Σ_k Q_kᵀ W_k,

and the pose follows with symplectic Euler, ``X⁺ = X + dt V⁺``, ``θ⁺ = θ + dt Ω⁺``. In pure
stick the library returns exactly the linear prediction, so the final velocity equals the
implicit one (unconditionally stable for the contact spring); in sliding only the bounded
friction magnitude is explicit, its direction dependence being implicit. This keeps the
coupled system stable for any physics step (up to the sensor periods); accuracy (stick–slip
timing, Stribeck transitions) still improves with a smaller step. Residual error: in a step
that changes from stick to slide the bristles are advanced with the predicted twist, not the
final one — O(dt), well below 10⁻⁶ of the object's energy in the tests.

Table
-----
A horizontal line at ``Y = table.height``; unilateral penalty contacts at the object's four
corners (normally only the two bottom ones touch): normal force
``N = k δ⁺ − c v_n⁺ ≥ 0`` on the penetration ``δ``, tangential anchor spring
``F_t = −k_t s⁺ − c_t v_t⁺`` limited to ``|F_t| ≤ μ_table N`` (Coulomb sliding beyond it), all
inside the same implicit solve and active set. Corners enter speculatively (when the
penetration predicted from the current velocity is positive), so an impact never starts
one step late inside the table, which would create spring energy from nothing. The table
stops the object from moving down and, through the two corner normals, from turning: this is
what makes the estimation exploration (push down 1 cm, twist ±10°) slide and twist the pads
on the object.

Grasp and drop
--------------
The pads touch the object while the gripper centre lies on the object's face (its width ×
height rectangle) and the opening is below the object's thickness; a pad that slides off the
face, or fingers that open, end the contact (bristles reset). Once the pads have closed past
a lost object they cannot re-grasp it until they open again. An object that leaves the grasp
and is not on the table is ``dropped``; it falls onto the table (or, without a table, stops
being integrated 1 m below the gripper).

Actuator (finger travel, hardware_protocols §2.4)
-------------------------------------------------
Quasi-static finger model in the opening ``x`` [m] (motor and finger inertia neglected, as in
the shared firmware emulator), positive voltage opens:

    D_f ẋ = k_FV V_eff + k_c (w − x)⁺ + k_s (−x)⁺,    D_f = c_guide + k_FV k_e / k_open,
    V_eff = clip(V, ±V_phase),  x ≤ stroke,

where ``w`` is the object thickness (pad/object compliance ``k_c``; absent when the pads are
not on the object) and ``k_s`` the pad-to-pad stop. At stall the grasp force is exactly
``f_n = k_c (w − x) = k_FV |V|`` (the driver's 3.9166 N/V); while the fingers move, back-EMF
(``k_e``) lowers it. Implicit Euler in ``x``. The ``first_order`` alternative moves the
fingers the same way in free air but, in contact, lets ``f_n`` follow ``max(0, −k_FV V_eff)``
with a time constant. The motor angle is ``θ_m = θ_closed + x / k_open``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple, Optional, Union

import numpy as np

from slip_cell_common.core.frames import FrameParams, planar_from_middle, planar_to_middle
from slip_cell_common.core.param_schema import ranged_field as _f

from .distributed import DistributedPlanarLuGre
from .limit_surface import LimitSurfaceCache, characteristic_radius
from .params import LuGreParams
from .presets import ContactPreset, ObjectPreset
from .reduced import ReducedPlanarLuGre
from .surfaces import ContactSurface, standard_surface

__all__ = [
    'ArmTrajectory',
    'FingerActuator',
    'FrictionSettings',
    'PadContact',
    'Plant',
    'SimActuatorParams',
    'TableParams',
    'minimum_jerk',
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


@dataclass(frozen=True)
class SimActuatorParams:
    """Gripper actuator of the simulation (parameter group ``actuator``; SI, volts at the link).

    The constants the driver uses (``newton_per_volt``, ``voltage_limit``,
    ``opening_per_rad``) default to the calibrated values of hardware_protocols §2.4.
    """

    model: str = field(default='voltage', metadata={
        'choices': ('voltage', 'first_order'),
        'description': 'voltage: motor with back-EMF and finger travel; first_order: force lag'})
    newton_per_volt: float = _f(3.9166, 'N/V', 0.1, 100.0, 'stall grasp force per volt')
    voltage_limit: float = _f(20.0, 'V', 0.5, 20.0, 'host clip of the voltage command')
    max_phase_voltage: float = _f(20.0 / math.sqrt(3.0), 'V', 0.5, 20.0,
                                  'voltage the driver can apply (SVPWM ceiling)')
    opening_per_rad: float = _f(0.0086751614, 'm/rad', 1.0e-4, 0.1,
                                'finger separation per motor radian')
    stroke: float = _f(0.08, 'm', 0.005, 0.5, 'opening at the open limit')
    back_emf: float = _f(0.4, 'V·s/rad', 0.0, 10.0, 'back-EMF constant (motor side)')
    guide_damping: float = _f(5.0, 'N·s/m', 0.0, 1.0e4, 'viscous damping of the finger guides')
    contact_stiffness: float = _f(2.0e4, 'N/m', 1.0e2, 1.0e7,
                                  'pad/object compliance along the grasp axis')
    stop_stiffness: float = _f(1.0e6, 'N/m', 1.0e3, 1.0e8, 'pad-to-pad stiffness when closed')
    time_constant: float = _f(0.01, 's', 1.0e-4, 1.0, 'first_order model: force lag')
    encoder_counts: int = field(default=4096, metadata={
        'unit': 'counts/rev', 'range': (16, 1 << 20), 'description': 'motor encoder resolution'})


@dataclass(frozen=True)
class TableParams:
    """The table the object can stand on (parameter group ``table``)."""

    enabled: bool = field(default=True, metadata={'description': 'simulate the table'})
    height: float = _f(0.0, 'm', -10.0, 10.0, 'world Y of the table surface')
    stiffness: float = _f(1.0e5, 'N/m', 1.0e2, 1.0e8, 'normal penalty stiffness per corner')
    damping: float = _f(300.0, 'N·s/m', 0.0, 1.0e5, 'normal damping per corner')
    tangential_stiffness: float = _f(1.0e5, 'N/m', 1.0e2, 1.0e8,
                                     'stick (anchor) stiffness per corner')
    tangential_damping: float = _f(300.0, 'N·s/m', 0.0, 1.0e5, 'stick damping per corner')


def minimum_jerk(tau: float) -> tuple[float, float, float]:
    """Quintic minimum-jerk profile ``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` and its τ-derivatives.

    Args:
        tau: Normalised time in [0, 1] (clipped).

    Returns:
        ``(s, ds/dτ, d²s/dτ²)``; zero velocity and acceleration at both ends.
    """
    if tau <= 0.0:
        return 0.0, 0.0, 0.0
    if tau >= 1.0:
        return 1.0, 0.0, 0.0
    t2 = tau * tau
    return (t2 * tau * (10.0 + tau * (-15.0 + 6.0 * tau)),
            30.0 * t2 * (1.0 + tau * (-2.0 + tau)),
            60.0 * tau * (1.0 + tau * (-3.0 + 2.0 * tau)))


class ArmTrajectory:
    """Gripper pose ``(X_g, Y_g, φ)`` driven by relative minimum-jerk moves (world frame).

    ``move`` starts a straight-line move of the grasp centre by ``(lateral, lift)`` [m] and a
    rotation ``rotation`` [rad] about the grasp axis, all with the same quintic time profile.
    """

    __slots__ = ('_start', '_delta', '_t0', '_duration', '_pose')

    def __init__(self, x: float, y: float, phi: float) -> None:
        self._pose = (x, y, phi)
        self._start = (x, y, phi)
        self._delta = (0.0, 0.0, 0.0)
        self._t0 = 0.0
        self._duration = 0.0

    def place(self, x: float, y: float, phi: float) -> None:
        """Put the gripper at a pose at rest (cancels a move)."""
        self.__init__(x, y, phi)  # type: ignore[misc]

    def move(self, t: float, lateral: float, lift: float, rotation: float,
             duration: float) -> float:
        """Start a relative move at ``t`` [s]; returns its end time [s]."""
        x, y, phi = self.evaluate(t)[:3]
        self._start = (x, y, phi)
        self._delta = (lateral, lift, rotation)
        self._t0 = t
        self._duration = duration
        return t + duration

    def moving(self, t: float) -> bool:
        """True while a move is in progress at ``t``."""
        return self._duration > 0.0 and t < self._t0 + self._duration

    @property
    def end_time(self) -> float:
        """End of the current (or last) move [s]."""
        return self._t0 + self._duration

    def evaluate(self, t: float) -> tuple[float, float, float, float, float, float]:
        """Pose and velocity ``(X_g, Y_g, φ, Ẋ_g, Ẏ_g, φ̇)`` at ``t`` [m, m, rad, m/s, rad/s]."""
        if self._duration <= 0.0:
            x, y, p = self._pose
            return x, y, p, 0.0, 0.0, 0.0
        tau = (t - self._t0) / self._duration
        s, ds, _ = minimum_jerk(tau)
        x0, y0, p0 = self._start
        dx, dy, dp = self._delta
        k = ds / self._duration
        if tau >= 1.0:
            self._pose = (x0 + dx, y0 + dy, p0 + dp)
            self._duration = 0.0
            x, y, p = self._pose
            return x, y, p, 0.0, 0.0, 0.0
        return x0 + s * dx, y0 + s * dy, p0 + s * dp, k * dx, k * dy, k * dp


class FingerActuator:
    """Finger travel and grasp force from the motor voltage (module docstring, "Actuator").

    Args:
        params: Actuator constants.
        opening: Initial opening [m].
    """

    def __init__(self, params: SimActuatorParams, opening: float) -> None:
        self.p = params
        self.x = opening
        self.rate = 0.0
        self.f_n = 0.0        #: pad–object normal force [N]
        self.f_stop = 0.0     #: pad–pad force at the closed stop [N]
        self._damp = params.guide_damping + \
            params.newton_per_volt * params.back_emf / params.opening_per_rad
        self._first_order = params.model == 'first_order'

    def place(self, opening: float) -> None:
        """Set the opening at rest (no force)."""
        self.x = opening
        self.rate = 0.0
        self.f_n = 0.0
        self.f_stop = 0.0

    def step(self, dt: float, voltage_v: float, width: float) -> None:
        """Advance by ``dt`` [s] with the applied voltage ``voltage_v`` [V] (positive opens).

        Args:
            dt: Step [s].
            voltage_v: Motor q-axis voltage [V].
            width: Object thickness between the pads [m], or a negative value when the pads
                are not on the object.
        """
        p = self.p
        v = min(max(voltage_v, -p.max_phase_voltage), p.max_phase_voltage)
        drive = p.newton_per_volt * v
        x0 = self.x
        if self._first_order and width >= 0.0 and (x0 <= width or self.f_n > 0.0):
            target = max(0.0, -drive)
            self.f_n += (target - self.f_n) * (1.0 - math.exp(-dt / p.time_constant))
            if target <= 0.0 and self.f_n < 1e-3 and drive > 0.0:
                self.f_n = 0.0
                x1 = min(width + dt * drive / self._damp, p.stroke)
            else:
                x1 = width - self.f_n / p.contact_stiffness
            self.rate = (x1 - x0) / dt
            self.x = x1
            self.f_stop = 0.0
            return
        h = dt / self._damp
        kc, ks = p.contact_stiffness, p.stop_stiffness
        on_object = width >= 0.0
        x1 = x0
        guess = x0
        for _ in range(3):
            # Springs active at the guess: object compliance (x < w), closed stop (x < 0).
            squeezed = on_object and guess < width
            k_sum = kc if squeezed else 0.0
            kw = kc * width if squeezed else 0.0
            if guess < 0.0:
                k_sum += ks
            x1 = (x0 + h * (drive + kw)) / (1.0 + h * k_sum)
            if (on_object and x1 < width) == squeezed and (x1 < 0.0) == (guess < 0.0):
                break
            guess = x1
        if x1 > p.stroke:
            x1 = p.stroke
        self.rate = (x1 - x0) / dt
        self.x = x1
        self.f_n = kc * (width - x1) if (on_object and x1 < width) else 0.0
        self.f_stop = ks * (-x1) if x1 < 0.0 else 0.0


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


def _solve3(h: list[float], r0: float, r1: float, r2: float) -> tuple[float, float, float]:
    """Solve the 3×3 system ``h x = r`` (row-major ``h``) by Cramer's rule."""
    a, b, c, d, e, f, g, hh, i = h
    c0 = e * i - f * hh
    c1 = f * g - d * i
    c2 = d * hh - e * g
    det = a * c0 + b * c1 + c * c2
    inv = 1.0 / det
    x0 = (r0 * c0 + b * (f * r2 - r1 * i) + c * (r1 * hh - e * r2)) * inv
    x1 = (a * (r1 * i - f * r2) + r0 * (f * g - d * i) + c * (d * r2 - r1 * g)) * inv
    x2 = (a * (e * r2 - r1 * hh) + b * (r1 * g - d * r2) + r0 * (d * hh - e * g)) * inv
    return x0, x1, x2


class _PadWorld(NamedTuple):
    """Per-φ constants of one pad in world axes (see `Plant._pad_world`)."""

    q: tuple[float, ...]        #: world -> pad map Q_k (row-major)
    d_stick: tuple[float, ...]  #: Q_kᵀ D̂_stick Q_k per newton of normal force
    cx: float                   #: CoP in world axes relative to the gripper centre [m]
    cy: float
    r_a: float                  #: characteristic radius [m]
    mu_s: float                 #: static friction coefficient


class Plant:
    """Object, pads, table, arm and actuator stepped at a fixed ``dt`` (module docstring).

    Args:
        preset: The object and its contacts.
        frames: Frame constants.
        dt: Physics step [s].
        friction: Friction-law settings.
        actuator: Actuator constants.
        table: Table settings.
        model: ``'reduced'`` or ``'distributed'`` pad model.
        integrator: Bristle integrator.
        surface: Pad shape; ``''`` uses the preset's.
        grid_n: Pressure-grid cells per side.
        gravity: Gravitational acceleration [m/s²] (acts along world −Y).
        cache: Shared limit-surface cache (a new one when omitted).
    """

    #: Without a table, a dropped object stops moving this far [m] below the gripper.
    FALL_LIMIT = 1.0

    def __init__(self, preset: ObjectPreset, frames: FrameParams, dt: float,
                 friction: FrictionSettings, actuator: SimActuatorParams, table: TableParams,
                 *, model: str = 'reduced', integrator: str = 'exponential', surface: str = '',
                 grid_n: int = 21, gravity: float = 9.81,
                 cache: Optional[LimitSurfaceCache] = None) -> None:
        self.dt = dt
        self.frames = frames
        self.friction = friction
        self.act_params = actuator
        self.table = table
        self.model_name = model
        self.integrator = integrator
        self.surface_override = surface
        self.grid_n = grid_n
        self.gravity = gravity
        self.cache = cache if cache is not None else LimitSurfaceCache()
        self.actuator = FingerActuator(actuator, actuator.stroke)
        self.arm = ArmTrajectory(0.0, 0.0, 0.0)
        self.voltage = 0.0
        self.disturbances: list[tuple[float, float, float, float]] = []
        self.set_preset(preset)

    # ------------------------------------------------------------------ configuration
    def set_preset(self, preset: ObjectPreset) -> None:
        """Build the pads for ``preset`` and place the scene (object on the table)."""
        preset.validate()
        if preset.thickness >= self.act_params.stroke:
            raise ValueError(f'preset {preset.name!r}: thickness {preset.thickness} m does not '
                             f'fit the stroke {self.act_params.stroke} m')
        self.preset = preset
        name = self.surface_override or preset.surface
        self.pads = tuple(PadContact(k, self.frames, preset.contact(k), name, self.friction,
                                     self.model_name, self.integrator, self.grid_n, self.dt,
                                     self.cache) for k in (1, 2))
        m, inertia = preset.mass, preset.inertia
        self._m = m
        self._inertia = inertia
        self._m_dt = m / self.dt
        self._i_dt = inertia / self.dt
        self._weight = m * self.gravity
        gx, gy = preset.com_offset
        hw = 0.5 * preset.width
        # The face the pads can touch: CoM offset, half width, extent below/above the grasp
        # point (object frame).
        self._face = (gx, gy, hw, preset.height_below, preset.height_above)
        # Corners relative to the CoM, object frame.
        self._corners = tuple((cx - gx, cy - gy) for cx, cy in (
            (-hw, -preset.height_below), (hw, -preset.height_below),
            (hw, preset.height_above), (-hw, preset.height_above)))
        self._corner_radius = max(math.hypot(x, y) for x, y in self._corners)
        self._qcache_phi = math.nan
        self._qcache: tuple[_PadWorld, _PadWorld]
        self._dsum_diag: Optional[tuple[float, float, float]] = None
        self.reset(True)

    def reset(self, object_on_table: bool = True) -> None:
        """Scene at the pick-up pose: gripper centre at the object's grasp point, fingers open.

        With ``object_on_table`` the object stands upright on the table (corners loaded to
        their static penetration); otherwise it starts at the same pose without a table
        contact below it (the table is still there).
        """
        p = self.preset
        th = self.table.height if self.table.enabled else 0.0
        gy = th + p.height_below
        self.arm.place(0.0, gy, 0.0)
        self.xg, self.yg, self.phi = 0.0, gy, 0.0
        self.vxg = self.vyg = self.wg = 0.0
        cx, cy = p.com_offset
        sink = 0.0
        if object_on_table and self.table.enabled:
            sink = 0.5 * p.mass * self.gravity / self.table.stiffness
        self.X, self.Y, self.th = cx, gy + cy - sink, 0.0
        self.VX = self.VY = self.W = 0.0
        self.actuator.place(self.act_params.stroke)
        self.voltage = 0.0
        self.disturbances = []
        for pad in self.pads:
            pad.reset()
        self.f_n = 0.0
        self.in_contact = False
        self.ever_grasped = False
        self.dropped = False
        self.frozen = False
        self.pads_outside = False
        self.grasp_point = (-cx, -cy)   # material point at the gripper centre (object frame,
        self.grasp_angle = 0.0          # relative to the CoM) and θ − φ at the grasp
        self.corner_n = [0.0, 0.0, 0.0, 0.0]
        self.corner_s = [0.0, 0.0, 0.0, 0.0]
        self.on_table = object_on_table and self.table.enabled
        self.nu_mid = (0.0, 0.0, 0.0)
        self.slip_integral = [0.0, 0.0, 0.0]   # ∫ ν dt in gripper_middle axes [m, m, rad]
        self.sliding = [False, False]
        self.steps = 0

    # ------------------------------------------------------------------ inputs
    def add_disturbance(self, fx: float, fy: float, torque: float, t_end: float) -> None:
        """External force ``(fx, fy)`` [N] in ``gripper_middle`` axes at the CoM and torque
        [N·m] about +z, until ``t_end`` [s]."""
        self.disturbances.append((fx, fy, torque, t_end))

    # ------------------------------------------------------------------ geometry
    def _object_between(self) -> bool:
        """True while the gripper centre lies on the object's face (pads can touch it)."""
        gx, gy, half_width, below, above = self._face
        c, s = math.cos(self.th), math.sin(self.th)
        dx, dy = self.xg - self.X, self.yg - self.Y
        bx = c * dx + s * dy + gx      # object frame, relative to G
        by = -s * dx + c * dy + gy
        return abs(bx) <= half_width and -below <= by <= above

    def grasp_relative(self) -> tuple[float, float, float, float, float, float]:
        """Grasp point pose and twist relative to the gripper, ``gripper_middle`` axes.

        Returns:
            ``(x, y, θ, vx, vy, ω)`` [m, m, rad, m/s, m/s, rad/s] of the object material point
            that was at the gripper centre when the grasp closed (before any grasp: the
            nominal grasp point), relative to the gripper centre; θ from the grasp moment.
        """
        gbx, gby = self.grasp_point
        c, s = math.cos(self.th), math.sin(self.th)
        ex, ey = c * gbx - s * gby, s * gbx + c * gby
        px, py = self.X + ex - self.xg, self.Y + ey - self.yg
        vx = self.VX - self.W * ey - self.vxg
        vy = self.VY + self.W * ex - self.vyg
        cp, sp = math.cos(self.phi), math.sin(self.phi)
        return (cp * px + sp * py, -sp * px + cp * py, self.th - self.phi - self.grasp_angle,
                cp * vx + sp * vy, -sp * vx + cp * vy, self.W - self.wg)

    def energy(self) -> float:
        """Kinetic plus gravitational energy of the object [J] (zero at the table height)."""
        return (0.5 * self._m * (self.VX * self.VX + self.VY * self.VY)
                + 0.5 * self._inertia * self.W * self.W
                + self._m * self.gravity * (self.Y - self.table.height))

    def mechanical_energy(self) -> float:
        """`energy` plus the energy stored in the table springs and the pad bristles [J].

        Bristles: ``½ σ0 f_n (z_x² + z_y² + z_τ²/r_a²)`` per reduced pad (z_τ carries r_a;
        τ = −σ0 f_n z_τ and ż_τ = r_a² ω in stick), ``½ σ0 f_n Σ p̂ ‖z_ij‖²`` per distributed
        pad. This is the quantity that must not grow in a passive motion.
        """
        e = self.energy()
        tp = self.table
        if tp.enabled:
            c, s = math.cos(self.th), math.sin(self.th)
            for i, (bx, by) in enumerate(self._corners):
                pen = tp.height - (self.Y + s * bx + c * by)
                if pen > 0.0:
                    e += 0.5 * tp.stiffness * pen * pen
                    e += 0.5 * tp.tangential_stiffness * self.corner_s[i] ** 2
        if self.in_contact:
            for pad in self.pads:
                k = 0.5 * pad.params.sigma0 * self.f_n
                model = pad.model
                if isinstance(model, ReducedPlanarLuGre):
                    z0, z1, z2 = model.state_tuple
                    e += k * (z0 * z0 + z1 * z1 + (z2 / pad.r_a) ** 2)
                else:
                    z = model.state
                    e += k * float(np.sum(pad.surface.pressure[..., None] * z * z))
        return e

    def motor_angle(self, theta_closed: float) -> float:
        """True motor angle [rad] for a given angle at the closed stop."""
        return theta_closed + self.actuator.x / self.act_params.opening_per_rad

    # ------------------------------------------------------------------ stepping
    def _pad_world(self, phi: float) -> tuple[_PadWorld, _PadWorld]:
        """Per-φ constants of both pads in world axes (cached while φ is unchanged).

        Per pad: ``Q_k`` (world → pad, row-major), ``Q_kᵀ D̂ Q_k`` for the stick damping per
        newton of normal force, the CoP in world axes relative to the gripper centre, ``r_a``
        and ``μ_s``.
        """
        if phi != self._qcache_phi:
            out = []
            for pad in self.pads:
                q, ds = pad.world_matrices(phi)
                cwx = q[0] * pad.cx + q[3] * pad.cy
                cwy = q[1] * pad.cx + q[4] * pad.cy
                out.append(_PadWorld(q, ds, cwx, cwy, pad.r_a, pad.params.mu_s))
            self._qcache = (out[0], out[1])
            d1, d2 = out[0][1], out[1][1]
            a0, a1, a2 = d1[0] + d2[0], d1[4] + d2[4], d1[8] + d2[8]
            scale = max(abs(a0), abs(a1), abs(a2))
            off = max(abs(d1[1] + d2[1]), abs(d1[2] + d2[2]), abs(d1[5] + d2[5]))
            # Pads with the CoP at the pad centre: D_w = diag(a, a, b) for any φ.
            self._dsum_diag = ((a0, a1, a2)
                               if off <= 1e-12 * scale and abs(a0 - a1) <= 1e-12 * scale
                               else None)
            self._qcache_phi = phi
        return self._qcache

    def step(self, t1: float) -> None:
        """Advance the plant from ``t1 − dt`` to ``t1`` [s] with the current voltage."""
        dt = self.dt
        self.steps += 1
        xg, yg, phi, vxg, vyg, wg = self.arm.evaluate(t1)
        # ---------------------------------------------------------------- actuator
        thick = self.preset.thickness
        between = False if self.frozen else self._object_between()
        act = self.actuator
        if not between:
            if act.x < thick:
                self.pads_outside = True
        elif act.x > thick:
            self.pads_outside = False
        on_face = between and not self.pads_outside
        act.step(dt, self.voltage, thick if on_face else -1.0)
        f_n = act.f_n
        contact = on_face and f_n > 0.0
        if contact != self.in_contact:
            if contact:
                c, s = math.cos(self.th), math.sin(self.th)
                dx, dy = self.xg - self.X, self.yg - self.Y
                self.grasp_point = (c * dx + s * dy, -s * dx + c * dy)
                self.grasp_angle = self.th - self.phi
                self.ever_grasped = True
            else:
                for pad in self.pads:
                    pad.reset()
                self.sliding = [False, False]
            self.in_contact = contact
        self.f_n = f_n if contact else 0.0
        if self.frozen:
            self._set_gripper(xg, yg, phi, vxg, vyg, wg)
            return
        # ---------------------------------------------------------------- external load
        m_dt, i_dt = self._m_dt, self._i_dt
        r0 = m_dt * self.VX
        r1 = m_dt * self.VY - self._weight
        r2 = i_dt * self.W
        if self.disturbances:
            r0, r1, r2 = self._add_disturbances(t1, phi, r0, r1, r2)
        corners = self._table_candidates() if self.table.enabled else ()
        dx, dy = xg - self.X, yg - self.Y
        if contact:
            ux, uy, uw = self._solve_with_pads(f_n, phi, dx, dy, vxg, vyg, wg, r0, r1, r2,
                                               corners)
        elif corners:
            ux, uy, uw = self._solve_table_only(r0, r1, r2, corners)
        else:
            ux, uy, uw = r0 / m_dt, r1 / m_dt, r2 / i_dt
        if not contact:
            if self.nu_mid[0] or self.nu_mid[1] or self.nu_mid[2]:
                for pad in self.pads:
                    pad.w = (0.0, 0.0, 0.0)
                    pad.f_n = 0.0
                    pad.nu = (0.0, 0.0, 0.0)
                self.nu_mid = (0.0, 0.0, 0.0)
        else:
            cp, sp = math.cos(phi), math.sin(phi)
            nvx, nvy = ux - dy * uw - vxg, uy + dx * uw - vyg
            nm0, nm1, nm2 = cp * nvx + sp * nvy, -sp * nvx + cp * nvy, uw - wg
            self.nu_mid = (nm0, nm1, nm2)
            si = self.slip_integral
            si[0] += nm0 * dt
            si[1] += nm1 * dt
            si[2] += nm2 * dt
        if corners:
            self._table_commit(corners, ux, uy, uw)
        else:
            self.on_table = False
        # ---------------------------------------------------------------- integrate
        self.VX, self.VY, self.W = ux, uy, uw
        self.X += dt * ux
        self.Y += dt * uy
        self.th += dt * uw
        self.xg, self.yg, self.phi = xg, yg, phi
        self.vxg, self.vyg, self.wg = vxg, vyg, wg
        if self.ever_grasped and not contact and not self.on_table:
            self.dropped = True
            if not self.table.enabled and self.yg - self.Y > self.FALL_LIMIT:
                self.frozen = True
                self.VX = self.VY = self.W = 0.0

    def _add_disturbances(self, t1: float, phi: float, r0: float, r1: float,
                          r2: float) -> tuple[float, float, float]:
        cp, sp = math.cos(phi), math.sin(phi)
        keep = []
        for fx, fy, tq, t_end in self.disturbances:
            if t1 <= t_end:
                r0 += cp * fx - sp * fy
                r1 += sp * fx + cp * fy
                r2 += tq
                keep.append((fx, fy, tq, t_end))
        self.disturbances = keep
        return r0, r1, r2

    def _solve_table_only(self, r0: float, r1: float, r2: float,
                          corners: tuple[list[float], ...]) -> tuple[float, float, float]:
        """Object on the table, no pad contact: active-set iteration over the corners."""
        m_dt, i_dt = self._m_dt, self._i_dt
        ux = uy = uw = 0.0
        for _ in range(10):
            hc, rc = self._table_terms(corners)
            h = [m_dt + hc[0], hc[1], hc[2], hc[3], m_dt + hc[4], hc[5], hc[6], hc[7],
                 i_dt + hc[8]]
            ux, uy, uw = _solve3(h, r0 + rc[0], r1 + rc[1], r2 + rc[2])
            if not self._table_update_modes(corners, ux, uy, uw):
                break
        return ux, uy, uw

    def _solve_with_pads(self, f_n: float, phi: float, dx: float, dy: float, vxg: float,
                         vyg: float, wg: float, r0: float, r1: float, r2: float,
                         corners: tuple[list[float], ...]) -> tuple[float, float, float]:
        """Implicit stick prediction, stick/slide active set, library step, final velocity.

        See the module docstring ("Time stepping"). Returns the final ``u⁺``.
        """
        m_dt, i_dt = self._m_dt, self._i_dt
        pad1, pad2 = self.pads
        c1, c2 = self._pad_world(phi)
        q1, ds1, cx1, cy1, ra1, ms1 = c1
        q2, ds2, cx2, cy2, ra2, ms2 = c2
        # Spring wrenches −σ0 f_n z of both pads, rotated to world axes (gripper centre).
        sx, sy, st = pad1.spring(f_n)
        w1 = (q1[0] * sx + q1[3] * sy + q1[6] * st, q1[1] * sx + q1[4] * sy + q1[7] * st,
              q1[2] * sx + q1[5] * sy + q1[8] * st)
        sx, sy, st = pad2.spring(f_n)
        w2 = (q2[0] * sx + q2[3] * sy + q2[6] * st, q2[1] * sx + q2[4] * sy + q2[7] * st,
              q2[2] * sx + q2[5] * sy + q2[8] * st)
        diag = self._dsum_diag
        pads = (pad1, pad2)
        # Warm start: a pad that slid in the last step keeps sliding unless its twist reverses
        # or vanishes (then the stick prediction decides again).
        slide = [self.sliding[0] and pad1.f_n > 0.0 and pad1.nu != (0.0, 0.0, 0.0),
                 self.sliding[1] and pad2.f_n > 0.0 and pad2.nu != (0.0, 0.0, 0.0)]
        if diag is not None and not corners and not (slide[0] or slide[1]):
            out = self._solve_pads_diagonal(f_n, diag, w1, w2, dx, dy, vxg, vyg, wg, r0, r1, r2)
            if out is not None:
                return out
        springs = (w1, w2)
        qs = (q1, q2)
        stick_d = (ds1, ds2)
        lims = ((cx1, cy1, ra1, ms1), (cx2, cy2, ra2, ms2))
        recheck = [slide[0], slide[1]]
        ws = [w1, w2]
        ds = [ds1, ds2]
        for k in (0, 1):
            if slide[k]:
                ws[k], ds[k] = self._sliding_terms(pads[k], qs[k], f_n, None, 1.0)
        hc: list[float] = [0.0] * 9
        rc = [0.0, 0.0, 0.0]
        ux = uy = uw = 0.0
        n0 = n1 = n2 = 0.0
        for _ in range(12):
            d1, d2 = ds
            w1, w2 = ws
            # D_w and W_w of the current modes (per unit f_n for D).
            a00 = f_n * (d1[0] + d2[0])
            a01 = f_n * (d1[1] + d2[1])
            a02 = f_n * (d1[2] + d2[2])
            a10 = f_n * (d1[3] + d2[3])
            a11 = f_n * (d1[4] + d2[4])
            a12 = f_n * (d1[5] + d2[5])
            a20 = f_n * (d1[6] + d2[6])
            a21 = f_n * (d1[7] + d2[7])
            a22 = f_n * (d1[8] + d2[8])
            # W(ν) = W_w − D_w (L u − b):  H += Lᵀ D_w L,  r += Lᵀ (W_w + D_w b).
            e0 = w1[0] + w2[0] + a00 * vxg + a01 * vyg + a02 * wg
            e1 = w1[1] + w2[1] + a10 * vxg + a11 * vyg + a12 * wg
            e2 = w1[2] + w2[2] + a20 * vxg + a21 * vyg + a22 * wg
            k02 = -dy * a00 + dx * a01 + a02
            k12 = -dy * a10 + dx * a11 + a12
            k22 = -dy * a20 + dx * a21 + a22
            h = [m_dt + a00, a01, k02,
                 a10, m_dt + a11, k12,
                 -dy * a00 + dx * a10 + a20, -dy * a01 + dx * a11 + a21,
                 i_dt - dy * k02 + dx * k12 + k22]
            g0, g1, g2 = r0 + e0, r1 + e1, r2 + e2 - dy * e0 + dx * e1
            if corners:
                hc, rc = self._table_terms(corners)
                for i in range(9):
                    h[i] += hc[i]
                g0 += rc[0]
                g1 += rc[1]
                g2 += rc[2]
            ux, uy, uw = _solve3(h, g0, g1, g2)
            n0, n1, n2 = ux - dy * uw - vxg, uy + dx * uw - vyg, uw - wg
            changed = self._table_update_modes(corners, ux, uy, uw) if corners else False
            for k in (0, 1):
                pad = pads[k]
                if slide[k]:
                    if recheck[k]:
                        recheck[k] = False
                        if self._twist_reversed(pad, qs[k], n0, n1, n2):
                            slide[k] = False
                            ws[k], ds[k] = springs[k], stick_d[k]
                            changed = True
                    continue
                d = stick_d[k]
                w = springs[k]
                fx = w[0] - f_n * (d[0] * n0 + d[1] * n1 + d[2] * n2)
                fy = w[1] - f_n * (d[3] * n0 + d[4] * n1 + d[5] * n2)
                tc = w[2] - f_n * (d[6] * n0 + d[7] * n1 + d[8] * n2)
                cx, cy, ra, ms = lims[k]
                tq = tc - (cx * fy - cy * fx)
                lam = math.sqrt(fx * fx + fy * fy + (tq / ra) ** 2) / f_n
                if lam > ms:
                    ws[k], ds[k] = self._sliding_terms(pad, qs[k], f_n, (fx, fy, tc), lam)
                    slide[k] = changed = True
            if not changed:
                break
        self.sliding = slide
        return self._step_models(f_n, n0, n1, n2, dx, dy, r0, r1, r2,
                                 (hc, rc) if corners else None)

    @staticmethod
    def _sliding_terms(pad: PadContact, q: tuple[float, ...], f_n: float,
                       pred: Optional[tuple[float, float, float]], lam: float
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
        p = pad.params
        g = pad.stribeck(*pad.nu)
        ra, cx, cy = pad.r_a, pad.cx, pad.cy
        vx, vy, om = pad.nu
        n0, n1, n2 = vx - om * cy, vy + om * cx, ra * om
        speed = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        if pred is None:
            k = f_n / pad.f_n
            wx, wy, wt = pad.w
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
                return w, pad.d_visc_pad
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
        v = pad.d_visc_pad
        return w, _congruence(q, (a00 + v[0], a01 + v[1], a02 + v[2], a11 + v[4], a12 + v[5],
                                  a22 + v[8]))

    @staticmethod
    def _twist_reversed(pad: PadContact, q: tuple[float, ...], n0: float, n1: float,
                        n2: float) -> bool:
        """True when the pad's new relative twist (world ``ν_w``) no longer continues the
        slide of the previous step: reversed (negative generalised dot product) or ~0."""
        v0 = q[0] * n0 + q[1] * n1 + q[2] * n2
        v1 = q[3] * n0 + q[4] * n1 + q[5] * n2
        v2 = q[6] * n0 + q[7] * n1 + q[8] * n2
        ra, cx, cy = pad.r_a, pad.cx, pad.cy
        a0, a1, a2 = v0 - v2 * cy, v1 + v2 * cx, ra * v2
        px, py, pw = pad.nu
        b0, b1, b2 = px - pw * cy, py + pw * cx, ra * pw
        slow = 1e-6 * pad.params.v_s
        return a0 * b0 + a1 * b1 + a2 * b2 <= 0.0 or a0 * a0 + a1 * a1 + a2 * a2 < slow * slow

    def _solve_pads_diagonal(self, f_n: float, diag: tuple[float, float, float],
                             w1: tuple[float, float, float], w2: tuple[float, float, float],
                             dx: float, dy: float, vxg: float, vyg: float, wg: float,
                             r0: float, r1: float, r2: float,
                             ) -> Optional[tuple[float, float, float]]:
        """Fast path: no table contact, both pads stick, ``D_w = f_n diag(a, a, b)``.

        Returns ``None`` when a pad would exceed its static limit (the general path then
        handles the slide).
        """
        a = f_n * diag[0]
        b = f_n * diag[2]
        e0 = w1[0] + w2[0] + a * vxg
        e1 = w1[1] + w2[1] + a * vyg
        e2 = w1[2] + w2[2] + b * wg
        m_dt, i_dt = self._m_dt, self._i_dt
        # H = diag(m/dt, m/dt, I/dt) + Lᵀ diag(a, a, b) L
        h00 = m_dt + a
        h02 = -a * dy
        h12 = a * dx
        h22 = i_dt + a * (dx * dx + dy * dy) + b
        g0, g1, g2 = r0 + e0, r1 + e1, r2 + e2 - dy * e0 + dx * e1
        # Eliminate u_x, u_y:  h00 ux + h02 uw = g0,  h00 uy + h12 uw = g1.
        inv = 1.0 / h00
        uw = (g2 - h02 * g0 * inv - h12 * g1 * inv) / (h22 - (h02 * h02 + h12 * h12) * inv)
        ux = (g0 - h02 * uw) * inv
        uy = (g1 - h12 * uw) * inv
        n0, n1, n2 = ux - dy * uw - vxg, uy + dx * uw - vyg, uw - wg
        c1, c2 = self._qcache
        for w, (_, d, cx, cy, ra, ms) in ((w1, c1), (w2, c2)):
            fx = w[0] - f_n * d[0] * n0
            fy = w[1] - f_n * d[4] * n1
            tq = w[2] - f_n * d[8] * n2 - (cx * fy - cy * fx)
            if fx * fx + fy * fy + (tq / ra) ** 2 > (ms * f_n) ** 2:
                return None
        self.sliding = [False, False]
        return self._step_models(f_n, n0, n1, n2, dx, dy, r0, r1, r2, None)

    def _step_models(self, f_n: float, n0: float, n1: float, n2: float, dx: float, dy: float,
                     r0: float, r1: float, r2: float,
                     table: Optional[tuple[list[float], list[float]]]
                     ) -> tuple[float, float, float]:
        """Step both friction models with the relative twist ``ν_w`` (world axes) and return
        ``u⁺``; ``table`` holds the implicit table terms ``(H, r)`` of the final active set
        (None without table contact)."""
        dt = self.dt
        # Library models with the implicit relative twist; their wrenches back to world axes.
        f0 = f1 = f2 = 0.0
        for pad, pw in zip(self.pads, self._qcache):
            q0, q1, q2, q3, q4, q5, q6, q7, q8 = pw.q
            v0 = q0 * n0 + q1 * n1 + q2 * n2
            v1 = q3 * n0 + q4 * n1 + q5 * n2
            v2 = q6 * n0 + q7 * n1 + q8 * n2
            wx, wy, wt, _ = pad.model.advance(v0, v1, v2, dt, f_n)
            pad.w = (wx, wy, wt)
            pad.nu = (v0, v1, v2)
            pad.f_n = f_n
            f0 += q0 * wx + q3 * wy + q6 * wt
            f1 += q1 * wx + q4 * wy + q7 * wt
            f2 += q2 * wx + q5 * wy + q8 * wt
        # Final velocity with the models' wrenches (table terms stay implicit).
        m_dt, i_dt = self._m_dt, self._i_dt
        if table is None:
            return (r0 + f0) / m_dt, (r1 + f1) / m_dt, (r2 + f2 - dy * f0 + dx * f1) / i_dt
        hc, rc = table
        h = [m_dt + hc[0], hc[1], hc[2], hc[3], m_dt + hc[4], hc[5], hc[6], hc[7],
             i_dt + hc[8]]
        return _solve3(h, r0 + rc[0] + f0, r1 + rc[1] + f1, r2 + rc[2] + f2 - dy * f0 + dx * f1)

    def _set_gripper(self, xg: float, yg: float, phi: float, vxg: float, vyg: float,
                     wg: float) -> None:
        self.xg, self.yg, self.phi = xg, yg, phi
        self.vxg, self.vyg, self.wg = vxg, vyg, wg

    # ------------------------------------------------------------------ table contact
    def _table_candidates(self) -> tuple[list[float], ...]:
        """Corners that touch the table by the end of the step (speculative contacts).

        A corner enters the solve when its penetration ``δ`` or its predicted penetration
        ``δ − dt·v_n`` (current normal velocity) is positive, so an approaching corner is
        caught in the step it would cross the surface instead of one step later (a late
        penalty contact would create spring energy from nothing). The solve keeps ``N ≥ 0``.

        Returns:
            ``[index, e_x, e_y, δ, active, slide_sign]`` per candidate (``e`` = corner minus
            CoM, world axes; δ may be negative for a speculative contact).
        """
        top = self.table.height
        margin = self.dt * (abs(self.VY) + abs(self.W) * self._corner_radius)
        if self.Y - self._corner_radius - margin > top:
            return ()
        c, s = math.cos(self.th), math.sin(self.th)
        out = []
        dt = self.dt
        for i, (bx, by) in enumerate(self._corners):
            ex = c * bx - s * by
            ey = s * bx + c * by
            pen = top - (self.Y + ey)
            if pen > 0.0 or pen - dt * (self.VY + self.W * ex) > 0.0:
                out.append([i, ex, ey, pen, 1.0, 0.0])
        return tuple(out)

    def _table_terms(self, corners: tuple[list[float], ...]) -> tuple[list[float], list[float]]:
        """Implicit table contributions ``(H, r)`` for the current active sets.

        Per active corner with lever ``e`` (``J_n = (0, 1, e_x)``, ``J_t = (1, 0, −e_y)``):
        normal ``N = k δ − (k dt + c) J_n u⁺``; tangential stick
        ``F_t = −k_t s − (k_t dt + c_t) J_t u⁺``, or sliding ``F_t = ±μ N(u⁺)``.
        """
        tp = self.table
        kn, dn = tp.stiffness, tp.stiffness * self.dt + tp.damping
        kt = tp.tangential_stiffness
        dtn = kt * self.dt + tp.tangential_damping
        mu = self.preset.table_mu
        cs = self.corner_s
        h00 = h01 = h02 = h11 = h12 = h21 = h22 = h20 = 0.0
        r0 = r1 = r2 = 0.0
        for i, ex, ey, pen, active, sgn in corners:
            if not active:
                continue
            ns = kn * pen
            r1 += ns
            r2 += ns * ex
            h11 += dn
            h12 += dn * ex
            h21 += dn * ex
            h22 += dn * ex * ex
            if sgn == 0.0:
                fs = -kt * cs[int(i)]
                r0 += fs
                r2 -= ey * fs
                h00 += dtn
                h02 -= dtn * ey
                h20 -= dtn * ey
                h22 += dtn * ey * ey
            else:
                a = sgn * mu
                r0 += a * ns
                r2 -= ey * a * ns
                h01 += a * dn
                h02 += a * dn * ex
                h21 -= ey * a * dn
                h22 -= ey * a * dn * ex
        return [h00, h01, h02, 0.0, h11, h12, h20, h21, h22], [r0, r1, r2]

    def _table_update_modes(self, corners: tuple[list[float], ...], ux: float, uy: float,
                            uw: float) -> bool:
        """Deactivate pulling corners, switch overloaded stick corners to sliding."""
        tp = self.table
        kn, dn = tp.stiffness, tp.stiffness * self.dt + tp.damping
        kt, dtn = tp.tangential_stiffness, tp.tangential_stiffness * self.dt + tp.tangential_damping
        mu = self.preset.table_mu
        changed = False
        for cr in corners:
            i, ex, ey, pen, active, sgn = cr
            if not active:
                continue
            n = kn * pen - dn * (uy + uw * ex)
            if n < 0.0:
                cr[4] = 0.0
                changed = True
                continue
            if sgn == 0.0:
                ft = -kt * self.corner_s[int(i)] - dtn * (ux - uw * ey)
                if abs(ft) > mu * n:
                    cr[5] = 1.0 if ft > 0.0 else -1.0
                    changed = True
        return changed

    def _table_commit(self, corners: tuple[list[float], ...], ux: float, uy: float,
                      uw: float) -> None:
        """Store corner forces and anchors after the final velocity."""
        tp = self.table
        kn, dn = tp.stiffness, tp.stiffness * self.dt + tp.damping
        kt = tp.tangential_stiffness
        mu = self.preset.table_mu
        touching = [False] * 4
        corner_n, corner_s = self.corner_n, self.corner_s
        for i, ex, ey, pen, active, sgn in corners:
            ii = int(i)
            if not active:
                continue
            n = max(0.0, kn * pen - dn * (uy + uw * ex))
            corner_n[ii] = n
            touching[ii] = True
            if sgn == 0.0:
                corner_s[ii] += self.dt * (ux - uw * ey)
            else:
                corner_s[ii] = -sgn * mu * n / kt
        for ii in range(4):
            if not touching[ii]:
                corner_n[ii] = 0.0
                corner_s[ii] = 0.0
        self.on_table = any(touching)
