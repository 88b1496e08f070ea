# SPDX-License-Identifier: Apache-2.0
"""slip_controller node through real DDS: set_mode validation, ExecuteSlip, stale inputs.

Sensor streams are built in ``gripper_middle`` (both pads see the same object motion) and
played in sim time with a test ``/clock``, so every assertion is on message stamps.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from slip_control.core.contact import ContactSource
from slip_control.core.signals import SensorSnapshot
from slip_control.core.trajectory import TrapezoidalTrajectory
from slip_cell_common.time_conv import stamp_to_seconds

pytestmark = pytest.mark.ros

T0 = 50.0
DT = 1.0 / 120.0


def _controller(harness, **params):
    from rclpy.parameter import Parameter
    from slip_control.slip_controller_node import SlipControllerNode
    overrides = [Parameter('use_sim_time', value=True)]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    node = harness.add(SlipControllerNode(context=harness.context,
                                          parameter_overrides=overrides))
    harness.advance(T0)
    return node


def _outputs(harness):
    from slip_cell_common.qos import LATCHED
    from slip_msgs.msg import GraspForceCommand, SlipControllerState, SlipTracking
    return (harness.collect(GraspForceCommand, 'gripper/grasp_force_cmd'),
            harness.collect(SlipControllerState, 'slip_control/state', LATCHED),
            harness.collect(SlipTracking, 'slip_control/tracking'))


def _set_mode(harness, mode: int, **kw):
    from slip_msgs.srv import SetSlipMode
    req = SetSlipMode.Request(mode=mode, duration=kw.get('duration', 0.0),
                              distance=kw.get('distance', 0.0), angle=kw.get('angle', 0.0),
                              latch_direction=kw.get('latch', False))
    req.direction.x, req.direction.y = kw.get('direction', (0.0, 0.0))
    res = harness.call(SetSlipMode, 'slip_control/set_mode', req)
    assert res is not None, 'slip_control/set_mode did not answer'
    return res


def _slide(snap: Callable[..., SensorSnapshot], t0: float, seconds: float, *,
           distance: float = 0.02, duration: float = 2.0,
           normal: float = 5.0) -> list[SensorSnapshot]:
    """Object sliding along gripper_middle −y on the trapezoid (friction 0.45·f_n opposing)."""
    traj = TrapezoidalTrajectory(distance, duration)
    out = []
    for i in range(1, int(round(seconds / DT)) + 1):
        t = t0 + i * DT
        _, v = traj.sample(t - t0)
        f = 0.45 * normal if v > 0.0 else 0.3 * normal
        out.append(snap(t, f=(0.0, f), v=(0.0, -v), normal=normal, ft_stamp=t - 0.001,
                        v2_stamp=t - 0.001))
    return out


def _hold_still(snap: Callable[..., SensorSnapshot], t0: float,
                seconds: float) -> list[SensorSnapshot]:
    return [snap(t0 + i * DT, f=(0.0, 1.0), normal=5.0, ft_stamp=t0 + i * DT - 0.001)
            for i in range(1, int(round(seconds / DT)) + 1)]


def _send_goal(harness, mode: int, feedback: list, **kw):
    from slip_msgs.action import ExecuteSlip
    client = harness.action_client(ExecuteSlip, 'slip_control/execute')
    assert harness.spin_until(client.server_is_ready, 10.0)
    goal = ExecuteSlip.Goal(mode=mode, duration=kw.get('duration', 2.0),
                            distance=kw.get('distance', 0.0), angle=kw.get('angle', 0.0),
                            latch_direction=kw.get('latch', False))
    goal.direction.y = kw.get('direction_y', 0.0)
    send = client.send_goal_async(goal, feedback_callback=feedback.append)
    assert harness.spin_until(send.done, 10.0)
    handle = send.result()
    assert handle.accepted
    return handle, handle.get_result_async()


def test_set_mode_rejects_bad_arguments_with_messages(harness, make_props) -> None:
    from slip_msgs.srv import SetSlipMode as M
    node = _controller(harness)
    cmds, states, _ = _outputs(harness)
    assert harness.spin_until(lambda: len(states) >= 1)
    assert states[-1].mode == M.Request.OFF and not states[-1].contact_valid

    res = _set_mode(harness, M.Request.HOLD)
    assert not res.success and 'no contact properties received' in res.message
    harness.publish_properties(make_props(source=ContactSource.DEFAULT))
    assert harness.spin_until(lambda: node.host.properties is not None)
    res = _set_mode(harness, M.Request.LINEAR, duration=2.0, distance=0.02)
    assert not res.success and 'DEFAULT (placeholder)' in res.message

    harness.publish_properties(make_props(mu_c=0.45, r=0.006))
    assert harness.spin_until(lambda: states and states[-1].contact_valid)
    cases = [
        (dict(mode=M.Request.LINEAR, duration=math.nan, distance=0.02),
         'duration = nan is not a finite number'),
        (dict(mode=M.Request.LINEAR, duration=2.0, distance=math.inf), 'distance = inf'),
        (dict(mode=M.Request.ROTATIONAL, duration=2.0, angle=-math.inf), 'angle = -inf'),
        (dict(mode=M.Request.LINEAR, duration=-1.0, distance=0.02), 'duration = -1.0 s outside'),
        (dict(mode=M.Request.LINEAR, duration=2.0, distance=0.5), 'beyond the grasp'),
        (dict(mode=M.Request.LINEAR, duration=2.0, distance=0.0), 'must be > 0'),
        (dict(mode=M.Request.ROTATIONAL, duration=2.0, angle=0.0), 'must be non-zero'),
        (dict(mode=9), 'unknown mode 9'),
    ]
    for kw, text in cases:
        mode = kw.pop('mode')
        res = _set_mode(harness, mode, **kw)
        assert not res.success and text in res.message, (mode, kw, res.message)
    harness.spin_for(0.05)
    assert states[-1].mode == M.Request.OFF and not cmds          # nothing changed

    # Only mu_c valid: LINEAR and HINGE allowed, HOLD and ROTATIONAL refused.
    harness.publish_properties(make_props(rotational_valid=False))
    assert harness.spin_until(lambda: node.host.properties is not None
                              and not node.host.properties.finger_1.rotational_valid)
    res = _set_mode(harness, M.Request.ROTATIONAL, duration=2.0, angle=0.3)
    assert not res.success and 'finger 1 r' in res.message
    res = _set_mode(harness, M.Request.HINGE)
    assert res.success, res.message


def test_hold_commands_carry_sim_stamps_timeout_and_source(harness, make_props,
                                                           snap) -> None:
    from slip_msgs.msg import GraspForceCommand
    from slip_msgs.srv import SetSlipMode as M
    node = _controller(harness)
    cmds, states, tracking = _outputs(harness)
    harness.publish_properties(make_props(mu_c=0.45, r=0.006))
    assert harness.spin_until(lambda: states and states[-1].contact_valid)
    res = _set_mode(harness, M.Request.HOLD)
    assert res.success, res.message
    data = _hold_still(snap, T0, 0.25)
    harness.play(data, node)
    assert harness.spin_until(lambda: len(cmds) >= len(data) - 2)
    stamps = np.array([stamp_to_seconds(c.header.stamp) for c in cmds])
    assert np.all((stamps >= T0) & (stamps <= data[-1].twist_1.stamp + 0.011))  # sim time
    assert all(c.timeout == pytest.approx(0.1) for c in cmds)
    assert all(c.source == GraspForceCommand.SOURCE_SLIP_CONTROLLER for c in cmds)
    # HOLD: 2·max(D/mu_c, 2 N) with D = 1 N → 4.44 N, no slip.
    assert cmds[-1].force == pytest.approx(2.0 * 1.0 / 0.45, rel=0.02)
    assert states[-1].mode == M.Request.HOLD and not states[-1].safe_hold
    assert not tracking                                          # tracking only in modes 1/2

    # Live tuning through the parameter service: validated on set, swapped between steps.
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    def set_param(name: str, value: float):
        req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        res = harness.call(SetParameters, 'slip_controller/set_parameters', req)
        assert res is not None
        return res.results[0]
    bad = set_param('hold.margin', 50.0)
    assert not bad.successful and 'hold.margin out of range' in bad.reason  # descriptor range
    assert 'Max: 10.0' in bad.reason
    assert set_param('hold.margin', 3.0).successful
    n = len(cmds)
    harness.play(_hold_still(snap, harness.t, 0.1), node)
    assert harness.spin_until(lambda: len(cmds) > n + 5)
    assert cmds[-1].force == pytest.approx(3.0 * 1.0 / 0.45, rel=0.02)
    assert node.controller.params.hold.margin == 3.0


def test_linear_goal_finishes_then_holds(harness, make_props, snap) -> None:
    from action_msgs.msg import GoalStatus
    from slip_msgs.srv import SetSlipMode as M
    node = _controller(harness)
    cmds, states, tracking = _outputs(harness)
    harness.publish_properties(make_props(mu_c=0.45, r=0.006))
    assert harness.spin_until(lambda: states and states[-1].contact_valid)
    feedback: list = []
    _, result = _send_goal(harness, M.Request.LINEAR, feedback, distance=0.02, duration=1.0,
                           direction_y=-1.0)
    harness.play(_slide(snap, harness.t, 1.3, distance=0.02, duration=1.0), node)
    assert harness.spin_until(result.done, 5.0)
    res = result.result()
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    assert res.result.message == 'done'
    assert abs(res.result.final_error) < 0.001
    assert res.result.elapsed == pytest.approx(1.0, abs=0.1)
    assert len(feedback) >= 100 and feedback[-1].feedback.tracking.mode == M.Request.LINEAR
    assert tracking and tracking[-1].done
    assert harness.spin_until(lambda: states[-1].mode == M.Request.HOLD)
    assert not states[-1].goal_active and 'LINEAR ended: done' in states[-1].reason
    n = len(cmds)
    harness.play(_hold_still(snap, harness.t, 0.1), node)       # HOLD keeps commanding
    assert harness.spin_until(lambda: len(cmds) > n + 5)


def test_mode_switch_and_new_goal_preempt_running_goal(harness, make_props,
                                                       snap) -> None:
    from action_msgs.msg import GoalStatus
    from slip_msgs.srv import SetSlipMode as M
    node = _controller(harness)
    _, states, _ = _outputs(harness)
    harness.publish_properties(make_props(mu_c=0.45, r=0.006))
    assert harness.spin_until(lambda: states and states[-1].contact_valid)

    fb1: list = []
    _, result1 = _send_goal(harness, M.Request.LINEAR, fb1, distance=0.02, direction_y=-1.0)
    harness.play(_slide(snap, harness.t, 0.3), node)
    assert fb1 and states[-1].goal_active
    fb2: list = []
    _, result2 = _send_goal(harness, M.Request.ROTATIONAL, fb2, angle=0.3)
    assert harness.spin_until(result1.done, 5.0)
    r1 = result1.result()
    assert r1.status == GoalStatus.STATUS_ABORTED and r1.result.message == 'preempted'
    assert r1.result.final_pos > 0.0

    harness.play(_hold_still(snap, harness.t, 0.1), node)
    assert fb2 and fb2[-1].feedback.tracking.mode == M.Request.ROTATIONAL
    res = _set_mode(harness, M.Request.HOLD)
    assert res.success, res.message
    assert harness.spin_until(result2.done, 5.0)
    r2 = result2.result()
    assert r2.status == GoalStatus.STATUS_ABORTED and r2.result.message == 'preempted'
    assert harness.spin_until(lambda: states[-1].mode == M.Request.HOLD)
    assert not states[-1].goal_active


def test_cancel_and_wrong_goal_mode(harness, make_props, snap) -> None:
    from action_msgs.msg import GoalStatus
    from slip_msgs.srv import SetSlipMode as M
    node = _controller(harness)
    _, states, _ = _outputs(harness)
    harness.publish_properties(make_props(mu_c=0.45, r=0.006))
    assert harness.spin_until(lambda: states and states[-1].contact_valid)
    _, bad = _send_goal(harness, M.Request.HOLD, [])
    assert harness.spin_until(bad.done, 5.0)
    assert bad.result().status == GoalStatus.STATUS_ABORTED
    assert 'use slip_control/set_mode' in bad.result().result.message

    handle, result = _send_goal(harness, M.Request.LINEAR, [], distance=0.02, direction_y=-1.0)
    harness.play(_slide(snap, harness.t, 0.2), node)
    cancel = handle.cancel_goal_async()
    assert harness.spin_until(cancel.done, 5.0) and cancel.result().goals_canceling
    assert harness.spin_until(result.done, 5.0)
    assert result.result().status == GoalStatus.STATUS_CANCELED
    assert result.result().result.message == 'canceled'
    assert harness.spin_until(lambda: states[-1].mode == M.Request.HOLD)


@pytest.mark.parametrize('stream', ['velocity', 'ft'])
def test_stream_stops_mid_slip_safe_hold_within_100ms(harness, make_props, snap,
                                                      stream: str) -> None:
    from action_msgs.msg import GoalStatus
    from slip_msgs.srv import SetSlipMode as M
    node = _controller(harness)
    cmds, states, _ = _outputs(harness)
    harness.publish_properties(make_props(mu_c=0.45, r=0.006))
    assert harness.spin_until(lambda: states and states[-1].contact_valid)
    _, result = _send_goal(harness, M.Request.LINEAR, [], distance=0.02, direction_y=-1.0)
    slide = _slide(snap, harness.t, 1.0)
    harness.play(slide[:60], node)                               # 0.5 s of slip
    assert harness.spin_until(lambda: len(cmds) >= 60)           # one command per step
    last = slide[59]
    t_stop = last.twist_1.stamp if stream == 'velocity' else last.wrench_1.stamp
    force_before = cmds[-1].force
    # The other stream keeps coming (sim time advances in 2 ms steps, F/T at 500 Hz).
    t = harness.t
    for i in range(1, 101):
        t = last.twist_1.stamp + 0.002 * i
        harness.advance(t)
        s = snap(t, f=(0.0, 2.25), v=(0.0, -0.0125), normal=5.0)
        if stream == 'velocity':
            harness.deliver(s, node, twists=False)
        elif i % 4 == 0:
            harness.deliver(s, node, wrenches=False)

    def stamp(m) -> float:
        return stamp_to_seconds(m.header.stamp)
    held = [s for s in states if s.safe_hold]
    assert held, [(stamp(s), s.reason) for s in states]
    assert 0.0 < stamp(held[0]) - t_stop <= 0.1
    assert held[0].mode == M.Request.HOLD and not held[0].goal_active
    assert not (held[0].velocity_fresh if stream == 'velocity' else held[0].ft_fresh)
    after = [c for c in cmds if stamp(c) > last.twist_1.stamp]
    assert after and stamp(after[0]) - t_stop <= 0.1             # safe-hold commands
    assert min(c.force for c in after) >= force_before - 1e-9  # never decreases in safe hold
    assert all(c.timeout == pytest.approx(0.1) for c in after)
    assert harness.spin_until(result.done, 5.0)
    res = result.result()
    assert res.status == GoalStatus.STATUS_ABORTED
    assert res.result.message == ('velocity stale' if stream == 'velocity' else 'F/T stale')


@pytest.mark.parametrize('stale_confirm', [0.5, 0.0])
def test_clock_ahead_of_queued_samples_is_a_backlog_not_a_stopped_stream(
        harness, make_props, snap, stale_confirm: float) -> None:
    """The node's clock jumps 83 ms ahead of the samples queued with it (a busy executor).

    With the stale verdict confirmed (``stale_confirm`` > 0) the queued samples arrive, the
    inputs are fresh again and the slip finishes; acting at once (0) ends it as
    "velocity stale" although no stream stopped.
    """
    from action_msgs.msg import GoalStatus
    from slip_msgs.srv import SetSlipMode as M
    node = _controller(harness, stale_confirm=stale_confirm)
    _, states, _ = _outputs(harness)
    harness.publish_properties(make_props(mu_c=0.45, r=0.006))
    assert harness.spin_until(lambda: states and states[-1].contact_valid)
    _, result = _send_goal(harness, M.Request.LINEAR, [], distance=0.02, duration=1.0,
                           direction_y=-1.0)
    slide = _slide(snap, harness.t, 1.3, distance=0.02, duration=1.0)
    harness.play(slide[:30], node)
    queued = slide[30:40]
    harness.advance(queued[-1].twist_1.stamp)        # the clock first (watchdog steps run)
    for s in queued:                                 # then what was queued with it
        harness.deliver(s, node)
    harness.play(slide[40:], node)
    assert harness.spin_until(result.done, 5.0)
    res = result.result()
    if stale_confirm > 0.0:
        assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
        assert abs(res.result.final_error) < 0.001
        assert not any(s.safe_hold for s in states)
    else:
        assert res.status == GoalStatus.STATUS_ABORTED
        assert res.result.message == 'velocity stale'
