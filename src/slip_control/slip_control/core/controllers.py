# SPDX-License-Identifier: Apache-2.0
"""Slip controllers, one class per mode (control_and_estimation §4; CE-2, CE-3, CE-5, CE-6).

Every controller turns the latest two-finger sensor snapshot into a desired per-finger grasp
force ``F_d`` [N] for the inner loop. Signals are the ``gripper_middle`` means of §1.2
(`signals`), contact properties the two-finger means ``μ_c``, ``r``.

HOLD (§4.4)::

    D   = ‖(F̄x, F̄y, τ̄/r)‖,   r ≥ 1e-5 m
    f_d = margin · max(D/μ_c, floor) + slip_gain · ‖(v̄x, v̄y, r·ω̄)‖
    out = f_d                               if f_d ≥ out   (rises at once)
    out = a·out + (1 − a)·f_d               otherwise      (a = 0.95: τ ≈ 0.16 s at 120 Hz)

LINEAR (§4.5; ``v`` = ``‖v̄‖`` or the signed ``v̄·ê`` of §4.2), ROTATIONAL (§4.6; ``ω``
= ``|ω̄|`` or ``σ·ω̄``)::

    x  += v·dt;  (x_d, v_d) = trapezoid(t);  v_c = v_d + kp·(x_d − x)
    acc = (v − v_prev)/dt;   E += (v_c − v)·dt
    f_slip = ft/μ_c (first sample), then a·f_slip + (1 − a)·ft/μ_c while acc < gate
    f_d = max(f_slip − ki·E + kd·f_slip·acc + kv·f_slip·(v − v_c), floor)

ROTATIONAL uses ``f_slip`` from ``D/μ_c`` and the extra floor
``ft/μ_c + kp_cop·max(0, ‖c‖ − r)``, ``‖c‖ = ‖v̄‖/(|ω̄| + 1e-3)`` (centre of rotation).

HINGE (§4.7)::

    f_d = max(floor, threshold · ft/μ_c + slip_gain · ‖v̄‖)

Timing and guards (CE-6, CE-7): a *step* is triggered by a new finger-1 twist; ``dt`` is the
difference of finger-1 twist stamps, and the trajectory time is that stamp minus the start
time. ``dt ≤ 0`` or ``dt > dt_max`` skips the position, derivative, integral and ``f_slip``
updates of that step. Stop tests use thresholds, never float equality (§4.9). A trajectory
ends "done" (success) only with its progress within ``trajectory.position_tolerance`` /
``angle_tolerance`` of the target; one that settles short of it ends at ``T + settle_timeout``
with "stalled: 4.1 of 20.0 mm" (a failure that says how far it got).

These are the thesis laws (control law ``thesis``); the model-based laws of
docs/model_slip_control.md share `TrajectoryController` (progress, stops, hand-over).

Stale inputs (CE-3), judged against the evaluation time ``t`` passed to `step` (the node
calls `step` on each finger-1 twist *and* from a watchdog timer, so staleness is detected
even when the velocity stream stops):

* HOLD: velocity stale → slip term 0 and the fall filter frozen (the force may rise, never
  fall); F/T stale → the last output is held. Both set ``safe_hold``.
* LINEAR, ROTATIONAL, HINGE: either stream stale → the mode ends at once and HOLD takes over
  in the same step (so the same safe-hold rules apply); trajectories report the reason.

A finished or aborted mode returns its HOLD successor in ``ControlOutput.next_controller``;
the HOLD output is what is published in that step (§4.1). The node swaps the successor in
with one assignment.

An instance is owned by one executor thread; `step` mutates its private state and is
deterministic given the sequence of ``(inputs, t)``.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, replace
from enum import IntEnum
from typing import ClassVar

from slip_control.core.contact import ContactProperties, ContactSource
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import (InputStatus, MiddleTwist, MiddleWrench, SensorSnapshot,
                                       Travel, assess_inputs, combine_twists, combine_wrenches,
                                       middle_travel_delta)
from slip_control.core.trajectory import TrapezoidalTrajectory

#: Smallest torsional radius used in any division [m] (CE-6).
R_GUARD = 1e-5
#: Rate offset in the centre-of-rotation estimate [rad/s] (§4.6).
OMEGA_GUARD = 1e-3


class SlipMode(IntEnum):
    """Slip-controller modes (mirror ``slip_msgs/SetSlipMode``)."""

    OFF = 0
    ROTATIONAL = 1
    LINEAR = 2
    HINGE = 3
    HOLD = 4


@dataclass(frozen=True, slots=True)
class ControlContact:
    """Contact properties as the controllers use them (§1.2: means of both fingers).

    Attributes:
        mu_c: ``(μ_c1 + μ_c2)/2`` [-], > 0.
        r: ``(r1 + r2)/2`` [m], or NaN when not known.
        r_valid: ``r`` may be used; otherwise the torsional terms are left out.
        source: Where the properties came from.
        preset_name: Preset name (empty unless a preset).
    """

    mu_c: float
    r: float = float('nan')
    r_valid: bool = False
    source: ContactSource = ContactSource.ESTIMATED
    preset_name: str = ''

    @staticmethod
    def from_properties(props: ContactProperties, *, use_r: bool = True) -> ControlContact:
        """Two-finger means of a property set (no validity check: see `mode_switch`)."""
        r = props.mean_r()
        r_ok = use_r and math.isfinite(r) and r > 0.0
        return ControlContact(mu_c=props.mean_mu_c(), r=r if r_ok else float('nan'),
                              r_valid=r_ok, source=props.source, preset_name=props.preset_name)

    @property
    def r_guarded(self) -> float:
        """``max(r, 1e-5 m)`` (CE-6); only meaningful when ``r_valid``."""
        return max(self.r, R_GUARD) if self.r_valid else R_GUARD

    def load(self, w: MiddleWrench) -> float:
        """``D`` [N]: ``‖(F̄x, F̄y, τ̄/r)‖``, or ``ft`` when ``r`` is not known."""
        if self.r_valid:
            return w.limit_surface_load(self.r_guarded)
        return w.tangential_force

    def slip_speed(self, v: MiddleTwist) -> float:
        """``v_s`` [m/s]: ``‖(v̄x, v̄y, r·ω̄)‖``, or ``‖v̄‖`` when ``r`` is not known."""
        return v.slip_speed(self.r_guarded) if self.r_valid else v.speed


@dataclass(frozen=True, slots=True)
class TrackingRecord:
    """One row of ``slip_control/tracking`` (modes LINEAR [m] and ROTATIONAL [rad]).

    Attributes:
        stamp: Finger-1 twist stamp of the step [s].
        mode: Mode of the trajectory.
        ref_pos: Trajectory position [m | rad].
        ref_vel: Trajectory velocity [m/s | rad/s].
        meas_pos: Integrated measured slip [m | rad].
        meas_vel: Measured slip rate (signed when direction-aware) [m/s | rad/s].
        force_cmd: Desired grasp force sent in this step [N].
        f_slip: Filtered slip-threshold force [N].
        integral: Integral of the rate error ``E`` [m | rad].
        done: The trajectory ended in this step.
    """

    stamp: float
    mode: SlipMode
    ref_pos: float
    ref_vel: float
    meas_pos: float
    meas_vel: float
    force_cmd: float
    f_slip: float
    integral: float
    done: bool


@dataclass(frozen=True, slots=True)
class SlipResult:
    """Outcome of a LINEAR or ROTATIONAL trajectory (``ExecuteSlip`` result).

    Attributes:
        mode: The trajectory's mode.
        success: True for "done": the progress is within the tolerance of the target
            (``trajectory.position_tolerance`` / ``angle_tolerance``).
        message: "done"; failures "stalled: 4.1 of 20.0 mm" (settled short of the target at
            ``T + settle_timeout``), "timeout: …, still moving", "slip reversed", "contact
            lost", "velocity stale", "F/T stale", "preempted"; the model laws add "overshoot:
            …" and "no slip at minimum force: …".
        final_pos: Integrated progress [m | rad].
        final_error: Target − final position [m | rad].
        elapsed: Time since the start [s].
    """

    mode: SlipMode
    success: bool
    message: str
    final_pos: float
    final_error: float
    elapsed: float


@dataclass(frozen=True, slots=True)
class ControlOutput:
    """Result of one controller step.

    Attributes:
        mode: Mode whose law produced ``force`` (HOLD in the step a trajectory ends).
        force: Desired grasp force to publish [N]; ``None`` = publish nothing this step.
        timeout: Expiry to send with the command [s] (``command_timeout``).
        status: Input freshness at ``t``.
        safe_hold: Stale inputs: holding without decreasing the force.
        tracking: Tracking row (LINEAR and ROTATIONAL steps only).
        result: Set in the step a trajectory ends.
        next_controller: Controller to swap in (the HOLD successor), or ``None``.
        reason: Short human-readable note on this step (for diagnostics).
    """

    mode: SlipMode
    force: float | None
    timeout: float
    status: InputStatus
    safe_hold: bool = False
    tracking: TrackingRecord | None = None
    result: SlipResult | None = None
    next_controller: SlipController | None = None
    reason: str = ''


@dataclass(frozen=True, slots=True)
class StepInputs:
    """What a control step works on: a new, synchronised sample, combined in ``gripper_middle``.

    Attributes:
        status: Freshness and synchronisation of the inputs.
        stamp: Finger-1 twist stamp that triggered the step [s].
        wrench: Combined wrench in ``gripper_middle``.
        twist: Combined slip twist in ``gripper_middle``.
    """

    status: InputStatus
    stamp: float
    wrench: MiddleWrench
    twist: MiddleTwist


class SlipController(ABC):
    """Common interface of the mode controllers.

    Args:
        params: Controller parameters (a snapshot; a new set needs a new controller).
        contact: Contact properties (means of both fingers).
    """

    mode: ClassVar[SlipMode]
    #: Law family (``ModeRequest.control_law``) of the class; the thesis laws are these.
    control_law: ClassVar[str] = 'thesis'

    def __init__(self, params: SlipControllerParams, contact: ControlContact) -> None:
        self._p = params
        self._c = contact
        self._out: float | None = None
        self._last_stamp: float | None = None

    @property
    def params(self) -> SlipControllerParams:
        """The parameter snapshot of this controller."""
        return self._p

    @property
    def contact(self) -> ControlContact:
        """The contact properties of this controller."""
        return self._c

    @property
    def last_force(self) -> float | None:
        """Last desired force this controller produced [N] (``None`` before the first)."""
        return self._out

    @property
    def goal_active(self) -> bool:
        """A trajectory (LINEAR or ROTATIONAL) is running."""
        return False

    def reset(self, t: float) -> None:
        """Forget the stamp history after the clock jumped backwards (house style §7).

        The next sample is then treated like a first one (no ``dt``, no derivative).

        Args:
            t: Current time [s] on the new clock.
        """
        del t
        self._last_stamp = None

    def abort(self, message: str, t: float) -> SlipResult | None:
        """End a running trajectory (e.g. "preempted"); ``None`` for modes without a goal.

        Args:
            message: Result message.
            t: Time of the abort [s].
        """
        del message, t
        return None

    @abstractmethod
    def step(self, inputs: SensorSnapshot, t: float) -> ControlOutput:
        """One control step.

        Args:
            inputs: Latest samples of both fingers.
            t: Evaluation time [s] on the stamps' clock (the trigger sample's arrival or a
                watchdog tick); only used to judge staleness.

        Returns:
            The output to publish (``force`` None = nothing new to publish).
        """

    # -- helpers -------------------------------------------------------------------------

    def _assess(self, inputs: SensorSnapshot, t: float) -> InputStatus:
        p = self._p
        return assess_inputs(inputs, t, velocity_stale_after=p.velocity_stale_after,
                             ft_stale_after=p.ft_stale_after, sync_tolerance=p.sync_tolerance)

    def _emit(self, force: float | None, status: InputStatus, reason: str = '', *,
              safe_hold: bool = False, mode: SlipMode | None = None) -> ControlOutput:
        return ControlOutput(mode=self.mode if mode is None else mode, force=force,
                             timeout=self._p.command_timeout, status=status,
                             safe_hold=safe_hold, reason=reason)

    def _next_sample(self, inputs: SensorSnapshot, status: InputStatus
                     ) -> ControlOutput | StepInputs:
        """The wait every law shares: a new finger-1 sample with synchronised fingers, combined
        in ``gripper_middle``; else the output that says why there is none (``_last_stamp``
        stays, so the next good sample's ``dt`` spans a skipped one)."""
        stamp = self._new_trigger(inputs)
        if stamp is None:
            return self._emit(None, status, 'no new sample')
        if not status.synced:
            return self._emit(None, status, 'finger velocities not synchronised')
        assert inputs.wrench_1 is not None and inputs.wrench_2 is not None
        assert inputs.twist_1 is not None and inputs.twist_2 is not None
        frames = self._p.frames
        return StepInputs(status, stamp,
                          combine_wrenches(frames, inputs.wrench_1, inputs.wrench_2),
                          combine_twists(frames, inputs.twist_1, inputs.twist_2))

    def _advance_stamp(self, stamp: float) -> float | None:
        """Record ``stamp`` as processed; the interval since the last one [s], or None on the
        first sample or after a gap longer than ``dt_max``."""
        dt = None if self._last_stamp is None else stamp - self._last_stamp
        self._last_stamp = stamp
        return dt if dt is not None and 0.0 < dt <= self._p.dt_max else None

    def _new_trigger(self, inputs: SensorSnapshot) -> float | None:
        """Stamp of the finger-1 twist if it was not processed yet, else ``None``."""
        tw = inputs.twist_1
        if tw is None:
            return None
        if self._last_stamp is not None and tw.stamp <= self._last_stamp:
            return None
        return tw.stamp


class OffController(SlipController):
    """OFF (mode 0): publishes nothing; the inner loop keeps the last target (§4.1)."""

    mode = SlipMode.OFF

    def __init__(self, params: SlipControllerParams,
                 contact: ControlContact | None = None) -> None:
        super().__init__(params, contact if contact is not None else ControlContact(mu_c=1.0))

    def step(self, inputs: SensorSnapshot, t: float) -> ControlOutput:
        """Report input freshness only; never a force."""
        return self._emit(None, self._assess(inputs, t), 'off')


class HoldController(SlipController):
    """HOLD (mode 4): slip avoidance with the ellipsoidal limit surface (§4.4).

    Args:
        params: Controller parameters.
        contact: Contact properties; ``r`` may be invalid only when HOLD is a safe-hold
            successor of LINEAR or HINGE (then ``D = ft``).
        initial_force: Output the fall filter starts from [N] (the previous controller's
            last force), so a hand-over never drops the force in one step.
    """

    mode = SlipMode.HOLD

    def __init__(self, params: SlipControllerParams, contact: ControlContact,
                 initial_force: float | None = None) -> None:
        super().__init__(params, contact)
        self._out = initial_force

    def hold_force(self, w: MiddleWrench, v: MiddleTwist | None) -> float:
        """Unshaped HOLD law ``f_d`` [N]; ``v = None`` means slip term 0 (stale velocity)."""
        h = self._p.hold
        f = h.margin * max(self._c.load(w) / self._c.mu_c, h.floor)
        if v is not None:
            f += h.slip_gain * self._c.slip_speed(v)
        return f

    def step(self, inputs: SensorSnapshot, t: float) -> ControlOutput:
        """HOLD law with rise-at-once / first-order-fall shaping and the stale rules."""
        st = self._assess(inputs, t)
        frames = self._p.frames
        if not st.ft_fresh:
            # Never lower the force, and raise it to the HOLD law on the last wrench received:
            # a HOLD that takes over from a slip mode would otherwise keep its low slip force
            # (0.6 N floor) and drop the object (found by the in-process evaluation).
            w1, w2 = inputs.wrench_1, inputs.wrench_2
            if w1 is not None and w2 is not None and all(
                    math.isfinite(x) for x in (w1.fx, w1.fy, w1.tz, w2.fx, w2.fy, w2.tz)):
                f = self.hold_force(combine_wrenches(frames, w1, w2), None)
                self._out = f if self._out is None else max(self._out, f)
            return self._emit(self._out, st, 'F/T stale: holding, never decreasing',
                              safe_hold=True)
        if not st.velocity_fresh:
            assert inputs.wrench_1 is not None and inputs.wrench_2 is not None
            w = combine_wrenches(frames, inputs.wrench_1, inputs.wrench_2)
            f = self.hold_force(w, None)
            self._out = f if self._out is None else max(self._out, f)
            return self._emit(self._out, st, 'velocity stale: slip term 0, no decrease',
                              safe_hold=True)
        sample = self._next_sample(inputs, st)
        if isinstance(sample, ControlOutput):
            return sample
        self._advance_stamp(sample.stamp)
        f_d = self.hold_force(sample.wrench, sample.twist)
        out = self._out
        if out is None or f_d >= out:
            out = f_d
        else:
            a = self._p.hold.fall_filter
            out = a * out + (1.0 - a) * f_d
        self._out = out
        return self._emit(out, st)


class HingeController(SlipController):
    """HINGE (mode 3): stop translation, let the object pivot (§4.7). No stop condition.

    Args:
        params: Controller parameters.
        contact: Contact properties (``μ_c`` used).
        initial_force: Last force of the controller this one replaces [N] (handed on to the
            HOLD successor if the inputs go stale before the first hinge step).
    """

    mode = SlipMode.HINGE

    def __init__(self, params: SlipControllerParams, contact: ControlContact,
                 initial_force: float | None = None) -> None:
        super().__init__(params, contact)
        self._out = initial_force

    def step(self, inputs: SensorSnapshot, t: float) -> ControlOutput:
        """Hinge law; stale inputs hand over to HOLD (safe hold) in the same step."""
        st = self._assess(inputs, t)
        if not (st.velocity_fresh and st.ft_fresh):
            hold = HoldController(self._p, self._c, initial_force=self._out)
            out = hold.step(inputs, t)
            why = 'velocity stale' if not st.velocity_fresh else 'F/T stale'
            return replace(out, next_controller=hold, reason=f'HINGE ended: {why}')
        sample = self._next_sample(inputs, st)
        if isinstance(sample, ControlOutput):
            return sample
        self._advance_stamp(sample.stamp)
        w, v = sample.wrench, sample.twist
        h = self._p.hinge
        self._out = max(h.floor, h.threshold * w.tangential_force / self._c.mu_c
                        + h.slip_gain * v.speed)
        return self._emit(self._out, st)


class TrajectoryController(SlipController):
    """Shared machinery of the LINEAR and ROTATIONAL laws (thesis and model): trajectory,
    progress from the fingers' travel, the common stop rules, results and the HOLD hand-over.

    Args:
        params: Controller parameters.
        contact: Contact properties.
        target: Distance [m] or signed angle [rad]; progress is measured along its sign.
        duration: Trajectory time ``T`` [s].
        t_start: Start time [s] (same clock as the stamps).
    """

    #: Unit of the progress in result messages and its scale from SI (mm or deg).
    unit: ClassVar[tuple[str, float]] = ('mm', 1000.0)

    def __init__(self, params: SlipControllerParams, contact: ControlContact, target: float,
                 duration: float, t_start: float) -> None:
        super().__init__(params, contact)
        self._target = abs(target)
        self._traj = TrapezoidalTrajectory(self._target, duration,
                                           params.trajectory.accel_fraction)
        self._t_start = t_start
        self._x = 0.0              # integrated progress [m | rad]
        self._travel_ref: tuple[Travel, Travel] | None = None   # finger travel at the last step
        self._reverse_since: float | None = None
        self._lost_since: float | None = None
        self._elapsed = 0.0
        self._done = False
        self._successor: HoldController | None = None

    # mode-specific pieces ------------------------------------------------------------------

    @abstractmethod
    def _progress_increment(self, d: MiddleTwist) -> float:
        """Progress [m | rad] of a middle-frame displacement ``d`` (fields are m, m, rad)."""

    @abstractmethod
    def _reversed(self, rate: float) -> bool:
        """The signed progress rate counts as reversed."""

    @abstractmethod
    def _tolerance(self) -> float:
        """Largest ``|P − x|`` that counts as reached [m | rad]."""

    # public --------------------------------------------------------------------------------

    @property
    def goal_active(self) -> bool:
        return not self._done

    @property
    def target(self) -> float:
        """Commanded distance or angle magnitude ``P`` [m | rad]."""
        return self._target

    @property
    def trajectory(self) -> TrapezoidalTrajectory:
        """The reference trajectory."""
        return self._traj

    @property
    def progress(self) -> float:
        """Integrated progress ``x`` or ``θ`` [m | rad]."""
        return self._x

    def reset(self, t: float) -> None:
        """Clock jumped backwards: keep progress and integrals, re-base the trajectory time.

        Args:
            t: Current time [s] on the new clock; the trajectory continues from its elapsed
                time.
        """
        super().reset(t)
        self._t_start = t - self._elapsed
        self._reverse_since = None
        self._lost_since = None

    def abort(self, message: str, t: float) -> SlipResult | None:
        """End the trajectory without a successor (the caller installs the next mode)."""
        if self._done:
            return None
        self._done = True
        return self._result(False, message, max(self._elapsed, t - self._t_start))

    # internals -----------------------------------------------------------------------------

    def _advance_progress(self, inputs: SensorSnapshot) -> None:
        """Add the travel since the last step to the progress.

        Progress comes from the fingers' integrated travel, not rate·dt: exact even when a step
        did not see every sample (skipped unsynchronised steps, executor backlog).
        """
        travel = (inputs.travel_1, inputs.travel_2)
        if self._travel_ref is not None:
            self._x += self._progress_increment(
                middle_travel_delta(self._p.frames, self._travel_ref, travel))
        self._travel_ref = travel

    @staticmethod
    def _held_for(since: float | None, active: bool, stamp: float, hold_time: float
                  ) -> tuple[float | None, bool]:
        """Debounce: ``(new since, condition held for longer than hold_time)``."""
        if not active:
            return None, False
        if since is None:
            return stamp, False
        return since, stamp - since > hold_time

    def _common_stops(self, stamp: float, rate: float, w: MiddleWrench) -> str:
        """Failures every trajectory law shares (§4.9): "contact lost", "slip reversed" or ''.

        A dropped object reads as zero slip speed and would look "settled", so a normal force
        below ``contact_lost_force`` (pads closing on nothing) for ``contact_lost_time`` ends
        the trajectory first, as a failure.
        """
        p = self._p
        self._lost_since, lost = self._held_for(
            self._lost_since, w.normal_force < p.contact_lost_force, stamp, p.contact_lost_time)
        if lost:
            return 'contact lost'
        self._reverse_since, reversed_ = self._held_for(
            self._reverse_since, p.direction_aware and self._reversed(rate), stamp,
            p.reversal.time)
        if reversed_:
            return 'slip reversed'
        return ''

    def _reached(self) -> bool:
        """The progress is within the tolerance of the target."""
        return abs(self._target - self._x) <= self._tolerance()

    def _shortfall(self, kind: str, suffix: str = '') -> str:
        """``'<kind>: 4.1 of 20.0 mm<suffix>'`` (progress against the target)."""
        name, scale = self.unit
        return (f'{kind}: {self._x * scale:.1f} of {self._target * scale:.1f} {name}'
                f'{suffix}')

    def _result(self, success: bool, message: str, elapsed: float) -> SlipResult:
        return SlipResult(mode=self.mode, success=success, message=message,
                          final_pos=self._x, final_error=self._target - self._x,
                          elapsed=elapsed)

    def _gate_step(self, inputs: SensorSnapshot, t: float) -> ControlOutput | StepInputs:
        """The common start of a step: the HOLD successor once finished, the end on stale
        inputs, and waiting for a new synchronised finger-1 sample; else the step's inputs."""
        if self._done:
            if self._successor is not None:
                return self._successor.step(inputs, t)
            return self._emit(None, self._assess(inputs, t), 'finished')
        st = self._assess(inputs, t)
        if not st.velocity_fresh:
            return self._finish(inputs, t, False, 'velocity stale', t - self._t_start, None)
        if not st.ft_fresh:
            return self._finish(inputs, t, False, 'F/T stale', t - self._t_start, None)
        return self._next_sample(inputs, st)

    def _finish(self, inputs: SensorSnapshot, t: float, success: bool, message: str,
                elapsed: float, track: TrackingRecord | None) -> ControlOutput:
        """End the trajectory and run the HOLD successor on the same inputs (§4.1)."""
        self._done = True
        result = self._result(success, message, elapsed)
        hold = HoldController(self._p, self._c, initial_force=self._out)
        self._successor = hold
        out = hold.step(inputs, t)
        if track is not None and out.force is not None:
            track = replace(track, force_cmd=out.force)
        return replace(out, tracking=track, result=result, next_controller=hold,
                       reason=f'{self.mode.name} ended: {message}')


class _ThesisTrajectory(TrajectoryController):
    """The thesis laws of LINEAR and ROTATIONAL (§4.5, §4.6): integrators and stop rule."""

    def __init__(self, params: SlipControllerParams, contact: ControlContact, target: float,
                 duration: float, t_start: float) -> None:
        super().__init__(params, contact, target, duration, t_start)
        self._integral = 0.0       # E [m | rad]
        self._f_slip: float | None = None
        self._v_prev: float | None = None

    # mode-specific pieces ------------------------------------------------------------------

    @abstractmethod
    def _progress_rate(self, v: MiddleTwist) -> float:
        """Signed (or magnitude) progress rate of this step [m/s | rad/s]; may latch."""

    @abstractmethod
    def _slip_ratio(self, w: MiddleWrench) -> float:
        """Slip-threshold force of this step [N] (``ft/μ_c`` or ``D/μ_c``)."""

    @abstractmethod
    def _gains(self) -> tuple[float, float, float, float, float, float, float]:
        """``(kp, ki, kd, k_rate, slip_filter, floor, accel_gate)``."""

    @abstractmethod
    def _extra_floor(self, w: MiddleWrench, v: MiddleTwist) -> float:
        """Additional force floor [N] (ROTATIONAL translation floor; 0 for LINEAR)."""

    @abstractmethod
    def _stop_threshold(self) -> float:
        """``stop_speed`` or ``stop_rate``."""

    def reset(self, t: float) -> None:
        super().reset(t)
        self._v_prev = None

    def step(self, inputs: SensorSnapshot, t: float) -> ControlOutput:
        """One LINEAR/ROTATIONAL step (§4.5/§4.6) with the stop conditions of §4.9."""
        gated = self._gate_step(inputs, t)
        if isinstance(gated, ControlOutput):
            return gated
        st, stamp, w, v = gated.status, gated.stamp, gated.wrench, gated.twist

        dt = None if self._last_stamp is None else stamp - self._last_stamp
        dt_ok = dt is not None and 0.0 < dt <= self._p.dt_max
        self._last_stamp = stamp
        tau = stamp - self._t_start
        self._elapsed = tau
        kp, ki, kd, k_rate, a, floor, gate = self._gains()

        rate = self._progress_rate(v)
        self._advance_progress(inputs)
        x_d, v_d = self._traj.sample(tau)
        v_cmd = v_d + kp * (x_d - self._x)
        acc = 0.0
        if dt_ok and self._v_prev is not None:
            assert dt is not None
            acc = (rate - self._v_prev) / dt
        ratio = self._slip_ratio(w)
        if self._f_slip is None:
            self._f_slip = ratio
        elif dt_ok and acc < gate:
            self._f_slip = a * self._f_slip + (1.0 - a) * ratio
        if dt_ok:
            assert dt is not None
            self._integral += (v_cmd - rate) * dt
        f_slip = self._f_slip
        f_d = (f_slip - ki * self._integral + kd * f_slip * acc
               + k_rate * f_slip * (rate - v_cmd))
        f_d = max(f_d, self._extra_floor(w, v), floor)
        self._v_prev = rate
        self._out = f_d

        message, success = self._stop_condition(stamp, tau, rate, w)
        track = TrackingRecord(stamp=stamp, mode=self.mode, ref_pos=x_d, ref_vel=v_d,
                               meas_pos=self._x, meas_vel=rate, force_cmd=f_d, f_slip=f_slip,
                               integral=self._integral, done=bool(message))
        if message:
            return self._finish(inputs, t, success, message, tau, track)
        return ControlOutput(mode=self.mode, force=f_d, timeout=self._p.command_timeout,
                             status=st, tracking=track)

    def _stop_condition(self, stamp: float, tau: float, rate: float, w: MiddleWrench
                        ) -> tuple[str, bool]:
        """Stop conditions (§4.9, CE-5): ``(message, success)``, ``('', False)`` to go on.

        Thresholds only, never float equality. The thesis rule ends at ``x ≥ P`` (early when the
        object runs ahead) or once settled after ``T``; "done" (success) needs the progress
        within the tolerance of the target. Settled short of it, the law keeps acting until
        ``T + settle_timeout``, then ends "stalled: x of P" (or "timeout: …, still moving").
        """
        failure = self._common_stops(stamp, rate, w)
        if failure:
            return failure, False
        settled = abs(rate) < self._stop_threshold()
        if self._x >= self._target or (tau >= self._traj.duration and settled
                                       and self._reached()):
            return 'done', True
        if tau >= self._traj.duration + self._p.settle_timeout:
            if not settled:
                return self._shortfall('timeout', ', still moving'), False
            floor = self._gains()[5]
            at_floor = self._out is not None and self._out <= floor * (1.0 + 1e-9)
            return self._shortfall('stalled at the minimum force' if at_floor
                                   else 'stalled'), False
        return '', False


class LinearController(_ThesisTrajectory):
    """LINEAR (mode 2): slide a distance along a trapezoid (§4.5, §4.2, §4.9).

    Args:
        params: Controller parameters.
        contact: Contact properties (``μ_c`` used; ``r`` only for the HOLD successor).
        distance: ``P`` [m], > 0.
        duration: ``T`` [s], > 0.
        t_start: Start time [s].
        direction: Commanded slip direction ``ê`` in ``gripper_middle`` xy (normalised here),
            or ``None`` to latch it from the first motion with ``‖v̄‖ ≥ latch_speed``.
    """

    mode = SlipMode.LINEAR

    def __init__(self, params: SlipControllerParams, contact: ControlContact,
                 distance: float, duration: float, t_start: float,
                 direction: tuple[float, float] | None = None) -> None:
        super().__init__(params, contact, distance, duration, t_start)
        self._e: tuple[float, float] | None = None
        if direction is not None:
            n = math.hypot(direction[0], direction[1])
            if not n > 0.0:
                raise ValueError('direction must be a non-zero xy vector (or None to latch)')
            self._e = (direction[0] / n, direction[1] / n)

    @property
    def direction(self) -> tuple[float, float] | None:
        """Slip direction ``ê`` (commanded or latched), ``None`` before latching."""
        return self._e

    def _progress_rate(self, v: MiddleTwist) -> float:
        if not self._p.direction_aware:
            return v.speed
        e = self._e
        if e is None:
            s = v.speed
            if s >= self._p.latch_speed:
                self._e = (v.vx / s, v.vy / s)
            return s
        return v.vx * e[0] + v.vy * e[1]

    def _progress_increment(self, d: MiddleTwist) -> float:
        e = self._e
        if not self._p.direction_aware or e is None:
            return d.speed
        return d.vx * e[0] + d.vy * e[1]

    def _slip_ratio(self, w: MiddleWrench) -> float:
        return w.tangential_force / self._c.mu_c

    def _gains(self) -> tuple[float, float, float, float, float, float, float]:
        g = self._p.linear
        return g.kp, g.ki, g.kd, g.kv, g.slip_filter, g.floor, g.accel_gate

    def _extra_floor(self, w: MiddleWrench, v: MiddleTwist) -> float:
        return 0.0

    def _reversed(self, rate: float) -> bool:
        return self._e is not None and rate < -self._p.reversal.speed

    def _stop_threshold(self) -> float:
        return self._p.linear.stop_speed

    def _tolerance(self) -> float:
        return self._p.trajectory.position_tolerance


class RotationalController(_ThesisTrajectory):
    """ROTATIONAL (mode 1): rotate the object an angle along a trapezoid (§4.6, §4.2, §4.9).

    Args:
        params: Controller parameters.
        contact: Contact properties (``μ_c`` and a valid ``r``).
        angle: Signed angle about ``gripper_middle`` +z [rad], ``|angle| > 0``.
        duration: ``T`` [s], > 0.
        t_start: Start time [s].
        latch: Take the sign from the first rotation with ``|ω̄| ≥ latch_rate`` instead of
            from ``angle``.
    """

    mode = SlipMode.ROTATIONAL
    unit = ('deg', 180.0 / math.pi)

    def __init__(self, params: SlipControllerParams, contact: ControlContact, angle: float,
                 duration: float, t_start: float, latch: bool = False) -> None:
        if not contact.r_valid:
            raise ValueError('ROTATIONAL needs a valid torsional radius r')
        super().__init__(params, contact, angle, duration, t_start)
        self._sigma: float | None = None if latch else math.copysign(1.0, angle)

    @property
    def sign(self) -> float | None:
        """Rotation sign ``σ`` (commanded or latched), ``None`` before latching."""
        return self._sigma

    def _progress_rate(self, v: MiddleTwist) -> float:
        if not self._p.direction_aware:
            return abs(v.omega)
        s = self._sigma
        if s is None:
            if abs(v.omega) >= self._p.latch_rate:
                self._sigma = math.copysign(1.0, v.omega)
            return abs(v.omega)
        return s * v.omega

    def _progress_increment(self, d: MiddleTwist) -> float:
        s = self._sigma
        if not self._p.direction_aware or s is None:
            return abs(d.omega)
        return s * d.omega

    def _slip_ratio(self, w: MiddleWrench) -> float:
        return self._c.load(w) / self._c.mu_c

    def _gains(self) -> tuple[float, float, float, float, float, float, float]:
        g = self._p.rotational
        return g.kp, g.ki, g.kd, g.kw, g.slip_filter, g.floor, g.accel_gate

    def _extra_floor(self, w: MiddleWrench, v: MiddleTwist) -> float:
        """Translation floor: ``margin·ft/μ_c`` + translation-speed term + kp_cop term [N].

        While a pad turns on an elliptical limit surface under tangential load ``ft``, its
        centre of rotation sits ``c = u/sqrt(1 − u²)·r`` from the pad centre (``u = ft/μN``):
        at the bare floor ``ft/μ_c`` (u → 1) the grasp point slides away as the object turns.
        The translation-speed term adds ``translation_gain·max(0, |v| − cor_limit·r·|ω|)``,
        i.e. force only for translation beyond what a centre of rotation ``cor_limit·r`` away
        explains; it has no division, so it cannot spike when ω crosses zero. The spec's
        ``kp_cop·max(0, ‖c‖ − r)`` (``‖c‖ = |v|/(|ω| + 1e-3)``) does spike there, so it is
        applied only while ``|ω| ≥ cop_min_rate`` and capped at ``cop_max_force``.
        """
        g = self._p.rotational
        f = g.translation_margin * w.tangential_force / self._c.mu_c
        omega = abs(v.omega)
        if g.kp_cop > 0.0 and omega >= g.cop_min_rate:
            c = v.speed / (omega + OMEGA_GUARD)
            f += min(g.kp_cop * max(0.0, c - self._c.r_guarded), g.cop_max_force)
        if g.translation_gain > 0.0:
            excess = v.speed - g.cor_limit * self._c.r_guarded * omega
            f += g.translation_gain * max(0.0, excess)
        return f

    def _reversed(self, rate: float) -> bool:
        return self._sigma is not None and rate < -self._p.reversal.rate

    def _stop_threshold(self) -> float:
        return self._p.rotational.stop_rate

    def _tolerance(self) -> float:
        return self._p.trajectory.angle_tolerance
