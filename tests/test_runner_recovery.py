# SPDX-License-Identifier: Apache-2.0
"""Issue 16: the experiment runner after a drop, on the real simulated cell.

``sim_gripper`` runs as its own process (installed console script, packages' YAML files, sim
time); the ``experiment_runner`` (arm backend ``sim``) and the ``slip_controller`` run in this
process on one executor with ``use_sim_time``, all through real DDS. The object is pulled out
of the grasp during ``hold_mode``; the runner must stop, say so, refuse what needs the object
with the re-grasp steps (instead of aborting every later goal at once), and get the object back
through ``go_to_object`` (the simulator's scene reset).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

FAST = {'release.wait': 1.0, 'grasp.wait': 0.3, 'step_timeout': 10.0,
        'motion_time.min': 0.2, 'motion_time.gain': 0.05}


def _share(pkg: str, rel: str) -> str:
    from ament_index_python.packages import get_package_share_directory
    return str(Path(get_package_share_directory(pkg)) / rel)


def _start_sim(tmp_path: Path, env: dict[str, str]) -> Any:
    """The installed sim_gripper with the cell and simulator YAML files, on sim time."""
    from ament_index_python.packages import get_package_prefix

    from slip_cell_common.testing import NodeProcess
    exe = Path(get_package_prefix('friction_models')) / 'lib' / 'friction_models' / 'sim_gripper'
    return NodeProcess([str(exe), '--ros-args',
                        '--params-file', _share('slip_gripper_driver', 'config/cell.yaml'),
                        '--params-file', _share('friction_models', 'config/sim_gripper.yaml'),
                        '-p', 'use_sim_time:=true'], tmp_path / 'sim.log', env)


class Cell:
    """The runner and the slip controller on this process's executor, plus a probe."""

    def __init__(self, ctx: Any, tmp_path: Path) -> None:
        from rclpy.action import ActionClient
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.parameter import Parameter

        from slip_cell_common.qos import LATCHED, SENSOR_SUB
        from slip_control.experiment_runner_node import ExperimentRunnerNode
        from slip_control.slip_controller_node import SlipControllerNode
        from slip_msgs.action import RunExperiment
        from slip_msgs.msg import ContactProperties, SimState
        sim_time = Parameter('use_sim_time', value=True)
        values = {**FAST, 'arm.backend': 'sim', 'recording.directory': str(tmp_path / 'bags')}
        self.executor = SingleThreadedExecutor(context=ctx)
        self.runner = ExperimentRunnerNode(context=ctx, parameter_overrides=[
            sim_time, *(Parameter(k, value=v) for k, v in values.items())])
        self.controller = SlipControllerNode(
            context=ctx, parameter_overrides=[sim_time],
            cli_args=['--ros-args',
                      '--params-file', _share('slip_gripper_driver', 'config/cell.yaml'),
                      '--params-file', _share('slip_control', 'config/slip_controller.yaml')])
        self.node = Node('recovery_probe', context=ctx, parameter_overrides=[sim_time])
        for n in (self.runner, self.controller, self.node):
            self.executor.add_node(n)
        self.states: list[Any] = []
        self.node.create_subscription(SimState, 'sim/state', self.states.append, SENSOR_SUB)
        self._props = self.node.create_publisher(ContactProperties, 'contact/properties',
                                                 LATCHED)
        self.client = ActionClient(self.node, RunExperiment, 'experiment/run')

    def spin_until(self, predicate: Any, timeout_s: float) -> bool:
        from slip_cell_common.calls import spin_until
        return spin_until(self.executor, predicate, timeout_s, step_s=0.002)

    def call(self, srv: Any, name: str, req: Any) -> Any:
        from slip_cell_common.calls import call_service
        client = self.node.create_client(srv, name)
        try:
            return call_service(self.executor, client, req, 20.0)
        finally:
            self.node.destroy_client(client)

    def publish_properties(self) -> None:
        from slip_cell_common.time_conv import seconds_to_stamp
        from slip_control.core.contact import ContactProperties, ContactSource, FingerContact
        from slip_control.slip_msgs_conv import properties_to_msg
        f = FingerContact(mu_c=0.5, mu_s=0.5, mu_v=0.0, r=0.005, u=2.5e-5, mu_c_std=0.005,
                          r_std=0.0002, n_linear=50, n_static=5, n_rotational=50,
                          linear_valid=True, viscous_valid=False, static_valid=True,
                          rotational_valid=True)
        self._props.publish(properties_to_msg(
            ContactProperties(f, f, ContactSource.ESTIMATED), seconds_to_stamp(0.0)))

    def send(self, mode: str, phases: list[str] | None = None, **goal: Any) -> Any:
        """Send a goal (feedback phases appended to ``phases``); returns the goal handle, or
        None when it was rejected."""
        from slip_msgs.action import RunExperiment
        assert self.spin_until(self.client.server_is_ready, 15.0)
        send = self.client.send_goal_async(
            RunExperiment.Goal(mode=mode, **goal),
            feedback_callback=None if phases is None else
            (lambda m: phases.append(m.feedback.phase)))
        assert self.spin_until(send.done, 15.0)
        return send.result() if send.result().accepted else None

    def run(self, mode: str, timeout_s: float = 60.0, **goal: Any) -> Any:
        handle = self.send(mode, **goal)
        assert handle is not None, f'{mode} rejected: {self.runner.last_rejection}'
        result = handle.get_result_async()
        assert self.spin_until(result.done, timeout_s), f'{mode} did not finish'
        return result.result()

    def close(self) -> None:
        self.client.destroy()
        for n in (self.runner, self.controller, self.node):
            self.executor.remove_node(n)
            n.destroy_node()
        self.executor.shutdown()


def test_runner_recovers_after_a_drop(ros_context, ros_env, tmp_path: Path) -> None:
    from action_msgs.msg import GoalStatus

    from slip_msgs.srv import ApplyDisturbance, ResetScene
    sim = _start_sim(tmp_path, ros_env)
    cell = Cell(ros_context, tmp_path)
    ok = GoalStatus.STATUS_SUCCEEDED
    try:
        assert cell.spin_until(lambda: len(cell.states) > 10, 30.0), sim.output()
        cell.publish_properties()
        for mode in ('release', 'reset_joints', 'go_to_object'):
            res = cell.run(mode)
            assert res.status == ok, (mode, res.result.message)
        # The object held in the air (as after pick_up_object), then grasped by the runner.
        res = cell.call(ResetScene, 'sim/reset_scene', ResetScene.Request(object_on_table=False))
        assert res.success, res.message
        res = cell.run('grasp')
        assert res.status == ok, res.result.message
        assert cell.runner.flags.holding

        # Pulled out of the grasp during hold_mode: the runner stops and says why.
        phases: list[str] = []
        handle = cell.send('hold_mode', phases, duration=30.0)
        assert handle is not None, cell.runner.last_rejection
        result = handle.get_result_async()
        assert cell.spin_until(lambda: 'hold' in phases, 20.0), phases
        pull = ApplyDisturbance.Request(duration=0.5)
        pull.force.y = -200.0
        assert cell.call(ApplyDisturbance, 'sim/apply_disturbance', pull).success
        assert cell.spin_until(result.done, 30.0), 'hold_mode did not stop after the drop'
        res = result.result()
        assert res.status == GoalStatus.STATUS_ABORTED
        assert "aborted during 'hold': the object was dropped (sim/state.object_dropped)" \
            in res.result.message
        assert cell.states[-1].object_dropped
        flags = cell.runner.flags
        assert flags.object_dropped and not flags.holding

        # Later goals are not aborted at once: refused, naming the re-grasp steps.
        assert cell.send('hold_mode', duration=1.0) is None
        assert "re-grasp it with 'release', then 'go_to_object', then 'grasp'" \
            in cell.runner.last_rejection
        assert "object lost during 'hold'" in cell.runner.last_rejection
        assert cell.send('grasp') is None
        assert "object_dropped (is True); run 'go_to_object' first" in \
            cell.runner.last_rejection

        # Re-grasp: release, go to the object (the simulator resets its scene), grasp.
        for mode in ('release', 'go_to_object', 'grasp'):
            res = cell.run(mode)
            assert res.status == ok, (mode, res.result.message)
        assert cell.spin_until(lambda: cell.states[-1].object_in_grasp, 5.0)
        assert not cell.states[-1].object_dropped
        assert cell.runner.flags.holding and not cell.runner.flags.object_dropped

        # Letting go in the air (a second demo starts this way) is no fault: release succeeds.
        res = cell.call(ResetScene, 'sim/reset_scene', ResetScene.Request(object_on_table=False))
        assert res.success, res.message
        res = cell.run('release')
        assert res.status == ok, res.result.message
        assert cell.spin_until(lambda: cell.states[-1].object_dropped, 5.0)
        for mode in ('go_to_object', 'grasp'):
            res = cell.run(mode)
            assert res.status == ok, (mode, res.result.message)
        assert cell.spin_until(lambda: cell.states[-1].object_in_grasp, 5.0)
    finally:
        cell.close()
        code = sim.stop()
    assert code == 0, sim.output()
