# SPDX-License-Identifier: Apache-2.0
"""The cores as harness agents: what the nodes do, on the simulated cell's events (SI units).

* `SensorInputs` turns the cell's F/T records (bias removed) and velocity lines into the
  cores' samples, as a node's subscriptions do, and can *cut* a stream at a time (fault
  injection: the samples stop reaching the consumer; the gripper's own inner loop keeps its
  F/T, as when a topic stops);
* `EstimatorAgent` steps the contact estimator on every finger-1 twist and polls it on every
  telemetry line (phase windows close on time), with the node's start pre-check
  (`start_precheck`: "no contact" is refused, never defaulted);
* `ControllerAgent` runs the ``slip_controller`` node's own host,
  `slip_control.core.controller_host.ControllerHost` (input snapshot, stale debounce, mode
  switching, HOLD successors): a step on every finger-1 twist and from a watchdog every
  ``watchdog_period`` of sim time (the node's timer); each force goes through
  ``harness.command_force(force, timeout)``. Stale verdicts are confirmed on sim time, the
  monotonic clock of this process (the in-process cell has no executor backlog).
"""
from __future__ import annotations

import dataclasses
import math

from friction_models.core.harness import Harness, HarnessError
from friction_models.core.sensors import FtSample, TelemetrySample, VelocitySample

from slip_bringup.core.evaluation.settings import EvaluationError
from slip_control.core import mode_switch
from slip_control.core.contact import ContactProperties
from slip_control.core.contact_estimator import (ContactEstimator, EstimationPhase,
                                                 EstimatorReport, StartOutcome, start_precheck)
from slip_control.core.controller_host import WATCHDOG_PERIOD_S, ControllerHost
from slip_control.core.controllers import ControlOutput, SlipMode, SlipResult, TrackingRecord
from slip_control.core.mode_switch import ModeRequest, SwitchOutcome
from slip_control.core.params import ContactEstimatorParams, SlipControllerParams
from slip_control.core.signals import SensorSnapshot, TwistSample, WrenchSample

_INF = math.inf
#: Fields of this build's mode request (a ``control_law`` family selector may be among them).
_REQUEST_FIELDS = frozenset(f.name for f in dataclasses.fields(ModeRequest))


def law_for(mode: int, family: str) -> str:
    """The ``control_law`` to put on a request of ``mode`` for ``family``: the family where
    the mode has it (``mode_switch.CONTROLLERS``), else '' (the controller's default, which
    falls back to the thesis law); '' for OFF."""
    if not family or mode == int(SlipMode.OFF):
        return ''
    registry = getattr(mode_switch, 'CONTROLLERS', None)
    if registry is None:
        return family
    try:
        key = (SlipMode(mode), family)
    except ValueError:
        return family                     # an invalid mode: let the controller refuse it
    return family if key in registry else ''


class SensorInputs:
    """Cell sensor events → core samples (what a node's subscriptions do).

    F/T records without a host bias are ignored (the driver publishes bias-removed wrenches
    only). `cut_ft` / `cut_velocity` stop delivering a stream from a time on (stamps ≥ t).
    Subclasses consume the samples in `take_wrench` and `take_twist`.
    """

    def __init__(self) -> None:
        self.ft_cut = _INF
        self.velocity_cut = _INF

    def cut_ft(self, t: float) -> None:
        """Deliver no F/T sample stamped at or after ``t`` [s]."""
        self.ft_cut = t

    def cut_velocity(self, t: float) -> None:
        """Deliver no velocity sample stamped at or after ``t`` [s]."""
        self.velocity_cut = t

    def on_ft(self, harness: Harness, sample: FtSample) -> None:
        """Deliver the finger's wrench (bias removed, ``ft_sensor_k``)."""
        b = sample.biased
        if b is None or sample.stamp >= self.ft_cut:
            return
        self.take_wrench(harness, sample.finger,
                         WrenchSample(b[0], b[1], b[2], b[5], sample.stamp, b[3], b[4]))

    def on_velocity(self, harness: Harness, sample: VelocitySample) -> None:
        """Deliver the finger's twist (``vel_sensor_k``)."""
        if sample.stamp >= self.velocity_cut:
            return
        self.take_twist(harness, sample.finger, TwistSample(sample.vx, sample.vy, sample.omega,
                                                            sample.stamp, sample.valid))

    def take_wrench(self, harness: Harness, finger: int, sample: WrenchSample) -> None:
        """A delivered wrench (override)."""

    def take_twist(self, harness: Harness, finger: int, sample: TwistSample) -> None:
        """A delivered twist (override)."""


class EstimatorAgent(SensorInputs):
    """The contact estimator as the node runs it: step on finger-1 twists, poll on time.

    Args:
        params: Estimator parameters.
        initial: Initial property set (default: the DEFAULT placeholder, never valid).
    """

    def __init__(self, params: ContactEstimatorParams = ContactEstimatorParams(),
                 initial: ContactProperties | None = None) -> None:
        super().__init__()
        self.snapshot = SensorSnapshot()
        self.estimator = ContactEstimator(params, initial)
        self.reports: list[EstimatorReport] = []
        self.starts: list[StartOutcome] = []

    def start(self, harness: Harness, phase: EstimationPhase, duration: float, *,
              precheck: bool = True) -> StartOutcome:
        """``StartEstimation`` at the current sim time.

        Args:
            harness: The harness (its time is the request time).
            phase: Phase to start.
            duration: Collection time [s].
            precheck: Refuse LINEAR/ROTATIONAL without fresh samples or contact, as the node
                does (``False`` exercises the core alone).
        """
        if precheck and phase in (EstimationPhase.LINEAR, EstimationPhase.ROTATIONAL):
            ok, message = start_precheck(self.snapshot, harness.t, self.estimator.params)
            if not ok:
                out = StartOutcome(False, message)
                self.starts.append(out)
                return out
        out = self.estimator.start(int(phase), duration, harness.t)
        if out.report is not None:
            self.reports.append(out.report)
        self.starts.append(out)
        return out

    def take_wrench(self, harness: Harness, finger: int, sample: WrenchSample) -> None:
        self.snapshot = self.snapshot.with_wrench(finger, sample)

    def take_twist(self, harness: Harness, finger: int, sample: TwistSample) -> None:
        self.snapshot = self.snapshot.with_twist(finger, sample)
        if finger == 1:
            rep = self.estimator.step(self.snapshot, harness.t)
            if rep is not None:
                self.reports.append(rep)

    def on_telemetry(self, harness: Harness, sample: TelemetrySample) -> None:
        """Close a phase whose window has passed even if no twist arrives."""
        rep = self.estimator.poll(harness.t)
        if rep is not None:
            self.reports.append(rep)


class ControllerAgent(SensorInputs):
    """The ``slip_controller`` node's host on the simulated cell (module docstring).

    Args:
        params: Controller parameters (frames must be the cell's).
        properties: Contact properties used for mode requests.
        watchdog_period: Extra steps on this period [s] so stale inputs are noticed.
        control_law: Control-law family set on every request whose mode has it (`law_for`;
            '' = leave the requests as they are); needs a ``control_law`` field on
            `ModeRequest`.

    Attributes:
        host: The `ControllerHost` (the same class the node runs).
        commands: ``(t, force)`` of every command the cell accepted [s, N].
        refused: ``(t, why)`` of commands the cell refused.
        tracking: Tracking rows of LINEAR/ROTATIONAL steps.
        results: ``(t, result)`` of every trajectory that ended.
        notes: ``(t, text)`` of the host's log lines.
        first_safe_hold: Time of the first safe-hold output since the last mode request [s].
        last_output: The last controller output.
    """

    def __init__(self, params: SlipControllerParams, properties: ContactProperties | None,
                 watchdog_period: float = WATCHDOG_PERIOD_S, control_law: str = '') -> None:
        super().__init__()
        if control_law and 'control_law' not in _REQUEST_FIELDS:
            raise EvaluationError(f'control law {control_law!r} requested, but this build\'s '
                                  'ModeRequest has no control_law field')
        self.control_law = control_law
        self._t = 0.0
        self.notes: list[tuple[float, str]] = []
        self.host = ControllerHost(params, properties,
                                   log=lambda level, text: self.notes.append((self._t, text)))
        self.watchdog_period = watchdog_period
        self._next_watchdog = -_INF
        self.commands: list[tuple[float, float]] = []
        self.refused: list[tuple[float, str]] = []
        self.tracking: list[TrackingRecord] = []
        self.results: list[tuple[float, SlipResult]] = []
        self.first_safe_hold: float | None = None
        self.last_output: ControlOutput | None = None

    @property
    def mode(self) -> SlipMode:
        """Mode of the controller in charge."""
        return self.host.mode

    @property
    def snapshot(self) -> SensorSnapshot:
        """Latest samples the host has."""
        return self.host.snapshot

    def set_mode(self, harness: Harness, request: ModeRequest) -> SwitchOutcome:
        """``SetSlipMode`` at the current sim time (validate, build, swap once; CE-2)."""
        t = self._now(harness)
        law = law_for(request.mode, self.control_law)
        if law:
            request = dataclasses.replace(request, control_law=law)
        outcome = self.host.switch(request, t)
        if not outcome.ok:
            return outcome
        if outcome.preempted is not None:
            self.results.append((t, outcome.preempted))
        if outcome.final_force is not None:
            self._command(harness, outcome.final_force, 0.0)
        self.first_safe_hold = None
        return outcome

    def require_mode(self, harness: Harness, request: ModeRequest) -> SwitchOutcome:
        """`set_mode`, raising `EvaluationError` when refused."""
        outcome = self.set_mode(harness, request)
        if not outcome.ok:
            raise EvaluationError(f'mode {request.mode} refused: {outcome.message}')
        return outcome

    def take_wrench(self, harness: Harness, finger: int, sample: WrenchSample) -> None:
        self.host.on_wrench(finger, sample)

    def take_twist(self, harness: Harness, finger: int, sample: TwistSample) -> None:
        if self.host.on_twist(finger, sample):
            self._step(harness)

    def on_telemetry(self, harness: Harness, sample: TelemetrySample) -> None:
        """Watchdog: a step every ``watchdog_period`` of sim time."""
        t = harness.t
        if t >= self._next_watchdog - 1e-9:
            if self._next_watchdog == -_INF:
                self._next_watchdog = t
            self._next_watchdog += self.watchdog_period
            self._step(harness)

    def forces_between(self, t0: float, t1: float) -> list[float]:
        """Commanded forces with ``t0 ≤ t ≤ t1`` [N]."""
        return [f for t, f in self.commands if t0 <= t <= t1]

    def _now(self, harness: Harness) -> float:
        self._t = harness.t
        self.host.observe_time(self._t)
        return self._t

    def _step(self, harness: Harness) -> None:
        t = self._now(harness)
        out = self.host.step(t, steady=t)
        if out is None:
            return                       # stale verdict being confirmed: last command stands
        self.last_output = out
        if out.force is not None:
            self._command(harness, out.force, out.timeout)
        if out.tracking is not None:
            self.tracking.append(out.tracking)
        if out.result is not None:
            self.results.append((t, out.result))
        if out.safe_hold and self.first_safe_hold is None:
            self.first_safe_hold = t

    def _command(self, harness: Harness, force: float, timeout: float) -> None:
        try:
            harness.command_force(force, timeout=timeout)
        except HarnessError as exc:     # the driver would refuse it too; keep running
            self.refused.append((harness.t, str(exc)))
            return
        self.commands.append((harness.t, force))
