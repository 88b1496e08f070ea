# SPDX-License-Identifier: Apache-2.0
"""HINGE with the ``model`` control law: the object turns about the grasp axis, the grasp point
does not translate (issue 15 items 5 and 6).

On the ellipsoidal limit surface of a pad (docs/control_and_estimation.md §4.4, §4.6), a
tangential load ``f_t`` and a torque ``τ`` (two-finger means) slip at the grasp force
``F = ‖(f_t, τ/r)‖/μ_c``, and the twist is normal to the surface there: the object turns about
a centre of rotation (CoR) ``c = r²·f_t/|τ|`` from the grasp point, so the grasp point
translates ``c`` per radian of turn. With ``s = f_t/(μ_c F)`` the same relations read

* torque capacity ``μ_c·r·F·√(1 − s²)`` — the object turns once the gravity torque exceeds it;
* translation per radian ``c = r·s/√(1 − s²)``.

The thesis HINGE (§4.7, ``F = 1.4·f_t/μ_c``) fixes ``s = 1/1.4``, i.e. ``c ≈ r``: an object
whose centre-of-mass lever is short never builds the torque to turn, and one whose lever is
long swings through hanging and lags the gripper. This law chooses the force as a multiple
``κ`` of the translation floor ``f_t/μ_c`` from the limit surface and the load measured at the
request, and damps the motion with the observed slip (`twist_observer`)::

    κ_c     = √(1 + (r/cor_offset)²)        a turn slips only about a CoR within cor_offset
    κ_swing = (D₀/μ_s)/(f_t₀/μ_c)           D₀ = ‖(f_t₀, τ₀/r)‖ at the request: the force at
                                            which that load breaks static friction
    κ       = max(min(κ_c, swing_fraction·κ_swing), 1/max_load_ratio)
    F       = k·κ·(f_t/μ_c)·(1 + translation_gain·e + rotation_damping·|ω̂|)
    e       = max(0, v̂_t − cor_offset·|ω̂|) while slipping   (translation beyond the CoR)

* ``κ_c`` keeps the grasp point from translating more than ``cor_offset`` per radian of turn;
* ``κ_swing`` caps it so that the object at the request pose can start to turn (a short lever);
* the translation term adds force while the grasp point translates beyond the allowed CoR
  (feedback: translation speed → more force), the damping term while the object swings fast
  (so it comes to rest instead of swinging through hanging and back);
* the factor ``k`` (1 by default) can adapt online: integral action on the excess translation
  while the slip is quasi-static (``adapt_up``), and a decay while no slip is observed under a
  torque whose CoR ``r²f_t/|τ|`` is within ``release_cor`` (``release_rate``: no rotation while
  a torque is measured → less force). Both are off by default: on drawn objects the integral
  action wound up on the swing's translation and the release let the grasp point slide
  (measured on 22 objects of population 11: 12 hinged within the targets without them, at most
  5 with them).

``k`` stays within ``[min_factor, max_factor]`` and the output within
``[min_force, max_force]`` (``model`` group). Loads are low-passed like the ``model`` HOLD's.

Refusals (`ModelHingeController.for_request`, before anything changes): no valid ``r``; no
wrench measured; no torque measured (``|τ̄| < min_torque``: the centre of mass is on the
vertical through the grasp point, nothing would swing the object). While no torque is measured
later, the step says so in its reason and holds against translation. Stale inputs hand over to
the ``model`` HOLD in the same step (as the thesis HINGE does, CE-3).
"""
from __future__ import annotations

import math
from dataclasses import replace

from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import ControlContact, ControlOutput, SlipController, SlipMode
from slip_control.core.model_hold import MODEL_LAW, LoadFilter, ModelHoldController, observer_config
from slip_control.core.model_trajectory import RequestRefused
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import SensorSnapshot, combine_twists, combine_wrenches
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
        self._k = 1.0
        ratio = static_ratio if static_ratio is not None else g.static_ratio
        self._static_ratio = max(1.0, ratio) if math.isfinite(ratio) else g.static_ratio
        self._kappa: float | None = None      # threshold ratio F/(ft/μ_c), set on the load

    @property
    def mu_s_ratio(self) -> float:
        """``μ_s/μ_c`` the law assumes for the break-away (from the properties or the
        ``static_ratio`` parameter)."""
        return self._static_ratio

    @property
    def threshold(self) -> float | None:
        """``κ``: the force as a multiple of ``f_t/μ_c`` before adaptation (None before the
        first load)."""
        return self._kappa

    def _choose_threshold(self, ft: float, tz: float) -> float:
        """``κ = clamp(min(κ_c, swing_fraction·κ_swing), 1/max_load_ratio)`` from a load.

        ``κ_c = √(1 + (r/cor_offset)²)`` keeps the turn's CoR within ``cor_offset``;
        ``κ_swing = (D/μ_s)/(f_t/μ_c)`` is the force at which the load at the request breaks
        static friction (``D = ‖(f_t, τ/r)‖``): a smaller force lets the object start to turn.
        """
        g = self._p.hinge_model
        r = self._c.r_guarded
        kappa_c = math.sqrt(1.0 + (r / g.cor_offset) ** 2)
        kappa = kappa_c
        if ft > 0.0:
            d = math.hypot(ft, tz / r)
            kappa = min(kappa_c, g.swing_fraction * d / ft / self._static_ratio)
        return max(kappa, 1.0 / g.max_load_ratio)

    @classmethod
    def for_request(cls, params: SlipControllerParams, contact: ControlContact,
                    inputs: SensorSnapshot | None, initial_force: float | None = None,
                    static_ratio: float | None = None) -> ModelHingeController:
        """Build for a HINGE request, or refuse it with the reason (`RequestRefused`).

        Refused: no valid ``r`` (the law couples force and torque through it); no fresh
        wrenches to measure the load on; no torque measured (``|τ̄| < min_torque``): the
        centre of mass is on the grasp axis or straight above or below it, nothing would swing
        the object (turn the gripper from hanging first, as the runner's hinge pose does).
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
                'through the grasp point, nothing would swing the object')
        ctl = cls(params, contact, initial_force=initial_force, static_ratio=static_ratio)
        ctl._kappa = ctl._choose_threshold(w.tangential_force, w.tz)
        return ctl

    @property
    def factor(self) -> float:
        """The learned force factor ``k`` [-]."""
        return self._k

    @property
    def observer(self) -> TwistObserver:
        """The slip observer."""
        return self._observer

    def reset(self, t: float) -> None:
        super().reset(t)
        self._observer.reset_time()

    def hinge_force(self, ft: float, slip: SlipEstimate) -> tuple[float, float]:
        """``(F, e)``: the law's force [N] (clamped) and the excess translation speed [m/s]."""
        g = self._p.hinge_model
        mu = self._c.mu_c
        kappa = self._kappa if self._kappa is not None else 1.0 / g.max_load_ratio
        excess = 0.0
        if slip.slipping:
            excess = max(0.0, slip.translation_speed - g.cor_offset * abs(slip.rotation_rate))
        f = max(self._k * kappa, 1.0 / g.max_load_ratio) * ft / mu
        f *= 1.0 + g.translation_gain * excess + g.rotation_damping * abs(slip.rotation_rate)
        return min(max(f, self._p.model.min_force), self._p.model.max_force), excess

    def step(self, inputs: SensorSnapshot, t: float) -> ControlOutput:
        """One ``model`` HINGE step; stale inputs hand over to the ``model`` HOLD."""
        st = self._assess(inputs, t)
        if not (st.velocity_fresh and st.ft_fresh):
            hold = ModelHoldController(self._p, self._c, initial_force=self._out)
            out = hold.step(inputs, t)
            why = 'velocity stale' if not st.velocity_fresh else 'F/T stale'
            return replace(out, next_controller=hold, reason=f'HINGE ended: {why}')
        stamp = self._new_trigger(inputs)
        if stamp is None:
            return self._emit(None, st, 'no new sample')
        if not st.synced:
            return self._emit(None, st, 'finger velocities not synchronised')
        dt = None if self._last_stamp is None else stamp - self._last_stamp
        if dt is not None and not 0.0 < dt <= self._p.dt_max:
            dt = None
        self._last_stamp = stamp
        assert inputs.wrench_1 is not None and inputs.wrench_2 is not None
        assert inputs.twist_1 is not None and inputs.twist_2 is not None
        frames = self._p.frames
        w = combine_wrenches(frames, inputs.wrench_1, inputs.wrench_2)
        v = combine_twists(frames, inputs.twist_1, inputs.twist_2)
        slip = self._observer.update(v, stamp)
        fx, fy, tz = self._load.update(w, dt)
        ft = math.hypot(fx, fy)
        if self._kappa is None:
            self._kappa = self._choose_threshold(ft, tz)
        reason = self._adapt(ft, tz, slip, dt)
        self._out, _ = self.hinge_force(ft, slip)
        return self._emit(self._out, st, reason)

    def _adapt(self, ft: float, tz: float, slip: SlipEstimate, dt: float | None) -> str:
        """Update the force factor ``k`` (module docstring); returns the step's reason."""
        g = self._p.hinge_model
        r = self._c.r_guarded
        torque = abs(tz)
        if dt is None:
            return ''
        if slip.slipping:
            # Integral action on the measured centre of rotation while the slip is slow enough
            # to be quasi-static (a fast swing's translation is inertial, not the pads'):
            # translation beyond cor_offset per radian raises k.
            e = max(0.0, slip.translation_speed - g.cor_offset * abs(slip.rotation_rate))
            if abs(slip.rotation_rate) <= g.quasi_static_rate:
                self._k *= math.exp(g.adapt_up * e * dt / g.cor_offset)
            reason = 'grasp point translating: more force' if e > 0.0 else ''
        elif torque < g.min_torque:
            reason = 'no torque measured: nothing swings the object (holding against translation)'
        elif r * r * ft / torque <= g.release_cor:
            self._k *= math.exp(-g.release_rate * dt)
            reason = 'not turning under a torque: less force'
        else:
            reason = ''
        self._k = min(max(self._k, g.min_factor), g.max_factor)
        return reason


def static_ratio(props: ContactProperties) -> float:
    """``mean(μ_s)/mean(μ_c)`` of a property set, or NaN when a finger's ``μ_s`` is not valid."""
    fingers = (props.finger_1, props.finger_2)
    if not all(f.static_valid and math.isfinite(f.mu_s) and f.mu_s > 0.0 for f in fingers):
        return math.nan
    return (fingers[0].mu_s + fingers[1].mu_s) / (fingers[0].mu_c + fingers[1].mu_c)
