# SPDX-License-Identifier: Apache-2.0
"""Runner sequences (§5.3, §3.8, §5.4) and the ROS-free step machine (CE-9)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from slip_control.core.contact import ContactProperties, ContactSource
from slip_control.core.controllers import SlipMode, SlipResult
from slip_control.core.contact_estimator import EstimationPhase
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.params import ExperimentRunnerParams
from slip_cell_common.core.force_profile import ForceTrackingProfile
from slip_control.core.runner_cell import CallResult, describe_read
from slip_control.core.runner_sequences import RUNNER_MODES, build_sequence
from slip_control.core.runner_steps import Action
from slip_control.core.sequence_runner import CellFlags, PoseOffset, SequenceRunner

P = ExperimentRunnerParams()


class _Later:
    """A pending call that completes at a given time."""

    def __init__(self, cell: FakeCell, at: float, result: CallResult) -> None:
        self.cell, self.at, self.res = cell, at, result

    def done(self) -> bool:
        return self.cell.now >= self.at

    def result(self) -> CallResult:
        return self.res


@dataclass
class FakeCell:
    """Records calls; arm moves end after their duration; services answer after 5 ms."""

    props: ContactProperties = field(default_factory=lambda: ContactProperties(
        source=ContactSource.ESTIMATED))
    reject_modes: tuple[int, ...] = ()
    never_answer: str = ''
    #: The estimator's last report, as ``contact/get_properties`` returns it.
    estimator_message: str = ''
    #: Outcome of a slip trajectory per mode (default: "done" at the target after its
    #: duration).
    slip_outcomes: dict[int, str] = field(default_factory=dict)
    now: float = 0.0
    calls: list[tuple[float, str, Any]] = field(default_factory=list)
    recording: bool = False

    def _rec(self, t: float, name: str, arg: Any = None) -> None:
        self.calls.append((t, name, arg))

    def command_force(self, force: float, t: float) -> CallResult:
        self._rec(t, 'force', force)
        return CallResult(True)

    def set_slip_mode(self, request: ModeRequest, t: float) -> Any:
        self._rec(t, 'mode', SlipMode(request.mode))
        if request.mode in self.reject_modes:
            return CallResult(False, 'HOLD needs valid mu_c and r')
        return _Later(self, t + 0.005, CallResult(True))

    def execute_slip(self, request: ModeRequest, t: float) -> Any:
        self._rec(t, 'execute', SlipMode(request.mode))
        if request.mode in self.reject_modes:
            return CallResult(False, 'slip_control/execute: beyond the grasp')
        target = request.distance if request.mode == SlipMode.LINEAR else abs(request.angle)
        message = self.slip_outcomes.get(request.mode, 'done')
        ok = message == 'done'
        pos = target if ok else 0.25 * target
        result = SlipResult(SlipMode(request.mode), ok, message, pos, target - pos,
                            request.duration if ok else 0.5)
        return _Later(self, t + (request.duration if ok else 0.5),
                      CallResult(ok, message, value=result))

    def start_estimation(self, phase: EstimationPhase, duration: float, t: float) -> Any:
        self._rec(t, 'estimate', (phase, duration))
        if self.never_answer == 'estimate':
            return _Later(self, math.inf, CallResult(True))
        return _Later(self, t + 0.005, CallResult(True))

    def read_properties(self, t: float) -> CallResult:
        self._rec(t, 'read')
        return CallResult(True, describe_read(self.props, self.estimator_message),
                          value=self.props)

    def bias_ft(self, t: float) -> CallResult:
        self._rec(t, 'bias')
        return CallResult(True)

    def move_gripper(self, lift: float, lateral: float, rotation: float, duration: float,
                     t: float) -> CallResult:
        self._rec(t, 'move', (lift, lateral, rotation, duration))
        return CallResult(True, until=t + duration)

    def move_to_pickup(self, position: tuple[float, ...], euler_xyz: tuple[float, ...],
                       t: float) -> CallResult:
        self._rec(t, 'pickup', position)
        return CallResult(True, until=t + 3.0)

    def move_joints(self, names: tuple[str, ...], positions: tuple[float, ...],
                    duration: float, t: float) -> CallResult:
        self._rec(t, 'joints', duration)
        return CallResult(True, until=t + duration)

    def start_recording(self, name: str, topics: tuple[str, ...], t: float) -> CallResult:
        self._rec(t, 'record', name)
        self.recording = True
        return CallResult(True, value=f'bags/{name}')

    def stop_recording(self, t: float) -> CallResult:
        self._rec(t, 'stop_record')
        self.recording = False
        return CallResult(True)

    def names(self) -> list[str]:
        return [c[1] for c in self.calls]


def _run(runner: SequenceRunner, cell: FakeCell, t_max: float = 200.0,
         dt: float = 0.002) -> Any:
    t = 0.0
    while t < t_max:
        cell.now = t
        prog = runner.poll(t)
        if prog.finished:
            return prog
        t += dt
    raise AssertionError('sequence did not finish')


def _valid_props() -> ContactProperties:
    from slip_control.core.contact import FingerContact
    f = FingerContact(mu_c=0.4, mu_s=0.44, mu_v=1.0, r=0.005, u=2.5e-5, linear_valid=True,
                      viscous_valid=True, static_valid=True, rotational_valid=True)
    return ContactProperties(f, f, ContactSource.ESTIMATED)


def test_est_contact_follows_the_exploration_procedure() -> None:
    cell = FakeCell(props=_valid_props())
    seq = build_sequence('est_contact', P, recording_name='est_contact_wood_1')
    runner = SequenceRunner(seq, cell, P, flags=CellFlags(at_pickup=True, joints_reset=True,
                                                          gripper_open=True))
    prog = _run(runner, cell)
    assert prog.success, prog.message
    assert prog.estimate is not None and prog.estimate.valid
    assert prog.bag_path == 'bags/est_contact_wood_1' and not cell.recording
    calls = cell.calls
    names = [c[1] for c in calls]
    assert names[0] == 'record' and names[-1] == 'stop_record'
    forces = [c[2] for c in calls if c[1] == 'force']
    assert forces == [10.0, 5.0, -8.0]
    est = [(c[0], c[2]) for c in calls if c[1] == 'estimate']
    assert [e[1][0] for e in est] == [EstimationPhase.LINEAR, EstimationPhase.ROTATIONAL]
    moves = [(c[0], c[2]) for c in calls if c[1] == 'move']
    assert moves[0][1] == (-0.01, 0.0, 0.0, 0.8)
    assert moves[1][1][2] == pytest.approx(0.17453) and moves[2][1][2] == pytest.approx(-0.17453)
    assert moves[-1][1][0] == pytest.approx(0.01)             # back to the pick-up pose
    # The linear phase covers the descent; the rotational phase starts ≈ 1 s later.
    assert moves[0][0] >= est[0][0]
    assert est[1][0] - est[0][0] == pytest.approx(1.0, abs=0.02)
    assert moves[1][0] >= est[1][0]
    # Grasp wait of 2 s before the exploration force.
    f_times = [c[0] for c in calls if c[1] == 'force']
    assert f_times[1] - f_times[0] >= 2.0
    assert runner.flags.gripper_open and not runner.flags.holding
    assert runner.flags.contact_estimated and runner.offset == PoseOffset()


def test_est_contact_reports_invalid_estimate_and_still_cleans_up() -> None:
    cell = FakeCell()           # ESTIMATED but no valid flags
    seq = build_sequence('est_contact', P, recording_name='abc')
    cell.estimator_message = 'ROTATIONAL estimation failed; finger 1: too few samples: 4 < 20'
    prog = _run(SequenceRunner(seq, cell, P, flags=CellFlags(at_pickup=True)), cell)
    assert not prog.success and 'contact estimate valid' in prog.message
    # The failure says why the estimate is invalid: the estimator's report of this run.
    assert 'finger 1: too few samples: 4 < 20' in prog.message, prog.message
    assert not cell.recording and cell.names()[-1] == 'stop_record'
    # It released and returned to the pick-up pose before the check.
    assert -8.0 in [c[2] for c in cell.calls if c[1] == 'force']


def test_preconditions_and_rejections_fail_cleanly() -> None:
    cell = FakeCell()
    prog = _run(SequenceRunner(build_sequence('pick_up_object', P), cell, P), cell)
    assert not prog.success and 'contact_estimated' in prog.message
    assert cell.calls == []
    cell = FakeCell(reject_modes=(int(SlipMode.HOLD),))
    seq = build_sequence('hold_mode', P, duration=5.0, recording_name='x_hold_mode_1')
    prog = _run(SequenceRunner(seq, cell, P, flags=CellFlags(holding=True)), cell)
    assert not prog.success and 'HOLD needs valid' in prog.message
    assert cell.names() == ['record', 'mode', 'stop_record']
    # Optional HOLD in `grasp` is only logged.
    cell = FakeCell(reject_modes=(int(SlipMode.HOLD),))
    prog = _run(SequenceRunner(build_sequence('grasp', P), cell, P), cell)
    assert prog.success and any('failed (ignored)' in line for line in prog.log)


def test_step_timeout() -> None:
    cell = FakeCell(props=_valid_props(), never_answer='estimate')
    seq = build_sequence('est_contact', P)
    prog = _run(SequenceRunner(seq, cell, P, flags=CellFlags(at_pickup=True, holding=True)),
                cell, t_max=100.0, dt=0.05)
    assert not prog.success and 'timed out after 30.0 s' in prog.message
    assert 30.0 < prog.elapsed < 31.0


def test_slip_sequences_and_hinge() -> None:
    cell = FakeCell()
    seq = build_sequence('linear_slippage', P, duration=2.0, distance=0.02,
                         recording_name='plastic_linear_t2_2cm_1')
    prog = _run(SequenceRunner(seq, cell, P, flags=CellFlags(holding=True)), cell)
    assert prog.success
    req = next(s.args['request'] for s in seq.steps if s.action == Action.EXECUTE_SLIP)
    assert req.mode == SlipMode.LINEAR and req.distance == 0.02 and req.latch_direction
    assert prog.elapsed >= 3.0                       # the 2 s trajectory, then 1 s settling
    assert prog.segments == ('LINEAR slip: done: 20.0 of 20.0 mm in 2.00 s',)
    assert prog.message == 'linear_slippage done (LINEAR slip: done: 20.0 of 20.0 mm in 2.00 s)'
    # Rotation, like the slide, goes the way gravity turns the object: sign latched.
    seq = build_sequence('rotational_slippage', P, duration=2.0, angle=0.35)
    req = next(s.args['request'] for s in seq.steps if s.action == Action.EXECUTE_SLIP)
    assert req.mode == SlipMode.ROTATIONAL and req.angle == 0.35 and req.latch_direction
    cell = FakeCell()
    seq = build_sequence('hinge_mode', P, recording_name='wood_hinge_mode_1')
    prog = _run(SequenceRunner(seq, cell, P, flags=CellFlags(holding=True, at_hinge=True)), cell)
    assert prog.success
    names = cell.names()
    assert names.index('stop_record') < len(names) - 2      # stopped before HOLD on
    modes = [c[2] for c in cell.calls if c[1] == 'mode']
    assert modes == [SlipMode.HINGE, SlipMode.HOLD]
    move = next(c[2] for c in cell.calls if c[1] == 'move')
    assert move[2] == pytest.approx(math.radians(60.0), abs=1e-6)
    assert move[3] == pytest.approx(4.19, abs=0.01)


def test_demo_runs_every_stage_in_order() -> None:
    cell = FakeCell(props=_valid_props())
    seq = build_sequence('demo', P, recording_name='demo_wood_1')
    prog = _run(SequenceRunner(seq, cell, P), cell, t_max=400.0, dt=0.01)
    assert prog.success, prog.message
    names = cell.names()
    assert names.index('joints') < names.index('pickup') < names.index('record')
    modes = [c[2] for c in cell.calls if c[1] in ('mode', 'execute')]
    assert modes == [SlipMode.OFF, SlipMode.HOLD, SlipMode.OFF, SlipMode.HOLD,
                     SlipMode.LINEAR, SlipMode.HINGE, SlipMode.HOLD, SlipMode.ROTATIONAL]
    assert [c[2] for c in cell.calls if c[1] == 'execute'] == [SlipMode.LINEAR,
                                                               SlipMode.ROTATIONAL]
    assert not cell.recording
    assert len(prog.segments) == 2 and all(': done: ' in line for line in prog.segments)


def test_a_failed_slip_segment_fails_the_demo_but_every_segment_reports() -> None:
    """Issue 16: a slip that ends "velocity stale" is not a success. The demo goes on (the
    rotational segment still runs and reports) and ends with success = False naming it."""
    cell = FakeCell(props=_valid_props(), slip_outcomes={int(SlipMode.LINEAR): 'velocity stale'})
    prog = _run(SequenceRunner(build_sequence('demo', P, recording_name='demo_x'), cell, P),
                cell, t_max=400.0, dt=0.01)
    assert prog.finished and not prog.success and prog.phase == 'failed'
    assert [c[2] for c in cell.calls if c[1] == 'execute'] == [SlipMode.LINEAR,
                                                               SlipMode.ROTATIONAL]
    assert prog.segments == ('LINEAR slip: velocity stale: 5.0 of 20.0 mm in 0.50 s',
                             'ROTATIONAL slip: done: 20.0 of 20.0 deg in 2.00 s')
    assert prog.message == ("demo: 1 of 2 slip segment(s) failed: 'LINEAR slip': velocity "
                            'stale: 5.0 of 20.0 mm in 0.50 s')
    assert 'LINEAR slip: FAILED: velocity stale: 5.0 of 20.0 mm in 0.50 s' in prog.log
    assert not cell.recording
    # A refused trajectory is a failed segment too.
    cell = FakeCell(reject_modes=(int(SlipMode.ROTATIONAL),))
    seq = build_sequence('rotational_slippage', P, duration=2.0, angle=3.0)
    prog = _run(SequenceRunner(seq, cell, P, flags=CellFlags(holding=True)), cell)
    assert not prog.success and 'beyond the grasp' in prog.message


def test_a_lost_object_stops_the_sequence_and_asks_for_a_re_grasp() -> None:
    """Issue 16: "contact lost" (the slip controller's drop detection, the one hardware has)
    marks the object lost; later goals that need it are refused naming the re-grasp steps
    instead of wedging, and ``go_to_object`` (scene reset in the simulator) puts it back."""
    from slip_control.core.sequence_runner import preflight
    cell = FakeCell(props=_valid_props(), slip_outcomes={int(SlipMode.LINEAR): 'contact lost'})
    runner = SequenceRunner(build_sequence('demo', P, recording_name='demo_x'), cell, P)
    prog = _run(runner, cell, t_max=400.0, dt=0.01)
    assert not prog.success
    assert "step 'LINEAR slip' failed: contact lost" in prog.message
    assert prog.object_lost.startswith("during 'LINEAR slip': contact lost")
    assert [c[2] for c in cell.calls if c[1] == 'execute'] == [SlipMode.LINEAR]  # stopped
    assert not cell.recording                                     # cleanup still ran
    flags = runner.flags
    assert flags.object_dropped and not flags.holding and not flags.at_pickup
    refusal = preflight(build_sequence('hold_mode', P, duration=1.0), flags)
    assert "holding (is False); run 'grasp' or 'pick_up_object' first" in refusal
    assert "re-grasp it with 'release', then 'go_to_object', then 'grasp'" in refusal
    assert "object_dropped (is True); run 'go_to_object' first" in \
        preflight(build_sequence('grasp', P), flags)
    # The demo puts it back by itself: release, then go to the object (scene reset), ...
    cell = FakeCell(props=_valid_props())
    runner = SequenceRunner(build_sequence('demo', P), cell, P, flags=flags)
    prog = _run(runner, cell, t_max=400.0, dt=0.01)
    assert prog.success, prog.message
    names = cell.names()
    assert names.index('force') < names.index('pickup') < names.index('execute')
    assert not runner.flags.object_dropped


def test_the_node_reports_a_drop_and_a_deliberate_release_is_none() -> None:
    """`lose_object` (the node's sim/state drop check) while holding; a second demo starting
    with the object lifted clears ``holding`` before it opens the gripper (so the fall is not
    a fault) and goes back to the object."""
    cell = FakeCell(props=_valid_props())
    runner = SequenceRunner(build_sequence('hold_mode', P, duration=10.0), cell, P,
                            flags=CellFlags(holding=True, at_hinge=True))
    t = 0.0
    while t < 1.0:
        cell.now = t
        runner.poll(t)
        t += 0.01
    runner.lose_object('the object was dropped (sim/state.object_dropped)', t)
    prog = _run(runner, cell)
    assert not prog.success and 'aborted during' in prog.message
    assert prog.object_lost == ("during 'hold': the object was dropped "
                                '(sim/state.object_dropped)')
    assert runner.flags.object_dropped and not runner.flags.holding
    assert not runner.flags.at_hinge
    # After a full demo the object is lifted and held; the next demo lets go first.
    seq = build_sequence('demo', P)
    lifted = CellFlags(holding=True, joints_reset=True, contact_estimated=True)
    cell = FakeCell(props=_valid_props())
    runner = SequenceRunner(seq, cell, P, flags=lifted)
    seen: list[tuple[str, bool]] = []
    t = 0.0
    while not runner.poll(t).finished:
        seen.append((runner.progress().phase, runner.flags.holding))
        cell.now = t = t + 0.01
    assert runner.progress().success
    assert ('release: wait', False) in seen                       # open, not holding
    assert cell.names().index('pickup') < cell.names().index('execute')


def test_bad_runner_requests() -> None:
    with pytest.raises(ValueError, match='unknown runner mode'):
        build_sequence('dance', P)
    with pytest.raises(ValueError, match='needs distance'):
        build_sequence('linear_slippage', P, duration=2.0)
    with pytest.raises(ValueError, match='not finite'):
        build_sequence('hold_mode', P, duration=float('nan'))
    for mode in RUNNER_MODES:
        seq = build_sequence(mode, P, duration=2.0, distance=0.02, angle=0.3)
        assert all(s.timeout > 0.0 for s in seq.steps)


def test_force_tracking_plays_the_one_profile() -> None:
    """§5.4 through the runner: the profile of `slip_cell_common.core.force_profile` (the one
    the driver's ``force_tracking_test`` tool plays), recorded from its first sample on."""
    fp = ForceTrackingProfile()
    assert fp.duration == pytest.approx(2 + 13 + 1 + 35 + 1)
    cell = FakeCell()
    seq = build_sequence('force_tracking_test', P, recording_name='sponge_1')
    prog = _run(SequenceRunner(seq, cell, P), cell, t_max=70.0, dt=0.002)
    assert prog.success
    calls = [c for c in cell.calls if c[1] in ('force', 'record', 'stop_record')]
    assert calls[0][1:] == ('force', 5.0) and calls[1][1] == 'record'
    assert calls[-2][1] == 'stop_record' and calls[-1][1:] == ('force', 0.0)
    played = [(t, f) for t, name, f in calls[2:-2]]
    t0 = played[0][0]
    assert played[-1][0] - t0 == pytest.approx(fp.duration, abs=0.003)
    t = np.array([p[0] for p in played]) - t0
    assert np.array([p[1] for p in played]) == pytest.approx(fp.targets(t), abs=1e-9)
    assert max(f for _, f in played) == 25.0 and not cell.recording


class _Abandoned:
    """A pending call that never answers and records whether it was cancelled."""

    def __init__(self) -> None:
        self.cancelled = False

    def done(self) -> bool:
        return False

    def result(self) -> CallResult:
        raise AssertionError('never done')

    def describe(self) -> str:
        return 'service contact/start not available'

    def cancel(self) -> None:
        self.cancelled = True


def test_timeout_names_what_it_waited_for_and_cancels_the_call() -> None:
    cell = FakeCell(props=_valid_props())
    pending = _Abandoned()
    cell.start_estimation = lambda phase, duration, t: pending  # type: ignore[method-assign]
    seq = build_sequence('est_contact', P)
    prog = _run(SequenceRunner(seq, cell, P, flags=CellFlags(at_pickup=True, holding=True)),
                cell, t_max=100.0, dt=0.05)
    assert 'timed out after 30.0 s (service contact/start not available)' in prog.message
    assert pending.cancelled


def test_abort_skips_main_steps_but_runs_cleanup() -> None:
    cell = FakeCell(props=_valid_props())
    seq = build_sequence('hold_mode', P, duration=10.0, recording_name='hold_x')
    runner = SequenceRunner(seq, cell, P, flags=CellFlags(holding=True))
    t = 0.0
    while t < 1.0:
        cell.now = t
        runner.poll(t)
        t += 0.01
    assert cell.recording and not runner.finished
    runner.abort('canceled by the client', t)
    prog = _run(runner, cell)
    assert prog.finished and not prog.success and not cell.recording
    assert "hold_mode: aborted during 'hold': canceled by the client" == prog.message
    assert prog.bag_path == 'bags/hold_x'


def test_fast_poll_only_during_the_force_profile() -> None:
    cell = FakeCell()
    runner = SequenceRunner(build_sequence('force_tracking_test', P), cell, P)
    seen = set()
    t = 0.0
    while not runner.poll(t).finished:
        seen.add((runner.progress().phase, runner.fast_poll))
        cell.now = t = t + 0.01
    assert ('force test: profile', True) in seen
    assert all(not fast for phase, fast in seen if phase != 'force test: profile')


def test_est_contact_then_pick_up_object_leaves_the_cell_ready_for_slip_modes() -> None:
    """Issue 18: after estimation and pick-up the cell holds the object (no extra `grasp`)."""
    from slip_control.core.sequence_runner import preflight
    cell = FakeCell(props=_valid_props())
    flags = CellFlags(at_pickup=True, joints_reset=True, gripper_open=True)
    for mode in ('est_contact', 'pick_up_object'):
        assert preflight(build_sequence(mode, P), flags) == ''
        runner = SequenceRunner(build_sequence(mode, P), cell, P, flags=flags)
        prog = _run(runner, cell)
        assert prog.success, prog.message
        flags = runner.flags
    assert flags.holding and not flags.gripper_open and not flags.at_pickup
    # pick_up_object closed on the object (grasp force), turned HOLD on, then lifted.
    tail = cell.calls[[c[1] for c in cell.calls].index('read') + 1:]
    assert [c[1] for c in tail if c[1] in ('force', 'mode', 'move')][-3:] == \
        ['force', 'mode', 'move']
    assert [c[2] for c in tail if c[1] == 'mode'][-1] == SlipMode.HOLD
    assert [c[2] for c in tail if c[1] == 'force'][-1] == P.grasp.force
    assert tail[-1][2][0] == pytest.approx(P.hold_height)
    slip = build_sequence('linear_slippage', P, duration=2.0, distance=0.02)
    assert preflight(slip, flags) == ''
    # Without the pick-up, the refusal names the missing step.
    refusal = preflight(slip, CellFlags(contact_estimated=True))
    assert "precondition not met: holding (is False); run 'grasp' or 'pick_up_object' first" \
        in refusal
    # Already holding (the old est_contact, grasp, pick_up_object order): no second grasp.
    cell = FakeCell(props=_valid_props())
    runner = SequenceRunner(build_sequence('pick_up_object', P), cell, P,
                            flags=CellFlags(contact_estimated=True, joints_reset=True,
                                            holding=True))
    assert _run(runner, cell).success and 'force' not in cell.names()
