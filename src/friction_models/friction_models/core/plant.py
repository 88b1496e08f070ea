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

Relative twist and friction (friction_models §1, §7, §14)
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

Table and actuator
------------------
The table's corner contacts (:mod:`.table`) join the same implicit solve; the fingers follow
the quasi-static actuator model of :mod:`.actuator` (the grasp normal force ``f_n`` both
pads carry), and the gripper pose the minimum-jerk arm of :mod:`.arm`. Pad models and their
linearisation are in :mod:`.pad_contact`.

Grasp and drop
--------------
The pads touch the object while the gripper centre lies on the object's face (its width ×
height rectangle) and the opening is below the object's thickness; a pad that slides off the
face, or fingers that open, end the contact (bristles reset). Once the pads have closed past
a lost object they cannot re-grasp it until they open again. An object that leaves the grasp
and is not on the table is ``dropped``; it falls onto the table (or, without a table, stops
being integrated 1 m below the gripper).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from slip_cell_common.core.frames import FrameParams

from .actuator import FingerActuator, SimActuatorParams
from .arm import ArmTrajectory
from .limit_surface import LimitSurfaceCache
from .pad_contact import FrictionSettings, PadContact
from .presets import ObjectPreset
from .reduced import ReducedPlanarLuGre
from .table import TableContact, TableParams

__all__ = [
    'Plant',
]


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
                 cache: LimitSurfaceCache | None = None) -> None:
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
        self.table_contact = TableContact(table, dt)
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
        self.table_contact.set_object(tuple((cx - gx, cy - gy) for cx, cy in (
            (-hw, -preset.height_below), (hw, -preset.height_below),
            (hw, preset.height_above), (-hw, preset.height_above))), preset.table_mu)
        self._qcache_phi = math.nan
        self._qcache: tuple[_PadWorld, _PadWorld]
        self._dsum_diag: tuple[float, float, float] | None = None
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
        self.table_contact.reset()
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
        e = self.table_contact.add_stored_energy(e, self.Y, self.th)
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
        table = self.table_contact
        corners = table.candidates(self.Y, self.th, self.VY, self.W) if self.table.enabled \
            else ()
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
        self.on_table = table.commit(corners, ux, uy, uw) if corners else False
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
            hc, rc = self.table_contact.terms(corners)
            h = [m_dt + hc[0], hc[1], hc[2], hc[3], m_dt + hc[4], hc[5], hc[6], hc[7],
                 i_dt + hc[8]]
            ux, uy, uw = _solve3(h, r0 + rc[0], r1 + rc[1], r2 + rc[2])
            if not self.table_contact.update_modes(corners, ux, uy, uw):
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
                ws[k], ds[k] = pads[k].sliding_terms(qs[k], f_n, None, 1.0)
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
                hc, rc = self.table_contact.terms(corners)
                for i in range(9):
                    h[i] += hc[i]
                g0 += rc[0]
                g1 += rc[1]
                g2 += rc[2]
            ux, uy, uw = _solve3(h, g0, g1, g2)
            n0, n1, n2 = ux - dy * uw - vxg, uy + dx * uw - vyg, uw - wg
            changed = self.table_contact.update_modes(corners, ux, uy, uw) if corners else False
            for k in (0, 1):
                pad = pads[k]
                if slide[k]:
                    if recheck[k]:
                        recheck[k] = False
                        if pad.twist_reversed(qs[k], n0, n1, n2):
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
                    ws[k], ds[k] = pad.sliding_terms(qs[k], f_n, (fx, fy, tc), lam)
                    slide[k] = changed = True
            if not changed:
                break
        self.sliding = slide
        return self._step_models(f_n, n0, n1, n2, dx, dy, r0, r1, r2,
                                 (hc, rc) if corners else None)

    def _solve_pads_diagonal(self, f_n: float, diag: tuple[float, float, float],
                             w1: tuple[float, float, float], w2: tuple[float, float, float],
                             dx: float, dy: float, vxg: float, vyg: float, wg: float,
                             r0: float, r1: float, r2: float,
                             ) -> tuple[float, float, float] | None:
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
                     table: tuple[list[float], list[float]] | None
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
