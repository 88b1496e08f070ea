# SPDX-License-Identifier: Apache-2.0
"""Contact estimation on the simulated cell: the runner's exploration, judged by the truth.

* `estimate` — the runner's ``est_contact`` (§3.8: 10 N, 5 N, linear phase 1 s over the 1 cm
  descent, rotational phase 1 s over the ±10° twist, release) → estimated vs true ``μ_c``,
  ``r`` per finger;
* `estimate_without_contact` — the estimator is asked to explore with the gripper open and
  nothing between the fingers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from slip_bringup.core.evaluation.agents import ControllerAgent, EstimatorAgent
from slip_bringup.core.evaluation.scene import controller_params, make_harness
from slip_bringup.core.evaluation.settings import EvalSettings, EvaluationError
from slip_bringup.core.evaluation.sim_runner_cell import (SequenceAgent, SimRunnerCell,
                                                          run_sequence)
from slip_bringup.core.evaluation.truth import TruthProbe
from slip_control.core.contact import ContactProperties, ContactSource
from slip_control.core.contact_estimator import EstimationPhase


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


def estimate(preset: str, settings: EvalSettings = EvalSettings()) -> EstimationOutcome:
    """Run the runner's ``est_contact`` (the §3.8 exploration) on ``preset``; compare with truth.

    The sequence is the experiment runner's own (`slip_control.core.exploration`), played by
    its step machine against `SimRunnerCell`: grasp without HOLD (there are no valid
    properties yet), exploration force, LINEAR phase over the descent, ROTATIONAL phase over
    the twist, release, read, return to the pick-up pose. Each phase is started through the
    estimator node's pre-check. The slip controller's host runs beside it (DEFAULT properties:
    HOLD is refused, OFF accepted), as in the node graph.
    """
    h = make_harness(preset, settings)
    agent = EstimatorAgent(settings.estimator)
    ctl = ControllerAgent(controller_params(settings, h.cell), agent.estimator.properties,
                          settings.watchdog_period)
    probe = TruthProbe()
    seq = SequenceAgent()
    for a in (agent, ctl, probe, seq):
        h.add_agent(a)
    cell = SimRunnerCell(h, agent, ctl)
    run_sequence(h, seq, cell, 'est_contact', settings.runner)
    descent = next((m for m in cell.moves if m.lift < 0.0), None)
    twists = [m for m in cell.moves if m.rotation != 0.0][:2]
    if descent is None or len(twists) < 2:
        raise EvaluationError(f'{preset}: the exploration did not run: '
                              f'{seq.progress.message if seq.progress else "no progress"}')
    i0, i1 = probe.at(descent.t_start), probe.at(descent.t_end)
    slide = math.hypot(probe.x[i1] - probe.x[i0], probe.y[i1] - probe.y[i0])
    theta0 = probe.theta[probe.at(twists[0].t_start)]
    twist = probe.peak_rotation(twists[0].t_start, twists[1].t_end, theta0)
    dropped = probe.dropped[probe.at(twists[1].t_end)]
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
