# SPDX-License-Identifier: Apache-2.0
"""ROTATIONAL slip with the ``model`` law (docs/model_slip_control.md §5).

The object turns under its own load torque, with its tangential load still on the pads. At the
request the two-finger mean load ``(F̄₀, τ̄₀)`` is measured; its torque sets the turning sign
(``σ = sign τ̄₀`` when latched, else the sign of the angle, which must agree). Each step the pads
must carry the tangential load ``f = ‖F̄‖`` and the torque

    τ_req = τ_load − Î·u/2,     Î = m̂·(ℓ² + k²),  m̂ = 2‖F̄₀‖/g,  ℓ = |τ̄₀|/‖F̄₀‖

(``u`` the wanted angular acceleration of `model_trajectory`, ``k`` the assumed radius of
gyration, ``ℓ`` the lever of the load perpendicular to it); in the form of `model_trajectory`
``F = F_model·(1 − u/A)`` with ``A = τ_load/(Î/2)``. ``τ_load`` follows the load as the object
turns: the measured torque plus ``Î·â/2`` (what the observed acceleration took), low-pass
filtered with ``load_time``, starting at ``τ̄₀``. The observer is fed the travel (turn) only.

The limit surface couples force and torque: a pad that turns while it carries ``f`` slides its
grasp point too. `slip_model.ContactModel.rotation_force` finds the twist whose steady friction
(reduced LuGre on the pre-computed limit surface, Stribeck at the observed rate) points along
``(f, τ_req)`` and the grasp force that gives it; that twist's translation is the least the
grasp point can slide while the object turns (``r·tan ψ`` per radian), so the force keeps the
grasp point as still as the physics allows.

Refused up front (`RequestRefused`): no fresh F/T or no contact; a load torque turning the
object against the commanded sign; a torque that static friction holds at ``min_force``;
a lever so short next to the torsional radius that the coupling would slide the grasp point
more than ``max_translation`` over the commanded angle; a load that needs more than
``max_force`` to be held.
"""
from __future__ import annotations

import math

from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import ControlContact, SlipMode
from slip_control.core.model_trajectory import (MeasuredLoad, ModelTrajectoryController,
                                                RequestRefused, measure_load)
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import MiddleTwist, MiddleWrench, SensorSnapshot
from slip_control.core.slip_model import ContactModel
from slip_control.core.slip_observer import ObserverNoise, SlipEstimate


class ModelRotationalController(ModelTrajectoryController):
    """ROTATIONAL (mode 1), ``model`` law (module docstring).

    Build it with `for_request` (measures the load, checks feasibility).

    Args:
        params: Controller parameters.
        contact: Contact properties (two-finger means with a valid ``r``).
        model: Friction model of the pads.
        angle: Signed angle about ``gripper_middle`` +z [rad], ``|angle| > 0``.
        duration: ``T`` [s].
        t_start: Start time [s].
        load: Load measured at the request.
        sign: Turning sign ``σ`` (±1).
        initial_force: Force of the controller this one replaces [N].
    """

    mode = SlipMode.ROTATIONAL
    unit = ('deg', 180.0 / math.pi)

    def __init__(self, params: SlipControllerParams, contact: ControlContact,
                 model: ContactModel, angle: float, duration: float, t_start: float,
                 load: MeasuredLoad, sign: float, initial_force: float | None = None) -> None:
        self._sigma = math.copysign(1.0, sign)
        g = params.model_rotational
        f0 = max(load.force, 1e-9)
        self._mass = 2.0 * f0 / params.model.gravity
        lever = abs(load.tz) / f0
        self._inertia = self._mass * (lever * lever + g.gyration_radius ** 2)
        self._tau_load = abs(load.tz)
        super().__init__(params, contact, model, angle, duration, t_start, load,
                         initial_force)

    @classmethod
    def for_request(cls, params: SlipControllerParams, props: ContactProperties,
                    contact: ControlContact, angle: float, duration: float, t_start: float,
                    latch: bool, inputs: SensorSnapshot | None,
                    initial_force: float | None = None) -> ModelRotationalController:
        """Measure the load, check that the turn is possible, build the controller.

        Args:
            params, contact, angle, duration, t_start, initial_force: As the class.
            props: Contact properties (the friction model's ``μ_c``, ``μ_s``, ``μ_v``, ``r``).
            latch: Take the sign from the load torque instead of from ``angle``.
            inputs: Latest sensor samples (the load is measured from them).

        Raises:
            RequestRefused: The turn is impossible or unsafe; the message says why.
        """
        m = params.model
        g = params.model_rotational
        load = measure_load(inputs, params, t_start)
        tau = load.tz
        if tau == 0.0:
            raise RequestRefused('no load torque on the pads: nothing would turn the object')
        sign = math.copysign(1.0, tau) if latch else math.copysign(1.0, angle)
        if math.copysign(1.0, tau) != sign:
            raise RequestRefused(
                f'the load torque {tau * 1e3:+.1f} mN*m per pad turns the object the other way '
                f'than the requested {math.degrees(angle):+.1f} deg')
        model = ContactModel(props, m.pressure_shape, m.stribeck_velocity)
        f = load.force
        static = model.rotation_force(f, abs(tau), 0.0).force
        if static < m.min_force * m.refusal_margin:
            # At min_force the pads hold it: the static limit surface is not reached.
            raise RequestRefused(
                f'the load torque {abs(tau) * 1e3:.1f} mN*m per pad cannot overcome static '
                f'torsional friction at the minimum force {m.min_force:.2f} N (it turns only '
                f'below {static:.2f} N; mu_s*r {model.static_torque_per_force * 1e3:.2f} mm)')
        peak = abs(angle) * 1.25 / duration
        sol = model.rotation_force(f, abs(tau), peak)
        slide = sol.translation_per_rad * abs(angle)
        if slide > g.max_translation:
            lever = abs(tau) / f if f > 0.0 else math.inf
            raise RequestRefused(
                f'the load lever {lever * 1e3:.1f} mm is too short for the torsional radius '
                f'{model.r * 1e3:.1f} mm: turning {math.degrees(abs(angle)):.1f} deg would '
                f'slide the grasp point {slide * 1e3:.1f} mm (limit '
                f'{g.max_translation * 1e3:.1f} mm)')
        hold = model.rotation_force(f, abs(tau), 0.0).force * model.mu_s / model.mu_c
        if hold > m.max_force:
            raise RequestRefused(
                f'holding the load ({f:.2f} N, {abs(tau) * 1e3:.1f} mN*m per pad) needs about '
                f'{hold:.1f} N, more than the maximum force {m.max_force:.1f} N')
        return cls(params, contact, model, angle, duration, t_start, load, sign,
                   initial_force)

    # -- views ---------------------------------------------------------------------------

    @property
    def sign(self) -> float:
        """Turning sign ``σ``."""
        return self._sigma

    @property
    def inertia(self) -> float:
        """Assumed inertia about the grasp point ``Î`` [kg·m²]."""
        return self._inertia

    @property
    def load_torque(self) -> float:
        """Current load-torque estimate per pad [N·m] (magnitude)."""
        return self._tau_load

    # -- mode pieces -----------------------------------------------------------------------

    def _observer_noise(self) -> ObserverNoise:
        g = self._p.model_rotational
        return ObserverNoise(jerk_psd=g.jerk_psd, position=g.angle_noise)

    def _gains(self) -> tuple[float, float, float, float]:
        g = self._p.model_rotational
        return g.bandwidth, g.damping, g.integral, g.force_lag

    def _progress_increment(self, d: MiddleTwist) -> float:
        return self._sigma * d.omega

    def _reversed(self, rate: float) -> bool:
        return rate < -self._p.reversal.rate

    def _tolerance(self) -> float:
        return self._p.trajectory.angle_tolerance

    def _stop_threshold(self) -> float:
        return self._p.model_rotational.stop_rate

    def _keep_rate(self) -> float:
        return self._p.model_rotational.keep_rate

    def _motion_threshold(self) -> float:
        return self._p.model_rotational.motion_rate

    def _measure(self, w: MiddleWrench, v: MiddleTwist) -> tuple[float | None, float]:
        return None, 0.0

    def _authority(self) -> float:
        return max(self._tau_load, 1e-9) / (0.5 * self._inertia)

    def _model_force(self, est: SlipEstimate, w: MiddleWrench, dt: float) -> float:
        return self._scaled_force(1.0, est, w, dt)

    def _scaled_force(self, scale: float, est: SlipEstimate, w: MiddleWrench,
                      dt: float) -> float:
        """The feedback scales the torque the pads carry, never the tangential load: the turn
        is what is controlled, the grasp point must keep its place (``translation_floor``)."""
        g = self._p.model_rotational
        if dt > 0.0 and g.load_time > 0.0:
            now = max(self._sigma * w.tz + 0.5 * self._inertia * est.accel, 0.0)
            a = math.exp(-dt / g.load_time)
            self._tau_load = a * self._tau_load + (1.0 - a) * now
        rate = max(est.rate, 0.0)
        f = w.tangential_force
        force = self._model.rotation_force(f, self._tau_load * scale, rate).force
        return max(force, g.translation_floor * f / self._model.mu_c)
