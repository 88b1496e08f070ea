# SPDX-License-Identifier: Apache-2.0
"""One drawn object through every scenario of the population evaluation, judged by the truth.

`evaluate_object(task)` draws object ``task.index`` of population ``task.seed``
(`friction_models.core.population.draw_object`) and runs on it, in the in-process simulated
cell (`slip_bringup.core.evaluation`: the experiment runner's exploration and the
``slip_controller`` node's own host):

1. **estimation** — the runner's ``est_contact`` exploration; per finger the estimate against
   the true ``μ_c`` and ``r``, and whether the reported 95 % interval (±1.96 σ) covers the
   truth;
2. with the **estimated** properties (the real pipeline; the true ones with
   ``truth_properties``), once per control-law family of the task:
   **hold** under `holding.scaled_pushes` (loads scaled to the object's weight),
   **linear** 20 mm / 2 s from the hanging pose (the gripper turned so that the CoM hangs
   straight below the grasp point; `poses.turn_to_hanging_angle`), **rotational** 20° / 2 s
   from the pose with the CoM lever horizontal (`poses.lever_horizontal_turn`; the sign of the
   angle is the one gravity drives) and **hinge** through 60° from the pose 60° from hanging
   (`poses.hinge_start_turn`). Each set-up turn starts from the object's rotation in the pads
   after the pick-up (an object whose CoM is off to the side swings before HOLD catches it).

Every scenario is also classified by `feasibility.assess` (stated physical criteria). Success
criteria (the issue's targets; all from the simulator truth, never the controller's belief):

=============  ==============================================================================
estimation     both fingers: ``|μ_c − μ_c,true| ≤ 0.01`` and ``|r − r_true| ≤ 10 % r_true``
hold           no drop; grasp-point slip ≤ 1 mm and rotation ≤ 2° over the pushes and taps;
               peak commanded force from HOLD on ≤ 1.5 × ``hold_force_needed_held`` + 1 N
               (the need in the pose the object is really held in: truth rotation in the pads)
linear         no drop; the controller ended the slip; ``|final error|`` ≤ 1 mm; tracking RMS
               over ``[0, T]`` ≤ 1 mm; end time within ±10 % of ``T``
rotational     the same with 1° for 1 mm
hinge          no drop; ``| |relative rotation| − 60° |`` ≤ 6°; grasp-point translation over
               the turn ≤ 10 mm
=============  ==============================================================================

``failure`` names the first criterion missed (``'<criterion>: <value>'``); when the controller
or the estimator said it succeeded (``reported``) and the truth disagrees, it starts with
``'reported success but '``. A refused request is ``'refused: …'``, a scenario that could not
be set up ``'error: …'``, and an exception inside the deployed code ``'crash: …'`` (recorded,
so that one object does not end a population run; the table counts them). The result
depends only on the task: the same task gives the same `ObjectResult` in any process
(``cpu_seconds`` aside).
"""
from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from friction_models.core.harness import HarnessError
from friction_models.core.population import PopulationObject, PopulationRanges, draw_object

from slip_bringup.core.evaluation.estimation import EstimationOutcome, estimate
from slip_bringup.core.evaluation.hinge import HingeOutcome, hinge
from slip_bringup.core.evaluation.holding import (HoldOutcome, Push, hold_under_disturbance,
                                                  scaled_pushes, sustained)
from slip_bringup.core.evaluation.poses import hanging_angle
from slip_bringup.core.evaluation.settings import EvalSettings, EvaluationError
from slip_bringup.core.evaluation.trajectories import (TrajectoryOutcome, linear_slip,
                                                       rotational_slip)
from slip_bringup.population.feasibility import (Feasibility, assess, hold_force_needed,
                                                hold_force_needed_held)
from slip_bringup.population.results import SCENARIOS, ObjectResult, ScenarioResult
from slip_bringup.population.statistics import Z_95
from slip_control.core import params as controller_params
from slip_control.core.contact import ContactProperties
from slip_control.core.mode_switch import ModeRequest

_NAN = math.nan
DEG = math.pi / 180.0

#: Control-law families: ``thesis`` (the reference laws, the requests' default) always; the
#: others of ``slip_control.core.params.CONTROL_LAWS`` when `ModeRequest` has ``control_law``.
THESIS = 'thesis'
KNOWN_FAMILIES = (THESIS, 'model')


@dataclass(frozen=True)
class Criteria:
    """Success thresholds of the population evaluation (SI; module docstring)."""

    mu_c_abs: float = 0.01                 # -
    r_rel: float = 0.10                    # -
    hold_slip: float = 0.001               # m
    hold_rotation: float = 2.0 * DEG       # rad
    hold_force_factor: float = 1.5         # -
    hold_force_offset: float = 1.0         # N
    linear_error: float = 0.001            # m (final and tracking RMS)
    rotational_error: float = 1.0 * DEG    # rad (final and tracking RMS)
    duration_rel: float = 0.10             # -
    hinge_rotation: float = 6.0 * DEG      # rad
    hinge_translation: float = 0.010       # m


#: Scenario set-ups (SI).
LINEAR_DISTANCE = 0.020
LINEAR_DURATION = 2.0
ROTATIONAL_ANGLE = 20.0 * DEG
ROTATIONAL_DURATION = 2.0
HINGE_TURN = 60.0 * DEG


@dataclass(frozen=True)
class PopulationTask:
    """Everything that determines one object's result (picklable; sent to the workers).

    Attributes:
        seed: Population seed.
        index: Object index in the population.
        ranges: Ranges the object is drawn from.
        controllers: Control-law families to run the controller scenarios with.
        scenarios: Scenarios to run (`SCENARIOS` order; estimation always runs: the
            controllers need its properties).
        physics_dt: Physics step [s].
        velocity_model: ``'chips'`` or ``'ideal'``.
        truth_properties: The controllers get the simulator's true contact properties instead
            of the estimate.
    """

    seed: int
    index: int
    ranges: PopulationRanges = PopulationRanges()
    controllers: tuple[str, ...] = (THESIS,)
    scenarios: tuple[str, ...] = SCENARIOS
    physics_dt: float = EvalSettings.physics_dt
    velocity_model: str = 'chips'
    truth_properties: bool = False


def _request_fields() -> set[str]:
    return {f.name for f in dataclasses.fields(ModeRequest)}


def available_families() -> tuple[str, ...]:
    """Control-law families this build can run (``thesis``, plus ``model`` once
    `ModeRequest` has a ``control_law`` field)."""
    if 'control_law' not in _request_fields():
        return (THESIS,)
    laws = tuple(getattr(controller_params, 'CONTROL_LAWS', KNOWN_FAMILIES))
    return (THESIS,) + tuple(law for law in laws if law != THESIS)


def noise_seed(seed: int, index: int) -> int:
    """Sensor-noise seed of object ``(seed, index)`` in [0, 2³¹) (independent of the draw)."""
    return int(np.random.SeedSequence([seed, index, 1]).generate_state(1)[0]) & 0x7FFFFFFF


def object_parameters(obj: PopulationObject) -> dict[str, float]:
    """The parameters the failure breakdown splits on (SI; ``gradient_map`` 0/1)."""
    p = obj.preset
    c1, c2 = p.finger_1, p.finger_2
    r_mean = 0.5 * (c1.r + c2.r)
    lever = math.hypot(*p.com_offset)
    return {
        'mass': p.mass,
        'mu_c_min': min(c1.mu_c, c2.mu_c),
        'mu_c_max': max(c1.mu_c, c2.mu_c),
        'static_ratio_max': max(c1.mu_s / c1.mu_c, c2.mu_s / c2.mu_c),
        'mu_v': 0.5 * (c1.mu_v + c2.mu_v),
        'r_mean': r_mean,
        'com_offset': lever,
        'com_lever_over_r': lever / r_mean,
        'com_angle_from_down': abs(hanging_angle(p.com_offset)),
        'thickness': p.thickness,
        'table_mu': p.table_mu,
        'noise_scale': obj.sensors.noise_scale,
        'gradient_map': 1.0 if 'grad' in p.surface else 0.0,
    }


def evaluate_object(task: PopulationTask) -> ObjectResult:
    """Run every scenario of ``task`` on its object (module docstring)."""
    cpu0 = time.process_time()        # cost accounting only, not control logic
    unknown = [c for c in task.controllers if c not in available_families()]
    if unknown:
        raise ValueError(f'unknown controller famil{"ies" if len(unknown) > 1 else "y"} '
                         f'{", ".join(unknown)} (available: {", ".join(available_families())})')
    obj = draw_object(task.seed, task.index, task.ranges)
    name = obj.name
    base = EvalSettings(physics_dt=task.physics_dt, seed=noise_seed(task.seed, task.index),
                        velocity_model=task.velocity_model, objects={name: obj.preset},
                        sensors=obj.sensors)
    weight = obj.preset.mass * 9.81
    pushes = scaled_pushes(weight)
    feas = assess(obj.preset, [(p.fx, p.fy, p.torque) for p in sustained(pushes)])
    results: list[ScenarioResult] = []
    est: EstimationOutcome | None = None
    try:
        est = estimate(name, base)
        results.append(judge_estimation(est))
    except (EvaluationError, HarnessError) as exc:
        results.append(ScenarioResult('estimation', '-', True, '', False,
                                      f'error: {exc}', {}, 'error'))
    properties: ContactProperties | None
    if task.truth_properties:
        properties = None
    else:
        properties = est.properties if est is not None else None
    criteria = Criteria()
    for family in task.controllers:
        # The family is named on every request when the build can (so a changed default law
        # does not change the reference); before control_law existed, thesis is the only law.
        settings = dataclasses.replace(
            base, control_law=family if 'control_law' in _request_fields() else '')
        for scenario in task.scenarios:
            if scenario == 'estimation':
                continue
            if est is None and not task.truth_properties:
                results.append(ScenarioResult(scenario, family, not feas.reason(scenario),
                                              feas.reason(scenario), False,
                                              'error: no estimate', {}, 'not run'))
                continue
            results.append(_scenario(scenario, family, name, obj, settings, properties,
                                     pushes, feas, criteria))
    return ObjectResult(seed=task.seed, index=task.index, name=name,
                        parameters=object_parameters(obj), surface=obj.preset.surface,
                        scenarios=tuple(results), cpu_seconds=time.process_time() - cpu0)


#: Set-up grasp of the HOLD scenario: this × the force the object's weight needs [-] ...
HOLD_SETUP_MARGIN = 1.5
#: ... at most this [N] (the gripper's range).
HOLD_SETUP_MAX_FORCE = 40.0


def _hold(name: str, obj: PopulationObject, pushes: tuple[Push, ...], settings: EvalSettings,
          properties: ContactProperties | None, criteria: Criteria) -> ScenarioResult:
    """HOLD under ``pushes``, judged against the need in the pose the object is held in.

    The scene starts with the object held still in the air: the set-up grasp is
    `HOLD_SETUP_MARGIN` × the force its weight needs (at least the simulator's 10 N), so a
    heavy object on a long lever does not swing in the pads before HOLD takes over — catching
    a swinging object is not the load the protocol measures.
    """
    still = hold_force_needed(obj.preset, ())
    setup = min(HOLD_SETUP_MAX_FORCE, max(settings.reset_grasp_force, HOLD_SETUP_MARGIN * still))
    out = hold_under_disturbance(name, pushes,
                                 dataclasses.replace(settings, reset_grasp_force=setup),
                                 properties)
    loads = [(p.fx, p.fy, p.torque) for p in sustained(pushes)]
    return judge_hold(out, hold_force_needed_held(obj.preset, loads, out.rotation_held),
                      criteria)


def _scenario(scenario: str, family: str, name: str, obj: PopulationObject,
              settings: EvalSettings, properties: ContactProperties | None,
              pushes: tuple[Push, ...], feas: Feasibility, criteria: Criteria) -> ScenarioResult:
    """Run one controller scenario and judge it; refusals and errors become failures."""
    reason = feas.reason(scenario)
    com = obj.preset.com_offset
    runs: dict[str, Callable[[], ScenarioResult]] = {
        'hold': lambda: _hold(name, obj, pushes, settings, properties, criteria),
        'linear': lambda: judge_trajectory(linear_slip(
            name, LINEAR_DISTANCE, LINEAR_DURATION, settings, properties, hang_com=com),
            criteria),
        'rotational': lambda: judge_trajectory(_rotational(name, com, settings, properties),
                                               criteria),
        'hinge': lambda: judge_hinge(_hinge(name, com, settings, properties), criteria),
    }
    if scenario not in runs:
        raise ValueError(f'unknown scenario {scenario!r} (known: {", ".join(SCENARIOS)})')
    try:
        judged = runs[scenario]()
    except EvaluationError as exc:
        text = str(exc)
        kind = 'refused' if 'refused' in text else 'error'
        judged = ScenarioResult(scenario, family, True, '', False, f'{kind}: {text}', {}, kind)
    except HarnessError as exc:
        judged = ScenarioResult(scenario, family, True, '', False, f'error: {exc}', {}, 'error')
    except Exception as exc:      # one object's crash must not end a population run
        judged = ScenarioResult(scenario, family, True, '', False,
                                f'crash: {type(exc).__name__}: {exc}', {}, 'crash')
    return dataclasses.replace(judged, controller=family, feasible=not reason,
                               infeasible_reason=reason)


def _rotational(name: str, com: tuple[float, float], settings: EvalSettings,
                properties: ContactProperties | None) -> TrajectoryOutcome:
    return rotational_slip(name, ROTATIONAL_ANGLE, ROTATIONAL_DURATION, settings, properties,
                           lever_com=com)


def _hinge(name: str, com: tuple[float, float], settings: EvalSettings,
           properties: ContactProperties | None) -> HingeOutcome:
    return hinge(name, HINGE_TURN, settings, properties, hinge_com=com)


def _worst(values: list[float]) -> float:
    """The value of largest magnitude (NaN if any is NaN)."""
    if any(not math.isfinite(v) for v in values):
        return _NAN
    return max(values, key=abs)


def _failure(claimed: bool, missed: list[str]) -> str:
    if not missed:
        return ''
    return ('reported success but ' if claimed else '') + missed[0]


# ----------------------------------------------------------------------------- judges
def judge_estimation(est: EstimationOutcome, criteria: Criteria = Criteria()
                     ) -> ScenarioResult:
    """Estimation against the truth, per finger (metrics: worst finger, coverage as 0–1)."""
    metrics: dict[str, float] = {}
    missed: list[str] = []
    ok_fingers = covered_mu = covered_r = 0
    for f in est.fingers:
        k = f.finger
        mu_err = f.mu_c_error
        r_rel = f.r_error / f.r_true
        metrics[f'mu_c_error_{k}'] = mu_err
        metrics[f'r_error_rel_{k}'] = r_rel
        metrics[f'mu_c_std_{k}'] = f.mu_c_std
        metrics[f'r_std_rel_{k}'] = f.r_std / f.r_true
        finite = math.isfinite(mu_err) and math.isfinite(r_rel)
        if finite and abs(mu_err) <= criteria.mu_c_abs and abs(r_rel) <= criteria.r_rel:
            ok_fingers += 1
        else:
            if not (math.isfinite(mu_err) and abs(mu_err) <= criteria.mu_c_abs):
                missed.append(f'mu_c error: finger {k} {mu_err:+.4f}')
            if not (math.isfinite(r_rel) and abs(r_rel) <= criteria.r_rel):
                missed.append(f'r error: finger {k} {100 * r_rel:+.1f} %')
        covered_mu += int(math.isfinite(mu_err) and abs(mu_err) <= Z_95 * f.mu_c_std)
        covered_r += int(math.isfinite(r_rel) and abs(f.r_error) <= Z_95 * f.r_std)
    n = len(est.fingers)
    metrics.update(mu_c_error=_worst([f.mu_c_error for f in est.fingers]),
                   r_error_rel=_worst([f.r_error / f.r_true for f in est.fingers]),
                   fingers_ok=ok_fingers / n,
                   mu_c_covered=covered_mu / n, r_covered=covered_r / n,
                   valid=float(est.valid), dropped=float(est.dropped),
                   claimed_success=float(est.valid))
    if est.dropped:
        missed.insert(0, 'dropped during the exploration')
    return ScenarioResult('estimation', '-', True, '', not missed,
                          _failure(est.valid, missed), metrics,
                          'valid' if est.valid else 'invalid')


def judge_hold(out: HoldOutcome, needed: float, criteria: Criteria = Criteria()
               ) -> ScenarioResult:
    """HOLD under the scaled pushes: no drop, slip, rotation, peak force against the need."""
    peak = max(out.force_max, out.force_max_settle)
    limit = criteria.hold_force_factor * needed + criteria.hold_force_offset
    metrics = {'slip_peak': out.slip_peak, 'rotation_peak': out.rotation_peak,
               'sustained_slip': out.sustained_slip, 'tap_slip': out.tap_slip,
               'slip_final': out.slip_final, 'force_peak': peak,
               'force_peak_settle': out.force_max_settle,
               'force_peak_disturbance': out.force_max, 'force_min': out.force_min,
               'force_needed': needed, 'force_peak_over_needed': peak / needed,
               'dropped': float(out.dropped), 'claimed_success': 0.0}
    missed = []
    if out.dropped:
        missed.append('dropped')
    if not out.slip_peak <= criteria.hold_slip:
        missed.append(f'slip: {out.slip_peak * 1e3:.2f} mm')
    if not out.rotation_peak <= criteria.hold_rotation:
        missed.append(f'rotation: {out.rotation_peak / DEG:.2f} deg')
    if not peak <= limit:
        missed.append(f'force peak: {peak:.1f} N > {limit:.1f} N')
    return ScenarioResult('hold', THESIS, True, '', not missed, _failure(False, missed),
                          metrics, 'held' if not out.dropped else 'dropped')


def judge_trajectory(out: TrajectoryOutcome, criteria: Criteria = Criteria()
                     ) -> ScenarioResult:
    """LINEAR or ROTATIONAL: drop, end, final error, tracking RMS, duration (truth)."""
    linear = out.mode.name == 'LINEAR'
    scenario = 'linear' if linear else 'rotational'
    tol = criteria.linear_error if linear else criteria.rotational_error
    unit, scale = ('mm', 1e3) if linear else ('deg', 1.0 / DEG)
    claimed = out.result is not None and out.result.success
    duration_rel = (out.result_time - out.duration) / out.duration
    metrics = {'final_error': out.final_error, 'achieved': out.achieved,
               'tracking_rms': out.trajectory_rms, 'tracking_max': out.trajectory_max,
               'controller_steps_tracking_rms': out.tracking_rms,
               'duration': out.result_time, 'duration_error_rel': duration_rel,
               ('off_axis' if linear else 'translation'): out.off_axis,
               'force_min': out.force_min, 'force_max': out.force_max,
               'dropped': float(out.dropped), 'claimed_success': float(claimed),
               'controller_final_error': out.result.final_error if out.result else _NAN}
    missed = []
    if out.dropped:
        missed.append('dropped')
    if out.result is None:
        missed.append('no end: the controller did not end the slip')
    if not abs(out.final_error) <= tol:
        missed.append(f'final error: {out.final_error * scale:+.2f} {unit}')
    if not out.trajectory_rms <= tol:
        missed.append(f'tracking: RMS {out.trajectory_rms * scale:.2f} {unit}')
    if out.result is not None and not abs(duration_rel) <= criteria.duration_rel:
        missed.append(f'duration: ended at {out.result_time:.2f} s of {out.duration:.1f} s')
    reported = out.result.message if out.result is not None else 'no result'
    return ScenarioResult(scenario, THESIS, True, '', not missed, _failure(claimed, missed),
                          metrics, reported)


def judge_hinge(out: HingeOutcome, criteria: Criteria = Criteria()) -> ScenarioResult:
    """HINGE: no drop, relative rotation 60 ± 6°, translation over the turn ≤ 10 mm."""
    metrics = {'rotation_error': out.rotation_error,
               'relative_rotation': out.relative_rotation, 'swing': out.swing,
               'object_turn': out.object_turn, 'translation_turn': out.translation_turn,
               'translation_peak': out.translation_peak, 'force_min': out.force_min,
               'force_max': out.force_max, 'dropped': float(out.dropped),
               'claimed_success': 0.0}
    missed = []
    if out.dropped:
        missed.append('dropped')
    if not abs(out.rotation_error) <= criteria.hinge_rotation:
        missed.append(f'rotation: {abs(out.relative_rotation) / DEG:.1f} deg of '
                      f'{abs(out.gripper_turn) / DEG:.0f}')
    if not out.translation_turn <= criteria.hinge_translation:
        missed.append(f'translation: {out.translation_turn * 1e3:.1f} mm')
    return ScenarioResult('hinge', THESIS, True, '', not missed, _failure(False, missed),
                          metrics, 'dropped' if out.dropped else 'hinged')
