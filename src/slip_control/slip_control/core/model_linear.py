# SPDX-License-Identifier: Apache-2.0
"""LINEAR slip with the ``model`` law (docs/model_slip_control.md §4).

The object slides under its own load: the static tangential force ``F̄₀`` and torque ``τ̄₀``
(two-finger means, ``gripper_middle``) measured when the request arrives. With ``ê`` the slip
direction (the commanded one, or the load's own when it is latched) and ``f₀ = F̄₀·ê`` the
load along it, the model force (`model_trajectory`) is

    F_model = slide_force(f₀, torque_share·τ̂, v̂) / κ,      A = g_e = 2f₀/m̂,  m̂ = 2‖F̄₀‖/g

`slip_model.ContactModel.slide_force` is the reduced LuGre model on the limit surface: the grasp
force at which the pads carry ``f₀`` and the torque together while the grasp point slides at the
observed speed ``v̂`` (``μ_s`` at rest, along the Stribeck curve to ``μ_c + μ_v·v``; the torque
makes the slip a combined one, which needs more force than the translation alone). ``τ̂`` is the
measured torque, filtered slowly (``torque_time``: when the object breaks loose the friction
torque collapses for a moment, the load does not); only ``torque_share`` of it is carried, the
rest lets the object turn towards hanging while it slides, as the limit surface makes it.
``κ`` corrects the model online: while the object slides clearly above the Stribeck speed and
hardly turns, the measured friction ``F̄·ê`` over the measured grasp force and the model's
coefficient is averaged into it (``adaptation``; clipped to ``KAPPA_RANGE``), so an estimated
``μ_c`` a few per cent off is not left to the integral.

Observer measurements: the travel along ``ê`` and the acceleration ``g_e·(1 − (F̄·ê)/f₀)`` read
from the pad forces (1-σ ``2·ft_noise/m̂``: sharp for heavy objects, nearly nothing for light
ones).

A slide during which the object turns more than ``max_turn`` ends "turned 61 deg while sliding
(load off the slip line): …": a centre of mass above the grasp topples once the grip is loose
enough to slide, whatever the force law (the limit surface leaves no torque capacity to a
translating pad).

Refused up front (`RequestRefused`), with the numbers: no fresh F/T or no contact; a commanded
direction more than ``max_direction_error`` away from the load; a load that static friction
holds even at ``min_force`` (``f₀ ≤ refusal_margin·μ̄_s·min_force``); a load that needs more than
``max_force`` to be held (the slide could not be stopped).
"""
from __future__ import annotations

import math

from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import ControlContact, SlipMode
from slip_control.core.model_trajectory import (MeasuredLoad, ModelTrajectoryController,
                                                RequestRefused, clamp, measure_load)
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import MiddleTwist, MiddleWrench, SensorSnapshot
from slip_control.core.slip_model import ContactModel
from slip_control.core.slip_observer import ObserverNoise, SlipEstimate

#: Range of the online friction correction ``κ`` [-] (a reading outside is clipped).
KAPPA_RANGE = (0.7, 1.4)


class ModelLinearController(ModelTrajectoryController):
    """LINEAR (mode 2), ``model`` law (module docstring).

    Build it with `for_request` (measures the load, checks feasibility).

    Args:
        params: Controller parameters.
        contact: Contact properties (two-finger means, for the HOLD successor).
        model: Friction model of the pads.
        distance: ``P`` [m], > 0.
        duration: ``T`` [s], > 0.
        t_start: Start time [s].
        load: Load measured at the request.
        direction: Unit slip direction ``ê`` in ``gripper_middle`` xy.
        initial_force: Force of the controller this one replaces [N].
    """

    mode = SlipMode.LINEAR

    def __init__(self, params: SlipControllerParams, contact: ControlContact,
                 model: ContactModel, distance: float, duration: float, t_start: float,
                 load: MeasuredLoad, direction: tuple[float, float],
                 initial_force: float | None = None) -> None:
        n = math.hypot(direction[0], direction[1])
        if not n > 0.0:
            raise ValueError('direction must be a non-zero xy vector')
        self._e = (direction[0] / n, direction[1] / n)
        f_along = load.fx * self._e[0] + load.fy * self._e[1]
        if not f_along > 0.0:
            raise ValueError('the load must push along the slip direction')
        self._f0 = f_along
        self._mass = 2.0 * load.force / params.model.gravity
        self._g_e = 2.0 * f_along / self._mass
        self._kappa = 1.0
        self._omega = 0.0
        self._turn = 0.0
        self._rate = 0.0
        self._torque = abs(load.tz)
        super().__init__(params, contact, model, distance, duration, t_start, load,
                         initial_force)

    @classmethod
    def for_request(cls, params: SlipControllerParams, props: ContactProperties,
                    contact: ControlContact, distance: float, duration: float, t_start: float,
                    direction: tuple[float, float] | None, inputs: SensorSnapshot | None,
                    initial_force: float | None = None) -> ModelLinearController:
        """Measure the load, check that the slide is possible, build the controller.

        Args:
            params, contact, distance, duration, t_start, initial_force: As the class.
            props: Contact properties (the friction model's ``μ_c``, ``μ_s``, ``μ_v``, ``r``).
            direction: Commanded direction (xy), or ``None`` for the load's own.
            inputs: Latest sensor samples (the load is measured from them).

        Raises:
            RequestRefused: The slide is impossible or unsafe; the message says why.
        """
        m = params.model
        load = measure_load(inputs, params, t_start)
        f = load.force
        if not f > 0.0:
            raise RequestRefused('no tangential load on the pads: nothing would make the '
                                 'object slide')
        if direction is None:
            e = (load.fx / f, load.fy / f)
        else:
            n = math.hypot(direction[0], direction[1])
            e = (direction[0] / n, direction[1] / n)
            cos = (load.fx * e[0] + load.fy * e[1]) / f
            off = math.acos(max(-1.0, min(1.0, cos)))
            if off > params.model_linear.max_direction_error:
                raise RequestRefused(
                    f'the load points {math.degrees(off):.0f} deg away from the requested '
                    f'direction (limit {math.degrees(params.model_linear.max_direction_error):.0f}'
                    ' deg): it cannot slide the object that way')
        model = ContactModel(props, m.pressure_shape, m.stribeck_velocity)
        f_along = load.fx * e[0] + load.fy * e[1]
        static = model.mu_s * m.min_force
        if f_along <= m.refusal_margin * static:
            raise RequestRefused(
                f'the load along the slip, {f_along:.2f} N per pad, cannot overcome static '
                f'friction {static:.2f} N at the minimum force {m.min_force:.2f} N '
                f'(mu_s {model.mu_s:.2f})')
        hold = f / model.mu_c
        if hold > m.max_force:
            raise RequestRefused(
                f'holding the load {f:.2f} N per pad needs {hold:.1f} N, more than the '
                f'maximum force {m.max_force:.1f} N: the slide could not be stopped')
        return cls(params, contact, model, distance, duration, t_start, load, e,
                   initial_force)

    # -- views ---------------------------------------------------------------------------

    @property
    def direction(self) -> tuple[float, float]:
        """Slip direction ``ê`` (unit, ``gripper_middle`` xy)."""
        return self._e

    @property
    def mass(self) -> float:
        """Object mass from the static load ``m̂`` [kg]."""
        return self._mass

    @property
    def friction_correction(self) -> float:
        """Online friction correction ``κ`` [-]."""
        return self._kappa

    # -- mode pieces -----------------------------------------------------------------------

    def _observer_noise(self) -> ObserverNoise:
        g = self._p.model_linear
        return ObserverNoise(jerk_psd=g.jerk_psd, position=g.position_noise)

    def _gains(self) -> tuple[float, float, float, float]:
        g = self._p.model_linear
        return g.bandwidth, g.damping, g.integral, g.force_lag

    def _progress_increment(self, d: MiddleTwist) -> float:
        self._turn += d.omega
        return d.vx * self._e[0] + d.vy * self._e[1]

    def _extra_stop(self) -> str:
        limit = self._p.model_linear.max_turn
        if limit > 0.0 and abs(self._turn) > limit:
            return self._shortfall(f'turned {math.degrees(abs(self._turn)):.0f} deg while '
                                   'sliding (load off the slip line)')
        return ''

    def _reversed(self, rate: float) -> bool:
        return rate < -self._p.reversal.speed

    def _tolerance(self) -> float:
        return self._p.trajectory.position_tolerance

    def _stop_threshold(self) -> float:
        return self._p.model_linear.stop_speed

    def _keep_rate(self) -> float:
        return self._p.model_linear.keep_speed

    def _motion_threshold(self) -> float:
        return self._p.model_linear.motion_speed

    def _measure(self, w: MiddleWrench, v: MiddleTwist) -> tuple[float | None, float]:
        self._rate = v.vx * self._e[0] + v.vy * self._e[1]
        self._omega = v.omega
        f_along = w.fx * self._e[0] + w.fy * self._e[1]
        accel = self._g_e * (1.0 - f_along / self._f0)
        return accel, 2.0 * self._p.model.ft_noise / self._mass

    def _authority(self) -> float:
        return self._g_e

    def _model_force(self, est: SlipEstimate, w: MiddleWrench, dt: float) -> float:
        g = self._p.model_linear
        speed = max(est.rate, 0.0)
        if dt > 0.0 and g.torque_time > 0.0:
            a = math.exp(-dt / g.torque_time)
            self._torque = a * self._torque + (1.0 - a) * abs(w.tz)
        if (g.adaptation > 0.0 and dt > 0.0 and speed > 3.0 * self._p.model.stribeck_velocity
                and self._rate > 3.0 * self._p.model.stribeck_velocity
                and w.normal_force > self._p.contact_lost_force
                and abs(self._omega) * self._model.r < 0.2 * speed):
            # Clean translation only: while the object also turns, the limit surface shares
            # the friction with the torque and the force along ê reads low.
            c = self._model.translation_coefficient(speed)
            f_along = w.fx * self._e[0] + w.fy * self._e[1]
            measured = clamp(f_along / (w.normal_force * c), KAPPA_RANGE[0], KAPPA_RANGE[1])
            a = math.exp(-dt / g.adaptation)
            self._kappa = a * self._kappa + (1.0 - a) * measured
        torque = self._torque * g.torque_share
        return self._model.slide_force(self._f0, torque, speed) / self._kappa
