# SPDX-License-Identifier: Apache-2.0
"""The experiment runner's sequences on the simulated cell, in process (SI units).

`SimRunnerCell` is the runner's `slip_control.core.runner_cell.CellInterface` made of direct
calls: the grasp-force command and the arm go to the cell (``sim_gripper``'s services), the
slip mode and the estimation to the agents that run the nodes' cores. `SequenceAgent` polls a
`slip_control.core.sequence_runner.SequenceRunner` on sim time as the ``experiment_runner``
node's timer does (every `POLL_PERIOD_S`, every telemetry line while it plays the force
profile). `run_sequence` plays one runner mode to its end. So the evaluation runs the runner's
own sequences — the §3.8 exploration of `slip_control.core.exploration` above all — and no
copy of them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from friction_models.core.harness import Harness, HarnessError
from friction_models.core.sensors import TelemetrySample

from slip_bringup.core.evaluation.agents import ControllerAgent, EstimatorAgent
from slip_bringup.core.evaluation.settings import EvaluationError
from slip_control.core.contact_estimator import EstimationPhase
from slip_control.core.mode_switch import ModeRequest
from slip_control.core.params import ExperimentRunnerParams
from slip_control.core.runner_cell import CallResult, CallReturn, describe_read
from slip_control.core.runner_sequences import build_sequence
from slip_control.core.sequence_runner import (CellFlags, PoseOffset, RunnerProgress,
                                               SequenceRunner)

#: The runner node's poll period [s] (its timer; sim time here).
POLL_PERIOD_S = 0.01

#: Flags of a fresh cell from `scene.make_harness`: at the pick-up pose, joints "reset" (the
#: simulated cell has none), open and biased, nothing held or estimated.
FRESH_CELL = CellFlags(at_pickup=True, joints_reset=True, gripper_open=True)


@dataclass(frozen=True)
class Move:
    """One arm motion the runner asked for (``gripper_middle`` conventions of the seam).

    Attributes:
        t_start: Request time [s].
        t_end: Expected end [s].
        lift: World-vertical displacement [m].
        lateral: World-horizontal displacement [m].
        rotation: About the grasp axis [rad].
    """

    t_start: float
    t_end: float
    lift: float
    lateral: float
    rotation: float


class _BiasDone:
    """Pending ``gripper/bias_ft``: done when the cell's bias window has closed."""

    def __init__(self, harness: Harness) -> None:
        self._h = harness

    def done(self) -> bool:
        return not self._h.cell.bias_in_progress

    def result(self) -> CallResult:
        return CallResult(True, 'biased')

    def describe(self) -> str:
        return 'the F/T bias window'


class _SlipDone:
    """Pending ``slip_control/execute``: done when the controller agent reports the end of the
    trajectory (its next result after the request)."""

    def __init__(self, agent: ControllerAgent, seen: int) -> None:
        self._agent = agent
        self._seen = seen

    def done(self) -> bool:
        return len(self._agent.results) > self._seen

    def result(self) -> CallResult:
        _, res = self._agent.results[self._seen]
        return CallResult(res.success, res.message, value=res)

    def describe(self) -> str:
        return 'the end of the slip trajectory'


@dataclass
class SimRunnerCell:
    """`CellInterface` on the harness and the core agents (module docstring).

    Attributes:
        harness: The simulated cell.
        estimator: The contact estimator's agent (``contact/start``, ``get_properties``).
        controller: The slip controller's agent (``slip_control/set_mode``); ``None``: mode
            requests are refused as by a controller that is not running.
        moves: Every accepted arm motion, in order.
    """

    harness: Harness
    estimator: EstimatorAgent
    controller: ControllerAgent | None = None
    moves: list[Move] = field(default_factory=list)

    def command_force(self, force: float, t: float) -> CallReturn:
        """``gripper/grasp_force_cmd`` [N], valid until replaced (as the runner sends it)."""
        try:
            self.harness.command_force(force, timeout=0.0)
        except HarnessError as exc:
            return CallResult(False, str(exc))
        return CallResult(True, f'{force:.2f} N commanded')

    def set_slip_mode(self, request: ModeRequest, t: float) -> CallReturn:
        """``slip_control/set_mode`` on the controller agent's host."""
        if self.controller is None:
            return CallResult(False, 'slip_control/set_mode: no slip controller in this cell')
        out = self.controller.set_mode(self.harness, request)
        return CallResult(out.ok, out.message if out.ok
                          else f'slip_control/set_mode: {out.message}')

    def execute_slip(self, request: ModeRequest, t: float) -> CallReturn:
        """``slip_control/execute`` on the controller agent's host: done when it ends."""
        if self.controller is None:
            return CallResult(False, 'slip_control/execute: no slip controller in this cell')
        out = self.controller.set_mode(self.harness, request)
        if not out.ok:
            return CallResult(False, f'slip_control/execute: {out.message}')
        return _SlipDone(self.controller, len(self.controller.results))

    def start_estimation(self, phase: EstimationPhase, duration: float, t: float) -> CallReturn:
        """``contact/start`` with the node's pre-check."""
        out = self.estimator.start(self.harness, phase, duration)
        return CallResult(out.accepted, out.message if out.accepted
                          else f'contact/start: {out.message}')

    def read_properties(self, t: float) -> CallReturn:
        """``contact/get_properties``."""
        props, _, message = self.estimator.estimator.get_properties()
        return CallResult(True, describe_read(props, message), value=props)

    def bias_ft(self, t: float) -> CallReturn:
        """``gripper/bias_ft``: done when the bias window has closed."""
        ok, message = self.harness.cell.bias_ft()
        if not ok:
            return CallResult(False, f'gripper/bias_ft: {message}')
        return _BiasDone(self.harness)

    def move_gripper(self, lift: float, lateral: float, rotation: float, duration: float,
                     t: float) -> CallReturn:
        """``sim/move_gripper``; ``until`` = the expected end."""
        ok, message, end = self.harness.cell.move_gripper(lift, lateral, rotation, duration)
        if not ok:
            return CallResult(False, f'sim/move_gripper refused: {message}')
        self.moves.append(Move(t, end, lift, lateral, rotation))
        return CallResult(True, message or 'moving', until=end)

    def move_to_pickup(self, position: tuple[float, ...], euler_xyz: tuple[float, ...],
                       t: float) -> CallReturn:
        """``sim/reset_scene``: object on the table between the open fingers."""
        del position, euler_xyz
        ok, message = self.harness.cell.reset(None, True)
        return CallResult(ok, message or 'scene reset: object on the table')

    def move_joints(self, names: tuple[str, ...], positions: tuple[float, ...],
                    duration: float, t: float) -> CallReturn:
        """No arm joints in the simulated cell: nothing to move."""
        del names, positions, duration
        return CallResult(True, 'simulated cell: no arm joints, nothing to move')

    def start_recording(self, name: str, topics: tuple[str, ...], t: float) -> CallReturn:
        """Nothing is recorded in process (the truth probe is the record)."""
        del topics
        return CallResult(True, f'in-process run: {name!r} not recorded')

    def stop_recording(self, t: float) -> CallReturn:
        """Nothing to stop."""
        return CallResult(True, 'not recording')


class SequenceAgent:
    """Polls a `SequenceRunner` on sim time like the runner node's timer.

    Args:
        poll_period: Poll period [s] (every telemetry line while the runner asks for fast
            polls).
    """

    def __init__(self, poll_period: float = POLL_PERIOD_S) -> None:
        self.poll_period = poll_period
        self.runner: SequenceRunner | None = None
        self.progress: RunnerProgress | None = None
        self._next = 0.0

    @property
    def finished(self) -> bool:
        """No sequence runs (none started, or the last one ended)."""
        return self.runner is None or self.runner.finished

    def start(self, harness: Harness, runner: SequenceRunner) -> None:
        """Run ``runner`` from now on (polled once at once, as the node's goal start does)."""
        self.runner = runner
        self._next = harness.t
        self._poll(harness.t)

    def on_telemetry(self, harness: Harness, sample: TelemetrySample) -> None:
        """Poll when due."""
        runner = self.runner
        if runner is None or runner.finished:
            return
        t = harness.t
        if t >= self._next - 1e-9 or runner.fast_poll:
            self._poll(t)

    def _poll(self, t: float) -> None:
        assert self.runner is not None
        while self._next <= t + 1e-9:
            self._next += self.poll_period
        self.progress = self.runner.poll(t)


def run_sequence(harness: Harness, agent: SequenceAgent, cell: SimRunnerCell, mode: str,
                 params: ExperimentRunnerParams = ExperimentRunnerParams(), *,
                 flags: CellFlags = FRESH_CELL, offset: PoseOffset = PoseOffset(),
                 timeout: float = 120.0, duration: float = 0.0, distance: float = 0.0,
                 angle: float = 0.0) -> SequenceRunner:
    """Play runner mode ``mode`` (``build_sequence``) on the cell until it ends.

    Args:
        harness: The cell (``agent`` must be one of its agents).
        agent: Polls the runner.
        cell: The seam the runner drives.
        mode: Runner mode (`slip_control.core.runner_sequences.RUNNER_MODES`).
        params: Runner parameters (their sim defaults are the node's YAML values).
        flags: Cell flags at the start.
        offset: Tool offset from the pick-up pose at the start.
        timeout: Longest sim time [s].
        duration: Goal ``duration`` [s] (`build_sequence`).
        distance: Goal ``distance`` [m].
        angle: Goal ``angle`` [rad].

    Returns:
        The finished runner (its ``progress()`` says how it ended; flags and offset carry on).

    Raises:
        EvaluationError: The sequence did not end within ``timeout``.
    """
    sequence = build_sequence(mode, params, duration=duration, distance=distance, angle=angle)
    runner = SequenceRunner(sequence, cell, params, flags, offset)
    agent.start(harness, runner)
    if not harness.run_until(lambda h: agent.finished, timeout):
        raise EvaluationError(f'runner mode {mode!r} did not end within {timeout:.0f} s '
                              f'(at {runner.progress().phase!r})')
    return runner
