# SPDX-License-Identifier: Apache-2.0
"""The experiment runner's modes as step data (control_and_estimation §5.3, §5.4).

`build_sequence` turns a runner mode and the runner parameters (ros_interfaces §6.6) into a
`slip_control.core.runner_steps.Sequence`: the §5.3 building blocks of `StepBuilder`, the
§3.8 exploration of `slip_control.core.exploration` and, for ``force_tracking_test``, the
§5.4 profile of `slip_cell_common.core.force_profile` (the one the driver's tool plays).
`slip_control.core.sequence_runner.SequenceRunner` executes the result.

LINEAR and ROTATIONAL slips run to the end of their trajectory (``slip_control/execute``, not
§5.3's "set the mode, wait ``duration`` + 1 s") so that every slip segment reports the
controller's outcome, then the object settles for `SETTLE_AFTER_SLIP` in HOLD.
"""
from __future__ import annotations

import math
from dataclasses import replace

from slip_cell_common.core.force_profile import ForceTrackingProfile
from slip_control.core.controllers import SlipMode
from slip_control.core.exploration import exploration_steps
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.params import ExperimentRunnerParams
from slip_control.core.runner_steps import Action, Sequence, Step, StepBuilder, make_step

RUNNER_MODES = ('reset_joints', 'release', 'grasp', 'go_to_object', 'est_contact',
                'pick_up_object', 'hold_mode', 'linear_slippage', 'rotational_slippage',
                'go_to_hinge_pose', 'hinge_mode', 'demo', 'force_tracking_test')

#: Modes that record a bag when a recording name is given (§5.3).
RECORDING_MODES = ('est_contact', 'hold_mode', 'linear_slippage', 'rotational_slippage',
                   'hinge_mode', 'demo', 'force_tracking_test')

#: Demo defaults when the goal leaves them at 0 (§5.5: 2 cm in 2 s, 20° in 2 s).
DEMO_DURATION = 2.0
DEMO_DISTANCE = 0.02
DEMO_ANGLE = math.radians(20.0)

#: Wait after a slip trajectory has ended [s]: the object comes to rest in HOLD before the
#: next motion (the ground truth of the slip is read over this second too).
SETTLE_AFTER_SLIP = 1.0


def build_sequence(mode: str, params: ExperimentRunnerParams, *, duration: float = 0.0,
                   distance: float = 0.0, angle: float = 0.0,
                   recording_name: str = '') -> Sequence:
    """The step data of one runner mode (§5.3).

    Args:
        mode: Runner mode name (`RUNNER_MODES`).
        params: Runner parameters.
        duration: [s] for ``hold_mode``, ``linear_slippage``, ``rotational_slippage``
            (``demo``: 0 = 2 s).
        distance: [m] for ``linear_slippage`` (``demo``: 0 = 0.02 m).
        angle: [rad] for ``rotational_slippage`` (``demo``: 0 = 20°). Like LINEAR's direction,
            the rotation sign is latched from the first motion (gravity turns the object, as
            the set-up of §5.5 arranges), so only ``|angle|`` matters here.
        recording_name: Bag name (≥ 3 characters to record).

    Raises:
        ValueError: unknown mode or missing/non-finite arguments.
    """
    for n, v in (('duration', duration), ('distance', distance), ('angle', angle)):
        if not math.isfinite(v):
            raise ValueError(f'{n} = {v!r} is not finite')
    b = StepBuilder(params)
    p = params
    rec_start, rec_stop = b.record(recording_name)
    linear = ModeRequest(int(SlipMode.LINEAR), duration=duration, distance=distance,
                         latch_direction=True)
    rotational = ModeRequest(int(SlipMode.ROTATIONAL), duration=duration, angle=angle,
                             latch_direction=True)

    def need(*names: str) -> None:
        vals = {'duration': duration, 'distance': distance, 'angle': angle}
        for n in names:
            if not (vals[n] > 0.0 if n != 'angle' else abs(vals[n]) > 0.0):
                raise ValueError(f'runner mode {mode!r} needs {n} (got {vals[n]!r})')

    steps: tuple[Step, ...]
    if mode == 'reset_joints':
        steps = b.reset_joints()
    elif mode == 'release':
        steps = b.release()
    elif mode == 'grasp':
        steps = (b.require('requires the object in place', object_dropped=False), *b.grasp())
    elif mode == 'go_to_object':
        steps = (b.require('requires open gripper and reset joints', gripper_open=True,
                           joints_reset=True), *b.go_to_object())
    elif mode == 'est_contact':
        steps = (b.require('requires the pick-up pose', at_pickup=True), *rec_start,
                 *exploration_steps(b), *b.release(), b.read(),
                 make_step('return to pick-up pose', Action.RETURN_TO_PICKUP, 60.0 + b.to),
                 b.require('contact estimate valid', contact_estimated=True))
    elif mode == 'pick_up_object':
        # Grasps first unless already holding (est_contact ends released): afterwards the cell
        # holds the object in the air, ready for the slip modes.
        steps = (b.require('requires an estimate and reset joints', contact_estimated=True,
                           joints_reset=True, object_dropped=False),
                 *b.grasp(hold=False, when={'holding': False}),
                 b.mode('pick up: HOLD on', ModeRequest(int(SlipMode.HOLD))),
                 b.move('pick up: lift', lift=p.hold_height, sets={'at_pickup': False}))
    elif mode == 'hold_mode':
        need('duration')
        steps = (b.require('requires holding', holding=True), *rec_start,
                 b.mode('HOLD on', ModeRequest(int(SlipMode.HOLD))),
                 b.wait('hold', duration))
    elif mode == 'linear_slippage':
        need('duration', 'distance')
        steps = (b.require('requires holding', holding=True), *rec_start,
                 b.slip('LINEAR slip', linear), b.wait('slip: settle', SETTLE_AFTER_SLIP))
    elif mode == 'rotational_slippage':
        need('duration', 'angle')
        steps = (b.require('requires holding', holding=True), *rec_start,
                 b.slip('ROTATIONAL slip', rotational),
                 b.wait('slip: settle', SETTLE_AFTER_SLIP))
    elif mode == 'go_to_hinge_pose':
        h = p.hinge
        steps = (b.require('requires holding', holding=True),
                 b.move('turn to hinge pose', rotation=h.start_angle,
                        sets={'at_hinge': True}))
    elif mode == 'hinge_mode':
        h = p.hinge
        steps = (b.require('requires the hinge pose', at_hinge=True), *rec_start,
                 b.mode('HINGE on', ModeRequest(int(SlipMode.HINGE))),
                 b.move('turn to hinge end', rotation=h.end_angle - h.start_angle),
                 b.wait('hinge wait', h.wait), *rec_stop,
                 b.mode('HOLD on', ModeRequest(int(SlipMode.HOLD))))
    elif mode == 'demo':
        h = p.hinge
        d = duration if duration > 0.0 else DEMO_DURATION
        lin = replace(linear, duration=d, distance=distance if distance > 0.0 else
                      DEMO_DISTANCE)
        rot = replace(rotational, duration=d, angle=angle if abs(angle) > 0.0 else DEMO_ANGLE)
        steps = (*b.release(when={'gripper_open': False}),
                 *b.reset_joints(when={'joints_reset': False}),
                 *b.go_to_object(when={'at_pickup': False}),
                 *rec_start,
                 *b.grasp(hold=False), *exploration_steps(b), b.read(),
                 *b.grasp(hold=True, hold_optional=False),
                 b.move('pick up: lift', lift=p.hold_height, sets={'at_pickup': False}),
                 b.slip('LINEAR slip', lin), b.wait('linear slip: settle', SETTLE_AFTER_SLIP),
                 b.move('turn to hinge pose', rotation=h.start_angle, sets={'at_hinge': True}),
                 b.mode('HINGE on', ModeRequest(int(SlipMode.HINGE))),
                 b.move('turn to hinge end', rotation=h.end_angle - h.start_angle),
                 b.wait('hinge wait', h.wait),
                 b.mode('HOLD on', ModeRequest(int(SlipMode.HOLD))),
                 b.move('turn back', rotation=-h.end_angle, sets={'at_hinge': False}),
                 b.slip('ROTATIONAL slip', rot),
                 b.wait('rotational slip: settle', SETTLE_AFTER_SLIP))
    elif mode == 'force_tracking_test':
        # §5.4: the profile holds its initial force first and last; recorded in between.
        fp = ForceTrackingProfile()
        # The slip controller must be OFF: a HOLD left on from an earlier mode would keep
        # commanding its own force next to the profile (both reach the force loop).
        steps = (b.mode('force test: slip mode OFF', ModeRequest(int(SlipMode.OFF))),
                 b.force('force test: initial force', fp.initial_force), *rec_start,
                 make_step('force test: profile', Action.PLAY_FORCE_PROFILE,
                           fp.duration + b.to, profile=fp, duration=fp.duration))
        return Sequence(mode, steps, (*rec_stop, b.force('force test: final force',
                                                         fp.final_force)))
    else:
        raise ValueError(f'unknown runner mode {mode!r} (one of {", ".join(RUNNER_MODES)})')
    return Sequence(mode, steps, rec_stop if mode in RECORDING_MODES else ())
