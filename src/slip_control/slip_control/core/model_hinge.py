# SPDX-License-Identifier: Apache-2.0
"""HINGE with the ``model`` control law: the gripper turns around the object, the object keeps
its orientation in the world and the grasp point does not translate (issue 15 items 5 and 6).

On the ellipsoidal limit surface of a pad (docs/control_and_estimation.md §4.4, §4.6), a
tangential load ``f_t`` and a torque ``τ`` (two-finger means) slip at the grasp force
``F = ‖(f_t, τ/r)‖/μ_c``, and the twist is normal to the surface there: the object turns about
a centre of rotation (CoR) ``c = r²·f_t/|τ|`` from the grasp point, so the grasp point
translates ``c`` per radian of turn. With ``s = f_t/(μ_c F)``: torque capacity
``μ_c·r·F·√(1 − s²)``, translation per radian ``r·s/√(1 − s²)``.

What turns the pads under the object is the weight's torque ``W·d·sin γ`` (``γ`` the CoM
lever's angle from hanging), and the CoR is then ``r²/(d·sin γ)``: the further the object is
from hanging, the less the grasp point translates. The thesis HINGE (§4.7,
``F = 1.4·f_t/μ_c``) lets the object swing towards hanging and lag the gripper, where the
torque and with it the CoR is worst. This law keeps the object where it is when HINGE starts:

    ψ̂   = θ̂ + φ̂ − (θ̂₀ + φ̂₀)        object's turn in the world since the request [rad]
          θ̂ = ∫ω̄ dt                  its turn in the pads (velocity sensors)
          φ̂ = atan2(−F̄x, −F̄y)        the gripper's turn, from the direction of the load
    e   = u·ψ̂                         u: the uphill sense (away from hanging) = −sign(τ₀)
    T   = T₀·(1 − k_p·e − k_i·∫e dt)   T₀ = max(|τ₀|, r²·f_t/max_cor)
    F   = ‖(f_t, T/r)‖/μ  ·(1 + rotation_damping·|ω̂| + translation_gain·ê),
          μ = μ_c slipping, μ_s stuck;   ê = max(0, v̂_t − cor_offset·|ω̂|) while slipping

``T`` is the torque the pads may carry before they turn under the object. At ``e = 0`` it is
the torque at the request, so the object neither swings down nor is carried along; when the
gripper turns uphill and drags the object with it (``e > 0``) the capacity falls below the
weight's torque and the pads slip round it; an object that swings down (``e < 0``) is caught
by the rising capacity. Static friction holds more than kinetic: while the observer sees no
slip the force is computed with ``μ_s`` (so the pads break loose as soon as ``e`` grows), while
it slips with ``μ_c``. ``max_cor`` puts a floor under ``T₀``: an object nearly hanging would
otherwise be released about a CoR far from the grasp point. The force never falls below
``f_t/(μ_c·max_load_ratio)`` (the pads carry the weight) and stays within
``[min_force, max_force]`` (``model`` group); the loads are low-passed like the ``model``
HOLD's; the rotation-rate term damps a fast swing, and the translation term adds force while
the grasp point translates more than ``cor_offset`` per radian of turn (a centre of pressure off
the pad centre, fingers of very different friction). The integral ``∫e dt`` is limited to
``±integral_limit``.

Measured by the population evaluation (estimated properties, truth as the judge; figures in
docs/model_slip_control.md §5a): seed 2026, all 132 feasible objects within 60 ± 6° and 10 mm;
seed 777, 134 of 140. The previous force-ratio law's swing towards hanging put the grasp point
through 10–30 mm on short levers.

Refusals (`ModelHingeController.for_request`, before anything changes): no valid ``r``; no
wrench measured; no torque measured (``|τ̄| < min_torque``: the centre of mass is on the
vertical through the grasp point, nothing would turn the pads under the object — turn the
gripper from hanging first, as the runner's hinge pose does). Stale inputs hand over to the
``model`` HOLD in the same step (as the thesis HINGE does, CE-3).
"""
from __future__ import annotations

import math
from dataclasses import replace

from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import ControlContact, ControlOutput, SlipController, SlipMode
from slip_control.core.model_hold import MODEL_LAW, LoadFilter, ModelHoldController, observer_config
from slip_control.core.model_trajectory import RequestRefused
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import SensorSnapshot, combine_wrenches
from slip_control.core.twist_observer import SlipEstimate, TwistObserver

#: What the law needs of the contact properties (for the request check).
REQUIREMENT = 'valid mu_c and r (the limit surface couples force and torque through r)'


def limit_surface_force(ft: float, mu_c: float, r: float, cor_offset: float) -> float:
    """Grasp force [N] at which a load ``ft`` [N] turns the object about a CoR ``cor_offset``.

    ``(ft/μ_c)·√(1 + (r/c)²)``: below it a load whose CoR ``r²ft/|τ|`` is within ``c`` turns
    the object, above it nothing slips (ellipsoidal limit surface, module docstring).
    """
    return ft / mu_c * math.sqrt(1.0 + (r / cor_offset) ** 2)


def torque_capacity(force: float, ft: float, mu_c: float, r: float) -> float:
    """Torque [N·m] the pad holds at grasp force ``force`` [N] under tangential load ``ft`` [N].

    ``μ_c·r·F·√(1 − s²)``, ``s = ft/(μ_c F)``; 0 when ``s ≥ 1`` (the pad slides already).
    """
    if not force > 0.0:
        return 0.0
    s = ft / (mu_c * force)
    return mu_c * r * force * math.sqrt(max(0.0, 1.0 - s * s))


def translation_per_radian(force: float, ft: float, mu_c: float, r: float) -> float:
    """Grasp-point translation per radian of turn [m] at slip: ``r·s/√(1 − s²)`` (inf at s ≥ 1)."""
    if not force > 0.0:
        return math.inf
    s = ft / (mu_c * force)
    return math.inf if s >= 1.0 else r * s / math.sqrt(1.0 - s * s)


class ModelHingeController(SlipController):
    """HINGE (mode 3), ``model`` law (module docstring).

    Args:
        params: Controller parameters (``hinge_model``, ``twist_observer``).
        contact: Contact properties with a valid ``r``.
        initial_force: The previous controller's last force [N] (handed on to the HOLD
            successor if the inputs go stale before the first hinge step).
        static_ratio: ``μ_s/μ_c`` (None or NaN: the ``static_ratio`` parameter).

    Raises:
        ValueError: ``r`` is not valid (a request is refused before this, see
            `mode_switch.check_contact`).
    """

    mode = SlipMode.HINGE
    control_law = MODEL_LAW

    def __init__(self, params: SlipControllerParams, contact: ControlContact,
                 initial_force: float | None = None, static_ratio: float | None = None
                 ) -> None:
        if not contact.r_valid:
            raise ValueError(f'the model HINGE needs {REQUIREMENT}')
        super().__init__(params, contact)
        g = params.hinge_model
        self._out = initial_force
        self._observer = TwistObserver(observer_config(params), contact.r_guarded)
        self._load = LoadFilter(params.hold_model.load_filter_time)
        ratio = static_ratio if static_ratio is not None else g.static_ratio
        self._static_ratio = max(1.0, ratio) if math.isfinite(ratio) else g.static_ratio
        self._tau_ref: float | None = None     # signed torque at the request [N·m]
        self._theta = 0.0                      # object's turn in the pads [rad]
        self._phi0: float | None = None        # gripper angle from the load at the start [rad]
        self._turn = 0.0                       # object's turn in the world, ψ̂ [rad]
        self._integral = 0.0                   # ∫e dt [rad·s]

    @classmethod
    def for_request(cls, params: SlipControllerParams, contact: ControlContact,
                    inputs: SensorSnapshot | None, initial_force: float | None = None,
                    static_ratio: float | None = None) -> ModelHingeController:
        """Build for a HINGE request, or refuse it with the reason (`RequestRefused`).

        Refused: no valid ``r`` (the law couples force and torque through it); no fresh
        wrenches to measure the load on; no torque measured (``|τ̄| < min_torque``): the
        centre of mass is on the grasp axis or straight above or below it, nothing would turn
        the pads under the object (turn the gripper from hanging first, as the runner's hinge
        pose does).
        """
        if not contact.r_valid:
            raise RequestRefused(f'the model HINGE needs {REQUIREMENT}; r is not valid')
        w1 = inputs.wrench_1 if inputs is not None else None
        w2 = inputs.wrench_2 if inputs is not None else None
        if w1 is None or w2 is None or not (w1.finite() and w2.finite()):
            raise RequestRefused('no wrench measured: the model HINGE needs the load on the '
                                 'pads to choose the grasp force')
        w = combine_wrenches(params.frames, w1, w2)
        g = params.hinge_model
        if abs(w.tz) < g.min_torque:
            raise RequestRefused(
                f'no torque measured (|tau| = {abs(w.tz) * 1e3:.2f} mN*m < min_torque = '
                f'{g.min_torque * 1e3:.2f} mN*m): the centre of mass is on the vertical '
                'through the grasp point, nothing would turn the pads under the object')
        ctl = cls(params, contact, initial_force=initial_force, static_ratio=static_ratio)
        ctl._tau_ref = w.tz
        return ctl

    @property
    def mu_s_ratio(self) -> float:
        """``μ_s/μ_c`` the law assumes for the break-away (from the properties or the
        ``static_ratio`` parameter)."""
        return self._static_ratio

    @property
    def reference_torque(self) -> float | None:
        """Signed torque at the request ``τ₀`` [N·m] (None before the first load)."""
        return self._tau_ref

    @property
    def world_turn(self) -> float:
        """``ψ̂``: the object's estimated turn in the world since the request [rad]."""
        return self._turn

    @property
    def observer(self) -> TwistObserver:
        """The slip observer."""
        return self._observer

    def reset(self, t: float) -> None:
        super().reset(t)
        self._observer.reset_time()

    def hinge_force(self, ft: float, slip: SlipEstimate) -> float:
        """The law's force [N] for tangential load ``ft`` [N] at the current ``ψ̂`` (clamped)."""
        g = self._p.hinge_model
        r = self._c.r_guarded
        ref = self._tau_ref if self._tau_ref is not None else 0.0
        t_ref = max(abs(ref), r * r * ft / g.max_cor)
        e = self._uphill() * self._turn
        torque = max(0.0, t_ref * (1.0 - g.orientation_gain * e
                                   - g.orientation_integral * self._integral))
        mu = self._c.mu_c * (1.0 if slip.slipping else self._static_ratio)
        f = max(math.hypot(ft, torque / r) / mu, ft / (self._c.mu_c * g.max_load_ratio))
        excess = 0.0
        if slip.slipping:
            excess = max(0.0, slip.translation_speed - g.cor_offset * abs(slip.rotation_rate))
        f *= 1.0 + g.rotation_damping * abs(slip.rotation_rate) + g.translation_gain * excess
        return min(max(f, self._p.model.min_force), self._p.model.max_force)

    def step(self, inputs: SensorSnapshot, t: float) -> ControlOutput:
        """One ``model`` HINGE step; stale inputs hand over to the ``model`` HOLD."""
        st = self._assess(inputs, t)
        if not (st.velocity_fresh and st.ft_fresh):
            hold = ModelHoldController(self._p, self._c, initial_force=self._out)
            out = hold.step(inputs, t)
            why = 'velocity stale' if not st.velocity_fresh else 'F/T stale'
            return replace(out, next_controller=hold, reason=f'HINGE ended: {why}')
        sample = self._next_sample(inputs, st)
        if isinstance(sample, ControlOutput):
            return sample
        dt = self._advance_stamp(sample.stamp)
        v = sample.twist
        slip = self._observer.update(v, sample.stamp)
        fx, fy, tz = self._load.update(sample.wrench, dt)
        if self._tau_ref is None:
            self._tau_ref = tz
        self._track_orientation(fx, fy, v.omega, dt)
        self._out = self.hinge_force(math.hypot(fx, fy), slip)
        reason = ''
        if abs(tz) < self._p.hinge_model.min_torque:
            reason = 'no torque measured: nothing turns the pads under the object'
        return self._emit(self._out, st, reason)

    def _uphill(self) -> float:
        """The sense of turn away from hanging (+1 or −1): opposite to the torque's sign."""
        return -1.0 if (self._tau_ref or 0.0) >= 0.0 else 1.0

    def _track_orientation(self, fx: float, fy: float, omega: float, dt: float | None) -> None:
        """Update ``ψ̂`` and ``∫e dt`` from the load direction and the turn in the pads."""
        g = self._p.hinge_model
        if dt is not None:
            self._theta += omega * dt
        phi = math.atan2(-fx, -fy)
        if self._phi0 is None:
            self._phi0 = phi
        self._turn = math.remainder(phi - self._phi0 + self._theta, 2.0 * math.pi)
        if dt is not None:
            self._integral = min(max(self._integral + self._uphill() * self._turn * dt,
                                     -g.integral_limit), g.integral_limit)


def static_ratio(props: ContactProperties) -> float:
    """``mean(μ_s)/mean(μ_c)`` of a property set, or NaN when a finger's ``μ_s`` is not valid."""
    fingers = (props.finger_1, props.finger_2)
    if not all(f.static_valid and math.isfinite(f.mu_s) and f.mu_s > 0.0 for f in fingers):
        return math.nan
    return (fingers[0].mu_s + fingers[1].mu_s) / (fingers[0].mu_c + fingers[1].mu_c)
