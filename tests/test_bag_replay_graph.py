"""Graph path: a recorded exploration replayed with /clock into the contact_estimator node.

The estimator runs as its own process with ``use_sim_time``; ``bag_replay`` publishes the
bag's sensor topics and ``/clock`` at a quarter of real time; this test starts the linear and
rotational phases at the simulated times the runner started them during the recording (taken
from the recorded arm motion) and compares the estimate the node publishes with the one the
node published during the recording, and with the simulator's truth.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from slip_cell_common.bag_io import read_messages, stamp_s
from slip_cell_common.time_conv import stamp_to_seconds

pytestmark = [pytest.mark.ros, pytest.mark.slow]

BAG = Path(__file__).resolve().parents[1] / 'bags' / 'est_contact_cardboard'
TOPICS = ['/finger_1/ft/wrench', '/finger_2/ft/wrench', '/finger_1/slip/twist',
          '/finger_2/slip/twist']


def _phase_starts(msgs: dict[str, Any]) -> list[float]:
    sim = [(stamp_s(m), m) for _, m in msgs['/sim/state']]
    return [ta for (ta, a), (_, b) in zip(sim, sim[1:]) if b.arm_moving and not a.arm_moving]


def test_estimator_node_reproduces_the_recorded_estimate_from_the_bag(
        ros_context, ros_env, tmp_path: Path) -> None:
    from ament_index_python.packages import get_package_prefix, get_package_share_directory
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock
    from slip_cell_common.qos import LATCHED
    from slip_cell_common.testing import NodeProcess, call_service, spin_until
    from slip_msgs.msg import ContactProperties
    from slip_msgs.srv import GetContactProperties, StartEstimation

    if not BAG.is_dir():
        pytest.fail('bags/est_contact_cardboard is missing: run `make bags`')
    recorded = read_messages(BAG, ['/contact/properties', '/sim/true_contact', '/sim/state'])
    starts = _phase_starts(recorded)
    assert len(starts) >= 2
    expected = [m for _, m in recorded['/contact/properties'] if m.source == 1 and m.valid][-1]

    prefix = Path(get_package_prefix('slip_control')) / 'lib' / 'slip_control'
    share = Path(get_package_share_directory('slip_control')) / 'config'
    estimator = NodeProcess([str(prefix / 'contact_estimator'), '--ros-args', '--params-file',
                             str(share / 'contact_estimator.yaml'), '-p', 'use_sim_time:=true'],
                            tmp_path / 'estimator.log', ros_env)
    node = Node('graph_replay_probe', context=ros_context,
                parameter_overrides=[Parameter('use_sim_time', value=True)])
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    clock: list[float] = []
    node.create_subscription(Clock, '/clock',
                             lambda m: clock.append(stamp_to_seconds(m.clock)), 10)
    props: list[ContactProperties] = []
    node.create_subscription(ContactProperties, 'contact/properties', props.append, LATCHED)
    start_client = node.create_client(StartEstimation, 'contact/start')
    replay = None
    try:
        # Warm the service path before the replay (a new client's first call takes ~2 s).
        warm = call_service(executor, node.create_client(
            GetContactProperties, 'contact/get_properties'), GetContactProperties.Request(), 30.0)
        assert warm is not None, estimator.output()
        assert spin_until(executor, start_client.service_is_ready, 30.0)
        replay = NodeProcess.python_module('slip_bringup.bag_cli', [
            'replay', str(BAG), '--rate', '0.25', '--start-delay', '20',
            *sum((['--topic', t] for t in TOPICS), [])], tmp_path / 'replay.log', ros_env)
        phases = [(StartEstimation.Request.LINEAR, starts[0]),
                  (StartEstimation.Request.ROTATIONAL, starts[1])]
        for phase, t_start in phases:
            assert spin_until(executor, lambda t=t_start: bool(clock) and clock[-1] >= t, 60.0), \
                replay.output()
            reply = call_service(executor, start_client,
                                 StartEstimation.Request(phase=phase, duration=1.0), 10.0)
            assert reply is not None and reply.accepted, (reply, estimator.output())
        assert spin_until(executor, lambda: any(p.valid and p.source == 1 for p in props), 60.0), \
            estimator.output()
    finally:
        executor.shutdown()
        node.destroy_node()
        if replay is not None:
            replay.stop()
        estimator.stop()
    got = [p for p in props if p.valid and p.source == 1][-1]
    truth = recorded['/sim/true_contact'][-1][1]
    for mine, theirs, true in ((got.finger_1, expected.finger_1, truth.finger_1),
                               (got.finger_2, expected.finger_2, truth.finger_2)):
        assert mine.mu_c == pytest.approx(theirs.mu_c, abs=0.02)
        assert mine.r == pytest.approx(theirs.r, abs=0.7e-3)
        assert mine.mu_c == pytest.approx(true.mu_c, abs=0.06)
