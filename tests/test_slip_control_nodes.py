# SPDX-License-Identifier: Apache-2.0
"""The three slip_control nodes as installed: console scripts with their YAML files, as
separate processes talking through real DDS (the YAML ↔ dataclass check is
tests/test_config_yaml.py)."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
CELL = ROOT / 'src' / 'slip_gripper_driver' / 'config' / 'cell.yaml'


@pytest.mark.ros
@pytest.mark.slow
def test_three_nodes_as_processes(ros_context, ros_env, tmp_path: Path) -> None:
    from action_msgs.msg import GoalStatus
    from rclpy.action import ActionClient
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from slip_cell_common.qos import LATCHED, SENSOR_SUB
    from slip_cell_common.testing import NodeProcess, call_service, spin_until
    from slip_msgs.action import RunExperiment
    from slip_msgs.msg import ContactProperties, GraspForceCommand, SlipControllerState
    from slip_msgs.srv import SetSlipMode, StartEstimation
    from std_srvs.srv import Trigger

    bin_dir = ROOT / 'install' / 'slip_control' / 'lib' / 'slip_control'
    share = ROOT / 'install' / 'slip_control' / 'share' / 'slip_control' / 'config'
    procs = {}
    for name in ('contact_estimator', 'slip_controller', 'experiment_runner'):
        argv = [str(bin_dir / name), '--ros-args', '-r', f'__node:={name}']
        if name == 'slip_controller':
            argv += ['--params-file', str(CELL)]
        argv += ['--params-file', str(share / f'{name}.yaml')]
        if name == 'experiment_runner':
            # Node-keyed file passed last (a -p value is a /** wildcard, which the
            # node-specific keys of the package YAML would beat).
            overrides = tmp_path / 'runner.overrides.yaml'
            overrides.write_text(yaml.safe_dump({name: {'ros__parameters': {
                'arm.backend': 'mock', 'release.wait': 0.2,
                'recording.directory': str(tmp_path / 'bags')}}}))
            argv += ['--params-file', str(overrides)]
        procs[name] = NodeProcess(argv, tmp_path / f'{name}.log', ros_env)
    node = Node('nodes_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    props: list = []
    states: list = []
    cmds: list = []
    node.create_subscription(ContactProperties, 'contact/properties', props.append, LATCHED)
    node.create_subscription(SlipControllerState, 'slip_control/state', states.append, LATCHED)
    node.create_subscription(GraspForceCommand, 'gripper/grasp_force_cmd', cmds.append,
                             SENSOR_SUB)
    node.create_service(Trigger, 'gripper/bias_ft',
                        lambda req, res: Trigger.Response(success=True, message='biased'))
    # Created first so discovery of its five endpoints runs while the services are called
    # (on a loaded machine Fast DDS discovery of a late joiner can take several seconds).
    client = ActionClient(node, RunExperiment, 'experiment/run')
    logs = lambda: '\n'.join(f'--- {n}\n{p.output()}' for n, p in procs.items())
    try:
        assert spin_until(executor, lambda: bool(props), 15.0), logs()
        assert props[-1].source == ContactProperties.SOURCE_DEFAULT and not props[-1].valid
        # The controller got the estimator's latched DEFAULT set (it says so in its state).
        assert spin_until(executor, lambda: bool(states) and 'contact properties: DEFAULT'
                          in states[-1].reason, 15.0), logs()
        assert states[-1].mode == SetSlipMode.Request.OFF and not states[-1].contact_valid

        res = call_service(executor, node.create_client(SetSlipMode, 'slip_control/set_mode'),
                           SetSlipMode.Request(mode=SetSlipMode.Request.HOLD), 15.0)
        assert res is not None and not res.success, logs()
        assert 'DEFAULT (placeholder)' in res.message
        res = call_service(executor, node.create_client(StartEstimation, 'contact/start'),
                           StartEstimation.Request(phase=1, duration=1.0), 15.0)
        assert res is not None and not res.accepted and 'no samples received' in res.message

        ready = spin_until(executor, client.server_is_ready, 30.0)
        seen = sorted(n for n, _ in node.get_service_names_and_types() if 'experiment' in n)
        assert ready, f'{seen}\n{node.get_node_names()}\n{logs()}'
        phases: list = []
        send = client.send_goal_async(RunExperiment.Goal(mode='release'),
                                      feedback_callback=lambda m: phases.append(m.feedback))
        assert spin_until(executor, send.done, 15.0) and send.result().accepted
        result = send.result().get_result_async()
        assert spin_until(executor, result.done, 30.0), logs()
        assert result.result().status == GoalStatus.STATUS_SUCCEEDED, logs()
        assert phases and phases[-1].phase == 'done'
        assert 0.2 <= phases[-1].elapsed < 1.0               # the override took effect
        assert spin_until(executor, lambda: any(
            c.force == -8.0 and c.source == GraspForceCommand.SOURCE_EXPERIMENT_RUNNER
            for c in cmds), 5.0)
    finally:
        client.destroy()
        executor.shutdown()
        node.destroy_node()
        codes = {n: p.stop() for n, p in procs.items()}
    assert codes == dict.fromkeys(procs, 0), logs()
