# SPDX-License-Identifier: Apache-2.0
"""In-process evaluation of the contact estimator and the slip controllers (issue 7 item 4).

The real cores (`ContactEstimator`, the mode controllers built by `build_controller`) run as
agents of the friction_models `Harness` on a `SimCell`: no DDS, sim time only, deterministic
for a given `EvalSettings` (seed, physics step), and as fast as Python allows.

Agents (the node logic, minus ROS):

* `SensorInputs` turns the cell's F/T records (bias removed) and velocity lines into the
  immutable `SensorSnapshot` the cores read, and can *cut* a stream at a time (fault
  injection: the samples stop reaching the consumer; the gripper's own inner loop keeps its
  F/T, as when a topic stops);
* `EstimatorAgent` steps the estimator on every finger-1 twist and polls it on every
  telemetry line (phase windows close on time), with the node's start pre-check
  (`start_precheck`: "no contact" is refused, never defaulted);
* `ControllerAgent` steps the controller in charge on every finger-1 twist and from a
  watchdog every ``watchdog_period`` (the node's 10 ms timer), sends each force through
  ``harness.command_force(force, timeout)``, swaps in HOLD successors, and records commands,
  tracking rows, results and the first safe-hold time.

Scenarios (each builds its own cell, homes and biases it; SI units throughout):

* `estimate` — the §3.8 exploration (10 N, 5 N, linear phase 1 s over the 1 cm descent,
  rotational phase 1 s over the ±10° twist, release) → estimated vs true ``μ_c``, ``r``;
* `pick_up` — grasp 10 N on the table, HOLD, lift 0.20 m (§5.3 ``pick_up_object``);
* `hold_under_disturbance` — object held in the air under HOLD, external pushes on its CoM;
* `linear_slip`, `rotational_slip` — LINEAR (latched direction, as the runner sends it) and
  ROTATIONAL slips from an object held in the air under HOLD; for rotation the gripper first
  turns the object ``tilt`` (90°) away from hanging (with HOLD), so that gravity drives the
  slip;
* `hinge` — HOLD to the hinge pose (+60°), HINGE, the gripper turns another 60°, HOLD;
* `stream_fault` — a sensor stream stops in the middle of a LINEAR slip;
* `estimate_without_contact` — the estimator is asked to explore with the gripper open and
  nothing between the fingers.

Every outcome is a frozen dataclass of physical quantities taken from the **simulator truth**
(`SimCell.state`: the grasp-relative pose ``x, y, θ`` of the object in ``gripper_middle``,
``dropped``, normal forces) next to what the sensors and the controller itself reported.
`evaluate_all` runs the table of issue 7 item 4 for the reference presets; `format_table`
prints it (CLI: ``slip_evaluate``).

Contact properties for the controller scenarios: by default the simulator's true per-finger
values (source ``GROUND_TRUTH``, flags from the estimator's plausibility limits), so a
controller scenario does not depend on the estimator; `evaluate_all` passes the properties
estimated in the same run (the real pipeline) unless told otherwise.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TypeVar

from friction_models.core.harness import Harness, HarnessError, default_motion_time
from friction_models.core.presets import ObjectPreset, load_presets, reference_presets
from friction_models.core.sensors import (FtSample, TelemetrySample, VelocitySample,
                                          VelocitySensorParams)
from friction_models.core.sim_cell import SimCell, SimParams

from slip_control.core.contact import ContactProperties, ContactSource
from slip_control.core.controllers import (ControlOutput, OffController, SlipController,
                                           SlipMode, SlipResult, TrackingRecord)
from slip_control.core.estimator import (ContactEstimator, EstimationPhase, EstimatorReport,
                                         StartOutcome, preset_finger, start_precheck)
from slip_control.core.mode_switch import ModeRequest, SwitchOutcome, build_controller
from slip_control.core.params import ContactEstimatorParams, SlipControllerParams
from slip_control.core.signals import SensorSnapshot, TwistSample, WrenchSample

__all__ = [
    'REFERENCE_PRESETS',
    'ControllerAgent',
    'EstimationOutcome',
    'EstimatorAgent',
    'EvalSettings',
    'EvaluationError',
    'FaultOutcome',
    'FingerEstimate',
    'HingeOutcome',
    'HoldOutcome',
    'NoContactOutcome',
    'OnlineOutcome',
    'PickUpOutcome',
    'PresetEvaluation',
    'Push',
    'SensorInputs',
    'TrajectoryOutcome',
    'TruthProbe',
    'DEFAULT_PUSHES',
    'LINEAR_CASES',
    'ONLINE_START_SCALES',
    'ROTATIONAL_CASES',
    'TAP_MAX_DURATION',
    'estimate',
    'estimate_without_contact',
    'evaluate_all',
    'evaluate_preset',
    'format_online_table',
    'format_table',
    'hinge',
    'hold_under_disturbance',
    'linear_slip',
    'make_harness',
    'online_refinement',
    'pick_up',
    'rotational_slip',
    'stream_fault',
    'true_properties',
]

#: The four reference objects of control_and_estimation §3.9, in table order.
REFERENCE_PRESETS: tuple[str, ...] = ('plastic', 'wood', 'case', 'cardboard')

_INF = math.inf
_NAN = math.nan
_T = TypeVar('_T')


class EvaluationError(RuntimeError):
    """A scenario could not be set up (a mode or a phase was refused; the message says why)."""


# ---------------------------------------------------------------------------------------------
# Settings and cell construction
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class EvalSettings:
    """How the cell and the cores are run (SI).

    Attributes:
        physics_dt: Physics step [s]. 1 ms here (the node runs 0.1 ms): about 8× faster, and
            the outcomes differ from those at 0.1 ms by far less than the test tolerances
            (compared when this module was written; the cell is stable for any step).
        seed: Seed of the cell's sensor noise.
        velocity_model: ``'chips'`` (quantised device chain) or ``'ideal'``.
        chunk: Harness chunk [s]: the transport latency between a sensor event and a command.
        watchdog_period: Period of the controller's watchdog step [s] (node: 0.01).
        settle: HOLD time before a controller scenario starts [s].
        presets_file: Extra presets YAML (friction_models format); '' = reference objects only.
        controller: Slip-controller parameters (``frames`` are replaced by the cell's).
        estimator: Estimator parameters.
    """

    physics_dt: float = 1.0e-3
    seed: int = 0
    velocity_model: str = 'chips'
    chunk: float = 1.0e-3
    watchdog_period: float = 0.01
    settle: float = 1.0
    presets_file: str = ''
    controller: SlipControllerParams = field(default_factory=SlipControllerParams)
    estimator: ContactEstimatorParams = field(default_factory=ContactEstimatorParams)


def _presets(settings: EvalSettings) -> dict[str, ObjectPreset]:
    if settings.presets_file:
        return load_presets(settings.presets_file)
    return reference_presets()


def make_harness(preset: str, settings: EvalSettings = EvalSettings()) -> Harness:
    """A homed, biased cell with ``preset`` on the table at the pick-up pose, fingers open.

    Raises:
        KeyError: Unknown preset (the message lists the known ones).
    """
    params = SimParams(physics_dt=settings.physics_dt, seed=settings.seed,
                       velocity_sensor=VelocitySensorParams(model=settings.velocity_model))
    cell = SimCell(params, _presets(settings), preset)
    h = Harness(cell, chunk=settings.chunk)
    h.home()
    h.bias()
    return h


def true_properties(cell: SimCell, params: ContactEstimatorParams = ContactEstimatorParams()
                    ) -> ContactProperties:
    """The cell's per-finger contact parameters as a ``GROUND_TRUTH`` property set.

    Flags come from the estimator's plausibility limits (`preset_finger`), so a truth outside
    them is marked invalid exactly like an estimate would be.
    """
    fingers = []
    for c in cell.true_contact():
        fingers.append(preset_finger({'mu_c': c.mu_c, 'mu_s': c.mu_s, 'mu_v': c.mu_v,
                                      'r': c.r}, params))
    return ContactProperties(fingers[0], fingers[1], ContactSource.GROUND_TRUTH,
                             preset_name=cell.preset.name)


def _controller_params(settings: EvalSettings, cell: SimCell) -> SlipControllerParams:
    """The controller parameters with the cell's frame constants (one cell.yaml in the graph)."""
    return replace(settings.controller, frames=cell.params.frames)


# ---------------------------------------------------------------------------------------------
# Agents
# ---------------------------------------------------------------------------------------------

class SensorInputs:
    """Cell sensor events → the cores' `SensorSnapshot` (what a node's subscriptions do).

    F/T records without a host bias are ignored (the driver publishes bias-removed wrenches
    only). `cut_ft` / `cut_velocity` stop delivering a stream from a time on (stamps ≥ t).
    """

    def __init__(self) -> None:
        self.snapshot = SensorSnapshot()
        self.ft_cut = _INF
        self.velocity_cut = _INF

    def cut_ft(self, t: float) -> None:
        """Deliver no F/T sample stamped at or after ``t`` [s]."""
        self.ft_cut = t

    def cut_velocity(self, t: float) -> None:
        """Deliver no velocity sample stamped at or after ``t`` [s]."""
        self.velocity_cut = t

    def on_ft(self, harness: Harness, sample: FtSample) -> None:
        """Replace the finger's wrench (bias removed, ``ft_sensor_k``)."""
        b = sample.biased
        if b is None or sample.stamp >= self.ft_cut:
            return
        self.snapshot = self.snapshot.with_wrench(
            sample.finger, WrenchSample(b[0], b[1], b[2], b[5], sample.stamp))

    def on_velocity(self, harness: Harness, sample: VelocitySample) -> None:
        """Replace the finger's twist; a finger-1 twist triggers a step."""
        if sample.stamp >= self.velocity_cut:
            return
        self.snapshot = self.snapshot.with_twist(
            sample.finger, TwistSample(sample.vx, sample.vy, sample.omega, sample.stamp,
                                       sample.valid))
        if sample.finger == 1:
            self.trigger(harness)

    def trigger(self, harness: Harness) -> None:
        """Called on every delivered finger-1 twist (override)."""


class EstimatorAgent(SensorInputs):
    """The contact estimator as the node runs it: step on finger-1 twists, poll on time.

    Args:
        params: Estimator parameters.
        initial: Initial property set (default: the DEFAULT placeholder, never valid).
    """

    def __init__(self, params: ContactEstimatorParams = ContactEstimatorParams(),
                 initial: ContactProperties | None = None) -> None:
        super().__init__()
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

    def trigger(self, harness: Harness) -> None:
        rep = self.estimator.step(self.snapshot, harness.t)
        if rep is not None:
            self.reports.append(rep)

    def on_telemetry(self, harness: Harness, sample: TelemetrySample) -> None:
        """Close a phase whose window has passed even if no twist arrives."""
        rep = self.estimator.poll(harness.t)
        if rep is not None:
            self.reports.append(rep)


class ControllerAgent(SensorInputs):
    """The slip controller as the node runs it (one controller object in charge).

    Args:
        params: Controller parameters (frames must be the cell's).
        properties: Contact properties used for mode requests.
        watchdog_period: Extra steps on this period [s] so stale inputs are noticed.
    """

    def __init__(self, params: SlipControllerParams, properties: ContactProperties | None,
                 watchdog_period: float = 0.01) -> None:
        super().__init__()
        self.params = params
        self.properties = properties
        self.controller: SlipController = OffController(params)
        self.watchdog_period = watchdog_period
        self._next_watchdog = -_INF
        self.commands: list[tuple[float, float]] = []
        self.refused: list[tuple[float, str]] = []
        self.tracking: list[TrackingRecord] = []
        self.results: list[tuple[float, SlipResult]] = []
        self.notes: list[tuple[float, str]] = []
        self.first_safe_hold: float | None = None
        self.last_output: ControlOutput | None = None

    @property
    def mode(self) -> SlipMode:
        """Mode of the controller in charge."""
        return self.controller.mode

    def set_mode(self, harness: Harness, request: ModeRequest) -> SwitchOutcome:
        """``SetSlipMode`` at the current sim time (validate, build, swap once; CE-2)."""
        t = harness.t
        outcome = build_controller(request, self.properties, self.params, t,
                                   previous=self.controller)
        if not outcome.ok:
            self.notes.append((t, f'refused: {outcome.message}'))
            return outcome
        if outcome.preempted is not None:
            self.results.append((t, outcome.preempted))
        if outcome.final_force is not None:
            self._command(harness, outcome.final_force, 0.0)
        assert outcome.controller is not None
        self.controller = outcome.controller
        self.first_safe_hold = None
        self.notes.append((t, outcome.message))
        return outcome

    def require_mode(self, harness: Harness, request: ModeRequest) -> SwitchOutcome:
        """`set_mode`, raising `EvaluationError` when refused."""
        outcome = self.set_mode(harness, request)
        if not outcome.ok:
            raise EvaluationError(f'mode {request.mode} refused: {outcome.message}')
        return outcome

    def trigger(self, harness: Harness) -> None:
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

    def _step(self, harness: Harness) -> None:
        t = harness.t
        out = self.controller.step(self.snapshot, t)
        self.last_output = out
        if out.force is not None:
            self._command(harness, out.force, out.timeout)
        if out.tracking is not None:
            self.tracking.append(out.tracking)
        if out.next_controller is not None:
            self.controller = out.next_controller
        if out.result is not None:
            self.results.append((t, out.result))
            self.notes.append((t, out.reason))
        if out.safe_hold and self.first_safe_hold is None:
            self.first_safe_hold = t

    def _command(self, harness: Harness, force: float, timeout: float) -> None:
        try:
            harness.command_force(force, timeout=timeout)
        except HarnessError as exc:     # the driver would refuse it too; keep running
            self.refused.append((harness.t, str(exc)))
            return
        self.commands.append((harness.t, force))


class TruthProbe:
    """Samples the simulator truth on every ``every``-th telemetry line (lists, SI)."""

    def __init__(self, every: int = 1) -> None:
        self.every = every
        self._n = 0
        self.t: list[float] = []
        self.x: list[float] = []
        self.y: list[float] = []
        self.theta: list[float] = []
        self.normal_force: list[float] = []
        self.object_theta: list[float] = []
        self.in_grasp: list[bool] = []
        self.dropped: list[bool] = []

    def on_telemetry(self, harness: Harness, sample: TelemetrySample) -> None:
        """Record one row."""
        self._n += 1
        if self._n % self.every:
            return
        s = harness.cell.state()
        self.t.append(s.stamp)
        self.x.append(s.x)
        self.y.append(s.y)
        self.theta.append(s.theta)
        self.normal_force.append(s.normal_force_1)
        self.object_theta.append(s.object_theta)
        self.in_grasp.append(s.in_grasp)
        self.dropped.append(s.dropped)

    def indices(self, t0: float, t1: float) -> range:
        """Row indices with ``t0 ≤ t ≤ t1`` (rows are in time order)."""
        lo = next((i for i, t in enumerate(self.t) if t >= t0 - 1e-12), len(self.t))
        hi = lo
        while hi < len(self.t) and self.t[hi] <= t1 + 1e-12:
            hi += 1
        return range(lo, hi)

    def peak_displacement(self, t0: float, t1: float, x0: float, y0: float) -> float:
        """Largest ``‖(x, y) − (x0, y0)‖`` in the window [m]."""
        return max((math.hypot(self.x[i] - x0, self.y[i] - y0) for i in self.indices(t0, t1)),
                   default=0.0)

    def peak_rotation(self, t0: float, t1: float, th0: float) -> float:
        """Largest ``|θ − θ0|`` in the window [rad]."""
        return max((abs(self.theta[i] - th0) for i in self.indices(t0, t1)), default=0.0)


def _controlled(preset: str, settings: EvalSettings, properties: ContactProperties | None,
                on_table: bool = False) -> tuple[Harness, ControllerAgent, TruthProbe]:
    """A cell with a controller agent and a truth probe; object held in the air under HOLD
    for ``settings.settle`` (or, with ``on_table``, standing on the table, controller OFF)."""
    h = make_harness(preset, settings)
    props = properties if properties is not None else true_properties(h.cell, settings.estimator)
    ctl = ControllerAgent(_controller_params(settings, h.cell), props, settings.watchdog_period)
    probe = TruthProbe()
    h.add_agent(ctl)
    h.add_agent(probe)
    if not on_table:
        h.reset(object_on_table=False)
        h.run_for(0.2)
        ctl.require_mode(h, ModeRequest(int(SlipMode.HOLD)))
        h.run_for(settings.settle)
    return h, ctl, probe


def _gravity_in_middle(arm_angle: float) -> tuple[float, float]:
    """Unit gravity direction in ``gripper_middle`` xy for a gripper turned ``arm_angle``."""
    return -math.sin(arm_angle), -math.cos(arm_angle)


# ---------------------------------------------------------------------------------------------
# Estimation
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FingerEstimate:
    """Estimated vs true contact of one finger (SI; NaN where the fit gave nothing).

    Attributes:
        finger: 1 or 2.
        mu_c: Estimated Coulomb coefficient [-].
        mu_c_true: Simulator value [-].
        mu_c_std: Estimator's 1-σ [-].
        r: Estimated torsional radius [m].
        r_true: Simulator value (the pad's characteristic radius) [m].
        r_std: Estimator's 1-σ [m].
        n_linear: Sliding samples of the linear fit.
        n_rotational: Samples of the rotational fit.
        linear_valid: ``μ_c`` flagged valid.
        rotational_valid: ``r`` flagged valid.
    """

    finger: int
    mu_c: float
    mu_c_true: float
    mu_c_std: float
    r: float
    r_true: float
    r_std: float
    n_linear: int
    n_rotational: int
    linear_valid: bool
    rotational_valid: bool

    @property
    def mu_c_error(self) -> float:
        """``μ_c − μ_c,true`` [-]."""
        return self.mu_c - self.mu_c_true

    @property
    def r_error(self) -> float:
        """``r − r_true`` [m]."""
        return self.r - self.r_true


@dataclass(frozen=True)
class EstimationOutcome:
    """Outcome of `estimate` (the §3.8 exploration).

    Attributes:
        preset: Object preset.
        fingers: Per-finger comparison.
        properties: Property set after the exploration (what the estimator publishes).
        valid: ``properties.valid``.
        messages: Reports of the phases, in order.
        slide: True slide of the object up between the pads over the descent [m].
        twist: True largest rotation of the pads on the object during the twist [rad].
        dropped: The object fell during the exploration.
    """

    preset: str
    fingers: tuple[FingerEstimate, FingerEstimate]
    properties: ContactProperties
    valid: bool
    messages: tuple[str, ...]
    slide: float
    twist: float
    dropped: bool


def _explore(h: Harness, agent: EstimatorAgent, grasp_force: float = 10.0,
             explore_force: float = 5.0, descent: float = 0.01, descent_time: float = 0.8,
             twist: float = math.radians(10.0), twist_time: float = 0.5,
             window: float = 1.0) -> tuple[float, float, bool]:
    """§3.8 steps 1–4 with the estimator agent; returns (slide, twist peak, dropped)."""
    h.command_force(grasp_force)
    h.run_for(2.0)
    h.command_force(explore_force)
    s0 = h.state()
    start = agent.start(h, EstimationPhase.LINEAR, window)
    if not start.accepted:
        raise EvaluationError(f'linear phase refused: {start.message}')
    h.move(lift=-descent, duration=descent_time)
    s1 = h.state()
    h.run_for(max(0.0, window - descent_time))
    start = agent.start(h, EstimationPhase.ROTATIONAL, window)
    if not start.accepted:
        raise EvaluationError(f'rotational phase refused: {start.message}')
    r0 = h.state().theta
    peak = 0.0
    end = h.move(rotation=twist, duration=twist_time, wait=False)

    def track(hh: Harness) -> bool:
        nonlocal peak
        peak = max(peak, abs(hh.state().theta - r0))
        return hh.t >= end - 1e-9 and not hh.cell.arm_moving

    h.run_until(track, twist_time + 0.1)
    end = h.move(rotation=-twist, duration=twist_time, wait=False)
    h.run_until(track, twist_time + 0.1)
    h.run_for(max(0.0, window - 2.0 * twist_time) + 0.02)
    dropped = h.state().dropped
    h.release()
    return math.hypot(s1.x - s0.x, s1.y - s0.y), peak, dropped


def estimate(preset: str, settings: EvalSettings = EvalSettings()) -> EstimationOutcome:
    """Run the §3.8 exploration on ``preset`` and compare the estimate with the truth.

    No HOLD during the initial grasp: there are no valid properties yet (§3.8 step 1, ours).
    Each phase is started through the node's pre-check; a refusal raises `EvaluationError`.
    """
    h = make_harness(preset, settings)
    agent = EstimatorAgent(settings.estimator)
    h.add_agent(agent)
    slide, twist, dropped = _explore(h, agent)
    props = agent.estimator.properties
    fingers = []
    for k, truth in zip((1, 2), h.cell.true_contact()):
        f = props.finger(k)
        fingers.append(FingerEstimate(
            finger=k, mu_c=f.mu_c, mu_c_true=truth.mu_c, mu_c_std=f.mu_c_std, r=f.r,
            r_true=truth.r, r_std=f.r_std, n_linear=f.n_linear, n_rotational=f.n_rotational,
            linear_valid=f.linear_valid, rotational_valid=f.rotational_valid))
    return EstimationOutcome(preset=preset, fingers=(fingers[0], fingers[1]), properties=props,
                             valid=props.valid and props.source == ContactSource.ESTIMATED,
                             messages=tuple(r.message for r in agent.reports), slide=slide,
                             twist=twist, dropped=dropped)


@dataclass(frozen=True)
class NoContactOutcome:
    """Outcome of `estimate_without_contact`.

    Attributes:
        start_accepted: The node-level start (with pre-check) accepted the LINEAR phase.
        start_message: Its answer.
        core_success: The core alone (no pre-check) ran the phase and reported success.
        core_message: Its report.
        core_changed: The core replaced the published property set.
        source: Source of the property set afterwards.
        valid: Validity of the property set afterwards.
        mu_c: ``μ_c`` of finger 1 afterwards (NaN or the DEFAULT placeholder, never a fit).
        in_grasp: Truth: the pads touched an object during the attempt.
    """

    start_accepted: bool
    start_message: str
    core_success: bool
    core_message: str
    core_changed: bool
    source: ContactSource
    valid: bool
    mu_c: float
    in_grasp: bool


def estimate_without_contact(preset: str = 'cardboard',
                             settings: EvalSettings = EvalSettings()) -> NoContactOutcome:
    """Ask for an exploration with the gripper open and nothing between the fingers.

    The gripper is first lifted 0.2 m off the object (fingers open), then the LINEAR phase is
    requested through the node's pre-check and, separately, from the core alone while the
    descent runs.
    """
    h = make_harness(preset, settings)
    agent = EstimatorAgent(settings.estimator)
    probe = TruthProbe()
    h.add_agent(agent)
    h.add_agent(probe)
    h.move(lift=0.2, duration=1.0)
    h.run_for(0.2)
    first = agent.start(h, EstimationPhase.LINEAR, 1.0)
    n_reports = len(agent.reports)
    core = agent.start(h, EstimationPhase.LINEAR, 1.0, precheck=False)
    if not core.accepted:
        raise EvaluationError(f'core refused the phase: {core.message}')
    h.move(lift=-0.01, duration=0.8)
    h.run_for(0.3)
    reports = agent.reports[n_reports:]
    if not reports:
        raise EvaluationError('the core never reported the LINEAR phase')
    rep = reports[-1]
    props = agent.estimator.properties
    return NoContactOutcome(
        start_accepted=first.accepted, start_message=first.message, core_success=rep.success,
        core_message=rep.message, core_changed=rep.changed, source=props.source,
        valid=props.valid, mu_c=props.finger_1.mu_c, in_grasp=any(probe.in_grasp))


# ---------------------------------------------------------------------------------------------
# Pick-up and hold
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PickUpOutcome:
    """Outcome of `pick_up` (truth unless noted).

    Attributes:
        preset: Object preset.
        lift: Rise of the object's CoM [m] (≈ the commanded 0.20 m when held).
        slip_peak: Largest grasp-point displacement relative to the pads from HOLD on [m].
        rotation_peak: Largest relative rotation from HOLD on [rad].
        force_min: Smallest commanded force under HOLD [N].
        force_max: Largest commanded force under HOLD [N].
        normal_force_final: True normal force at the end [N].
        dropped: The object fell.
    """

    preset: str
    lift: float
    slip_peak: float
    rotation_peak: float
    force_min: float
    force_max: float
    normal_force_final: float
    dropped: bool


def pick_up(preset: str, settings: EvalSettings = EvalSettings(),
            properties: ContactProperties | None = None, lift: float = 0.20,
            hold: float = 1.0) -> PickUpOutcome:
    """§5.3 ``grasp`` then ``pick_up_object``: 10 N for 2 s, HOLD on, lift, hold."""
    h, ctl, probe = _controlled(preset, settings, properties, on_table=True)
    h.command_force(10.0)
    h.run_for(2.0)
    y0 = h.state().object_y
    ctl.require_mode(h, ModeRequest(int(SlipMode.HOLD)))
    t0 = h.t
    s0 = h.state()
    h.move(lift=lift)
    h.run_for(hold)
    s = h.state()
    forces = ctl.forces_between(t0, h.t) or [_NAN]
    return PickUpOutcome(preset=preset, lift=s.object_y - y0,
                         slip_peak=probe.peak_displacement(t0, h.t, s0.x, s0.y),
                         rotation_peak=probe.peak_rotation(t0, h.t, s0.theta),
                         force_min=min(forces), force_max=max(forces),
                         normal_force_final=s.normal_force_1, dropped=s.dropped)


@dataclass(frozen=True)
class Push:
    """One external load on the object's CoM (``gripper_middle`` axes, SI).

    Attributes:
        fx: Force x [N].
        fy: Force y [N] (−: pulls down at the pick-up pose).
        torque: Torque about +z [N·m].
        duration: How long it acts [s].
        pause: Time after it before the next one [s].
    """

    fx: float = 0.0
    fy: float = 0.0
    torque: float = 0.0
    duration: float = 0.5
    pause: float = 0.5


#: Sustained pulls, pushes and twists, then escalating taps (the hold protocol of §5.5 in
#: simulation). Forces act on the CoM; the reference objects weigh 0.8–2.0 N.
DEFAULT_PUSHES: tuple[Push, ...] = (
    Push(fy=-1.0),                                 # pull down 1 N
    Push(fy=-3.0),                                 # pull down 3 N
    Push(fx=2.0),                                  # push sideways 2 N
    Push(torque=0.02),                             # twist 0.02 N·m
    Push(fy=-2.0, duration=0.02),                  # taps down: 2, 4, 6 N for 20 ms
    Push(fy=-4.0, duration=0.02),
    Push(fy=-6.0, duration=0.02),
    Push(fx=-4.0, duration=0.02),                  # tap sideways 4 N
)

#: Pushes shorter than this count as taps [s].
TAP_MAX_DURATION = 0.1


@dataclass(frozen=True)
class HoldOutcome:
    """Outcome of `hold_under_disturbance` (truth unless noted).

    Attributes:
        preset: Object preset.
        pushes: The loads applied.
        slip_peak: Largest grasp-point displacement from the pose before the first push [m].
        rotation_peak: Largest relative rotation from that pose [rad].
        slip_final: Displacement at the end [m].
        push_slip: Per push, the largest displacement during it and its pause, from the pose
            at its start [m].
        sustained_slip: Largest `push_slip` of the sustained pushes [m] (0 if none).
        tap_slip: Largest `push_slip` of the taps (shorter than `TAP_MAX_DURATION`) [m].
        force_min: Smallest commanded force during the window [N].
        force_max: Largest commanded force during the window [N].
        dropped: The object fell.
    """

    preset: str
    pushes: tuple[Push, ...]
    slip_peak: float
    rotation_peak: float
    slip_final: float
    push_slip: tuple[float, ...]
    sustained_slip: float
    tap_slip: float
    force_min: float
    force_max: float
    dropped: bool


def hold_under_disturbance(preset: str, pushes: Sequence[Push] = DEFAULT_PUSHES,
                           settings: EvalSettings = EvalSettings(),
                           properties: ContactProperties | None = None) -> HoldOutcome:
    """HOLD on an object held in the air while ``pushes`` act on it one after the other."""
    h, ctl, probe = _controlled(preset, settings, properties)
    t0 = h.t
    s0 = h.state()
    per_push = []
    for p in pushes:
        ts = h.t
        sp = h.state()
        h.disturb(p.fx, p.fy, p.torque, p.duration)
        h.run_for(p.duration + p.pause)
        per_push.append(probe.peak_displacement(ts, h.t, sp.x, sp.y))
    s = h.state()
    forces = ctl.forces_between(t0, h.t) or [_NAN]
    taps = [d for p, d in zip(pushes, per_push) if p.duration < TAP_MAX_DURATION]
    sustained = [d for p, d in zip(pushes, per_push) if p.duration >= TAP_MAX_DURATION]
    return HoldOutcome(preset=preset, pushes=tuple(pushes),
                       slip_peak=probe.peak_displacement(t0, h.t, s0.x, s0.y),
                       rotation_peak=probe.peak_rotation(t0, h.t, s0.theta),
                       slip_final=math.hypot(s.x - s0.x, s.y - s0.y), push_slip=tuple(per_push),
                       sustained_slip=max(sustained, default=0.0),
                       tap_slip=max(taps, default=0.0), force_min=min(forces),
                       force_max=max(forces), dropped=s.dropped)


# ---------------------------------------------------------------------------------------------
# Trajectories
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class TrajectoryOutcome:
    """Outcome of `linear_slip` or `rotational_slip`.

    Truth (``gripper_middle``): progress is measured along the commanded direction — for
    LINEAR along gravity (the direction the runner's latched request slides in), for
    ROTATIONAL along the sign of the commanded angle.

    Attributes:
        preset: Object preset.
        mode: LINEAR or ROTATIONAL.
        target: Commanded distance [m] or signed angle [rad].
        duration: Commanded ``T`` [s].
        achieved: True progress at the end [m | rad] (≥ 0 when it moved the right way).
        final_error: ``|target| − achieved`` [m | rad] (truth).
        off_axis: LINEAR: largest sideways displacement [m]; ROTATIONAL: largest grasp-point
            translation [m].
        tracking_rms: RMS of (reference − true progress) at the controller's steps [m | rad].
        tracking_max: Largest absolute such error [m | rad].
        result: The controller's own result (sensor-integrated progress), if it ended.
        result_time: When it ended, from the request [s] (NaN if it did not).
        force_min: Smallest commanded force during the trajectory [N].
        force_max: Largest commanded force during the trajectory [N].
        dropped: The object fell.
    """

    preset: str
    mode: SlipMode
    target: float
    duration: float
    achieved: float
    final_error: float
    off_axis: float
    tracking_rms: float
    tracking_max: float
    result: SlipResult | None
    result_time: float
    force_min: float
    force_max: float
    dropped: bool


def _run_trajectory(h: Harness, ctl: ControllerAgent, probe: TruthProbe, request: ModeRequest,
                    progress: Callable[[int], float], wait: float
                    ) -> tuple[float, list[float], SlipResult | None, float, list[float]]:
    """Request a trajectory, run ``wait`` [s]; returns start time, truth errors at the
    tracking steps, the result, its time from the start, and the forces."""
    t0 = h.t
    n_track = len(ctl.tracking)
    n_res = len(ctl.results)
    ctl.require_mode(h, request)
    h.run_for(wait)
    errors = [row.ref_pos - _interp_progress(probe, progress, row.stamp)
              for row in ctl.tracking[n_track:]]
    ended = [(t, r) for t, r in ctl.results[n_res:] if r.mode == SlipMode(request.mode)]
    result = ended[0][1] if ended else None
    result_time = ended[0][0] - t0 if ended else _NAN
    forces = ctl.forces_between(t0, t0 + (result_time if ended else wait)) or [_NAN]
    return t0, errors, result, result_time, forces


def _interp_progress(probe: TruthProbe, progress: Callable[[int], float], t: float) -> float:
    """True progress at time ``t`` (nearest probe rows, linear interpolation)."""
    ts = probe.t
    if not ts:
        return _NAN
    lo = 0
    hi = len(ts) - 1
    if t <= ts[0]:
        return progress(0)
    if t >= ts[-1]:
        return progress(hi)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if ts[mid] <= t:
            lo = mid
        else:
            hi = mid
    a = (t - ts[lo]) / (ts[hi] - ts[lo])
    return progress(lo) + a * (progress(hi) - progress(lo))


def _rms(values: Sequence[float]) -> float:
    return math.sqrt(sum(v * v for v in values) / len(values)) if values else _NAN


def linear_slip(preset: str, distance: float = 0.02, duration: float = 2.0,
                settings: EvalSettings = EvalSettings(),
                properties: ContactProperties | None = None,
                latch_direction: bool = True) -> TrajectoryOutcome:
    """LINEAR slip of ``distance`` [m] in ``duration`` [s] on an object held in the air.

    The request is the runner's (§5.3 ``linear_slippage``: direction latched from the first
    motion); gravity makes the object slide down. The runner waits ``duration + 1 s``; this
    waits ``duration + 1.5 s`` so the hand-over to HOLD is included.
    """
    h, ctl, probe = _controlled(preset, settings, properties)
    s0 = h.state()
    gx, gy = _gravity_in_middle(s0.arm_angle)
    request = ModeRequest(int(SlipMode.LINEAR), duration=duration, distance=distance,
                          direction=(0.0, 0.0, 0.0) if latch_direction else (gx, gy, 0.0),
                          latch_direction=latch_direction)

    def along(i: int) -> float:
        return (probe.x[i] - s0.x) * gx + (probe.y[i] - s0.y) * gy

    t0, errors, result, result_time, forces = _run_trajectory(
        h, ctl, probe, request, along, duration + 1.5)
    s = h.state()
    achieved = (s.x - s0.x) * gx + (s.y - s0.y) * gy
    side = max((abs((probe.x[i] - s0.x) * gy - (probe.y[i] - s0.y) * gx)
                for i in probe.indices(t0, h.t)), default=0.0)
    return TrajectoryOutcome(
        preset=preset, mode=SlipMode.LINEAR, target=distance, duration=duration,
        achieved=achieved, final_error=distance - achieved, off_axis=side,
        tracking_rms=_rms(errors), tracking_max=max((abs(e) for e in errors), default=_NAN),
        result=result, result_time=result_time, force_min=min(forces), force_max=max(forces),
        dropped=s.dropped)


def rotational_slip(preset: str, angle: float = math.radians(20.0), duration: float = 2.0,
                    settings: EvalSettings = EvalSettings(),
                    properties: ContactProperties | None = None,
                    tilt: float = math.radians(90.0),
                    tilt_time: float | None = None) -> TrajectoryOutcome:
    """ROTATIONAL slip of ``angle`` [rad, signed about ``gripper_middle`` +z] in ``duration``.

    Set-up: object held in the air under HOLD; the gripper turns by ``−sign(angle)·tilt``
    (motion time: the runner's default unless ``tilt_time``), so the object hangs ``tilt``
    away from vertical and gravity turns it the requested way (like the reference's set-ups
    "15"/"60" of §5.5). The request is the runner's (sign from the angle).

    ``tilt`` defaults to 90°: the reference presets carry their CoM only 1 cm below the grasp
    point, so near vertical the gravity torque falls below the torsional friction at the
    controller's force floor and the object stops short (from 60°, a 45° command ends 3–15°
    short on every preset); from 90° the 45° slip ends 45° from vertical.
    """
    if not abs(tilt) >= abs(angle):
        raise ValueError(f'tilt {tilt!r} rad must be at least |angle| {abs(angle)!r} rad: '
                         'gravity can only turn the object back to hanging')
    h, ctl, probe = _controlled(preset, settings, properties)
    turn = -math.copysign(abs(tilt), angle)
    h.move(rotation=turn, duration=tilt_time if tilt_time is not None else
           default_motion_time(0.0, turn))
    h.run_for(0.5)
    s0 = h.state()
    sign = math.copysign(1.0, angle)
    request = ModeRequest(int(SlipMode.ROTATIONAL), duration=duration, angle=angle)

    def along(i: int) -> float:
        return sign * (probe.theta[i] - s0.theta)

    t0, errors, result, result_time, forces = _run_trajectory(
        h, ctl, probe, request, along, duration + 1.5)
    s = h.state()
    achieved = sign * (s.theta - s0.theta)
    return TrajectoryOutcome(
        preset=preset, mode=SlipMode.ROTATIONAL, target=angle, duration=duration,
        achieved=achieved, final_error=abs(angle) - achieved,
        off_axis=probe.peak_displacement(t0, h.t, s0.x, s0.y), tracking_rms=_rms(errors),
        tracking_max=max((abs(e) for e in errors), default=_NAN), result=result,
        result_time=result_time, force_min=min(forces), force_max=max(forces),
        dropped=s.dropped)


# ---------------------------------------------------------------------------------------------
# Online refinement during controlled slip
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class OnlineOutcome:
    """Outcome of `online_refinement`: per-finger values, finger 1 then finger 2.

    Attributes:
        preset: Object preset.
        start_scale: Factor applied to the true ``μ_c`` and ``r`` for the starting estimate.
        mu_c_true: True ``μ_c``.
        r_true: True ``r`` [m].
        mu_c_start: Starting ``μ_c`` (``start_scale · μ_c_true``).
        r_start: Starting ``r`` [m].
        mu_c_online: ``μ_c`` after the LINEAR slip with ONLINE running.
        r_online: ``r`` [m] after the ROTATIONAL slip with ONLINE running.
        published_linear: The estimator published an online-updated set during the LINEAR run.
        published_rotational: Same during the ROTATIONAL run.
        dropped: The object fell in either run.
    """

    preset: str
    start_scale: float
    mu_c_true: tuple[float, float]
    r_true: tuple[float, float]
    mu_c_start: tuple[float, float]
    r_start: tuple[float, float]
    mu_c_online: tuple[float, float]
    r_online: tuple[float, float]
    published_linear: bool
    published_rotational: bool
    dropped: bool

    @staticmethod
    def _rel(values: tuple[float, float], truth: tuple[float, float]) -> float:
        return max(abs(v - t) / t for v, t in zip(values, truth))

    @property
    def mu_c_error_start(self) -> float:
        """Largest relative ``μ_c`` error of the starting estimate [-]."""
        return self._rel(self.mu_c_start, self.mu_c_true)

    @property
    def mu_c_error_online(self) -> float:
        """Largest relative ``μ_c`` error after the online update [-]."""
        return self._rel(self.mu_c_online, self.mu_c_true)

    @property
    def r_error_start(self) -> float:
        """Largest relative ``r`` error of the starting estimate [-]."""
        return self._rel(self.r_start, self.r_true)

    @property
    def r_error_online(self) -> float:
        """Largest relative ``r`` error after the online update [-]."""
        return self._rel(self.r_online, self.r_true)


def _scaled(props: ContactProperties, scale: float) -> ContactProperties:
    """``props`` with every finger's ``μ_c`` and ``r`` multiplied by ``scale`` (source
    ESTIMATED, as a poor exploration would have published)."""
    return replace(props, source=ContactSource.ESTIMATED,
                   finger_1=replace(props.finger_1, mu_c=props.finger_1.mu_c * scale,
                                    r=props.finger_1.r * scale),
                   finger_2=replace(props.finger_2, mu_c=props.finger_2.mu_c * scale,
                                    r=props.finger_2.r * scale))


def online_refinement(preset: str, start_scale: float = 0.8,
                      settings: EvalSettings = EvalSettings()) -> OnlineOutcome:
    """How well the ONLINE phase (§3.6) corrects a wrong estimate during controlled slip.

    Starts from the true properties scaled by ``start_scale`` (both ``μ_c`` and ``r``), which
    the controllers also use. Run 1: ONLINE on, LINEAR 2 cm in 2 s (held in the air; refines
    ``μ_c``). Run 2 starts from the properties run 1 ended with: ONLINE on, ROTATIONAL 20° in
    2 s from 90° off vertical (refines ``r``, which needs ``μ_c``). The estimator is the node's
    core with ``online.enabled``.
    """
    if not (math.isfinite(start_scale) and start_scale > 0.0):
        raise ValueError(f'start_scale must be finite and > 0, got {start_scale!r}')
    est_params = replace(settings.estimator,
                         online=replace(settings.estimator.online, enabled=True))
    probe_cell = make_harness(preset, settings).cell
    truth = true_properties(probe_cell, est_params)
    start = _scaled(truth, start_scale)

    def run(initial: ContactProperties, request: ModeRequest, tilt: float
            ) -> tuple[ContactProperties, bool, bool]:
        h, ctl, _ = _controlled(preset, settings, initial)
        if tilt:
            h.move(rotation=tilt, duration=default_motion_time(0.0, tilt))
            h.run_for(0.5)
        agent = EstimatorAgent(est_params, initial)
        h.add_agent(agent)
        outcome = agent.start(h, EstimationPhase.ONLINE, 0.0)
        if not outcome.accepted:
            raise EvaluationError(f'{preset}: ONLINE refused: {outcome.message}')
        ctl.require_mode(h, request)
        h.run_for(request.duration + 1.0)
        props = agent.estimator.properties
        return props, props.online_updated, h.state().dropped

    lin, pub_lin, drop_lin = run(start, ModeRequest(int(SlipMode.LINEAR), duration=2.0,
                                                    distance=0.02, latch_direction=True), 0.0)
    # The rotation starts from what the slide left (the demo's order: linear, then rotational).
    rot, pub_rot, drop_rot = run(lin, ModeRequest(int(SlipMode.ROTATIONAL), duration=2.0,
                                                  angle=math.radians(20.0)),
                                 -math.radians(90.0))

    def pair(p: ContactProperties, name: str) -> tuple[float, float]:
        return getattr(p.finger_1, name), getattr(p.finger_2, name)

    return OnlineOutcome(
        preset=preset, start_scale=start_scale, mu_c_true=pair(truth, 'mu_c'),
        r_true=pair(truth, 'r'), mu_c_start=pair(start, 'mu_c'), r_start=pair(start, 'r'),
        mu_c_online=pair(lin, 'mu_c'), r_online=pair(rot, 'r'), published_linear=pub_lin,
        published_rotational=pub_rot, dropped=drop_lin or drop_rot)


#: Starting errors of `online_refinement` in the table: true ``μ_c`` and ``r`` times these.
ONLINE_START_SCALES: tuple[float, ...] = (0.8, 1.2)


def format_online_table(outcomes: Sequence[OnlineOutcome]) -> str:
    """Table of `online_refinement` outcomes: largest relative error over the two fingers,
    start → online, for ``μ_c`` (after the LINEAR slide) and ``r`` (after the ROTATIONAL slip).
    """
    lines = ['Online refinement (ONLINE during LINEAR 2 cm/2 s, then ROTATIONAL 20 deg/2 s; '
             'max relative error over the fingers)',
             f'{"preset":<10} {"start":>5}  {"mu_c err start->online":>22}  '
             f'{"r err start->online":>19}  {"published":>9}  {"drops":>5}']
    for o in outcomes:
        pub = '/'.join('yes' if b else 'no' for b in (o.published_linear,
                                                       o.published_rotational))
        lines.append(
            f'{o.preset:<10} {o.start_scale:>4.2f}x  '
            f'{100 * o.mu_c_error_start:>8.1f} % -> {100 * o.mu_c_error_online:>5.1f} %  '
            f'{100 * o.r_error_start:>5.1f} % -> {100 * o.r_error_online:>5.1f} %  {pub:>9}  '
            f'{int(o.dropped):>5}')
    return '\n'.join(lines)


# ---------------------------------------------------------------------------------------------
# Hinge
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class HingeOutcome:
    """Outcome of `hinge` (truth).

    Attributes:
        preset: Object preset.
        gripper_turn: Turn of the gripper under HINGE [rad].
        swing: Relative rotation while HINGE settles at the hinge pose, before the turn [rad].
        relative_rotation: Rotation of the object relative to the pads from the start of the
            turn to the end of the wait [rad]; ``−gripper_turn`` for an ideal hinge (the object
            keeps its orientation in the world while the gripper turns about it).
        object_turn: Turn of the object in the world over the same window [rad] (ideal 0).
        translation_peak: Largest grasp-point displacement relative to the pads from HINGE on
            to the end [m] (ideal 0: HINGE stops translation).
        translation_turn: Grasp-point displacement from the start of the turn to the end of
            the wait [m].
        force_min: Smallest commanded force under HINGE [N].
        force_max: Largest commanded force under HINGE [N].
        dropped: The object fell.
    """

    preset: str
    gripper_turn: float
    swing: float
    relative_rotation: float
    object_turn: float
    translation_peak: float
    translation_turn: float
    force_min: float
    force_max: float
    dropped: bool

    @property
    def rotation_error(self) -> float:
        """``|gripper_turn| − |relative_rotation|`` [rad]: how much the object followed."""
        return abs(self.gripper_turn) - abs(self.relative_rotation)


def hinge(preset: str, turn: float = math.radians(60.0), settings: EvalSettings = EvalSettings(),
          properties: ContactProperties | None = None, start_angle: float = math.radians(60.0),
          settle: float = 1.0, wait: float = 2.0) -> HingeOutcome:
    """§5.3 ``go_to_hinge_pose`` + ``hinge_mode`` on an object held in the air.

    HOLD while the gripper turns to the hinge pose (``start_angle``), HINGE on, ``settle``
    [s] (the object swings towards hanging; this pause is ours, so the turn is measured on its
    own), the gripper turns another ``turn`` (runner's motion time), ``wait``, HOLD on.
    """
    h, ctl, probe = _controlled(preset, settings, properties)
    h.move(rotation=start_angle)
    h.run_for(0.3)
    ctl.require_mode(h, ModeRequest(int(SlipMode.HINGE)))
    t_on = h.t
    s_on = h.state()
    h.run_for(settle)
    s1 = h.state()
    h.move(rotation=turn)
    h.run_for(wait)
    t_end = h.t
    s2 = h.state()
    forces = ctl.forces_between(t_on, t_end) or [_NAN]
    ctl.require_mode(h, ModeRequest(int(SlipMode.HOLD)))
    h.run_for(0.5)
    s3 = h.state()
    return HingeOutcome(
        preset=preset, gripper_turn=turn, swing=s1.theta - s_on.theta,
        relative_rotation=s2.theta - s1.theta, object_turn=s2.object_theta - s1.object_theta,
        translation_peak=probe.peak_displacement(t_on, h.t, s_on.x, s_on.y),
        translation_turn=math.hypot(s2.x - s1.x, s2.y - s1.y), force_min=min(forces),
        force_max=max(forces), dropped=s3.dropped)


# ---------------------------------------------------------------------------------------------
# Faults
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FaultOutcome:
    """Outcome of `stream_fault`.

    Attributes:
        preset: Object preset.
        stream: ``'ft'`` or ``'velocity'``.
        t_cut: Time the stream stopped, from the LINEAR request [s].
        reaction: Time from the cut to the controller's first safe-hold output [s] (NaN: none).
        result: The trajectory's result (e.g. "F/T stale").
        mode_after: Mode in charge at the end.
        force_at_cut: Last force commanded before the cut [N].
        force_after: Last force commanded at the end [N].
        slip_after: Largest true displacement of the grasp point after the cut [m].
        creep: True displacement over the last 0.5 s of the observation [m] (≈ 0 once the
            safe hold has stopped the object).
        dropped: The object fell.
    """

    preset: str
    stream: str
    t_cut: float
    reaction: float
    result: SlipResult | None
    mode_after: SlipMode
    force_at_cut: float
    force_after: float
    slip_after: float
    creep: float
    dropped: bool


def stream_fault(preset: str, stream: str, at: float, distance: float = 0.02,
                 duration: float = 2.0, observe: float = 1.5,
                 settings: EvalSettings = EvalSettings(),
                 properties: ContactProperties | None = None) -> FaultOutcome:
    """Stop the F/T (``'ft'``) or velocity (``'velocity'``) stream ``at`` [s] into a LINEAR
    slip and watch the controller and the object for ``observe`` [s]."""
    if stream not in ('ft', 'velocity'):
        raise ValueError(f"stream must be 'ft' or 'velocity', got {stream!r}")
    h, ctl, probe = _controlled(preset, settings, properties)
    t0 = h.t
    ctl.require_mode(h, ModeRequest(int(SlipMode.LINEAR), duration=duration, distance=distance,
                                    latch_direction=True))
    h.run_until_time(t0 + at)
    t_cut = h.t
    s_cut = h.state()
    before = [f for t, f in ctl.commands if t <= t_cut]
    if stream == 'ft':
        ctl.cut_ft(t_cut)
    else:
        ctl.cut_velocity(t_cut)
    ctl.first_safe_hold = None
    h.run_for(max(0.0, observe - 0.5))
    s_late = h.state()
    h.run_for(min(0.5, observe))
    s = h.state()
    ended = [r for t, r in ctl.results if t >= t_cut]
    safe = ctl.first_safe_hold
    return FaultOutcome(
        preset=preset, stream=stream, t_cut=t_cut - t0,
        reaction=(safe - t_cut) if safe is not None else _NAN,
        result=ended[0] if ended else None, mode_after=ctl.mode,
        force_at_cut=before[-1] if before else _NAN,
        force_after=ctl.commands[-1][1] if ctl.commands else _NAN,
        slip_after=probe.peak_displacement(t_cut, h.t, s_cut.x, s_cut.y),
        creep=math.hypot(s.x - s_late.x, s.y - s_late.y), dropped=s.dropped)


# ---------------------------------------------------------------------------------------------
# The table
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PresetEvaluation:
    """Every scenario of the table for one preset (``None`` where skipped).

    Attributes:
        preset: Object preset.
        estimation: The exploration.
        properties_source: Where the controllers' properties came from.
        pick_up: Pick-up under HOLD.
        hold: Hold under disturbance.
        linear: LINEAR outcomes keyed by ``(distance [m], duration [s])``.
        rotational: ROTATIONAL outcomes keyed by ``(angle [rad], duration [s])``.
        hinge: Hinge through 60°.
        notes: Scenarios that could not run and why.
    """

    preset: str
    estimation: EstimationOutcome
    properties_source: str
    pick_up: PickUpOutcome | None
    hold: HoldOutcome | None
    linear: Mapping[tuple[float, float], TrajectoryOutcome]
    rotational: Mapping[tuple[float, float], TrajectoryOutcome]
    hinge: HingeOutcome | None
    notes: tuple[str, ...] = ()


#: LINEAR cases of the table (distance [m], duration [s]).
LINEAR_CASES: tuple[tuple[float, float], ...] = ((0.02, 2.0), (0.04, 5.0))
#: ROTATIONAL cases of the table (angle [rad], duration [s]).
ROTATIONAL_CASES: tuple[tuple[float, float], ...] = ((math.radians(20.0), 2.0),
                                                     (math.radians(45.0), 5.0))


def evaluate_preset(preset: str, settings: EvalSettings = EvalSettings(), *,
                    quick: bool = False, use_truth: bool = False,
                    progress: Callable[[str], None] | None = None) -> PresetEvaluation:
    """Run the estimation and every controller scenario for one preset.

    Args:
        preset: Object preset.
        settings: Cell and core settings.
        quick: Only the 2 s trajectories; no pick-up.
        use_truth: Give the controllers the true contact properties instead of the estimate.
        progress: Called with a short note before each scenario (CLI).
    """
    say = progress if progress is not None else (lambda _text: None)
    say(f'{preset}: estimation')
    est = estimate(preset, settings)
    notes: list[str] = []
    props: ContactProperties | None
    if use_truth:
        props, source = None, 'GROUND_TRUTH'
    elif est.valid:
        props, source = est.properties, 'ESTIMATED'
    else:
        props, source = None, 'GROUND_TRUTH'
        notes.append('estimate invalid: the controllers ran on the true properties')

    def attempt(name: str, fn: Callable[[], _T]) -> _T | None:
        say(f'{preset}: {name}')
        try:
            return fn()
        except EvaluationError as exc:
            notes.append(f'{name}: {exc}')
            return None

    pick = None if quick else attempt('pick-up', lambda: pick_up(preset, settings, props))
    hold = attempt('hold under disturbance',
                   lambda: hold_under_disturbance(preset, DEFAULT_PUSHES, settings, props))
    lin: dict[tuple[float, float], TrajectoryOutcome] = {}
    for d, T in LINEAR_CASES[:1] if quick else LINEAR_CASES:
        out = attempt(f'linear {d * 100:.0f} cm / {T:.0f} s',
                      lambda d=d, T=T: linear_slip(preset, d, T, settings, props))
        if out is not None:
            lin[(d, T)] = out
    rot: dict[tuple[float, float], TrajectoryOutcome] = {}
    for a, T in ROTATIONAL_CASES[:1] if quick else ROTATIONAL_CASES:
        out = attempt(f'rotational {math.degrees(a):.0f} deg / {T:.0f} s',
                      lambda a=a, T=T: rotational_slip(preset, a, T, settings, props))
        if out is not None:
            rot[(a, T)] = out
    hng = attempt('hinge 60 deg', lambda: hinge(preset, math.radians(60.0), settings, props))
    return PresetEvaluation(preset=preset, estimation=est, properties_source=source,
                            pick_up=pick, hold=hold, linear=lin, rotational=rot, hinge=hng,
                            notes=tuple(notes))


def evaluate_all(presets: Sequence[str] = REFERENCE_PRESETS,
                 settings: EvalSettings = EvalSettings(), *, quick: bool = False,
                 use_truth: bool = False, progress: Callable[[str], None] | None = None
                 ) -> tuple[PresetEvaluation, ...]:
    """`evaluate_preset` for each preset, in order."""
    return tuple(evaluate_preset(p, settings, quick=quick, use_truth=use_truth,
                                 progress=progress) for p in presets)


def _fmt(value: float | None, scale: float = 1.0, digits: int = 2, width: int = 7) -> str:
    if value is None or not math.isfinite(value):
        return f'{"n/a":>{width}}'
    return f'{value * scale:{width}.{digits}f}'


def format_table(rows: Sequence[PresetEvaluation]) -> str:
    """The issue-7 table: estimate − truth, and target − achieved from the simulator truth.

    Columns of the slip table: LINEAR and ROTATIONAL final errors; HOLD: largest slip under
    the sustained pushes and under the taps (each from the pose at the push), largest
    rotation; HINGE: ``|relative rotation|`` over the 60° turn (ideal 60°) and the grasp-point
    translation over the turn; pick-up slip; number of scenarios in which the object fell.
    """
    lines: list[str] = []
    deg = 180.0 / math.pi
    lines.append('Contact estimation (estimate - truth)')
    lines.append(f'{"preset":<10} {"mu_c f1":>8} {"mu_c f2":>8} {"r f1 mm":>8} {"r f2 mm":>8}'
                 f'  {"valid":>5}  {"mu_c true":>11}  {"r true mm":>11}')
    for row in rows:
        f1, f2 = row.estimation.fingers
        lines.append(
            f'{row.preset:<10} {_fmt(f1.mu_c_error, 1, 4, 8)} {_fmt(f2.mu_c_error, 1, 4, 8)} '
            f'{_fmt(f1.r_error, 1e3, 2, 8)} {_fmt(f2.r_error, 1e3, 2, 8)}  '
            f'{str(row.estimation.valid):>5}  {f1.mu_c_true:5.3f}/{f2.mu_c_true:5.3f}  '
            f'{f1.r_true * 1e3:5.2f}/{f2.r_true * 1e3:5.2f}')
    lines.append('')
    lines.append('Slip control (simulator truth; final error = target - achieved)')
    lines.append(f'{"preset":<10} {"props":<12} {"lin 2cm/2s":>10} {"lin 4cm/5s":>10} '
                 f'{"rot 20/2s":>9} {"rot 45/5s":>9} {"hold push":>9} {"hold tap":>8} '
                 f'{"hold rot":>8} {"hinge rel":>9} {"hinge tr":>8} {"pick-up":>7} '
                 f'{"drops":>5}')
    lines.append(f'{"":<10} {"":<12} {"[mm]":>10} {"[mm]":>10} {"[deg]":>9} {"[deg]":>9} '
                 f'{"[mm]":>9} {"[mm]":>8} {"[deg]":>8} {"[deg]":>9} {"[mm]":>8} {"[mm]":>7} '
                 f'{"":>5}')
    for row in rows:
        lin = [row.linear.get(k) for k in LINEAR_CASES]
        rot = [row.rotational.get(k) for k in ROTATIONAL_CASES]
        hold, hng, pick = row.hold, row.hinge, row.pick_up
        outcomes: list[object] = [*lin, *rot, hold, hng, pick]
        drops = sum(1 for o in outcomes if o is not None and getattr(o, 'dropped', False))
        lines.append(
            f'{row.preset:<10} {row.properties_source:<12} '
            f'{_fmt(lin[0].final_error if lin[0] else None, 1e3, 2, 10)} '
            f'{_fmt(lin[1].final_error if lin[1] else None, 1e3, 2, 10)} '
            f'{_fmt(rot[0].final_error if rot[0] else None, deg, 2, 9)} '
            f'{_fmt(rot[1].final_error if rot[1] else None, deg, 2, 9)} '
            f'{_fmt(hold.sustained_slip if hold else None, 1e3, 3, 9)} '
            f'{_fmt(hold.tap_slip if hold else None, 1e3, 3, 8)} '
            f'{_fmt(hold.rotation_peak if hold else None, deg, 2, 8)} '
            f'{_fmt(abs(hng.relative_rotation) if hng else None, deg, 1, 9)} '
            f'{_fmt(hng.translation_turn if hng else None, 1e3, 2, 8)} '
            f'{_fmt(pick.slip_peak if pick else None, 1e3, 3, 7)} {drops:>5}')
    lines.append('')
    lines.append('Details: controller self-report (sensor-integrated final error) and extras')
    for row in rows:
        parts = []
        for (d, T), o in row.linear.items():
            r = o.result
            parts.append(f'linear {d * 100:.0f} cm / {T:.0f} s: controller error '
                         f'{_fmt(r.final_error if r else None, 1e3, 2, 0)} mm '
                         f'({r.message if r else "no result"}); tracking rms/max '
                         f'{o.tracking_rms * 1e3:.2f}/{o.tracking_max * 1e3:.2f} mm; sideways '
                         f'{o.off_axis * 1e3:.2f} mm; force {o.force_min:.2f}-{o.force_max:.2f} N'
                         f'{"; DROPPED" if o.dropped else ""}')
        for (a, T), o in row.rotational.items():
            r = o.result
            parts.append(f'rotational {math.degrees(a):.0f} deg / {T:.0f} s: controller error '
                         f'{_fmt(r.final_error if r else None, deg, 2, 0)} deg '
                         f'({r.message if r else "no result"}); tracking rms/max '
                         f'{o.tracking_rms * deg:.2f}/{o.tracking_max * deg:.2f} deg; grasp-point '
                         f'translation {o.off_axis * 1e3:.1f} mm; force '
                         f'{o.force_min:.2f}-{o.force_max:.2f} N'
                         f'{"; DROPPED" if o.dropped else ""}')
        if row.hold is not None:
            ho = row.hold
            per = ', '.join(f'{d * 1e3:.2f}' for d in ho.push_slip)
            parts.append(f'hold: slip per push [mm] {per}; peak {ho.slip_peak * 1e3:.2f} mm, '
                         f'rotation {math.degrees(ho.rotation_peak):.2f} deg; force '
                         f'{ho.force_min:.2f}-{ho.force_max:.2f} N'
                         f'{"; DROPPED" if ho.dropped else ""}')
        if row.hinge is not None:
            hg = row.hinge
            parts.append(f'hinge: swing at HINGE on {math.degrees(hg.swing):.1f} deg; relative '
                         f'rotation over the turn {math.degrees(hg.relative_rotation):.1f} deg; '
                         f'object turned {math.degrees(hg.object_turn):.1f} deg in the world; '
                         f'translation peak {hg.translation_peak * 1e3:.1f} mm; force '
                         f'{hg.force_min:.2f}-{hg.force_max:.2f} N'
                         f'{"; DROPPED" if hg.dropped else ""}')
        if row.pick_up is not None:
            pu = row.pick_up
            parts.append(f'pick-up: lift {pu.lift * 1e3:.1f} mm, slip {pu.slip_peak * 1e3:.3f} mm,'
                         f' force {pu.force_min:.2f}-{pu.force_max:.2f} N'
                         f'{"; DROPPED" if pu.dropped else ""}')
        lines.append(f'{row.preset}:')
        lines.extend(f'  {p}' for p in parts)
        lines.extend(f'  NOTE {n}' for n in row.notes)
    return '\n'.join(lines)
