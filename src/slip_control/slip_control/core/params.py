# SPDX-License-Identifier: Apache-2.0
"""Parameter sets of the slip_control nodes as frozen dataclasses (ros_interfaces spec §6.4–6.6).

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


@dataclass(frozen=True)
class EstimatorRotationalParams:
    """Sample gates of the rotational phase (§3.4)."""

    min_abs_omega: float = _f(0.1, 'rad/s', 0.0, 10.0,
                              'skip rotational samples turning slower than this')
    max_speed: float = _f(0.005, 'm/s', 0.0, 0.1,
                          'skip rotational samples translating faster than this')


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
    """Parameters of ``slip_control/contact_estimator`` (ros_interfaces §6.4)."""

    linear: EstimatorLinearParams = _group(EstimatorLinearParams)
    rotational: EstimatorRotationalParams = _group(EstimatorRotationalParams)
    min_normal_force: float = _f(1.0, 'N', 0.0, 100.0, 'skip samples with f_n below this')
    u_clamp_factor: float = _f(5.0, '-', 1.0, 1000.0, 'u = r^2 when |u| exceeds this times r^2')
    min_samples_linear: int = _i(20, 3, 1000000, 'sliding samples needed for linear_valid')
    min_samples_rotational: int = _i(20, 3, 1000000,
                                     'rotational samples needed for rotational_valid')
    min_speed_span: float = _f(0.002, 'm/s', 0.0, 1.0,
                               'speed span needed to fit mu_v (viscous_valid)')
    mu_c_max: float = _f(2.0, '-', 1e-3, 10.0, 'largest plausible mu_c')
    r_min: float = _f(0.001, 'm', 1e-6, 1.0, 'smallest plausible torsional radius')
    r_max: float = _f(0.05, 'm', 1e-6, 1.0, 'largest plausible torsional radius')
    sync_tolerance: float = _f(0.020, 's', 0.0, 1.0,
                               'finger-2 velocity stamp within this of finger 1')
    ft_stale_after: float = _f(0.020, 's', 0.0, 1.0, 'F/T samples older than this are stale')
    start_max_age: float = _f(0.5, 's', 0.001, 60.0,
                              '(addition) contact/start refuses a LINEAR/ROTATIONAL phase when '
                              'a sensor stream is missing or its latest sample is older')
    online: EstimatorOnlineParams = _group(EstimatorOnlineParams)
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
class TrajectoryParams:
    """Trapezoidal reference trajectories (§4.3)."""

    accel_fraction: float = _f(0.2, '-', 0.01, 0.5,
                               'acceleration (and deceleration) time as a fraction of T')


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
        '(addition) longest wait on the steady clock before a stale verdict is acted on '
        '(an executor backlog is not a stopped stream; see StaleDebounce)')
    command_timeout: float = _f(0.1, 's', 0.0, 10.0, 'expiry sent with each grasp-force command')
    dt_max: float = _f(0.1, 's', 1e-3, 10.0,
                       'sample intervals above this skip derivative and integral updates')
    hold: HoldParams = _group(HoldParams)
    linear: LinearParams = _group(LinearParams)
    rotational: RotationalParams = _group(RotationalParams)
    hinge: HingeParams = _group(HingeParams)
    trajectory: TrajectoryParams = _group(TrajectoryParams)
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

    directory: str = field(default='bags', metadata={'description': 'bag output directory'})
    topics: tuple[str, ...] = field(default=(
        'gripper/grasp_force_cmd', 'gripper/motor_command', 'gripper/status',
        'finger_1/ft/wrench', 'finger_2/ft/wrench', 'finger_1/slip/twist',
        'finger_2/slip/twist', 'gripper/static_frames', 'gripper/finger_frames',
        'slip_control/tracking', 'slip_control/state', 'contact/properties', '/diagnostics',
        'sim/state', 'sim/true_contact'),
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


def all_param_classes() -> tuple[type, ...]:
    """The node parameter classes of this package (for config-YAML tests)."""
    return (ContactEstimatorParams, SlipControllerParams, ExperimentRunnerParams)
