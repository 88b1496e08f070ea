# SPDX-License-Identifier: Apache-2.0
"""Shared machinery of the model-based LINEAR and ROTATIONAL laws (docs/model_slip_control.md §3).

Per control step (one per new finger-1 twist, like the thesis laws)::

    p          = travel along the slip (as the thesis laws: the sensors' counts, summed)
    (p̂, v̂, â)  = SlipObserver(p[, a from the pad forces])            (Kalman filter, filterpy)
    (p_d, v_d, a_d) = trapezoid(t)
    v_c  = v_d + ω_n/(2ζ)·(p_d − p̂),   ≥ keep_rate before the deceleration
    u    = a_d + 2ζω_n·(v_c − (v̂ + â·lead)) + k_i·ω_n³·∫(p_d − p̂)dt        (wanted acceleration)
    F    = F_model(observed state) · clamp(1 − u/A, 0, max_scale) · (1 − β)
    F    = clamp(max(F, F_prev·e^(−fall_rate·dt)), min_force, max_force)

``F_model`` is the grasp force at which the pads' friction just carries the load at the
observed slip speed (the mode's friction-model inversion, `slip_model`), ``A`` the acceleration
the load alone would give the object (so ``u/A`` is the share of friction to take away), and:

* ``β`` — break-away: while the object sticks behind the reference it grows by
  ``breakaway_rate`` per second (up to ``breakaway_max``) until the object moves; the integral
  waits meanwhile, so it has not wound up when the object breaks loose. At rest ``F_model``
  is already the static (``μ_s``) force; once the observer sees motion, the Stribeck curve of
  the model raises it to the kinetic force at once, which stops the run-away that static
  friction above kinetic would give;
* ``keep_rate`` — an object ahead of the reference slows down instead of sticking (a new
  break-away would jump again);
* ``lead`` — the inner grasp-force loop's lag, anticipated with the observed acceleration;
* falls of the command are slewed with ``fall_rate`` (the inner loop undershoots a step down);
  rises act at once;
* arrived (in the deceleration, within half the tolerance of the target) and at rest: no
  further break-away, no integral — the last fraction of a millimetre is not worth a jump.

The trajectory ends (§3.3):

* "done" at the first step with ``t ≥ T``, the progress within the tolerance of the target and
  the observed rate below the stop threshold — on time, never early: an object ahead of the
  reference is held back by the feedback, not released;
* "overshoot: 21.3 of 20.0 mm" as soon as the progress passes the target by more than the
  tolerance (the load cannot pull it back), then HOLD;
* "no slip at minimum force: 0.2 of 20.0 mm" after ``no_slip_time`` at ``min_force`` without
  motion (the request passed the up-front check, but the contact holds better than estimated);
* mode-specific failures (LINEAR: "turned 61 deg while sliding …");
* "stalled: …" / "timeout: …, still moving" at ``T + settle_timeout``;
* the shared failures of `TrajectoryController` ("contact lost", "slip reversed" judged on the
  observed rate, stale inputs).

A request the law cannot carry out is refused before anything changes (`RequestRefused`, raised
by the mode's ``for_request``), with the measured numbers in the reason. The tracking rows carry
the observed rate in ``meas_vel`` and the unclamped model force in ``f_slip``.
"""
from __future__ import annotations

import math
from abc import abstractmethod
from dataclasses import dataclass

from slip_control.core.controllers import (ControlContact, ControlOutput, TrackingRecord,
                                           TrajectoryController)
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import (MiddleTwist, MiddleWrench, SensorSnapshot,
                                       assess_inputs, combine_wrenches)
from slip_control.core.slip_model import ContactModel
from slip_control.core.slip_observer import ObserverNoise, SlipEstimate, SlipObserver

#: Name of the law family (``ModeRequest.control_law``).
MODEL_LAW = 'model'


class RequestRefused(ValueError):
    """A request the law cannot carry out; ``str(exc)`` is the reason (measured numbers)."""


@dataclass(frozen=True, slots=True)
class MeasuredLoad:
    """Load on the pads at the request: two-finger means in ``gripper_middle``.

    Attributes:
        fx: Mean x force the object puts on the pads [N].
        fy: Mean y force [N].
        tz: Mean torque about +z [N·m].
        grasp_force: Measured grasp force [N].
    """

    fx: float
    fy: float
    tz: float
    grasp_force: float

    @property
    def force(self) -> float:
        """Tangential load per pad ``‖(F̄x, F̄y)‖`` [N]."""
        return math.hypot(self.fx, self.fy)


def measure_load(inputs: SensorSnapshot | None, params: SlipControllerParams,
                 t: float) -> MeasuredLoad:
    """The load at the request from the latest wrenches (fresh, in contact).

    Raises:
        RequestRefused: No fresh wrench of both fingers, or no grasp force.
    """
    if inputs is None or inputs.wrench_1 is None or inputs.wrench_2 is None:
        raise RequestRefused('no F/T samples to measure the load with')
    st = assess_inputs(inputs, t, velocity_stale_after=params.velocity_stale_after,
                       ft_stale_after=params.ft_stale_after,
                       sync_tolerance=params.sync_tolerance)
    if not st.ft_fresh:
        raise RequestRefused(f'the F/T samples are stale ({st.ft_age:.3f} s old): '
                             'cannot measure the load')
    w = combine_wrenches(params.frames, inputs.wrench_1, inputs.wrench_2)
    if w.normal_force < params.contact_lost_force:
        raise RequestRefused(f'no contact: grasp force {w.normal_force:.2f} N')
    return MeasuredLoad(w.fx, w.fy, w.tz, w.normal_force)


def clamp(value: float, low: float, high: float) -> float:
    """``value`` limited to ``[low, high]``."""
    return low if value < low else high if value > high else value


class ModelTrajectoryController(TrajectoryController):
    """Base of the model-based trajectory laws (module docstring).

    Args:
        params: Controller parameters.
        contact: Contact properties (two-finger means, for the HOLD successor).
        model: Friction model of the pads.
        target: Distance [m] or signed angle [rad].
        duration: ``T`` [s].
        t_start: Start time [s].
        load: Load measured at the request.
        initial_force: Force of the controller this one replaces [N] (the first output is
            computed in the first step; this is handed on if the inputs go stale before).
    """

    control_law = MODEL_LAW

    def __init__(self, params: SlipControllerParams, contact: ControlContact,
                 model: ContactModel, target: float, duration: float, t_start: float,
                 load: MeasuredLoad, initial_force: float | None = None) -> None:
        super().__init__(params, contact, target, duration, t_start)
        self._model = model
        self._load = load
        self._out = initial_force
        self._observer = SlipObserver(self._observer_noise())
        self._integral = 0.0
        self._breakaway = 0.0
        self._v_ref = 0.0
        self._min_since: float | None = None
        self._last_est = SlipEstimate(0.0, 0.0, 0.0, 0.0)

    # mode-specific pieces ------------------------------------------------------------------

    @abstractmethod
    def _observer_noise(self) -> ObserverNoise:
        """Noise levels of the observer."""

    @abstractmethod
    def _gains(self) -> tuple[float, float, float, float]:
        """``(ω_n, ζ, integral fraction, force-loop lead [s])``."""

    @abstractmethod
    def _measure(self, w: MiddleWrench, v: MiddleTwist) -> tuple[float | None, float]:
        """``(acceleration or None, its 1-σ)`` measured this step (besides the travel)."""

    @abstractmethod
    def _model_force(self, est: SlipEstimate, w: MiddleWrench, dt: float) -> float:
        """Grasp force [N] at which the pads' friction just carries the load at the observed
        slip state (no acceleration)."""

    def _scaled_force(self, scale: float, est: SlipEstimate, w: MiddleWrench,
                      dt: float) -> float:
        """The model force with the feedback factor ``scale`` applied [N] (LINEAR: to all of
        it; ROTATIONAL overrides: to the torque only)."""
        return self._model_force(est, w, dt) * scale

    @abstractmethod
    def _authority(self) -> float:
        """Acceleration the load alone gives the object [m/s² | rad/s²] (all friction gone):
        the wanted acceleration ``u`` scales the model force by ``1 − u/authority``."""

    @abstractmethod
    def _stop_threshold(self) -> float:
        """Observed rate below which the object counts as stopped."""

    def _extra_stop(self) -> str:
        """A mode-specific failure to end with ('' = none)."""
        return ''

    @abstractmethod
    def _keep_rate(self) -> float:
        """Smallest rate set-point before the deceleration [m/s | rad/s] (0 = none)."""

    @abstractmethod
    def _motion_threshold(self) -> float:
        """Observed rate above which the object counts as moving."""

    # public --------------------------------------------------------------------------------

    @property
    def model(self) -> ContactModel:
        """The pads' friction model."""
        return self._model

    @property
    def load(self) -> MeasuredLoad:
        """The load measured at the request."""
        return self._load

    @property
    def estimate(self) -> SlipEstimate:
        """The observer's latest estimate."""
        return self._last_est

    def step(self, inputs: SensorSnapshot, t: float) -> ControlOutput:
        """One step of the model law (module docstring)."""
        gated = self._gate_step(inputs, t)
        if isinstance(gated, ControlOutput):
            return gated
        st, stamp, w, v = gated.status, gated.stamp, gated.wrench, gated.twist
        dt = 0.0 if self._last_stamp is None else stamp - self._last_stamp
        if not 0.0 < dt <= self._p.dt_max:
            dt = 0.0
        self._last_stamp = stamp
        tau = stamp - self._t_start
        self._elapsed = tau

        self._advance_progress(inputs)
        accel, accel_std = self._measure(w, v)
        est = self._observer.step(dt, position=self._x, accel=accel, accel_std=accel_std)
        self._last_est = est
        x_d, v_d = self._traj.sample(tau)
        a_d = self._traj.accel_at(tau)
        self._v_ref = v_d
        wn, zeta, ki, lead = self._gains()
        e_p = x_d - est.position
        m = self._p.model
        moving = abs(est.rate) >= self._motion_threshold()
        decelerating = tau >= self._traj.duration * (1.0 - self._p.trajectory.accel_fraction)
        # Arrived: in the deceleration and within half the tolerance of the target. A stuck
        # object is then left where it is (another break-away for the last fraction of a
        # millimetre would jump past the target).
        arrived = decelerating and self._target - est.position <= 0.5 * self._tolerance()
        # Break-away: while the object sticks behind the reference, lower the force by a
        # growing fraction until it moves (static friction above the model's, or a load the
        # model over-estimates); the integral waits, so it has not wound up when it slides.
        if moving or e_p <= 0.0 or arrived:
            self._breakaway = 0.0
        elif dt > 0.0:
            self._breakaway = min(self._breakaway + m.breakaway_rate * dt, m.breakaway_max)
        # Cascade form of the PD law: rate set-point from the position error, acceleration
        # from the rate error. Before the deceleration the set-point stays at least
        # keep_rate: an object ahead of the reference slows down instead of sticking (static
        # friction above kinetic would make it jump again when it breaks loose).
        v_c = v_d + 0.5 * wn / zeta * e_p
        if not decelerating:
            v_c = max(v_c, self._keep_rate())
        # Lead for the inner force loop's lag: act on the rate the object will have when the
        # command takes effect.
        rate_ahead = est.rate + est.accel * lead
        u = (a_d + 2.0 * zeta * wn * (v_c - rate_ahead)
             + ki * wn * wn * wn * self._integral)
        scale = clamp(1.0 - u / self._authority(), 0.0, m.max_scale) * (1.0 - self._breakaway)
        if arrived:
            # Arrived: stop here (an object still moving would run past the target).
            scale = max(scale, m.arrival_scale if moving else 1.0)
        f_raw = self._scaled_force(scale, est, w, dt)
        if self._out is not None and dt > 0.0 and m.fall_rate > 0.0:
            # Falls are slewed (the inner loop undershoots a step down and would break the
            # object loose below the intended force); rises act at once.
            f_raw = max(f_raw, self._out * math.exp(-m.fall_rate * dt))
        force = clamp(f_raw, m.min_force, m.max_force)
        # Conditional integration: only while sliding, and no wind-up while the force is
        # clamped against the error (behind at min_force; ahead at max_force).
        blocked = (e_p > 0.0 and f_raw <= m.min_force) or (e_p < 0.0 and f_raw >= m.max_force)
        if dt > 0.0 and moving and not blocked and not arrived:
            self._integral += e_p * dt
        self._out = force

        message, success = self._stop_condition(stamp, tau, w, est, force)
        track = TrackingRecord(stamp=stamp, mode=self.mode, ref_pos=x_d, ref_vel=v_d,
                               meas_pos=self._x, meas_vel=est.rate, force_cmd=force,
                               f_slip=f_raw, integral=self._integral, done=bool(message))
        if message:
            return self._finish(inputs, t, success, message, tau, track)
        return ControlOutput(mode=self.mode, force=force, timeout=self._p.command_timeout,
                             status=st, tracking=track)

    # internals -----------------------------------------------------------------------------

    def _stop_condition(self, stamp: float, tau: float, w: MiddleWrench, est: SlipEstimate,
                        force: float) -> tuple[str, bool]:
        """``(message, success)`` or ``('', False)`` (module docstring; reversal is judged on
        the observed rate)."""
        failure = self._common_stops(stamp, est.rate, w) or self._extra_stop()
        if failure:
            return failure, False
        tol = self._tolerance()
        if self._x > self._target + tol:
            return self._shortfall('overshoot'), False
        settled = abs(est.rate) < self._stop_threshold()
        if tau >= self._traj.duration and settled and self._reached():
            return 'done', True
        m = self._p.model
        at_min = force <= m.min_force and abs(est.rate) < self._motion_threshold()
        self._min_since, no_slip = self._held_for(
            self._min_since, at_min and not self._reached(), stamp, m.no_slip_time)
        if no_slip:
            return self._shortfall('no slip at minimum force'), False
        if tau >= self._traj.duration + self._p.settle_timeout:
            if not settled:
                return self._shortfall('timeout', ', still moving'), False
            return self._shortfall('stalled'), False
        return '', False
