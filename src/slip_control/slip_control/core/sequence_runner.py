# SPDX-License-Identifier: Apache-2.0
"""The experiment runner's step machine (control_and_estimation §5; CE-9), ROS-free.

`SequenceRunner` executes a `slip_control.core.runner_steps.Sequence` against a
`slip_control.core.runner_cell.CellInterface`, polled with the current time ``t`` [s] (no
clocks are read here, CE-7), checking and time-limiting every step. The cell flags (§5.1) and
the tool offset from the pick-up pose are tracked so that preconditions and "return to the
pick-up pose" work across steps and goals.

Slip segments (``EXECUTE_SLIP``) report the controller's outcome. A failed segment is logged
as FAILED and the sequence goes on (so that every segment of a ``demo`` reports), but the
sequence then ends with ``success = False`` naming every failed segment. A segment that ends
"contact lost", or `SequenceRunner.lose_object` (the node's drop detection), marks the
object lost: ``holding`` is cleared, ``object_dropped`` set, the remaining main steps are
skipped, and the next grasp must be preceded by ``go_to_object`` (the simulator resets its
scene there; on hardware the operator puts the object back) instead of wedging the runner.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

from slip_cell_common.core.force_profile import ForceTrackingProfile
from slip_control.core.contact import ContactProperties
from slip_control.core.controllers import SlipMode, SlipResult
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.params import ExperimentRunnerParams
from slip_control.core.runner_cell import CallResult, CallReturn, CellInterface, Pending
from slip_control.core.runner_steps import (FLAG_CLEARED_BY, FLAG_SOURCES, Action, Sequence,
                                            Step)

#: The slip outcome that means the object left the grasp (`SlipResult.message`).
CONTACT_LOST = 'contact lost'

#: The runner modes that re-grasp a lost object, in order.
RE_GRASP = ('release', 'go_to_object', 'grasp')


@dataclass(frozen=True, slots=True)
class CellFlags:
    """State flags of the cell (§5.1)."""

    holding: bool = False
    at_pickup: bool = False
    at_hinge: bool = False
    joints_reset: bool = False
    gripper_open: bool = False
    contact_estimated: bool = False
    object_dropped: bool = False   #: (addition) lost during a sequence; put back before a grasp


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
        segments: One line per slip segment: its outcome (`describe_slip`).
        object_lost: Why the object was lost during this sequence ('' if it was not).
    """

    phase: str
    elapsed: float
    finished: bool
    success: bool
    message: str
    estimate: ContactProperties | None
    bag_path: str
    log: tuple[str, ...]
    segments: tuple[str, ...] = ()
    object_lost: str = ''


def describe_slip(request: ModeRequest, result: SlipResult) -> str:
    """``'done: 19.9 of 20.0 mm in 2.05 s'``: a slip segment's outcome against its target."""
    if request.mode == int(SlipMode.ROTATIONAL):
        unit, scale, target = 'deg', 180.0 / math.pi, abs(request.angle)
    else:
        unit, scale, target = 'mm', 1e3, abs(request.distance)
    return (f'{result.message}: {result.final_pos * scale:.1f} of {target * scale:.1f} {unit} '
            f'in {result.elapsed:.2f} s')


def precondition_refusal(flags: CellFlags, required: Mapping[str, bool]) -> str:
    """Why ``flags`` do not meet ``required`` (naming the runner modes that set the missing
    flags), or '' when they do."""
    missing = [k for k, v in required.items() if getattr(flags, k) != v]
    if not missing:
        return ''
    text = 'precondition not met: ' + ', '.join(f'{k} (is {getattr(flags, k)})'
                                                for k in missing)
    hints = [' or '.join(repr(m) for m in FLAG_SOURCES[k]) for k in missing
             if required[k] and k in FLAG_SOURCES]
    hints += [' or '.join(repr(m) for m in FLAG_CLEARED_BY[k]) for k in missing
              if not required[k] and k in FLAG_CLEARED_BY]
    if hints:
        text += '; run ' + ', then '.join(hints) + ' first'
    if flags.object_dropped:
        text += ('; the object was lost: re-grasp it with '
                 + ', then '.join(repr(m) for m in RE_GRASP) + ' (the simulated cell resets its '
                 'scene at go_to_object; on hardware put the object back at the pick-up pose)')
    return text


def preflight(sequence: Sequence, flags: CellFlags) -> str:
    """Check a sequence's leading preconditions against ``flags`` before it starts.

    Returns:
        The refusal of the first leading ``REQUIRE`` step that fails, or '' (the sequence may
        start; later checks, e.g. a valid estimate after exploring, are made while running).
    """
    for step in sequence.steps:
        if step.action != Action.REQUIRE:
            return ''
        refusal = precondition_refusal(flags, step.args['flags'])
        if refusal:
            return f'{sequence.mode}: {refusal}'
    return ''


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
        self._estimate_note = ''
        self._bag = ''
        self._last_t = 0.0
        self._segments: list[str] = []
        self._segment_failures: list[str] = []
        self._lost = ''

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
                    profile: ForceTrackingProfile = step.args['profile']
                    self._cell.command_force(profile.target(t - self._profile_t0), t)
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

    def lose_object(self, message: str, t: float) -> None:
        """The object left the grasp (e.g. ``sim/state.object_dropped``): mark it lost and
        stop the main steps (the cleanup steps still run).

        Args:
            message: What detected it (becomes part of the failure message).
            t: Current time [s].
        """
        name = self._current.name if self._current is not None else 'between steps'
        self._mark_lost(f'during {name!r}: {message}')
        self.abort(message, t)

    def progress(self) -> RunnerProgress:
        """Current progress without advancing."""
        t0 = self._t0 if self._t0 is not None else self._last_t
        failed = bool(self._failure or self._segment_failures)
        if self._finished:
            phase = 'failed' if failed else 'done'
        else:
            phase = self._current.name if self._current is not None else 'starting'
        if self._finished and failed:
            parts = [self._failure] if self._failure else []
            if self._segment_failures:
                n, total = len(self._segment_failures), len(self._segments)
                parts.append(f'{self._seq.mode}: {n} of {total} slip segment(s) failed: '
                             + '; '.join(self._segment_failures))
            msg = ' | '.join(parts)
        elif self._finished:
            msg = f'{self._seq.mode} done' + (f' ({"; ".join(self._segments)})'
                                              if self._segments else '')
        else:
            msg = ''
        return RunnerProgress(phase=phase, elapsed=self._last_t - t0, finished=self._finished,
                              success=self._finished and not failed, message=msg,
                              estimate=self._estimate, bag_path=self._bag,
                              log=tuple(self._log), segments=tuple(self._segments),
                              object_lost=self._lost)

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
        if act == Action.EXECUTE_SLIP:
            return c.execute_slip(a['request'], t)
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
            refusal = precondition_refusal(self.flags, a['flags'])
            if refusal and self._estimate_note and a['flags'].get('contact_estimated') \
                    and not self.flags.contact_estimated:
                refusal += f'; the estimate read in this run: {self._estimate_note}'
            return CallResult(False, refusal) if refusal else CallResult(True)
        raise ValueError(f'unknown action {act!r}')

    def _apply(self, step: Step, res: CallResult, t: float) -> None:
        if step.action == Action.EXECUTE_SLIP and not self._in_cleanup:
            self._slip_outcome(step, res)
            return
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
            self._estimate_note = '' if res.value.valid else res.message
            self.flags = replace(self.flags, contact_estimated=res.value.valid)
        elif step.action == Action.START_RECORDING and isinstance(res.value, str):
            self._bag = res.value
        if step.sets:
            self.flags = replace(self.flags, **dict(step.sets))
        self._until = res.until
        if self._until is None:
            self._done(step, res.message or 'ok')

    def _slip_outcome(self, step: Step, res: CallResult) -> None:
        """Log a slip segment's outcome; a failure is counted and the sequence goes on,
        unless the object was lost."""
        result = res.value if isinstance(res.value, SlipResult) else None
        text = describe_slip(step.args['request'], result) if result is not None else \
            (res.message or 'failed')
        self._segments.append(f'{step.name}: {text}')
        if res.ok:
            self._done(step, text)
            return
        if result is not None and result.message == CONTACT_LOST:
            self._mark_lost(f'during {step.name!r}: {text}')
            self._fail(step, text)
            return
        self._segment_failures.append(f'{step.name!r}: {text}')
        self._log.append(f'{step.name}: FAILED: {text}')
        self._current = None
        self._until = None
        self._pending = None

    def _mark_lost(self, note: str) -> None:
        self._lost = note
        self.flags = replace(self.flags, holding=False, at_pickup=False, at_hinge=False,
                             object_dropped=True)

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
        message = f'timed out after {step.timeout:.1f} s{detail}'
        if step.action == Action.EXECUTE_SLIP:
            self._segments.append(f'{step.name}: no outcome: {message}')
        self._fail(step, message)
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
