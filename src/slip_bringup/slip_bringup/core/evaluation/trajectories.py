# SPDX-License-Identifier: Apache-2.0
"""LINEAR and ROTATIONAL slips on the simulated cell, judged by the truth.

Both start from an object held in the air under HOLD: LINEAR with the direction latched (as
the runner sends it), ROTATIONAL after the gripper turned the object ``tilt`` (90°) away from
hanging (with HOLD), so that gravity drives the slip.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from friction_models.core.harness import Harness, default_motion_time

from slip_bringup.core.evaluation.agents import ControllerAgent
from slip_bringup.core.evaluation.poses import (gravity_in_middle, lever_horizontal_turn,
                                                turn_to_hanging_angle)
from slip_bringup.core.evaluation.scene import controlled_scene
from slip_bringup.core.evaluation.settings import EvalSettings
from slip_bringup.core.evaluation.truth import (TruthProbe, centre_point_displacement,
                                                interp_progress)
from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import SlipMode, SlipResult
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.trajectory import TrapezoidalTrajectory

_NAN = math.nan


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
        trajectory_rms: RMS of (reference − true progress) over the whole commanded duration
            ``[0, T]``, at every truth row, whenever the controller ended [m | rad].
        trajectory_max: Largest absolute such error [m | rad].
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
    trajectory_rms: float = _NAN
    trajectory_max: float = _NAN


def _truth_tracking(probe: TruthProbe, progress: Callable[[int], float], t0: float,
                    target: float, duration: float, accel_fraction: float
                    ) -> tuple[float, float]:
    """RMS and largest |reference − true progress| over ``[t0, t0 + duration]`` [m | rad]."""
    ref = TrapezoidalTrajectory(abs(target), duration, accel_fraction)
    errors = [ref.sample(probe.t[i] - t0)[0] - progress(i)
              for i in probe.indices(t0, t0 + duration)]
    return _rms(errors), max((abs(e) for e in errors), default=_NAN)


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
    errors = [row.ref_pos - interp_progress(probe, progress, row.stamp)
              for row in ctl.tracking[n_track:]]
    ended = [(t, r) for t, r in ctl.results[n_res:] if r.mode == SlipMode(request.mode)]
    result = ended[0][1] if ended else None
    result_time = ended[0][0] - t0 if ended else _NAN
    forces = ctl.forces_between(t0, t0 + (result_time if ended else wait)) or [_NAN]
    return t0, errors, result, result_time, forces


def turn_gripper(h: Harness, turn: float, duration: float | None = None,
                 settle: float = 0.5) -> None:
    """Turn the gripper by ``turn`` [rad] (runner's motion time unless ``duration`` [s]), then
    wait ``settle`` [s] (also without a turn)."""
    if turn != 0.0:
        h.move(rotation=turn, duration=duration if duration is not None else
               default_motion_time(0.0, turn))
    h.run_for(settle)


def _rms(values: Sequence[float]) -> float:
    return math.sqrt(sum(v * v for v in values) / len(values)) if values else _NAN


def linear_slip(preset: str, distance: float = 0.02, duration: float = 2.0,
                settings: EvalSettings = EvalSettings(),
                properties: ContactProperties | None = None,
                latch_direction: bool = True,
                hang_com: Sequence[float] | None = None) -> TrajectoryOutcome:
    """LINEAR slip of ``distance`` [m] in ``duration`` [s] on an object held in the air.

    The request is the runner's (§5.3 ``linear_slippage``: direction latched from the first
    motion); gravity makes the object slide down. The runner waits ``duration + 1 s``; this
    waits ``duration + 1.5 s`` so the hand-over to HOLD is included.

    ``hang_com`` (the object's CoM offset from the grasp point, object frame [m]): before the
    request, the gripper turns under HOLD so that the CoM hangs straight below the grasp point
    (`poses.turn_to_hanging_angle`, from the object's rotation in the pads after the pick-up),
    the one pose in which a gravity-driven slide is a translation (elsewhere the weight's
    torque turns the object while the pads slide; docs/evaluation.md).
    """
    h, ctl, probe = controlled_scene(preset, settings, properties)
    if hang_com is not None:
        s = h.state()
        turn_gripper(h, turn_to_hanging_angle(hang_com, 0.0, s.theta) - s.arm_angle)
    s0 = h.state()
    gx, gy = gravity_in_middle(s0.arm_angle)
    request = ModeRequest(int(SlipMode.LINEAR), duration=duration, distance=distance,
                          direction=(0.0, 0.0, 0.0) if latch_direction else (gx, gy, 0.0),
                          latch_direction=latch_direction)

    def along(i: int) -> float:
        dx, dy = probe.displacement(i, s0.x, s0.y, s0.theta)
        return dx * gx + dy * gy

    t0, errors, result, result_time, forces = _run_trajectory(
        h, ctl, probe, request, along, duration + 1.5)
    s = h.state()
    dx, dy = centre_point_displacement(s0.x, s0.y, s0.theta, s.x, s.y, s.theta)
    achieved = dx * gx + dy * gy

    def sideways(i: int) -> float:
        ex, ey = probe.displacement(i, s0.x, s0.y, s0.theta)
        return abs(ex * gy - ey * gx)

    side = max((sideways(i) for i in probe.indices(t0, h.t)), default=0.0)
    rms, worst = _truth_tracking(probe, along, t0, distance, duration,
                                 settings.controller.trajectory.accel_fraction)
    return TrajectoryOutcome(
        preset=preset, mode=SlipMode.LINEAR, target=distance, duration=duration,
        achieved=achieved, final_error=distance - achieved, off_axis=side,
        tracking_rms=_rms(errors), tracking_max=max((abs(e) for e in errors), default=_NAN),
        result=result, result_time=result_time, force_min=min(forces), force_max=max(forces),
        dropped=s.dropped, trajectory_rms=rms, trajectory_max=worst)


def rotational_slip(preset: str, angle: float = math.radians(20.0), duration: float = 2.0,
                    settings: EvalSettings = EvalSettings(),
                    properties: ContactProperties | None = None,
                    tilt: float = math.radians(90.0),
                    tilt_time: float | None = None,
                    turn: float | None = None,
                    lever_com: Sequence[float] | None = None) -> TrajectoryOutcome:
    """ROTATIONAL slip of ``angle`` [rad, signed about ``gripper_middle`` +z] in ``duration``.

    Set-up: object held in the air under HOLD; the gripper turns by ``−sign(angle)·tilt``
    (motion time: the runner's default unless ``tilt_time``), so the object hangs ``tilt``
    away from vertical and gravity turns it the requested way (like the reference's set-ups
    "15"/"60" of §5.5). The request is the runner's (sign from the angle).

    ``turn`` [rad], when given, replaces ``−sign(angle)·tilt`` as the gripper's set-up turn
    (an object whose CoM is not below the grasp point needs its own; see
    `scene.lever_horizontal_turn`); ``tilt`` is then not used.

    ``lever_com`` (CoM offset from the grasp point, object frame [m]), when given, replaces
    both: the set-up turn puts the CoM lever horizontal (`poses.lever_horizontal_turn`, from the
    object's rotation in the pads after the pick-up), and the sign of ``angle`` becomes the one
    gravity drives from there.

    ``tilt`` defaults to 90°: the reference presets carry their CoM only 1 cm below the grasp
    point, so near vertical the gravity torque falls below the torsional friction at the
    controller's force floor and the object stops short (from 60°, a 45° command ends 3–15°
    short on every preset); from 90° the 45° slip ends 45° from vertical.
    """
    if turn is None and not abs(tilt) >= abs(angle):
        raise ValueError(f'tilt {tilt!r} rad must be at least |angle| {abs(angle)!r} rad: '
                         'gravity can only turn the object back to hanging')
    h, ctl, probe = controlled_scene(preset, settings, properties)
    if lever_com is not None:
        s = h.state()
        turn, gravity_sign = lever_horizontal_turn(lever_com, s.theta)
        turn -= s.arm_angle
        angle = gravity_sign * abs(angle)
    elif turn is None:
        turn = -math.copysign(abs(tilt), angle)
    turn_gripper(h, turn, tilt_time)
    s0 = h.state()
    sign = math.copysign(1.0, angle)
    request = ModeRequest(int(SlipMode.ROTATIONAL), duration=duration, angle=angle)

    def along(i: int) -> float:
        return sign * (probe.theta[i] - s0.theta)

    t0, errors, result, result_time, forces = _run_trajectory(
        h, ctl, probe, request, along, duration + 1.5)
    s = h.state()
    achieved = sign * (s.theta - s0.theta)
    rms, worst = _truth_tracking(probe, along, t0, angle, duration,
                                 settings.controller.trajectory.accel_fraction)
    return TrajectoryOutcome(
        preset=preset, mode=SlipMode.ROTATIONAL, target=angle, duration=duration,
        achieved=achieved, final_error=abs(angle) - achieved,
        off_axis=probe.peak_displacement(t0, h.t, s0.x, s0.y, s0.theta),
        tracking_rms=_rms(errors),
        tracking_max=max((abs(e) for e in errors), default=_NAN), result=result,
        result_time=result_time, force_min=min(forces), force_max=max(forces),
        dropped=s.dropped, trajectory_rms=rms, trajectory_max=worst)
