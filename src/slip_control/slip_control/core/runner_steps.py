# SPDX-License-Identifier: Apache-2.0
"""Experiment-runner steps as data (control_and_estimation §5.3; CE-9).

A sequence is a tuple of `Step` s — ``(name, action, args, timeout)`` plus an optional flag
condition — and a tuple of cleanup steps that always run at the end (stop recording, …).
`StepBuilder` makes the §5.3 building blocks (release, grasp, moves, …) from the runner
parameters; `slip_control.core.runner_sequences` assembles them into the runner modes and
`slip_control.core.sequence_runner` executes them.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from enum import StrEnum
from types import MappingProxyType
from typing import Any

from slip_control.core.controllers import SlipMode
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.params import ExperimentRunnerParams


class Action(StrEnum):
    """Step actions."""

    COMMAND_FORCE = 'command_force'            # force [N]
    SET_SLIP_MODE = 'set_slip_mode'            # request: ModeRequest
    EXECUTE_SLIP = 'execute_slip'              # request: ModeRequest; ends with the trajectory
    START_ESTIMATION = 'start_estimation'      # phase: EstimationPhase, duration [s]
    READ_PROPERTIES = 'read_properties'
    BIAS_FT = 'bias_ft'
    MOVE_GRIPPER = 'move_gripper'              # lift, lateral [m], rotation [rad], duration [s]
    RETURN_TO_PICKUP = 'return_to_pickup'      # relative move undoing the tracked offset
    MOVE_TO_PICKUP = 'move_to_pickup'
    MOVE_JOINTS = 'move_joints'                # names, positions [rad], duration [s]
    WAIT = 'wait'                              # seconds [s]
    PLAY_FORCE_PROFILE = 'play_force_profile'  # profile: ForceTrackingProfile, duration
    START_RECORDING = 'start_recording'        # bag_name, topics
    STOP_RECORDING = 'stop_recording'
    REQUIRE = 'require'                        # flags that must hold (in `flags`)


#: State flags of the cell (§5.1; ``object_dropped`` is an addition: the object was lost
#: during a sequence and must be put back before the next grasp).
FLAG_NAMES = ('holding', 'at_pickup', 'at_hinge', 'joints_reset', 'gripper_open',
              'contact_estimated', 'object_dropped')

#: The runner modes that set each flag (the step a refused precondition asks for).
FLAG_SOURCES: Mapping[str, tuple[str, ...]] = MappingProxyType({
    'holding': ('grasp', 'pick_up_object'),
    'at_pickup': ('go_to_object',),
    'at_hinge': ('go_to_hinge_pose',),
    'joints_reset': ('reset_joints',),
    'gripper_open': ('release',),
    'contact_estimated': ('est_contact',),
})

#: The runner modes that clear each flag (the step a refusal asks for when a flag must be
#: false): ``go_to_object`` puts a lost object back (the simulator resets its scene; on
#: hardware the operator places the object at the pick-up pose).
FLAG_CLEARED_BY: Mapping[str, tuple[str, ...]] = MappingProxyType({
    'object_dropped': ('go_to_object',),
})

#: Extra time a slip trajectory may take beyond its duration before its step times out [s]
#: (the controller settles and ends it itself; §5.3 waits ``duration`` + 1 s).
SLIP_SETTLE_S = 1.0


@dataclass(frozen=True, slots=True)
class Step:
    """One checked, time-limited runner step.

    Attributes:
        name: Shown as the action feedback ``phase``.
        action: What to do.
        args: Action arguments (SI), read-only.
        timeout: Time limit from the step's start [s].
        when: Run only if these flags have these values (else skipped).
        sets: Flags set when the step succeeds.
        optional: A failure is logged and the sequence continues.
    """

    name: str
    action: Action
    args: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    timeout: float = 30.0
    when: tuple[tuple[str, bool], ...] = ()
    sets: tuple[tuple[str, bool], ...] = ()
    optional: bool = False


@dataclass(frozen=True, slots=True)
class Sequence:
    """A runner mode as data: main steps and cleanup steps (always run, failures logged)."""

    mode: str
    steps: tuple[Step, ...]
    cleanup: tuple[Step, ...] = ()


def make_step(name: str, action: Action, timeout: float, *,
              when: Mapping[str, bool] | None = None,
              sets: Mapping[str, bool] | None = None, optional: bool = False,
              **args: Any) -> Step:
    """One `Step`; ``when``/``sets`` as mappings, the remaining keywords are its arguments."""
    return Step(name=name, action=action, args=MappingProxyType(dict(args)), timeout=timeout,
                when=tuple((when or {}).items()), sets=tuple((sets or {}).items()),
                optional=optional)


class StepBuilder:
    """Builds the step tuples of §5.3 from the runner parameters (``to``: default timeout [s])."""

    def __init__(self, p: ExperimentRunnerParams) -> None:
        self.p = p
        self.to = p.step_timeout

    def wait(self, name: str, seconds: float, **kw: Any) -> Step:
        """Wait ``seconds`` [s]."""
        return make_step(name, Action.WAIT, seconds + self.to, seconds=seconds, **kw)

    def force(self, name: str, force: float, **kw: Any) -> Step:
        """Command a grasp force [N]."""
        return make_step(name, Action.COMMAND_FORCE, self.to, force=force, **kw)

    def mode(self, name: str, request: ModeRequest, **kw: Any) -> Step:
        """Request a slip mode; the runner's ``control_law`` is named on it unless the request
        names one."""
        if self.p.control_law and not request.control_law:
            request = replace(request, control_law=self.p.control_law)
        return make_step(name, Action.SET_SLIP_MODE, self.to, request=request, **kw)

    def slip(self, name: str, request: ModeRequest, **kw: Any) -> Step:
        """Run a LINEAR or ROTATIONAL trajectory to its end (``slip_control/execute``); the
        step reports the controller's outcome and fails unless it is "done". The runner's
        ``control_law`` is named on it unless the request names one."""
        if self.p.control_law and not request.control_law:
            request = replace(request, control_law=self.p.control_law)
        return make_step(name, Action.EXECUTE_SLIP, request.duration + SLIP_SETTLE_S + self.to,
                         request=request, **kw)

    def move(self, name: str, lift: float = 0.0, lateral: float = 0.0, rotation: float = 0.0,
             duration: float | None = None, **kw: Any) -> Step:
        """Relative tool move (m, m, rad) in ``duration`` [s] (default: the motion time)."""
        d = duration if duration is not None else self.p.motion_duration(
            math.hypot(lift, lateral), rotation)
        return make_step(name, Action.MOVE_GRIPPER, d + self.to, lift=lift, lateral=lateral,
                         rotation=rotation, duration=d, **kw)

    def require(self, name: str, **flags: bool) -> Step:
        """Fail unless the cell flags have these values."""
        return make_step(name, Action.REQUIRE, self.to, flags=MappingProxyType(dict(flags)))

    # §5.3 building blocks --------------------------------------------------------------

    def release(self, **kw: Any) -> tuple[Step, ...]:
        """§5.3 ``release``: OFF, open, wait, bias F/T. Letting go is deliberate: ``holding``
        is cleared before the gripper opens, so an object that falls is not a fault."""
        r = self.p.release
        return (self.mode('release: slip mode OFF', ModeRequest(int(SlipMode.OFF)),
                          sets={'holding': False}, **kw),
                self.force('release: open', r.force, **kw),
                self.wait('release: wait', r.wait, **kw),
                make_step('release: bias F/T', Action.BIAS_FT, self.to,
                          sets={'gripper_open': True, 'holding': False}, **kw))

    def grasp(self, *, hold: bool = True, hold_optional: bool = True,
              **kw: Any) -> tuple[Step, ...]:
        """§5.3 ``grasp``: close, wait, HOLD on (optional unless ``hold_optional`` false)."""
        g = self.p.grasp
        steps = [self.force('grasp: close', g.force, sets={'gripper_open': False}, **kw),
                 self.wait('grasp: wait', g.wait, sets={'holding': True}, **kw)]
        if hold:
            steps.append(self.mode('grasp: HOLD on', ModeRequest(int(SlipMode.HOLD)),
                                   optional=hold_optional, **kw))
        return tuple(steps)

    def reset_joints(self, **kw: Any) -> tuple[Step, ...]:
        """§5.3 ``reset_joints``: the joint move to the reset vector."""
        j = self.p.reset_joints
        return (make_step('reset joints', Action.MOVE_JOINTS, j.time + self.to, names=j.names,
                          positions=j.positions, duration=j.time,
                          sets={'joints_reset': True, 'at_pickup': False, 'at_hinge': False},
                          **kw),)

    def go_to_object(self, **kw: Any) -> tuple[Step, ...]:
        """§5.3 ``go_to_object``: the Cartesian move to the pick-up pose."""
        return (make_step('go to object', Action.MOVE_TO_PICKUP, self.to,
                          position=self.p.pickup.position, euler_xyz=self.p.pickup.euler_xyz,
                          sets={'at_pickup': True, 'at_hinge': False, 'object_dropped': False},
                          **kw),)

    def read(self) -> Step:
        """Read the contact properties (sets ``contact_estimated``)."""
        return make_step('read contact properties', Action.READ_PROPERTIES, self.to)

    def record(self, name: str) -> tuple[tuple[Step, ...], tuple[Step, ...]]:
        """Start/stop steps for a recording (none when ``name`` has < 3 characters)."""
        if len(name) < 3:
            return (), ()
        start = make_step('start recording', Action.START_RECORDING, self.to, bag_name=name,
                          topics=self.p.recording.topics)
        stop = make_step('stop recording', Action.STOP_RECORDING, self.to)
        return (start,), (stop,)
