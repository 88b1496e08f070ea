# SPDX-License-Identifier: Apache-2.0
"""experiment_runner node through real DDS: sequences over the mock and sim arm backends.

The runner, the real slip controller and a driver node (``gripper/bias_ft``, a fake simulator
arm interface) share one executor on a private context; times are shortened by parameters.
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from slip_cell_common.time_conv import clock_seconds

pytestmark = pytest.mark.ros

FAST = {'release.wait': 0.1, 'grasp.wait': 0.1, 'step_timeout': 3.0,
        'motion_time.min': 0.1, 'motion_time.gain': 0.05}


def _runner(harness, tmp_path: Path, **params):
    from rclpy.parameter import Parameter
    from slip_control.experiment_runner_node import ExperimentRunnerNode
    values = {**FAST, 'recording.directory': str(tmp_path / 'bags'), **params}
    return harness.add(ExperimentRunnerNode(context=harness.context, parameter_overrides=[
        Parameter(k, value=v) for k, v in values.items()]))


def _controller(harness):
    from slip_control.slip_controller_node import SlipControllerNode
    return harness.add(SlipControllerNode(context=harness.context))


def _bias_service(harness) -> list:
    from std_srvs.srv import Trigger
    calls: list = []

    def bias(req, res):
        calls.append(req)
        res.success, res.message = True, 'biased'
        return res
    harness.node.create_service(Trigger, 'gripper/bias_ft', bias)
    return calls


def _run(harness, mode: str, *, timeout_s: float = 20.0, cancel_after: float | None = None,
         **goal):
    from slip_msgs.action import RunExperiment
    client = harness.action_client(RunExperiment, 'experiment/run')
    assert harness.spin_until(client.server_is_ready, 10.0)
    feedback: list = []
    send = client.send_goal_async(RunExperiment.Goal(mode=mode, **goal),
                                  feedback_callback=lambda m: feedback.append(m.feedback))
    assert harness.spin_until(send.done, 10.0) and send.result().accepted
    handle = send.result()
    result = handle.get_result_async()
    if cancel_after is not None:
        harness.spin_for(cancel_after)
        cancel = handle.cancel_goal_async()
        assert harness.spin_until(cancel.done, 5.0)
    assert harness.spin_until(result.done, timeout_s), f'{mode} did not finish'
    return result.result(), [f.phase for f in feedback]


def _rejected(harness, mode: str, **goal) -> bool:
    """Send a goal and report whether the server rejected it in its goal response."""
    from slip_msgs.action import RunExperiment
    client = harness.action_client(RunExperiment, 'experiment/run')
    assert harness.spin_until(client.server_is_ready, 10.0)
    send = client.send_goal_async(RunExperiment.Goal(mode=mode, **goal))
    assert harness.spin_until(send.done, 10.0)
    return not send.result().accepted


def _props(make_props):
    return make_props(mu_c=0.45, r=0.006)


def test_release_grasp_and_hold_mode_with_recording(harness, make_props,
                                                    tmp_path: Path) -> None:
    from action_msgs.msg import GoalStatus
    from slip_cell_common.bag_io import read_messages
    from slip_msgs.msg import GraspForceCommand
    runner = _runner(harness, tmp_path)
    _controller(harness)
    bias = _bias_service(harness)
    cmds = harness.collect(GraspForceCommand, 'gripper/grasp_force_cmd')

    res, phases = _run(harness, 'release')
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    # Feedback = the step running at each poll (instant steps may not show up).
    assert phases == ['release: slip mode OFF', 'release: wait', 'release: bias F/T', 'done']
    assert len(bias) == 1 and runner.flags.gripper_open and not runner.flags.holding
    assert harness.spin_until(lambda: any(c.force == -8.0 for c in cmds))
    opened = [c for c in cmds if c.force == -8.0][0]
    assert opened.source == GraspForceCommand.SOURCE_EXPERIMENT_RUNNER and opened.timeout == 0.0
    assert res.result.estimate.source == 0 and not res.result.estimate.valid
    assert math.isnan(res.result.estimate.finger_1.mu_c)        # no estimate: NaN, not numbers

    # grasp: HOLD is optional there; without valid properties it is refused and logged.
    res, _ = _run(harness, 'grasp')
    assert res.status == GoalStatus.STATUS_SUCCEEDED and runner.flags.holding

    harness.publish_properties(_props(make_props))
    harness.spin_for(0.1)
    res, phases = _run(harness, 'hold_mode', duration=0.3, recording_name='hold_test')
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    assert phases == ['HOLD on', 'hold', 'done']
    bag = Path(res.result.bag_path)
    assert bag.parent == tmp_path / 'bags' and bag.name == 'hold_test' and bag.exists()
    recorded = read_messages(bag)
    assert '/slip_control/state' in recorded and '/contact/properties' in recorded
    res, _ = _run(harness, 'hold_mode', duration=0.1, recording_name='hold_test')
    assert Path(res.result.bag_path).name == 'hold_test_2'   # never overwrites a bag


def test_refusals_timeouts_and_cancel(harness, make_props, tmp_path: Path) -> None:
    from action_msgs.msg import GoalStatus
    runner = _runner(harness, tmp_path, step_timeout=0.5)
    # Invalid goals are rejected in the goal response (never accepted, then aborted); the
    # reason is logged and kept for diagnostics.
    assert _rejected(harness, 'juggle')
    assert "unknown runner mode 'juggle'" in runner.last_rejection
    assert 'demo' in runner.last_rejection
    assert _rejected(harness, 'linear_slippage', duration=2.0)
    assert 'needs distance' in runner.last_rejection
    assert _rejected(harness, 'hold_mode', duration=1.0, recording_name='ab')
    assert 'recording_name' in runner.last_rejection
    assert '>= 3 characters' in runner.last_rejection
    assert _rejected(harness, 'hold_mode', duration=1.0)
    assert 'precondition not met: holding (is False)' in runner.last_rejection
    assert "run 'grasp' or 'pick_up_object' first" in runner.last_rejection

    # No slip controller running: the first step times out and says what it waited for.
    res, _ = _run(harness, 'release')
    assert res.status == GoalStatus.STATUS_ABORTED
    assert ("step 'release: slip mode OFF' failed: timed out after 0.5 s "
            '(service slip_control/set_mode not available)') in res.result.message


def test_cancel_runs_cleanup(harness, make_props, tmp_path: Path) -> None:
    from action_msgs.msg import GoalStatus
    runner = _runner(harness, tmp_path)
    _controller(harness)
    _bias_service(harness)
    harness.publish_properties(_props(make_props))
    res, _ = _run(harness, 'grasp')
    assert res.status == GoalStatus.STATUS_SUCCEEDED and runner.flags.holding
    res, phases = _run(harness, 'hold_mode', duration=30.0, recording_name='cancelled',
                       cancel_after=0.5)
    assert res.status == GoalStatus.STATUS_CANCELED
    assert 'canceled by the client' in res.result.message and 'hold' in phases
    assert Path(res.result.bag_path).exists()                 # cleanup stopped the recorder


def test_sim_backend_moves_and_checks_the_clock(harness, tmp_path: Path) -> None:
    from action_msgs.msg import GoalStatus
    from slip_msgs.srv import MoveGripper, ResetScene
    moves: list = []
    offset = [0.0]

    def move(req, res):
        moves.append((req.lift, req.lateral, req.rotation, req.duration))
        now = clock_seconds(harness.node.get_clock())
        res.success, res.message = True, 'moving'
        res.expected_end = now + req.duration + offset[0]
        return res

    def reset(req, res):
        res.success, res.message = True, f'scene reset, object_on_table={req.object_on_table}'
        return res
    harness.node.create_service(MoveGripper, 'sim/move_gripper', move)
    harness.node.create_service(ResetScene, 'sim/reset_scene', reset)
    runner = _runner(harness, tmp_path, **{'arm.backend': 'sim'})
    _controller(harness)
    assert runner.arm.name == 'sim'
    assert _rejected(harness, 'go_to_object')
    assert 'precondition not met: gripper_open (is False), joints_reset (is False)' \
        in runner.last_rejection
    assert "run 'release', then 'reset_joints' first" in runner.last_rejection
    res, _ = _run(harness, 'grasp')
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    res, _ = _run(harness, 'go_to_hinge_pose')
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    # motion time max(motion_time.min, gain·(5·|Δp| + |Δangle|)) = max(0.1, 0.05·1.047) s
    assert moves == [(0.0, 0.0, pytest.approx(1.0471976), pytest.approx(0.1))]
    assert runner.flags.at_hinge

    offset[0] = -1.0e6                      # an expected_end on another clock is caught
    res, _ = _run(harness, 'go_to_hinge_pose')
    assert res.status == GoalStatus.STATUS_ABORTED
    assert "is not on this node's clock" in res.result.message


def test_ur_backend_is_refused_clearly(ros_context) -> None:
    from rclpy.parameter import Parameter
    from slip_control.arm_backends import ArmUnavailableError
    from slip_control.experiment_runner_node import ExperimentRunnerNode
    with pytest.raises(ArmUnavailableError, match="'ur' is not implemented yet"):
        ExperimentRunnerNode(context=ros_context,
                             parameter_overrides=[Parameter('arm.backend', value='ur')])


@pytest.mark.slow
def test_est_contact_then_pick_up_object_then_a_slip_mode_is_accepted(
        harness, make_props, tmp_path: Path) -> None:
    """Issue 18: the documented order needs no extra `grasp` before a slip mode."""
    from action_msgs.msg import GoalStatus
    from slip_cell_common.time_conv import seconds_to_stamp
    from slip_control.slip_msgs_conv import properties_to_msg
    from slip_msgs.msg import SlipControllerState
    from slip_msgs.srv import GetContactProperties, StartEstimation
    from slip_cell_common.qos import LATCHED
    props = _props(make_props)
    runner = _runner(harness, tmp_path, **{'estimation.descent_time': 0.1,
                                          'estimation.linear_window': 0.2,
                                          'estimation.twist_time': 0.1,
                                          'estimation.rotational_window': 0.3})
    _controller(harness)
    _bias_service(harness)
    harness.node.create_service(StartEstimation, 'contact/start', lambda req, res: (
        setattr(res, 'accepted', True), setattr(res, 'message', 'started'), res)[-1])

    def get_properties(req, res):
        res.properties = properties_to_msg(props, seconds_to_stamp(1.0))
        res.valid, res.message = True, 'estimated'
        return res
    harness.node.create_service(GetContactProperties, 'contact/get_properties', get_properties)
    harness.publish_properties(props)
    states = harness.collect(SlipControllerState, 'slip_control/state', LATCHED)

    for mode in ('release', 'reset_joints', 'go_to_object', 'est_contact', 'pick_up_object'):
        res, _ = _run(harness, mode, timeout_s=60.0)
        assert res.status == GoalStatus.STATUS_SUCCEEDED, (mode, res.result.message)
    assert runner.flags.holding and runner.flags.contact_estimated
    res, phases = _run(harness, 'linear_slippage', duration=2.0, distance=0.02,
                       cancel_after=0.5)
    assert 'LINEAR slip' in phases, phases   # not refused: the slip segment ran
    # LINEAR accepted: its state, or (it ends at once here) the HOLD after it saying so.
    assert any(s.mode == 2 or s.reason.startswith('LINEAR ended') for s in states), \
        [(s.mode, s.reason) for s in states]
    assert res.status == GoalStatus.STATUS_CANCELED, res.result.message
    # No sensor streams in this graph: the trajectory itself ends "velocity stale", and the
    # result says so instead of claiming the slip.
    assert "'LINEAR slip': velocity stale" in res.result.message
