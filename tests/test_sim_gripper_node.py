"""sim_gripper as a process: the drivers' interface at the real rates, bias, force loop, sim time.

The node under test is the installed console script, started in its own process with the
packages' YAML files; the test node runs with ``use_sim_time`` and measures rates on the
simulated clock (header stamps), so the result does not depend on the machine's load.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from slip_cell_common.time_conv import clock_seconds, stamp_to_seconds

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _share(pkg: str, rel: str) -> str:
    from ament_index_python.packages import get_package_share_directory
    return str(Path(get_package_share_directory(pkg)) / rel)


def start_sim(tmp_path: Path, env: dict[str, str], *extra: str, name: str = 'sim',
              overrides: dict[str, Any] | None = None):
    """Start the installed sim_gripper with the cell and simulator YAML files (+ overrides)."""
    import yaml
    if overrides:
        path = tmp_path / f'{name}.overrides.yaml'
        path.write_text(yaml.safe_dump({'sim_gripper': {'ros__parameters': overrides}}))
        extra = ('--params-file', str(path), *extra)
    from ament_index_python.packages import get_package_prefix
    from slip_cell_common.testing import NodeProcess
    exe = Path(get_package_prefix('friction_models')) / 'lib' / 'friction_models' / 'sim_gripper'
    return NodeProcess([str(exe), '--ros-args',
                        '--params-file', _share('slip_gripper_driver', 'config/cell.yaml'),
                        '--params-file', _share('friction_models', 'config/sim_gripper.yaml'),
                        *extra], tmp_path / f'{name}.log', env)


class Probe:
    """Subscribes to every topic of the simulated cell and keeps what arrives."""

    def __init__(self, ctx: Any) -> None:
        from geometry_msgs.msg import TwistStamped, WrenchStamped
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.parameter import Parameter
        from sensor_msgs.msg import JointState
        from slip_cell_common.qos import LATCHED, SENSOR_PUB
        from slip_msgs.msg import (ContactProperties, GripperStatus, MotorCommand, PlanarSlip,
                                   SimState, TransformArray)
        self.node = Node('sim_probe', context=ctx, parameter_overrides=[
            Parameter('use_sim_time', value=True)])
        self.executor = SingleThreadedExecutor(context=ctx)
        self.executor.add_node(self.node)
        self.msgs: dict[str, list[Any]] = {}
        topics = {
            'gripper/status': (GripperStatus, SENSOR_PUB),
            'gripper/motor_command': (MotorCommand, SENSOR_PUB),
            'gripper/joint_states': (JointState, SENSOR_PUB),
            'finger_1/ft/wrench': (WrenchStamped, SENSOR_PUB),
            'finger_2/ft/wrench': (WrenchStamped, SENSOR_PUB),
            'finger_1/slip/twist': (TwistStamped, SENSOR_PUB),
            'finger_2/slip/twist': (TwistStamped, SENSOR_PUB),
            'finger_1/slip/state': (PlanarSlip, SENSOR_PUB),
            'sim/state': (SimState, SENSOR_PUB),
            'gripper/static_frames': (TransformArray, LATCHED),
            'sim/true_contact': (ContactProperties, LATCHED),
        }
        for topic, (kind, qos) in topics.items():
            self.msgs[topic] = []  # reliable, depth 100 (SENSOR_PUB): the probe must not drop
            self.node.create_subscription(kind, topic, self.msgs[topic].append, qos)

    def spin_until(self, predicate: Any, timeout_s: float) -> bool:
        from slip_cell_common.testing import spin_until
        return spin_until(self.executor, predicate, timeout_s)

    def call(self, srv: Any, name: str, req: Any, timeout_s: float = 15.0) -> Any:
        from slip_cell_common.testing import call_service
        return call_service(self.executor, self.node.create_client(srv, name), req, timeout_s)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


def _stamp(msg: Any) -> float:
    return stamp_to_seconds(msg.header.stamp)


def _rate(msgs: list[Any], t0: float, t1: float) -> float:
    """Publication rate [Hz] within ``[t0, t1)`` of stamp time, from the median spacing of
    the stamps: a best-effort probe on a loaded host misses some samples, which says nothing
    of the publisher (at least half of the window's samples must have arrived)."""
    stamps = sorted(_stamp(m) for m in msgs if t0 <= _stamp(m) < t1)
    if len(stamps) < 3:
        return 0.0
    spacing = float(np.median(np.diff(stamps)))
    if spacing <= 0.0 or len(stamps) < 0.5 * (t1 - t0) / spacing:
        return 0.0
    return 1.0 / spacing


def test_sim_speaks_the_driver_interface_at_real_rates(ros_context, ros_env,
                                                       tmp_path: Path) -> None:
    from slip_cell_common.qos import COMMAND
    from slip_msgs.msg import GraspForceCommand
    from std_srvs.srv import Trigger
    sim = start_sim(tmp_path, ros_env)
    probe = Probe(ros_context)
    status = probe.msgs['gripper/status']
    try:
        assert probe.spin_until(lambda: len(status) > 50, 30.0), sim.output()
        biased = probe.call(Trigger, 'gripper/bias_ft', Trigger.Request())
        assert biased is not None and biased.success, (biased, sim.output())

        # Rates on the simulated clock, over 2 s of sim time after the bias.
        t_start = _stamp(status[-1])
        assert probe.spin_until(lambda: _stamp(status[-1]) > t_start + 2.5, 30.0)
        window = (t_start + 0.25, t_start + 2.25)
        expected = {'gripper/status': 500.0, 'gripper/motor_command': 500.0,
                    'finger_1/ft/wrench': 500.0, 'finger_2/ft/wrench': 500.0,
                    'finger_1/slip/twist': 120.0, 'finger_2/slip/twist': 120.0,
                    'finger_1/slip/state': 120.0, 'gripper/joint_states': 100.0,
                    'sim/state': 100.0}
        rates = {t: _rate(probe.msgs[t], *window) for t in expected}
        for topic, hz in expected.items():
            assert rates[topic] == pytest.approx(hz, rel=0.10), (topic, rates)

        # Frames, signs and the probe's clock following /clock.
        wrench = probe.msgs['finger_1/ft/wrench'][-1]
        assert wrench.header.frame_id == 'ft_sensor_1'
        assert probe.msgs['finger_2/slip/twist'][-1].header.frame_id == 'vel_sensor_2'
        now = clock_seconds(probe.node.get_clock())
        assert abs(now - _stamp(status[-1])) < 0.5, 'probe clock must follow /clock'
        frames = probe.msgs['gripper/static_frames']
        assert frames and len(frames[-1].transforms) == 4
        truth = probe.msgs['sim/true_contact']
        assert truth and truth[-1].preset_name == 'cardboard'
        assert truth[-1].finger_1.mu_c == pytest.approx(0.5136, abs=1e-3)

        # Command 10 N (stamped on the simulated clock): the inner loop converges.
        pub = probe.node.create_publisher(GraspForceCommand, 'gripper/grasp_force_cmd', COMMAND)
        assert probe.spin_until(lambda: pub.get_subscription_count() > 0, 10.0)
        cmd = GraspForceCommand(force=10.0, source=GraspForceCommand.SOURCE_TEST)
        cmd.header.stamp = probe.node.get_clock().now().to_msg()
        pub.publish(cmd)
        t_cmd = _stamp(status[-1])
        assert probe.spin_until(lambda: _stamp(status[-1]) > t_cmd + 2.0, 30.0)
        late = [m for m in status if _stamp(m) > t_cmd + 1.5]
        assert all(m.in_contact and m.ft_biased for m in late)
        assert all(abs(m.measured_grasp_force - 10.0) < 0.5 for m in late), \
            [round(m.measured_grasp_force, 2) for m in late[:20]]
        w1, w2 = probe.msgs['finger_1/ft/wrench'][-1], probe.msgs['finger_2/ft/wrench'][-1]
        assert w1.wrench.force.z < -9.0 and w2.wrench.force.z < -9.0, 'squeezing: Fz < 0'
        state = probe.msgs['sim/state'][-1]
        assert state.object_in_grasp and state.normal_force_1 == pytest.approx(10.0, abs=0.6)
    finally:
        probe.close()
        code = sim.stop()
    assert code == 0, sim.output()
    assert 'Traceback' not in sim.output()


def test_bad_input_is_refused_with_clear_messages(ros_context, ros_env, tmp_path: Path) -> None:
    from lifecycle_msgs.srv import GetState
    from slip_cell_common.qos import COMMAND
    from slip_msgs.msg import GraspForceCommand
    from slip_msgs.srv import MoveGripper, ResetScene

    bad = start_sim(tmp_path, ros_env, name='bad', overrides={'preset': 'no_such_object'})
    good = start_sim(tmp_path, ros_env, '-r', '__node:=sim_b', '-r', '__ns:=/b', name='good')
    probe = Probe(ros_context)
    try:
        state = probe.call(GetState, 'sim_gripper/get_state', GetState.Request(), 30.0)
        assert state is not None and state.current_state.label == 'unconfigured', bad.output()
        assert "unknown preset 'no_such_object'" in bad.output()
        assert 'cardboard' in bad.output(), 'the error lists the known presets'

        scene = probe.call(ResetScene, '/b/sim/reset_scene', ResetScene.Request(
            preset='nope', object_on_table=True), 30.0)
        assert scene is not None and not scene.success and 'known presets' in scene.message
        move = probe.call(MoveGripper, '/b/sim/move_gripper', MoveGripper.Request(
            lift=math.nan, duration=1.0))
        assert move is not None and not move.success and 'finite' in move.message
        pub = probe.node.create_publisher(GraspForceCommand, '/b/gripper/grasp_force_cmd',
                                          COMMAND)
        assert probe.spin_until(lambda: pub.get_subscription_count() > 0, 10.0)
        pub.publish(GraspForceCommand(force=math.nan))
        assert probe.spin_until(lambda: 'rejected' in good.output(), 10.0), good.output()
        assert good.running(), 'the simulation keeps running after bad input'
    finally:
        probe.close()
        bad_code, good_code = bad.stop(), good.stop()
    assert 'Traceback' not in bad.output() + good.output()
    assert good_code == 0
    assert bad_code == 1, 'autostart failure is reported in the exit code'


def test_sim_on_sim_time_sets_its_own_clock_without_subscribing_to_it(
        ros_context, ros_env, tmp_path: Path) -> None:
    """``use_sim_time`` on the /clock source: no /clock subscription, node clock = sim time."""
    from diagnostic_msgs.msg import DiagnosticArray
    sim = start_sim(tmp_path, ros_env, '-p', 'use_sim_time:=true')
    probe = Probe(ros_context)
    diags: list[Any] = []
    probe.node.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 10)
    status = probe.msgs['gripper/status']
    try:
        assert probe.spin_until(lambda: len(status) > 50 and len(diags) > 1, 30.0), sim.output()
        readers = probe.node.get_subscriptions_info_by_topic('/clock')
        assert [r.node_name for r in readers if r.node_name == 'sim_gripper'] == [], readers
        assert any(r.node_name == 'sim_probe' for r in readers)  # the query itself works
        # Its diagnostics timer and stamps run on the simulated clock (not the system clock).
        assert abs(_stamp(diags[-1]) - _stamp(status[-1])) < 2.0, \
            (_stamp(diags[-1]), _stamp(status[-1]))
        assert 'sets its own clock from the simulation' in sim.output()
        # The node says which simulation core runs (compiled in the built workspace).
        cores = {kv.value for d in diags for st in d.status for kv in st.values
                 if kv.key == 'simulation_core'}
        from friction_models.core import NATIVE_STATUS
        assert cores == {str(NATIVE_STATUS)}, cores
        assert f'simulation core {NATIVE_STATUS}' in sim.output()
    finally:
        probe.close()
        code = sim.stop()
    assert code == 0, sim.output()
    assert 'Traceback' not in sim.output()


def test_sim_waits_for_a_starved_streaming_controller(ros_context, ros_env,
                                                      tmp_path: Path) -> None:
    """A commander that streams grasp-force commands (timeout > 0) and then stalls: simulated
    time stops at most ``max_input_lag`` past its newest command, resumes with the next one,
    and runs on without it after ``max_input_wait`` of wall time."""
    import time

    import yaml
    from slip_cell_common.qos import COMMAND
    from slip_msgs.msg import GraspForceCommand
    config = yaml.safe_load(Path(_share('friction_models', 'config/sim_gripper.yaml')).read_text())
    params = config['sim_gripper']['ros__parameters']
    lag, wait = params['max_input_lag'], params['max_input_wait']
    assert 0.0 < lag <= 0.05, 'the lead is a few control steps, not the command expiry'
    sim = start_sim(tmp_path, ros_env)
    probe = Probe(ros_context)
    clock = probe.node.get_clock()
    try:
        assert probe.spin_until(lambda: len(probe.msgs['sim/state']) > 20, 30.0), sim.output()
        pub = probe.node.create_publisher(GraspForceCommand, 'gripper/grasp_force_cmd', COMMAND)
        assert probe.spin_until(lambda: pub.get_subscription_count() > 0, 10.0)

        def command() -> float:
            stamp = clock.now()
            cmd = GraspForceCommand(force=2.0, timeout=0.1,
                                    source=GraspForceCommand.SOURCE_TEST)
            cmd.header.stamp = stamp.to_msg()
            pub.publish(cmd)
            return stamp.nanoseconds * 1e-9

        def spin_for(wall_s: float) -> float:
            """Spin ``wall_s`` of wall time; the probe's clock (the simulation's /clock)."""
            end = time.monotonic() + wall_s
            while time.monotonic() < end:
                probe.executor.spin_once(timeout_sec=0.005)
            return clock_seconds(clock)

        last = 0.0
        end = time.monotonic() + 1.0
        while time.monotonic() < end:  # a controller streaming at ~100 Hz of simulated time
            probe.executor.spin_once(timeout_sec=0.002)
            if clock_seconds(clock) - last >= 0.01:
                last = command()
        # The commander stalls (shorter than max_input_wait): the simulation waits for it.
        early = spin_for(0.1)
        stalled = spin_for(0.2)
        assert stalled - last <= lag + 0.01, (last, early, stalled, lag)
        assert stalled - early < 0.005, 'simulated time stood still while the commander stalled'
        resumed_from = command()
        assert spin_for(0.1) > resumed_from, 'a new command lets the simulation go on'
        # A commander silent beyond max_input_wait is given up on: the simulation runs on.
        before = clock_seconds(clock)
        assert spin_for(wait + 0.5) - before > 0.3
        assert 'runs on without waiting' in sim.output()
    finally:
        probe.close()
        code = sim.stop()
    assert code == 0, sim.output()
    assert 'Traceback' not in sim.output()
