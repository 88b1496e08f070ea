# SPDX-License-Identifier: Apache-2.0
"""Experiment-runner sequences as data and a ROS-free step machine (control_and_estimation §5).

A sequence is a tuple of `Step` s — ``(name, action, args, timeout)`` plus an optional flag
condition — and a tuple of cleanup steps that always run at the end (stop recording, …).
`build_sequence` turns a runner mode (§5.3) and the runner parameters (ros_interfaces §6.6)
into that data; `SequenceRunner` executes it against a `CellInterface`, polled with the
current time ``t`` [s] (no clocks are read here, CE-7), checking and time-limiting every step
(CE-9).

The cell seam
-------------
`CellInterface` is what the ROS node implements with topics, services and the arm backend,
and what an in-process simulation harness implements by calling the cores directly. Every
method returns either a finished `CallResult` or a `Pending` (e.g. wrapping an rclpy future);
the machine polls ``Pending.done()`` and never blocks. ``CallResult.until`` keeps the step
busy until that time (arm motions report their expected end).

The arm seam (`CellInterface.move_gripper`, same as ``slip_msgs/MoveGripper``): a motion
*relative to the current tool pose*, along a smooth profile, with

* ``lift`` [m]: world-vertical displacement, + up;
* ``lateral`` [m]: world-horizontal displacement in the grasp plane;
* ``rotation`` [rad]: about the grasp axis (``gripper_middle`` +z) — for the UR backend this
  is the first intrinsic-xyz Euler angle of the pick-up orientation (§5.2);
* ``duration`` [s] > 0.

It returns the expected end time. A UR adapter turns each call into one Cartesian waypoint;
``move_to_pickup`` and ``move_joints`` are the two absolute moves (§5.3 ``go_to_object``,
``reset_joints``); a backend that cannot do them (the simulated cell) resets its scene
instead. The machine tracks the offset from the pick-up pose so that "return to the pick-up
pose" is a relative move too.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from enum import StrEnum
from types import MappingProxyType
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import SlipMode
from slip_control.core.estimator import EstimationPhase
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.params import ExperimentRunnerParams

# ---------------------------------------------------------------------------------------------
# The seam
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class CallResult:
    """Outcome of one cell call.

    Attributes:
        ok: The call succeeded.
        message: Why not, or a note.
        until: Keep the step busy until this time [s] (arm motion end), or ``None``.
        value: Payload (``read_properties``: a `ContactProperties`).
    """

    ok: bool
    message: str = ''
    until: float | None = None
    value: Any = None


@runtime_checkable
class Pending(Protocol):
    """An asynchronous call in flight (e.g. an rclpy service future)."""

    def done(self) -> bool:
        """The call has finished."""

    def result(self) -> CallResult:
        """Its outcome (only after `done`)."""

    # Optional (looked up with getattr): ``describe() -> str`` says what the call waits for
    # (used in timeout messages); ``cancel() -> None`` is called when the call is abandoned.


CallReturn = CallResult | Pending


class CellInterface(Protocol):
    """What the experiment runner drives: gripper, slip controller, estimator, arm, recorder.

    All arguments SI; ``t`` is the current time [s] on the runner's clock.
    """

    def command_force(self, force: float, t: float) -> CallReturn:
        """Publish a grasp-force command [N] (per finger; < 0 opens)."""

    def set_slip_mode(self, request: ModeRequest, t: float) -> CallReturn:
        """``SetSlipMode``; a rejection is ``ok = False`` with the controller's message."""

    def start_estimation(self, phase: EstimationPhase, duration: float, t: float) -> CallReturn:
        """``StartEstimation`` for ``duration`` [s]."""

    def read_properties(self, t: float) -> CallReturn:
        """``GetContactProperties``; ``value`` = `ContactProperties`."""

    def bias_ft(self, t: float) -> CallReturn:
        """Bias both F/T sensors (gripper open and empty)."""

    def move_gripper(self, lift: float, lateral: float, rotation: float, duration: float,
                     t: float) -> CallReturn:
        """Relative tool motion (see the module docstring); ``until`` = expected end [s]."""

    def move_to_pickup(self, position: tuple[float, ...], euler_xyz: tuple[float, ...],
                       t: float) -> CallReturn:
        """Absolute Cartesian move to the pick-up pose (robot ``base``; m, rad)."""

    def move_joints(self, names: tuple[str, ...], positions: tuple[float, ...],
                    duration: float, t: float) -> CallReturn:
        """Absolute joint move [rad] in ``duration`` [s]."""

    def start_recording(self, name: str, topics: tuple[str, ...], t: float) -> CallReturn:
        """Start the in-process recorder; ``value`` = bag path."""

    def stop_recording(self, t: float) -> CallReturn:
        """Stop the recorder (no-op when not recording)."""


# ---------------------------------------------------------------------------------------------
# Sequences as data
# ---------------------------------------------------------------------------------------------

class Action(StrEnum):
    """Step actions."""

    COMMAND_FORCE = 'command_force'            # force [N]
    SET_SLIP_MODE = 'set_slip_mode'            # request: ModeRequest
    START_ESTIMATION = 'start_estimation'      # phase: EstimationPhase, duration [s]
    READ_PROPERTIES = 'read_properties'
    BIAS_FT = 'bias_ft'
    MOVE_GRIPPER = 'move_gripper'              # lift, lateral [m], rotation [rad], duration [s]
    RETURN_TO_PICKUP = 'return_to_pickup'      # relative move undoing the tracked offset
    MOVE_TO_PICKUP = 'move_to_pickup'
    MOVE_JOINTS = 'move_joints'                # names, positions [rad], duration [s]
    WAIT = 'wait'                              # seconds [s]
    PLAY_FORCE_PROFILE = 'play_force_profile'  # profile: str, duration [s]
    START_RECORDING = 'start_recording'        # bag_name, topics
    STOP_RECORDING = 'stop_recording'
    REQUIRE = 'require'                        # flags that must hold (in `flags`)


#: State flags of the cell (§5.1).
FLAG_NAMES = ('holding', 'at_pickup', 'at_hinge', 'joints_reset', 'gripper_open',
              'contact_estimated')


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


def _step(name: str, action: Action, timeout: float, *, when: Mapping[str, bool] | None = None,
          sets: Mapping[str, bool] | None = None, optional: bool = False,
          **args: Any) -> Step:
    return Step(name=name, action=action, args=MappingProxyType(dict(args)), timeout=timeout,
                when=tuple((when or {}).items()), sets=tuple((sets or {}).items()),
                optional=optional)


class _Builder:
    """Builds the step tuples of §5.3 from the runner parameters."""

    def __init__(self, p: ExperimentRunnerParams) -> None:
        self.p = p
        self.to = p.step_timeout

    def wait(self, name: str, seconds: float, **kw: Any) -> Step:
        return _step(name, Action.WAIT, seconds + self.to, seconds=seconds, **kw)

    def force(self, name: str, force: float, **kw: Any) -> Step:
        return _step(name, Action.COMMAND_FORCE, self.to, force=force, **kw)

    def mode(self, name: str, request: ModeRequest, **kw: Any) -> Step:
        return _step(name, Action.SET_SLIP_MODE, self.to, request=request, **kw)

    def move(self, name: str, lift: float = 0.0, lateral: float = 0.0, rotation: float = 0.0,
             duration: float | None = None, **kw: Any) -> Step:
        d = duration if duration is not None else self.p.motion_duration(
            math.hypot(lift, lateral), rotation)
        return _step(name, Action.MOVE_GRIPPER, d + self.to, lift=lift, lateral=lateral,
                     rotation=rotation, duration=d, **kw)

    def require(self, name: str, **flags: bool) -> Step:
        return _step(name, Action.REQUIRE, self.to, flags=MappingProxyType(dict(flags)))

    # §5.3 building blocks --------------------------------------------------------------

    def release(self, **kw: Any) -> tuple[Step, ...]:
        r = self.p.release
        return (self.mode('release: slip mode OFF', ModeRequest(int(SlipMode.OFF)), **kw),
                self.force('release: open', r.force, **kw),
                self.wait('release: wait', r.wait, **kw),
                _step('release: bias F/T', Action.BIAS_FT, self.to,
                      sets={'gripper_open': True, 'holding': False}, **kw))

    def grasp(self, *, hold: bool = True, hold_optional: bool = True,
              **kw: Any) -> tuple[Step, ...]:
        g = self.p.grasp
        steps = [self.force('grasp: close', g.force, sets={'gripper_open': False}, **kw),
                 self.wait('grasp: wait', g.wait, sets={'holding': True}, **kw)]
        if hold:
            steps.append(self.mode('grasp: HOLD on', ModeRequest(int(SlipMode.HOLD)),
                                   optional=hold_optional, **kw))
        return tuple(steps)

    def reset_joints(self, **kw: Any) -> tuple[Step, ...]:
        j = self.p.reset_joints
        return (_step('reset joints', Action.MOVE_JOINTS, j.time + self.to, names=j.names,
                      positions=j.positions, duration=j.time,
                      sets={'joints_reset': True, 'at_pickup': False, 'at_hinge': False},
                      **kw),)

    def go_to_object(self, **kw: Any) -> tuple[Step, ...]:
        return (_step('go to object', Action.MOVE_TO_PICKUP, self.to,
                      position=self.p.pickup.position, euler_xyz=self.p.pickup.euler_xyz,
                      sets={'at_pickup': True, 'at_hinge': False}, **kw),)

    def exploration(self) -> tuple[Step, ...]:
        """§3.8 steps 1–3 (grasp if needed, 5 N, linear and rotational phases with moves)."""
        e = self.p.estimation
        return (
            *self.grasp(hold=False, when={'holding': False}),
            self.mode('explore: HOLD on (if allowed)', ModeRequest(int(SlipMode.HOLD)),
                      optional=True),
            self.mode('explore: slip mode OFF', ModeRequest(int(SlipMode.OFF))),
            self.force('explore: exploration force', e.force),
            _step('explore: start linear phase', Action.START_ESTIMATION, self.to,
                  phase=EstimationPhase.LINEAR, duration=e.linear_window),
            self.move('explore: descend', lift=-e.descent, duration=e.descent_time),
            self.wait('explore: settle', max(0.0, e.linear_window - e.descent_time)),
            _step('explore: start rotational phase', Action.START_ESTIMATION, self.to,
                  phase=EstimationPhase.ROTATIONAL, duration=e.rotational_window),
            self.move('explore: twist', rotation=e.twist_angle, duration=e.twist_time),
            self.move('explore: twist back', rotation=-e.twist_angle, duration=e.twist_time),
            self.wait('explore: finish window',
                      max(0.0, e.rotational_window - 2.0 * e.twist_time)),
        )

    def read(self) -> Step:
        return _step('read contact properties', Action.READ_PROPERTIES, self.to)

    def record(self, name: str) -> tuple[tuple[Step, ...], tuple[Step, ...]]:
        """Start/stop steps for a recording (none when ``name`` has < 3 characters)."""
        if len(name) < 3:
            return (), ()
        start = _step('start recording', Action.START_RECORDING, self.to, bag_name=name,
                      topics=self.p.recording.topics)
        stop = _step('stop recording', Action.STOP_RECORDING, self.to)
        return (start,), (stop,)


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
    b = _Builder(params)
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
        steps = b.grasp()
    elif mode == 'go_to_object':
        steps = (b.require('requires open gripper and reset joints', gripper_open=True,
                           joints_reset=True), *b.go_to_object())
    elif mode == 'est_contact':
        steps = (b.require('requires the pick-up pose', at_pickup=True), *rec_start,
                 *b.exploration(), *b.release(), b.read(),
                 _step('return to pick-up pose', Action.RETURN_TO_PICKUP, 60.0 + b.to),
                 b.require('contact estimate valid', contact_estimated=True))
    elif mode == 'pick_up_object':
        steps = (b.require('requires an estimate and reset joints', contact_estimated=True,
                           joints_reset=True),
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
                 b.mode('LINEAR slip', linear), b.wait('slip', duration + 1.0))
    elif mode == 'rotational_slippage':
        need('duration', 'angle')
        steps = (b.require('requires holding', holding=True), *rec_start,
                 b.mode('ROTATIONAL slip', rotational), b.wait('slip', duration + 1.0))
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
                 *b.grasp(hold=False), *b.exploration(), b.read(),
                 *b.grasp(hold=True, hold_optional=False),
                 b.move('pick up: lift', lift=p.hold_height, sets={'at_pickup': False}),
                 b.mode('LINEAR slip', lin), b.wait('linear slip', lin.duration + 1.0),
                 b.move('turn to hinge pose', rotation=h.start_angle, sets={'at_hinge': True}),
                 b.mode('HINGE on', ModeRequest(int(SlipMode.HINGE))),
                 b.move('turn to hinge end', rotation=h.end_angle - h.start_angle),
                 b.wait('hinge wait', h.wait),
                 b.mode('HOLD on', ModeRequest(int(SlipMode.HOLD))),
                 b.move('turn back', rotation=-h.end_angle, sets={'at_hinge': False}),
                 b.mode('ROTATIONAL slip', rot), b.wait('rotational slip', rot.duration + 1.0))
    elif mode == 'force_tracking_test':
        steps = (b.force('force test: 5 N', 5.0), *rec_start, b.wait('force test: wait', 2.0),
                 _step('force test: profile', Action.PLAY_FORCE_PROFILE,
                       FORCE_PROFILE_DURATION + b.to, profile='force_tracking',
                       duration=FORCE_PROFILE_DURATION),
                 b.force('force test: back to 5 N', 5.0), b.wait('force test: settle', 1.0))
        return Sequence(mode, steps, (*rec_stop, b.force('force test: 0 N', 0.0)))
    else:
        raise ValueError(f'unknown runner mode {mode!r} (one of {", ".join(RUNNER_MODES)})')
    return Sequence(mode, steps, rec_stop if mode in RECORDING_MODES else ())


# ---------------------------------------------------------------------------------------------
# Force-tracking profile (§5.4)
# ---------------------------------------------------------------------------------------------

SQUARE_LEVELS = (5.0, 10.0, 5.0, 15.0, 5.0, 20.0, 5.0, 25.0, 5.0, 25.0, 15.0, 25.0, 5.0)
SINE_FREQUENCIES = (1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0)
LEVEL_TIME = 1.0
SINE_TIME = 5.0
GAP_TIME = 1.0
FORCE_PROFILE_DURATION = (len(SQUARE_LEVELS) * LEVEL_TIME + GAP_TIME
                          + len(SINE_FREQUENCIES) * SINE_TIME)


def force_tracking_profile(t: ArrayLike) -> NDArray[np.float64]:
    """Desired force [N] of the §5.4 profile at ``t`` [s] from its start (vectorised).

    Square wave (1 s per level), 1 s at 5 N, then ``5 + 10·(sin(2πft) + 1)/2`` for 5 s at each
    frequency; 5 N outside.
    """
    ta = np.asarray(t, dtype=np.float64)
    out = np.full(ta.shape, 5.0)
    n_sq = len(SQUARE_LEVELS)
    idx = np.floor(ta / LEVEL_TIME).astype(int)
    sq = (ta >= 0.0) & (idx < n_sq)
    out[sq] = np.asarray(SQUARE_LEVELS)[idx[sq]]
    ts = ta - (n_sq * LEVEL_TIME + GAP_TIME)
    k = np.floor(ts / SINE_TIME).astype(int)
    sn = (ts >= 0.0) & (k < len(SINE_FREQUENCIES))
    f = np.asarray(SINE_FREQUENCIES)[np.clip(k, 0, len(SINE_FREQUENCIES) - 1)]
    tl = ts - k * SINE_TIME
    out[sn] = (5.0 + 10.0 * (np.sin(2.0 * np.pi * f * tl) + 1.0) / 2.0)[sn]
    return out


# ---------------------------------------------------------------------------------------------
# Step machine
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class CellFlags:
    """State flags of the cell (§5.1)."""

    holding: bool = False
    at_pickup: bool = False
    at_hinge: bool = False
    joints_reset: bool = False
    gripper_open: bool = False
    contact_estimated: bool = False


@dataclass(frozen=True, slots=True)
class PoseOffset:
    """Tool offset from the pick-up pose accumulated by relative moves (m, m, rad)."""

    lift: float = 0.0
    lateral: float = 0.0
    rotation: float = 0.0


@dataclass(frozen=True, slots=True)
class RunnerProgress:
    """State of a running sequence (action feedback and result).

    Attributes:
        phase: Name of the current step (or "done"/"failed").
        elapsed: Time since the first poll [s].
        finished: No more steps will run.
        success: All main steps succeeded (meaningful when finished).
        message: Summary or the failure.
        estimate: Last contact properties read, if any.
        bag_path: Path reported by the recorder, if any.
        log: One line per finished or skipped step.
    """

    phase: str
    elapsed: float
    finished: bool
    success: bool
    message: str
    estimate: ContactProperties | None
    bag_path: str
    log: tuple[str, ...]


class SequenceRunner:
    """Executes a `Sequence` against a `CellInterface`, one non-blocking `poll` at a time.

    Poll at ≥ 50 Hz; during ``play_force_profile`` the profile is commanded on every poll, so
    poll at 500 Hz there (§5.4).

    Args:
        sequence: The steps.
        cell: The cell seam.
        params: Runner parameters (motion times for the return move).
        flags: State flags at the start.
        offset: Tool offset from the pick-up pose at the start.
    """

    def __init__(self, sequence: Sequence, cell: CellInterface, params: ExperimentRunnerParams,
                 flags: CellFlags = CellFlags(), offset: PoseOffset = PoseOffset()) -> None:
        self._seq = sequence
        self._cell = cell
        self._p = params
        self.flags = flags
        self.offset = offset
        self._queue: list[Step] = list(sequence.steps)
        self._in_cleanup = False
        self._current: Step | None = None
        self._step_t0 = 0.0
        self._pending: Pending | None = None
        self._until: float | None = None
        self._profile_t0 = 0.0
        self._t0: float | None = None
        self._log: list[str] = []
        self._failure = ''
        self._finished = False
        self._estimate: ContactProperties | None = None
        self._bag = ''
        self._last_t = 0.0

    @property
    def finished(self) -> bool:
        """No more steps will run."""
        return self._finished

    @property
    def fast_poll(self) -> bool:
        """The current step commands on every poll (force profile): poll at 500 Hz."""
        return self._current is not None and \
            self._current.action == Action.PLAY_FORCE_PROFILE

    def poll(self, t: float) -> RunnerProgress:
        """Advance as far as possible at time ``t`` [s] without blocking."""
        if self._t0 is None:
            self._t0 = t
        self._last_t = t
        while not self._finished:
            if self._current is None:
                if not self._next_step(t):
                    break
                continue
            step = self._current
            if self._pending is not None:
                if not self._pending.done():
                    if self._timed_out(step, t):
                        continue
                    break
                res = self._pending.result()
                self._pending = None
                self._apply(step, res, t)
                continue
            if self._until is not None:
                if step.action == Action.PLAY_FORCE_PROFILE and t < self._until:
                    f = float(force_tracking_profile(t - self._profile_t0))
                    self._cell.command_force(f, t)
                if t < self._until:
                    if self._timed_out(step, t):
                        continue
                    break
                self._until = None
            self._done(step, 'ok')
        return self.progress()

    def abort(self, message: str, t: float) -> None:
        """Stop the main steps now (cancel, cell fault); the cleanup steps still run.

        The running step's call is cancelled if its `Pending` has a ``cancel()`` method.
        Poll on to run the cleanup; `progress` then reports failure with ``message``.

        Args:
            message: Why (becomes the failure message).
            t: Current time [s].
        """
        self._last_t = t
        if self._finished or self._in_cleanup:
            return
        name = self._current.name if self._current is not None else 'between steps'
        self._cancel_pending()
        self._log.append(f'{name}: ABORTED: {message}')
        self._current = None
        self._until = None
        self._failure = f'{self._seq.mode}: aborted during {name!r}: {message}'
        self._queue = []

    def progress(self) -> RunnerProgress:
        """Current progress without advancing."""
        t0 = self._t0 if self._t0 is not None else self._last_t
        if self._finished:
            phase = 'failed' if self._failure else 'done'
        else:
            phase = self._current.name if self._current is not None else 'starting'
        msg = self._failure or (f'{self._seq.mode} done' if self._finished else '')
        return RunnerProgress(phase=phase, elapsed=self._last_t - t0, finished=self._finished,
                              success=self._finished and not self._failure, message=msg,
                              estimate=self._estimate, bag_path=self._bag,
                              log=tuple(self._log))

    # internals ------------------------------------------------------------------------------

    def _next_step(self, t: float) -> bool:
        if not self._queue:
            if not self._in_cleanup:
                self._in_cleanup = True
                self._queue = list(self._seq.cleanup)
                return True
            self._finished = True
            return False
        step = self._queue.pop(0)
        if not all(getattr(self.flags, k) == v for k, v in step.when):
            self._log.append(f'{step.name}: skipped (condition not met)')
            return True
        self._current = step
        self._step_t0 = t
        self._until = None
        res = self._begin(step, t)
        if isinstance(res, CallResult):
            self._apply(step, res, t)
        else:
            self._pending = res
        return True

    def _begin(self, step: Step, t: float) -> CallReturn:
        a, c = step.args, self._cell
        act = step.action
        if act == Action.COMMAND_FORCE:
            return c.command_force(float(a['force']), t)
        if act == Action.SET_SLIP_MODE:
            return c.set_slip_mode(a['request'], t)
        if act == Action.START_ESTIMATION:
            return c.start_estimation(a['phase'], float(a['duration']), t)
        if act == Action.READ_PROPERTIES:
            return c.read_properties(t)
        if act == Action.BIAS_FT:
            return c.bias_ft(t)
        if act == Action.MOVE_GRIPPER:
            return c.move_gripper(float(a['lift']), float(a['lateral']), float(a['rotation']),
                                  float(a['duration']), t)
        if act == Action.RETURN_TO_PICKUP:
            o = self.offset
            if abs(o.lift) + abs(o.lateral) + abs(o.rotation) <= 0.0:
                return CallResult(True, 'already at the pick-up pose')
            d = self._p.motion_duration(math.hypot(o.lift, o.lateral), o.rotation)
            return c.move_gripper(-o.lift, -o.lateral, -o.rotation, d, t)
        if act == Action.MOVE_TO_PICKUP:
            return c.move_to_pickup(tuple(a['position']), tuple(a['euler_xyz']), t)
        if act == Action.MOVE_JOINTS:
            return c.move_joints(tuple(a['names']), tuple(a['positions']),
                                 float(a['duration']), t)
        if act == Action.WAIT:
            return CallResult(True, until=t + float(a['seconds']))
        if act == Action.PLAY_FORCE_PROFILE:
            self._profile_t0 = t
            return CallResult(True, until=t + float(a['duration']))
        if act == Action.START_RECORDING:
            return c.start_recording(str(a['bag_name']), tuple(a['topics']), t)
        if act == Action.STOP_RECORDING:
            return c.stop_recording(t)
        if act == Action.REQUIRE:
            missing = [f'{k} (is {getattr(self.flags, k)})' for k, v in a['flags'].items()
                       if getattr(self.flags, k) != v]
            if missing:
                return CallResult(False, 'precondition not met: ' + ', '.join(missing))
            return CallResult(True)
        raise ValueError(f'unknown action {act!r}')

    def _apply(self, step: Step, res: CallResult, t: float) -> None:
        if not res.ok:
            if step.optional or self._in_cleanup:
                self._done(step, f'failed (ignored): {res.message}')
                return
            self._fail(step, res.message or 'failed')
            return
        if step.action == Action.MOVE_GRIPPER:
            a, o = step.args, self.offset
            self.offset = PoseOffset(o.lift + float(a['lift']), o.lateral + float(a['lateral']),
                                     o.rotation + float(a['rotation']))
        elif step.action in (Action.RETURN_TO_PICKUP, Action.MOVE_TO_PICKUP):
            self.offset = PoseOffset()
        elif step.action == Action.READ_PROPERTIES and isinstance(res.value, ContactProperties):
            self._estimate = res.value
            self.flags = replace(self.flags, contact_estimated=res.value.valid)
        elif step.action == Action.START_RECORDING and isinstance(res.value, str):
            self._bag = res.value
        if step.sets:
            self.flags = replace(self.flags, **dict(step.sets))
        self._until = res.until
        if self._until is None:
            self._done(step, res.message or 'ok')

    def _done(self, step: Step, note: str) -> None:
        self._log.append(f'{step.name}: {note}')
        self._current = None
        self._until = None
        self._pending = None

    def _timed_out(self, step: Step, t: float) -> bool:
        if t - self._step_t0 <= step.timeout:
            return False
        detail = ''
        describe = getattr(self._pending, 'describe', None)
        if callable(describe):
            detail = f' ({describe()})'
        self._cancel_pending()
        self._fail(step, f'timed out after {step.timeout:.1f} s{detail}')
        return True

    def _cancel_pending(self) -> None:
        """Give an abandoned call the chance to clean up (e.g. drop an rclpy future)."""
        cancel = getattr(self._pending, 'cancel', None)
        if callable(cancel):
            cancel()
        self._pending = None

    def _fail(self, step: Step, message: str) -> None:
        self._log.append(f'{step.name}: FAILED: {message}')
        self._current = None
        self._until = None
        self._pending = None
        if self._in_cleanup:
            return
        self._failure = f'{self._seq.mode}: step {step.name!r} failed: {message}'
        self._queue = []          # skip the remaining main steps; cleanup still runs
