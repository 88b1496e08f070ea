# SPDX-License-Identifier: Apache-2.0
"""Parameter sets of the slip_control nodes as frozen dataclasses (ros_interfaces §6.4–6.6).

One dataclass per node; groups are nested dataclasses flattened with ``.`` by
`slip_cell_common.core.param_schema` (``linear.kp``). Defaults are those of
ros_interfaces §6.4–6.6 and control_and_estimation §4.10. Fields beyond those tables are marked
*(addition)* in their description; they make limits and tuning knobs parameters instead of
literals (house style §11).

``validate()`` checks every field against its metadata (range, choices, finiteness) plus the
cross-field rules, and raises `ParameterError` listing all problems at once.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from slip_cell_common.core import names
from slip_cell_common.core.frames import FrameParams
from slip_cell_common.core.param_schema import ParameterError, check_value, flatten, specs
from slip_cell_common.core.param_schema import ranged_field as _f


def _problems(instance: Any) -> list[str]:
    """Range/choice/finiteness problems of every (flattened) field of ``instance``."""
    flat = flatten(instance)
    problems: list[str] = []
    for spec in specs(type(instance)):
        problems.extend(check_value(spec, flat[spec.name]))
    return problems


def _raise_if(problems: list[str]) -> None:
    if problems:
        raise ParameterError('; '.join(problems))


def _i(default: int, low: int, high: int, description: str) -> Any:
    return _f(default, '-', low, high, description)


def _b(default: bool, description: str) -> Any:
    return field(default=default, metadata={'description': description})


def _group(cls: type) -> Any:
    return field(default_factory=cls)


# ---------------------------------------------------------------------------------------------
# contact_estimator (§6.4; control_and_estimation §3)
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class EstimatorLinearParams:
    """Sample gates of the linear phase (§3.3)."""

    max_abs_omega: float = _f(0.1, 'rad/s', 0.0, 10.0,
                              'skip linear samples rotating faster than this')
    static_speed: float = _f(0.002, 'm/s', 0.0, 0.1,
                             'below this sliding speed a sample counts as static')
    fit_min_speed: float = _f(0.006, 'm/s', 0.0, 0.1,
                              '(addition) sliding samples slower than this stay out of the '
                              'mu_c/mu_v fit: near the Stribeck speed the static excess of '
                              'friction biases mu_c up (falls back to every sliding sample '
                              'when too few are faster)')


@dataclass(frozen=True)
class EstimatorRotationalParams:
    """Sample gates of the rotational phase (§3.4)."""

    min_abs_omega: float = _f(0.1, 'rad/s', 0.0, 10.0,
                              'skip rotational samples turning slower than this')
    max_speed: float = _f(0.02, 'm/s', 0.0, 0.1,
                          'skip rotational samples whose pad centre translates faster than '
                          'this (the load-share gate below does the fine selection)')
    max_load_share: float = _f(0.5, '-', 0.05, 1.0,
                               '(addition) skip samples whose tangential force exceeds this '
                               'share of mu_c f_n, far from pure rotation (unless fewer than '
                               'min_samples_rotational would remain)')
    min_slip_speed: float = _f(0.002, 'm/s', 0.0, 0.1,
                               '(addition) skip samples whose rotational sliding speed r |w| '
                               'is below this (Stribeck region); lowered to half, then a '
                               'quarter, when too few samples are faster')
    viscous_shape: float = _f(1.2, '-', 0.5, 3.0,
                              '(addition) u / r^2 of the pressure map, used to remove the '
                              'viscous torque mu_v u |w| (9/8 uniform disc, 4/3 line)')


@dataclass(frozen=True)
class EstimatorOnlineParams:
    """Online update during controlled slip (§3.6, corrected)."""

    enabled: bool = _b(False, 'allow the ONLINE phase (optional feature)')
    min_speed: float = _f(0.005, 'm/s', 0.0, 0.1,
                          'sliding speed needed for a mu_c update')
    max_abs_omega: float = _f(0.3, 'rad/s', 0.0, 10.0,
                              'rotation rate above which no mu_c update is made')
    forgetting: float = _f(0.999, '-', 0.5, 1.0,
                           '(addition) RLS forgetting factor per sample (0.999 = ~1000 samples)')
    force_noise: float = _f(0.05, 'N', 1e-6, 10.0,
                            '(addition) 1-sigma noise of the tangential force')
    torque_noise: float = _f(0.0005, 'N*m', 1e-9, 1.0,
                             '(addition) 1-sigma noise of the torque')
    initial_std_mu_c: float = _f(0.15, '-', 1e-6, 2.0,
                                 '(addition) prior 1-sigma of mu_c (lower bound of the fit std)')
    initial_std_mu_v: float = _f(2.0, '1/(m/s)', 1e-6, 100.0,
                                 '(addition) prior 1-sigma of mu_v')
    initial_std_r: float = _f(0.002, 'm', 1e-7, 0.05,
                              '(addition) prior 1-sigma of r (lower bound of the fit std)')
    min_normal_force: float = _f(0.3, 'N', 0.0, 100.0,
                                 '(addition) skip online samples with f_n below this (sliding '
                                 'in the air happens at the controllers\' force floor)')
    limit_surface_exponent: float = _f(1.7, '-', 1.0, 2.0,
                                       '(addition) exponent n of the pad limit surface '
                                       '(f_t/(mu_c f_n))^n + (tau/(mu_c r f_n))^n = 1 used '
                                       'for r: 2 = ellipsoid, 1.7 = uniformly pressed disc')
    max_load_ratio: float = _f(0.9, '-', 0.1, 1.0,
                               '(addition) r is updated only while the Coulomb part of f_t is '
                               'at most this fraction of mu_c f_n')
    r_needs_mu_c_rel_std: float = _f(0.08, '-', 0.0, 1.0,
                                     '(addition) r is updated only while the 1-sigma of mu_c '
                                     'is at most this fraction of mu_c')
    min_updates: int = _i(10, 1, 100000,
                          '(addition) updates before the online result is published')
    publish_period: float = _f(0.2, 's', 0.0, 10.0,
                               '(addition) minimum time between published online updates')


@dataclass(frozen=True)
class ContactEstimatorParams:
    """Parameters of ``slip_control/contact_estimator`` (ros_interfaces §6.4).

    ``frames`` (the pad offset locates the centre of pressure from the sensor torques) comes
    from the shared ``cell.yaml`` in a graph, like the slip controller's.
    """

    linear: EstimatorLinearParams = _group(EstimatorLinearParams)
    rotational: EstimatorRotationalParams = _group(EstimatorRotationalParams)
    min_normal_force: float = _f(1.0, 'N', 0.0, 100.0, 'skip samples with f_n below this')
    min_samples_linear: int = _i(20, 3, 1000000, 'sliding samples needed for linear_valid')
    min_samples_rotational: int = _i(20, 3, 1000000,
                                     'rotational samples needed for rotational_valid')
    min_speed_span: float = _f(0.002, 'm/s', 0.0, 1.0,
                               'speed span needed to fit mu_v (viscous_valid)')
    mu_c_max: float = _f(2.0, '-', 1e-3, 10.0, 'largest plausible mu_c')
    mu_c_std_floor: float = _f(0.001, '-', 0.0, 1.0,
                               '(addition) model-error 1-sigma added in quadrature to the fit '
                               'std of mu_c (calibrated on a population, docs/evaluation.md)')
    r_std_floor: float = _f(0.02, '-', 0.0, 1.0,
                            '(addition) model-error 1-sigma of r as a fraction of r, added in '
                            'quadrature (ellipsoidal limit surface vs the pad\'s own)')
    r_min: float = _f(0.001, 'm', 1e-6, 1.0, 'smallest plausible torsional radius')
    r_max: float = _f(0.05, 'm', 1e-6, 1.0, 'largest plausible torsional radius')
    sync_tolerance: float = _f(0.020, 's', 0.0, 1.0,
                               'finger-2 velocity stamp within this of finger 1')
    ft_stale_after: float = _f(0.020, 's', 0.0, 1.0, 'F/T samples older than this are stale')
    start_max_age: float = _f(0.5, 's', 0.001, 60.0,
                              '(addition) contact/start refuses a LINEAR/ROTATIONAL phase when '
                              'a sensor stream is missing or its latest sample is older')
    online: EstimatorOnlineParams = _group(EstimatorOnlineParams)
    frames: FrameParams = _group(FrameParams)
    preset_file: str = field(default='', metadata={
        'read_only': True, 'description': 'CSV or YAML file with contact presets'})
    preset_name: str = field(default='', metadata={
        'description': 'preset (object) to load at start; empty = none'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every problem (ranges and cross-field rules)."""
        problems = _problems(self)
        if self.r_min >= self.r_max:
            problems.append(f'r_min = {self.r_min} must be below r_max = {self.r_max} m')
        if self.preset_name and not self.preset_file:
            problems.append('preset_name is set but preset_file is empty')
        _raise_if(problems)


# ---------------------------------------------------------------------------------------------
# slip_controller (§6.5; control_and_estimation §4)
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class HoldParams:
    """HOLD (slip avoidance, §4.4)."""

    margin: float = _f(2.0, '-', 1.0, 10.0, 'safety factor on the limit-surface force D/mu_c')
    floor: float = _f(2.0, 'N', 0.0, 40.0, 'minimum of the limit-surface force before margin')
    slip_gain: float = _f(100.0, 'N/(m/s)', 0.0, 10000.0, 'force per slip speed')
    fall_filter: float = _f(0.95, '-', 0.0, 1.0,
                            'per-sample factor of the first-order fall (0.95 = 0.16 s at 120 Hz)')


@dataclass(frozen=True)
class LinearParams:
    """LINEAR slip (§4.5, §4.9)."""

    kp: float = _f(2.0, '1/s', 0.0, 100.0, 'position-error gain of the commanded speed')
    ki: float = _f(1000.0, 'N/m', 0.0, 100000.0, 'integral gain on the speed error')
    kd: float = _f(0.1, 's^2/m', 0.0, 100.0, 'acceleration damping (times f_slip)')
    kv: float = _f(50.0, 's/m', 0.0, 10000.0, 'speed-error gain (times f_slip)')
    slip_filter: float = _f(0.95, '-', 0.0, 1.0, 'per-sample filter factor of f_slip')
    floor: float = _f(0.6, 'N', 0.0, 40.0, 'minimum desired grasp force')
    accel_gate: float = _f(0.1, 'm/s^2', 0.0, 100.0, 'f_slip is updated only below this')
    stop_speed: float = _f(0.0005, 'm/s', 0.0, 0.1,
                           'after T, the trajectory ends once |v| is below this')


@dataclass(frozen=True)
class RotationalParams:
    """ROTATIONAL slip (§4.6, §4.9)."""

    kp: float = _f(2.0, '1/s', 0.0, 100.0, 'angle-error gain of the commanded rate')
    ki: float = _f(40.0, 'N/rad', 0.0, 100000.0, 'integral gain on the rate error')
    kd: float = _f(0.05, 's^2/rad', 0.0, 100.0, 'angular-acceleration damping (times f_slip)')
    kw: float = _f(2.0, 's/rad', 0.0, 10000.0, 'rate-error gain (times f_slip)')
    slip_filter: float = _f(0.95, '-', 0.0, 1.0, 'per-sample filter factor of f_slip')
    floor: float = _f(0.6, 'N', 0.0, 40.0, 'minimum desired grasp force')
    accel_gate: float = _f(0.3927, 'rad/s^2', 0.0, 100.0, 'f_slip is updated only below this')
    translation_margin: float = _f(
        1.0, '-', 1.0, 10.0,
        'factor on ft/mu_c in the translation floor (1.0 = reference; 1.4 keeps the centre of '
        'rotation within about r of the pad centre on an elliptical limit surface)')
    kp_cop: float = _f(0.0, 'N/m', 0.0, 100000.0,
                       'translation floor gain on the centre-of-rotation distance beyond r')
    cop_min_rate: float = _f(0.026, 'rad/s', 0.0, 10.0,
                             'the kp_cop term is applied only while |omega| is at least this')
    cop_max_force: float = _f(5.0, 'N', 0.0, 100.0, 'cap of the kp_cop term')
    translation_gain: float = _f(
        300.0, 'N/(m/s)', 0.0, 10000.0,
        'force per grasp-point translation speed beyond cor_limit*r*|omega|')
    cor_limit: float = _f(1.0, '-', 0.0, 100.0,
                          'allowed centre-of-rotation offset, in units of r')
    stop_rate: float = _f(0.006, 'rad/s', 0.0, 1.0,
                          'after T, the trajectory ends once |omega| is below this')


@dataclass(frozen=True)
class HingeParams:
    """HINGE (§4.7)."""

    threshold: float = _f(1.4, '-', 1.0, 10.0, 'factor on the translational slip force ft/mu_c')
    floor: float = _f(0.6, 'N', 0.0, 40.0, 'minimum desired grasp force')
    slip_gain: float = _f(100.0, 'N/(m/s)', 0.0, 10000.0, 'force per translational slip speed')


@dataclass(frozen=True)
class TwistObserverParams:
    """(addition) Kalman filter of the slip twist used by the ``model`` HOLD and HINGE
    (twist_observer)."""

    accel_std: float = _f(0.3, 'm/s^2', 1e-4, 100.0,
                          'std of the slip acceleration driving the observer model')
    velocity_noise: float = _f(0.0005, 'm/s', 1e-6, 0.1,
                               'std of one velocity sample (quantisation and noise)')
    detect_speed: float = _f(0.0015, 'm/s', 1e-5, 0.1,
                             'estimated translation speed above which the object slips')
    detect_rate: float = _f(0.05, 'rad/s', 1e-4, 10.0,
                            'estimated rotation rate above which the object slips')


@dataclass(frozen=True)
class ModelHoldParams:
    """(addition) HOLD with the ``model`` law (model_hold): the force the measured load needs."""

    margin: float = _f(1.45, '-', 1.0, 10.0, 'factor on the limit-surface force D/mu_c')
    extra_force: float = _f(0.7, 'N', 0.0, 40.0, 'force added to margin*D/mu_c')
    max_margin: float = _f(1.45, '-', 1.0, 10.0,
                           'the force stays below (max_margin + learned margin) times the '
                           'remembered sustained D/mu_c, plus max_extra_force')
    max_extra_force: float = _f(0.9, 'N', 0.0, 40.0, 'see max_margin')
    slip_gain: float = _f(100.0, 's/m', 0.0, 10000.0,
                          'force per observed slip speed, relative to max(need, min_force)')
    adapt_gain: float = _f(500.0, '1/m', 0.0, 1.0e6,
                           'learned extra margin per metre of observed slip path beyond '
                           'adapt_deadzone')
    adapt_deadzone: float = _f(0.001, 'm', 0.0, 1.0,
                               'slip path (in the decaying memory) that teaches nothing: a '
                               'tap beyond the margin may slip this much')
    adapt_decay: float = _f(5.0, 's', 0.0, 3600.0,
                            'time constant of the slip path\'s decay (0 = never)')
    adapt_max: float = _f(1.0, '-', 0.0, 10.0, 'largest learned extra margin')
    load_filter_time: float = _f(0.008, 's', 0.0, 1.0,
                                 'time constant of the load low-pass (sensor noise)')
    sustain_time: float = _f(0.05, 's', 0.0, 1.0,
                             'a load counts as sustained once it lasted this long (a shorter '
                             'tap does not raise the force bound)')
    memory_time: float = _f(20.0, 's', 0.0, 3600.0,
                            'time constant of the decay of the remembered sustained need')
    fall_time: float = _f(0.3, 's', 0.0, 60.0, 'time constant of a force decrease')


@dataclass(frozen=True)
class ModelHingeParams:
    """(addition) HINGE with the ``model`` law (model_hinge): the object keeps its orientation
    in the world while the gripper turns, the grasp point does not translate."""

    orientation_gain: float = _f(2.0, '1/rad', 0.0, 100.0,
                                 'relative fall of the torque the pads may carry per radian '
                                 'the object is dragged away from hanging')
    orientation_integral: float = _f(1.0, '1/(rad*s)', 0.0, 1000.0,
                                     'the same for the time integral of that turn')
    integral_limit: float = _f(0.25, 'rad*s', 0.0, 100.0,
                               'bound of the integral of the turn')
    max_cor: float = _f(0.008, 'm', 1e-4, 1.0,
                        'the reference torque is at least r^2 ft/max_cor (a nearly hanging '
                        'object is not released about a centre of rotation further away)')
    max_load_ratio: float = _f(0.95, '-', 0.1, 1.0,
                               'largest f_t/(mu_c F): the force never falls below '
                               'ft/(mu_c max_load_ratio)')
    rotation_damping: float = _f(0.5, 's/rad', 0.0, 100.0,
                                 'relative force increase per observed rotation rate (damps '
                                 'a fast swing)')
    translation_gain: float = _f(100.0, 's/m', 0.0, 100000.0,
                                 'relative force increase per grasp-point translation speed '
                                 'beyond cor_offset*|omega| while slipping (0 = off)')
    cor_offset: float = _f(0.005, 'm', 1e-4, 0.1,
                           'grasp-point translation per radian of turn the translation term '
                           'tolerates')
    static_ratio: float = _f(1.3, '-', 1.0, 3.0,
                             'mu_s/mu_c assumed when the properties carry no valid mu_s')
    min_torque: float = _f(0.0005, 'N*m', 0.0, 1.0,
                           'mean torque below this counts as no torque (sensor noise)')


@dataclass(frozen=True)
class TrajectoryParams:
    """Trapezoidal reference trajectories (§4.3)."""

    accel_fraction: float = _f(0.2, '-', 0.01, 0.5,
                               'acceleration (and deceleration) time as a fraction of T')
    position_tolerance: float = _f(
        0.001, 'm', 1e-6, 0.1,
        '(addition) LINEAR ends "done" only within this of the distance; otherwise it ends '
        '"stalled" or "timeout" at T + settle_timeout')
    angle_tolerance: float = _f(
        0.01745, 'rad', 1e-6, 1.0,
        '(addition) ROTATIONAL ends "done" only within this of the angle (1 deg)')


#: Pressure shapes the model-based laws can assume (friction_models STANDARD_SURFACES).
PRESSURE_SHAPES: tuple[str, ...] = ('square', 'circle', 'line', 'line_grad', 'line_grad_x',
                                    'non_convex_1', 'non_convex_2')

#: Control-law families of the slip modes (docs/model_slip_control.md §1).
CONTROL_LAWS: tuple[str, ...] = ('thesis', 'model')


@dataclass(frozen=True)
class ModelParams:
    """Model-based slip laws: the friction model and what they share
    (docs/model_slip_control.md §2, §3)."""

    pressure_shape: str = field(default='circle', metadata={
        'choices': PRESSURE_SHAPES,
        'description': 'pressure map assumed for the pads\' limit surface (scaled to the '
                       'estimated r)'})
    stribeck_velocity: float = _f(1.0e-3, 'm/s', 1e-6, 1.0,
                                  'Stribeck velocity v_s of the friction model')
    gravity: float = _f(9.81, 'm/s^2', 0.1, 100.0, 'gravity (object mass from its static load)')
    min_force: float = _f(0.6, 'N', 0.0, 40.0, 'smallest grasp force commanded')
    max_force: float = _f(40.0, 'N', 0.1, 80.0, 'largest grasp force commanded (gripper limit)')
    refusal_margin: float = _f(
        1.0, '-', 0.5, 10.0,
        'a slip is refused when the load is below this times what static friction carries at '
        'min_force (1.0: only what the model says is impossible)')
    no_slip_time: float = _f(0.5, 's', 0.01, 10.0,
                             'at min_force without motion this long ends "no slip at minimum '
                             'force"')
    ft_noise: float = _f(0.03, 'N', 1e-4, 10.0,
                         '1-sigma of the two-finger mean tangential force (observer)')
    breakaway_rate: float = _f(1.0, '1/s', 0.0, 100.0,
                               'while the object sticks behind the reference, the force is '
                               'lowered by this fraction per second until it moves')
    breakaway_max: float = _f(0.9, '-', 0.0, 0.99, 'largest break-away reduction')
    max_scale: float = _f(3.0, '-', 1.0, 100.0,
                          'largest factor the feedback applies to the model force')
    arrival_scale: float = _f(1.5, '-', 1.0, 100.0,
                              'factor on the model force once the object arrived (within half '
                              'the tolerance, decelerating) but still moves')
    fall_rate: float = _f(5.0, '1/s', 0.0, 1000.0,
                          'the force command falls at most this fraction per second '
                          '(exponentially; rises act at once; 0 = no limit)')


@dataclass(frozen=True)
class ModelLinearParams:
    """Model-based LINEAR slip (docs/model_slip_control.md §4)."""

    bandwidth: float = _f(70.0, 'rad/s', 0.1, 200.0,
                          'natural frequency of the tracking-error dynamics')
    damping: float = _f(1.0, '-', 0.1, 5.0, 'damping ratio of the tracking-error dynamics')
    integral: float = _f(0.03, '-', 0.0, 5.0,
                         'integral gain as a fraction of bandwidth^3')
    force_lag: float = _f(0.02, 's', 0.0, 1.0,
                          'lead for the inner grasp-force loop: the rate feedback acts on the '
                          'observed rate this far ahead (rate + acceleration x lag)')
    adaptation: float = _f(0.05, 's', 0.0, 10.0,
                           'time constant of the online friction correction from the F/T '
                           'while sliding (0 = off)')
    motion_speed: float = _f(0.002, 'm/s', 1e-5, 0.1,
                             'observed speed above which the object counts as sliding')
    torque_share: float = _f(0.5, '-', 0.0, 1.0,
                             'share of the measured load torque the model force carries '
                             '(0: translation only; the object then turns towards hanging '
                             'while it slides)')
    keep_speed: float = _f(0.003, 'm/s', 0.0, 0.1,
                           'before the deceleration the speed set-point stays at least this, '
                           'so an object ahead slows down instead of sticking')
    torque_time: float = _f(0.3, 's', 0.0, 10.0,
                            'time constant of the load-torque estimate (slow: the friction '
                            'torque collapses for a moment when the object breaks away, the '
                            'load does not)')
    max_turn: float = _f(1.0472, 'rad', 0.0, 6.3,
                         'a slide during which the object turns more than this ends "turned '
                         '… while sliding" (the load torque swings it; 0 = never)')
    max_direction_error: float = _f(
        1.0472, 'rad', 0.0, 3.1416,
        'a commanded direction further than this from the static load is refused')
    jerk_psd: float = _f(100.0, 'm^2/s^5', 1e-9, 1e6, 'observer: white-jerk spectral density')
    position_noise: float = _f(1.0e-5, 'm', 1e-9, 0.01, 'observer: travel noise (1-sigma)')
    stop_speed: float = _f(0.002, 'm/s', 0.0, 0.1,
                           'after T, "done" needs the observed speed below this too')


@dataclass(frozen=True)
class ModelRotationalParams:
    """Model-based ROTATIONAL slip (docs/model_slip_control.md §5)."""

    bandwidth: float = _f(30.0, 'rad/s', 0.1, 200.0,
                          'natural frequency of the tracking-error dynamics')
    damping: float = _f(0.7, '-', 0.1, 5.0, 'damping ratio of the tracking-error dynamics')
    integral: float = _f(0.6, '-', 0.0, 5.0,
                         'integral gain as a fraction of bandwidth^3')
    force_lag: float = _f(0.0, 's', 0.0, 1.0,
                          'lead for the inner grasp-force loop (0: the turn\'s acceleration '
                          'estimate is too noisy to lead with)')
    motion_rate: float = _f(0.026, 'rad/s', 1e-5, 10.0,
                            'observed rate above which the object counts as turning')
    keep_rate: float = _f(0.0, 'rad/s', 0.0, 10.0,
                          'before the deceleration the rate set-point stays at least this '
                          '(0: the turn runs at Stribeck speeds, where sliding is unstable)')
    translation_floor: float = _f(1.0, '-', 0.0, 10.0,
                                  'the force never falls below this times ft/mu_c: the pads '
                                  'keep carrying the tangential load whatever the torque '
                                  'feedback asks')
    gyration_radius: float = _f(0.04, 'm', 0.0, 1.0,
                                'radius of gyration assumed for the object\'s inertia about '
                                'its centre of mass (inertia = m (lever^2 + this^2))')
    load_time: float = _f(0.1, 's', 0.0, 10.0,
                          'time constant of the load-torque estimate (measured torque plus '
                          'inertia times the observed acceleration)')
    max_translation: float = _f(
        0.005, 'm', 0.0, 0.1,
        'a rotation whose limit-surface coupling slides the grasp point further than this over '
        'the commanded angle is refused (lever too short for the torsional radius)')
    jerk_psd: float = _f(3000.0, 'rad^2/s^5', 1e-9, 1e6, 'observer: white-jerk spectral density')
    angle_noise: float = _f(1.0e-4, 'rad', 1e-9, 1.0, 'observer: turn noise (1-sigma)')
    stop_rate: float = _f(0.03, 'rad/s', 0.0, 10.0,
                          'after T, "done" needs the observed rate below this too')


@dataclass(frozen=True)
class ReversalParams:
    """Reversal abort of the direction-aware slip modes (§4.2)."""

    speed: float = _f(0.002, 'm/s', 0.0, 0.1, 'LINEAR: signed speed below -speed is reversed')
    rate: float = _f(0.013, 'rad/s', 0.0, 1.0, 'ROTATIONAL: signed rate below -rate is reversed')
    time: float = _f(0.1, 's', 0.0, 10.0, 'reversed for longer than this aborts to HOLD')


@dataclass(frozen=True)
class SlipControllerParams:
    """Parameters of ``slip_control/slip_controller`` (ros_interfaces §6.5)."""

    direction_aware: bool = _b(True, 'signed progress and reversal abort (false = reference)')
    allow_preset_properties: bool = _b(False, 'accept preset contact properties for slip modes')
    velocity_stale_after: float = _f(0.050, 's', 0.001, 1.0,
                                     'velocity older than this -> safe hold')
    ft_stale_after: float = _f(0.020, 's', 0.001, 1.0,
                               'F/T older than this -> hold the last output')
    sync_tolerance: float = _f(0.020, 's', 0.0, 1.0,
                               'finger-2 velocity stamp within this of finger 1')
    stale_confirm: float = _f(
        0.020, 's', 0.0, 0.5,
        '(addition) longest wait on the node clock (simulated time under use_sim_time, the '
        'steady clock on the system clock) before a stale verdict is acted on (an executor '
        'backlog is not a stopped stream; see StaleDebounce)')
    command_timeout: float = _f(0.1, 's', 0.0, 10.0, 'expiry sent with each grasp-force command')
    dt_max: float = _f(0.1, 's', 1e-3, 10.0,
                       'sample intervals above this skip derivative and integral updates')
    hold: HoldParams = _group(HoldParams)
    linear: LinearParams = _group(LinearParams)
    rotational: RotationalParams = _group(RotationalParams)
    hinge: HingeParams = _group(HingeParams)
    twist_observer: TwistObserverParams = _group(TwistObserverParams)
    hold_model: ModelHoldParams = _group(ModelHoldParams)
    hinge_model: ModelHingeParams = _group(ModelHingeParams)
    trajectory: TrajectoryParams = _group(TrajectoryParams)
    default_control_law: str = field(default='thesis', metadata={
        'choices': CONTROL_LAWS,
        'description': '(addition) control law of requests that leave control_law empty '
                       '(modes without that law use thesis)'})
    model: ModelParams = _group(ModelParams)
    model_linear: ModelLinearParams = _group(ModelLinearParams)
    model_rotational: ModelRotationalParams = _group(ModelRotationalParams)
    settle_timeout: float = _f(1.0, 's', 0.0, 60.0,
                               'a trajectory not finished by T + this ends with "timeout"')
    latch_speed: float = _f(0.002, 'm/s', 0.0, 0.1,
                            'speed at which the slip direction is latched')
    latch_rate: float = _f(0.026, 'rad/s', 0.0, 1.0,
                           '(addition) rate at which the rotation sign is latched (2 counts)')
    reversal: ReversalParams = _group(ReversalParams)
    contact_lost_force: float = _f(
        0.25, 'N', 0.0, 10.0,
        '(addition) a trajectory ends with "contact lost" when the measured normal force '
        'stays below this')
    contact_lost_time: float = _f(0.1, 's', 0.0, 10.0,
                                  '(addition) how long the normal force must stay below')
    min_duration: float = _f(0.1, 's', 1e-3, 10.0, '(addition) shortest trajectory duration')
    max_duration: float = _f(60.0, 's', 0.1, 3600.0, '(addition) longest trajectory duration')
    max_linear_distance: float = _f(0.1, 'm', 1e-4, 1.0,
                                    '(addition) longest LINEAR slip (limited by the grasp)')
    max_angle: float = _f(2.0 * math.pi, 'rad', 1e-3, 4.0 * math.pi,
                          '(addition) largest ROTATIONAL slip angle magnitude')
    frames: FrameParams = _group(FrameParams)

    def validate(self) -> None:
        """Raise `ParameterError` listing every problem (ranges and cross-field rules)."""
        problems = _problems(self)
        if self.min_duration > self.max_duration:
            problems.append('min_duration must not exceed max_duration')
        if self.sync_tolerance > self.velocity_stale_after:
            problems.append('sync_tolerance must not exceed velocity_stale_after')
        _raise_if(problems)


# ---------------------------------------------------------------------------------------------
# experiment_runner (§6.6; control_and_estimation §5)
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ArmParams:
    """Robot-arm backend (§5.1)."""

    backend: str = field(default='mock', metadata={
        'choices': ('mock', 'sim', 'ur'), 'read_only': True,
        'description': 'arm interface: mock, sim (simulated cell) or ur (full installs)'})


@dataclass(frozen=True)
class PickupParams:
    """Pick-up pose in the robot ``base`` frame (§5.2)."""

    position: tuple[float, ...] = field(default=(-0.10, -0.85, 0.23), metadata={
        'unit': 'm', 'range': (-3.0, 3.0), 'description': 'pick-up position (x, y, z)'})
    euler_xyz: tuple[float, ...] = field(default=(1.5707963, 0.0, 1.5707963), metadata={
        'unit': 'rad', 'range': (-2.0 * math.pi, 2.0 * math.pi),
        'description': 'pick-up orientation, intrinsic xyz; the first angle turns about the '
                       'grasp axis'})


@dataclass(frozen=True)
class ResetJointsParams:
    """Joint reset move (§5.2)."""

    names: tuple[str, ...] = field(default=(
        'elbow', 'shoulder_lift', 'shoulder_pan', 'wrist_1', 'wrist_2', 'wrist_3'),
        metadata={'description': 'joint names of the reset vector'})
    positions: tuple[float, ...] = field(default=(
        -2.371, -1.679, -1.422, 0.909, 1.422, -1.571), metadata={
        'unit': 'rad', 'range': (-2.0 * math.pi, 2.0 * math.pi),
        'description': 'reset joint positions, same order as names'})
    time: float = _f(10.0, 's', 0.1, 120.0, 'duration of the joint reset move')


@dataclass(frozen=True)
class ForceWaitParams:
    """A grasp-force command followed by a wait (``grasp``)."""

    force: float = _f(10.0, 'N', -20.0, 40.0, 'grasp-force command')
    wait: float = _f(2.0, 's', 0.0, 60.0, 'wait after the command')


@dataclass(frozen=True)
class ReleaseParams:
    """The opening command of ``release`` followed by a wait.

    A class of its own (not ``ForceWaitParams`` with other defaults): the parameter schema
    declares nested groups from their class defaults.
    """

    force: float = _f(-8.0, 'N', -20.0, 40.0, 'opening grasp-force command (< 0)')
    wait: float = _f(1.0, 's', 0.0, 60.0, 'wait after the command')


@dataclass(frozen=True)
class EstimationParams:
    """Exploration moves of ``est_contact`` (§3.8)."""

    force: float = _f(5.0, 'N', 0.0, 40.0, 'grasp force during the exploration')
    descent: float = _f(0.01, 'm', 0.0, 0.1, 'downward tool move of the linear phase')
    descent_time: float = _f(0.8, 's', 0.05, 10.0, 'duration of the descent')
    linear_window: float = _f(1.0, 's', 0.05, 10.0, 'duration of the linear phase')
    twist_angle: float = _f(0.17453, 'rad', 0.0, 1.0,
                            'tool twist about the grasp axis (each way) of the rotational phase')
    twist_time: float = _f(0.5, 's', 0.05, 10.0, 'duration of each twist')
    rotational_window: float = _f(1.0, 's', 0.05, 10.0, 'duration of the rotational phase')


@dataclass(frozen=True)
class RunnerHingeParams:
    """Hinge experiment (§5.2)."""

    start_angle: float = _f(1.0471976, 'rad', -2.0 * math.pi, 2.0 * math.pi,
                            'tool turn about the grasp axis of the hinge pose')
    end_angle: float = _f(2.0943951, 'rad', -2.0 * math.pi, 2.0 * math.pi,
                          'tool turn at the end of the hinge motion')
    wait: float = _f(2.0, 's', 0.0, 60.0, 'wait after the hinge motion')


@dataclass(frozen=True)
class MotionTimeParams:
    """Default motion time ``max(min, gain·(distance_weight·|Δp| + |Δangle|))`` (§5.2)."""

    min: float = _f(1.0, 's', 0.0, 60.0, 'shortest motion')
    gain: float = _f(4.0, 's', 0.0, 60.0, 'seconds per unit of weighted motion')
    distance_weight: float = _f(5.0, '1/m', 0.0, 1000.0, 'weight of translation vs rotation')


@dataclass(frozen=True)
class RecordingParams:
    """In-process bag recording (§5.1, §5.3)."""

    directory: str = field(default='', metadata={
        'description': 'bag output directory; empty = $SLIP_DATA_DIR/bags, else '
                       '~/.local/share/slip_cell/bags (never the working directory)'})
    topics: tuple[str, ...] = field(default=(
        names.GRASP_FORCE_CMD, names.MOTOR_COMMAND, names.GRIPPER_STATUS,
        names.ft_wrench(1), names.ft_wrench(2), names.slip_twist(1),
        names.slip_twist(2), names.STATIC_FRAMES, names.FINGER_FRAMES,
        names.SLIP_TRACKING, names.SLIP_CONTROLLER_STATE, names.CONTACT_PROPERTIES,
        names.DIAGNOSTICS, names.SIM_STATE, names.SIM_TRUE_CONTACT),
        metadata={'description': 'topics recorded by every handler (glob patterns; absent '
                                 'topics, e.g. sim/* on hardware, are simply not recorded)'})


@dataclass(frozen=True)
class ExperimentRunnerParams:
    """Parameters of ``slip_control/experiment_runner`` (ros_interfaces §6.6)."""

    arm: ArmParams = _group(ArmParams)
    pickup: PickupParams = _group(PickupParams)
    hold_height: float = _f(0.20, 'm', 0.0, 1.0, 'lift above the pick-up pose')
    reset_joints: ResetJointsParams = _group(ResetJointsParams)
    grasp: ForceWaitParams = _group(ForceWaitParams)
    release: ReleaseParams = _group(ReleaseParams)
    estimation: EstimationParams = _group(EstimationParams)
    hinge: RunnerHingeParams = _group(RunnerHingeParams)
    motion_time: MotionTimeParams = _group(MotionTimeParams)
    recording: RecordingParams = _group(RecordingParams)
    step_timeout: float = _f(30.0, 's', 0.1, 3600.0, 'default time limit of one runner step')
    control_law: str = field(default='', metadata={
        'choices': ('',) + CONTROL_LAWS,
        'description': '(addition) control law named on every slip-mode request (thesis, '
                       'model); empty = the slip controller\'s default_control_law'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every problem (ranges and cross-field rules)."""
        problems = _problems(self)
        if len(self.pickup.position) != 3 or len(self.pickup.euler_xyz) != 3:
            problems.append('pickup.position and pickup.euler_xyz need 3 values each')
        if len(self.reset_joints.names) != len(self.reset_joints.positions):
            problems.append('reset_joints.names and reset_joints.positions differ in length')
        if self.release.force >= 0.0:
            problems.append('release.force must be negative (opening)')
        if self.estimation.linear_window < self.estimation.descent_time:
            problems.append('estimation.linear_window must cover estimation.descent_time')
        if self.estimation.rotational_window < self.estimation.twist_time:
            problems.append('estimation.rotational_window must cover estimation.twist_time')
        _raise_if(problems)

    def motion_duration(self, distance: float, angle: float) -> float:
        """Default motion time [s] for a translation ``distance`` [m] and rotation [rad]."""
        m = self.motion_time
        return max(m.min, m.gain * (m.distance_weight * abs(distance) + abs(angle)))
