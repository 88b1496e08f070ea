# SPDX-License-Identifier: Apache-2.0
"""The cell as the standard tools see it (issue 18): ``/tf_static``, ``/tf``,
``robot_description``, ``joint_states`` and the gripper actions, from the installed simulator
and the installed gripper driver (against the pty firmware emulator), read by a real subscriber
in this process.

Checked: frame names and parents; the finger separation in ``/tf`` equals the opening measured
on the same telemetry line (and, in simulation, the true opening); the scene frames
(``world → tool0``, ``world → sim_object``) agree with the simulator's own object pose; the
URDF parses with the documented joints; the driver publishes no finger frames until homed and
rejects a gripper goal then; a GripperCommand goal moves the real fingers.
"""
from __future__ import annotations

import math
import time
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from slip_cell_common.time_conv import stamp_to_seconds

pytestmark = [pytest.mark.ros, pytest.mark.slow]

PAD_OFFSET = 0.0078  # frames.pad_offset of config/cell.yaml [m]
STATIC_EDGES = {('tool0', 'gripper_base_link'), ('gripper_base_link', 'gripper_middle'),
                ('ft_sensor_1', 'vel_sensor_1'), ('ft_sensor_2', 'vel_sensor_2')}


def _share(pkg: str, rel: str) -> str:
    from ament_index_python.packages import get_package_share_directory
    return str(Path(get_package_share_directory(pkg)) / rel)


def _exe(pkg: str, name: str) -> str:
    from ament_index_python.packages import get_package_prefix
    return str(Path(get_package_prefix(pkg)) / 'lib' / pkg / name)


class TfProbe:
    """A subscriber to the TF topics, the model, joint states, status and markers."""

    def __init__(self, ctx: Any) -> None:
        from geometry_msgs.msg import PoseStamped
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from sensor_msgs.msg import JointState
        from std_msgs.msg import String
        from tf2_msgs.msg import TFMessage
        from visualization_msgs.msg import MarkerArray

        from slip_cell_common.qos import LATCHED, SENSOR_PUB
        from slip_cell_common.tf_publishing import ROBOT_DESCRIPTION_QOS, TF_QOS, TF_STATIC_QOS
        from slip_msgs.msg import GripperStatus, SimState
        self.node = Node('tf_probe', context=ctx)
        self.executor = SingleThreadedExecutor(context=ctx)
        self.executor.add_node(self.node)
        self.msgs: dict[str, list[Any]] = {}
        for topic, kind, qos in (('/tf', TFMessage, TF_QOS), ('/tf_static', TFMessage,
                                                               TF_STATIC_QOS),
                                 ('robot_description', String, ROBOT_DESCRIPTION_QOS),
                                 ('gripper/status', GripperStatus, SENSOR_PUB),
                                 ('gripper/joint_states', JointState, SENSOR_PUB),
                                 ('sim/state', SimState, SENSOR_PUB),
                                 ('sim/object_pose', PoseStamped, SENSOR_PUB),
                                 ('sim/markers', MarkerArray, LATCHED)):
            self.msgs[topic] = []
            self.node.create_subscription(kind, topic, self.msgs[topic].append, qos)

    def spin_until(self, predicate: Any, timeout_s: float) -> bool:
        from slip_cell_common.testing import spin_until
        return spin_until(self.executor, predicate, timeout_s)

    def call(self, srv: Any, name: str, req: Any, timeout_s: float = 15.0) -> Any:
        from slip_cell_common.testing import call_service
        return call_service(self.executor, self.node.create_client(srv, name), req, timeout_s)

    def gripper_goal(self, position: float, max_effort: float,
                     timeout_s: float = 30.0) -> tuple[bool, Any]:
        """Send a GripperCommand goal: ``(accepted, result response or None)``."""
        from control_msgs.action import GripperCommand
        from rclpy.action import ActionClient
        client = ActionClient(self.node, GripperCommand, 'gripper/gripper_cmd')
        try:
            assert self.spin_until(client.server_is_ready, 15.0)
            goal = GripperCommand.Goal()
            goal.command.position, goal.command.max_effort = position, max_effort
            send = client.send_goal_async(goal)
            assert self.spin_until(send.done, 10.0)
            if not send.result().accepted:
                return False, None
            result = send.result().get_result_async()
            assert self.spin_until(result.done, timeout_s)
            return True, result.result()
        finally:
            client.destroy()

    def transforms(self, topic: str) -> list[Any]:
        return [t for m in self.msgs[topic] for t in m.transforms]

    def latest(self, child: str) -> Any:
        return next(t for t in reversed(self.transforms('/tf')) if t.child_frame_id == child)

    def finger_pairs(self) -> dict[float, float]:
        """``{stamp: finger separation [m]}`` from every /tf message with both fingers."""
        out = {}
        for m in self.msgs['/tf']:
            z = {t.child_frame_id: t.transform.translation.z for t in m.transforms
                 if t.header.frame_id == 'gripper_middle'}
            if {'ft_sensor_1', 'ft_sensor_2'} <= set(z):
                out[stamp_to_seconds(m.transforms[0].header.stamp)] = \
                    z['ft_sensor_2'] - z['ft_sensor_1'] - 2.0 * PAD_OFFSET
        return out

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


def _pose(t: Any) -> tuple[np.ndarray, Rotation]:
    tr, q = t.transform.translation, t.transform.rotation
    return np.array([tr.x, tr.y, tr.z]), Rotation.from_quat([q.x, q.y, q.z, q.w])


def _compose(a: tuple[np.ndarray, Rotation], b: tuple[np.ndarray, Rotation]
             ) -> tuple[np.ndarray, Rotation]:
    return a[0] + a[1].apply(b[0]), a[1] * b[1]


def _check_urdf(text: str, stroke: float) -> None:
    robot = ET.fromstring(text)
    joints = {j.get('name'): j for j in robot.iter('joint')}
    links = {link.get('name') for link in robot.iter('link')}
    assert {'tool0', 'gripper_base_link', 'gripper_middle', 'ft_sensor_1', 'ft_sensor_2',
            'vel_sensor_1', 'vel_sensor_2'} <= links
    for k in (1, 2):
        joint = joints[f'finger_{k}_joint']
        assert joint.get('type') == 'prismatic'
        assert joint.find('parent').get('link') == 'gripper_middle'
        assert joint.find('child').get('link') == f'ft_sensor_{k}'
        assert float(joint.find('limit').get('upper')) == pytest.approx(stroke / 2.0)
    assert joints['finger_2_joint'].find('mimic').get('joint') == 'finger_1_joint'
    fixed = {(j.find('parent').get('link'), j.find('child').get('link'))
             for j in joints.values() if j.get('type') == 'fixed'}
    assert STATIC_EDGES <= fixed


def test_simulator_tf_tree_model_and_true_opening(ros_context: Any, ros_env: dict[str, str],
                                                  tmp_path: Path) -> None:
    from slip_cell_common.qos import COMMAND
    from slip_cell_common.testing import NodeProcess
    from slip_msgs.msg import GraspForceCommand
    sim = NodeProcess([_exe('friction_models', 'sim_gripper'), '--ros-args',
                       '--params-file', _share('slip_gripper_driver', 'config/cell.yaml'),
                       '--params-file', _share('friction_models', 'config/sim_gripper.yaml')],
                      tmp_path / 'sim.log', ros_env)
    probe = TfProbe(ros_context)
    m = probe.msgs
    try:
        assert probe.spin_until(lambda: len(probe.finger_pairs()) > 5 and m['/tf_static']
                                and m['robot_description'] and m['sim/markers']
                                and len(m['sim/state']) > 5, 30.0), sim.output()
        # Static frames: one latched message with the whole set.
        static = {(t.header.frame_id, t.child_frame_id) for t in m['/tf_static'][-1].transforms}
        assert static == STATIC_EDGES
        moving = {(t.header.frame_id, t.child_frame_id) for t in probe.transforms('/tf')}
        assert moving == {('gripper_middle', 'ft_sensor_1'), ('gripper_middle', 'ft_sensor_2'),
                          ('world', 'tool0'), ('world', 'sim_object')}
        # Known opening from the start (homed with the simulated limits): status, joints, TF.
        first = m['gripper/status'][0]
        assert first.homed and math.isfinite(first.opening)
        assert all(math.isfinite(p) for j in m['gripper/joint_states'] for p in j.position)

        # Close on the object (open loop, 5 N): the frames follow the measured opening.
        pub = probe.node.create_publisher(GraspForceCommand, 'gripper/grasp_force_cmd', COMMAND)
        assert probe.spin_until(lambda: pub.get_subscription_count() > 0, 10.0)
        pub.publish(GraspForceCommand(force=5.0, source=GraspForceCommand.SOURCE_TEST))
        assert probe.spin_until(lambda: m['sim/state'][-1].opening < 0.0605 and
                                abs(m['gripper/status'][-1].opening_rate) < 1e-3, 30.0), \
            sim.output()
        n0 = len(m['/tf'])
        assert probe.spin_until(lambda: len(m['/tf']) > n0 + 20, 10.0)
        status = {stamp_to_seconds(s.header.stamp): s.opening for s in m['gripper/status']}
        pairs = probe.finger_pairs()
        matched = [(sep, status[t]) for t, sep in pairs.items() if t in status]
        assert len(matched) > 20
        for separation, opening in matched:
            assert separation == pytest.approx(opening, abs=1e-9)
        last_sep = matched[-1][0]
        assert 0.055 < last_sep < 0.0605                       # on the 60 mm object
        assert last_sep == pytest.approx(m['sim/state'][-1].opening, abs=2e-4)   # the truth
        joints = m['gripper/joint_states'][-1]
        assert list(joints.name) == ['finger_1_joint', 'finger_2_joint']
        assert joints.position[0] == pytest.approx(last_sep / 2.0, abs=2e-4)

        # Scene: world → tool0 → … → gripper_middle places the object where the simulator
        # says it is (object pose relative to gripper_middle).
        tool = _pose(probe.latest('tool0'))
        obj = _pose(probe.latest('sim_object'))
        static_tf = {t.child_frame_id: t for t in m['/tf_static'][-1].transforms}
        mid = _compose(_compose(tool, _pose(static_tf['gripper_base_link'])),
                       _pose(static_tf['gripper_middle']))
        obj_in_mid = mid[1].inv().apply(obj[0] - mid[0])
        from friction_models.core.presets import load_presets
        cx, cy = load_presets(Path(_share('friction_models', 'config/sim_presets.yaml'))
                              )['cardboard'].com_offset
        pose = m['sim/object_pose'][-1].pose.position    # grasp point, gripper_middle
        assert obj_in_mid == pytest.approx([pose.x + cx, pose.y + cy, 0.0], abs=2e-3)
        assert obj[1].apply([0.0, 1.0, 0.0]) == pytest.approx([0.0, 0.0, 1.0], abs=0.05), \
            'object upright: its y axis is world z'

        _check_urdf(m['robot_description'][-1].data, stroke=0.08)
        box = m['sim/markers'][-1].markers[0]
        assert box.header.frame_id == 'sim_object' and box.frame_locked
        assert (box.scale.x, box.scale.y, box.scale.z) == pytest.approx((0.08, 0.14, 0.06))
    finally:
        probe.close()
        code = sim.stop()
    assert code == 0, sim.output()
    assert 'Traceback' not in sim.output()


def test_gripper_action_moves_the_simulated_fingers(ros_context: Any, ros_env: dict[str, str],
                                                    tmp_path: Path) -> None:
    from control_msgs.action import ParallelGripperCommand
    from rclpy.action import ActionClient

    from slip_cell_common.testing import NodeProcess
    sim = NodeProcess([_exe('friction_models', 'sim_gripper'), '--ros-args',
                       '--params-file', _share('slip_gripper_driver', 'config/cell.yaml'),
                       '--params-file', _share('friction_models', 'config/sim_gripper.yaml')],
                      tmp_path / 'sim.log', ros_env)
    probe = TfProbe(ros_context)
    m = probe.msgs
    try:
        assert probe.spin_until(lambda: len(m['sim/state']) > 5, 30.0), sim.output()
        # Open to 70 mm: reached, the true opening follows, the frames with it.
        ok, res = probe.gripper_goal(0.035, 10.0)
        assert ok and res.result.reached_goal and not res.result.stalled, sim.output()
        assert res.status == 4                                   # SUCCEEDED
        assert res.result.position == pytest.approx(0.035, abs=6e-4)
        assert probe.spin_until(lambda: len(m['sim/state']) > 0, 1.0)
        probe.spin_until(lambda: False, 0.3)
        assert m['sim/state'][-1].opening == pytest.approx(0.070, abs=1.5e-3)
        sep = list(probe.finger_pairs().values())[-1]
        assert sep == pytest.approx(m['sim/state'][-1].opening, abs=3e-4)
        # Close onto the 60 mm object with 12 N: stalled, held, not reached.
        ok, res = probe.gripper_goal(0.0, 12.0)
        assert ok and res.result.stalled and not res.result.reached_goal, sim.output()
        assert res.status == 4 and res.result.position == pytest.approx(0.030, abs=1.5e-3)
        probe.spin_until(lambda: False, 0.5)
        assert m['sim/state'][-1].normal_force_1 == pytest.approx(12.0, rel=0.15)
        # Out of range or inconsistent goals are rejected when they arrive.
        ok, _ = probe.gripper_goal(0.05, 10.0)
        assert not ok and 'outside [0, 0.0400] m' in sim.output()
        client = ActionClient(probe.node, ParallelGripperCommand,
                              'gripper/parallel_gripper_cmd')
        try:
            assert probe.spin_until(client.server_is_ready, 10.0)
            goal = ParallelGripperCommand.Goal()
            goal.command.name = ['finger_1_joint', 'finger_2_joint']
            goal.command.position = [0.03, 0.02]
            send = client.send_goal_async(goal)
            assert probe.spin_until(send.done, 10.0) and not send.result().accepted
            assert 'both move together' in sim.output()
            # A valid parallel goal, cancelled while it opens: canceled, fingers stop.
            goal.command.position = [0.04, 0.04]
            goal.command.effort = [3.0, 3.0]
            send = client.send_goal_async(goal)
            assert probe.spin_until(send.done, 10.0) and send.result().accepted
            probe.spin_until(lambda: False, 0.15)
            cancel = send.result().cancel_goal_async()
            result = send.result().get_result_async()
            assert probe.spin_until(lambda: cancel.done() and result.done(), 10.0)
            assert result.result().status == 5                  # CANCELED
            state = result.result().result.state
            assert list(state.name) == ['finger_1_joint', 'finger_2_joint']
            assert 0.03 < state.position[0] < 0.0395
        finally:
            client.destroy()
    finally:
        probe.close()
        code = sim.stop()
    assert code == 0, sim.output()
    assert 'Traceback' not in sim.output()


def test_driver_tf_tree_against_the_firmware_emulator(ros_context: Any, ros_env: dict[str, str],
                                                      tmp_path: Path) -> None:
    from std_srvs.srv import Trigger

    from slip_cell_common.testing import NodeProcess
    from slip_gripper_driver.core.firmware_emulator import (
        FirmwareEmulator,
        GripperModelParams,
        PtyFirmwareEmulator,
    )
    firmware = PtyFirmwareEmulator(FirmwareEmulator(GripperModelParams(initial_opening=0.04)),
                                   link_path=str(tmp_path / 'usb-gripper'))
    firmware.start()
    site = tmp_path / 'site.yaml'
    site.write_text('gripper_driver:\n  ros__parameters:\n'
                    f"    serial: {{port: '{firmware.port}'}}\n"
                    "    ft: {mode: 'topic'}\n"   # no boxes: the loop runs open
                    '    link: {stale_after: 0.5, fault_after: 1.0}\n')
    share = Path(_share('slip_gripper_driver', 'config'))
    proc = NodeProcess([_exe('slip_gripper_driver', 'gripper_driver'), '--ros-args',
                        '--params-file', str(share / 'cell.yaml'),
                        '--params-file', str(share / 'gripper_driver.yaml'),
                        '--params-file', str(site)], tmp_path / 'driver.log', ros_env)
    probe = TfProbe(ros_context)
    m = probe.msgs
    try:
        assert probe.spin_until(lambda: m['/tf_static'] and m['robot_description'] and
                                len(m['gripper/joint_states']) > 10, 30.0), proc.output()
        static = {(t.header.frame_id, t.child_frame_id) for t in m['/tf_static'][-1].transforms}
        assert static == STATIC_EDGES
        _check_urdf(m['robot_description'][-1].data, stroke=0.08)
        # Not homed: the opening is unknown, and nothing pretends otherwise.
        assert not m['/tf'] and math.isnan(m['gripper/joint_states'][-1].position[0])
        ok, _ = probe.gripper_goal(0.02, 10.0)
        assert not ok and 'call gripper/home first' in proc.output()

        reply = probe.call(Trigger, 'gripper/home', Trigger.Request(), 60.0)
        assert reply is not None and reply.success, (reply, proc.output())
        assert probe.spin_until(lambda: len(probe.finger_pairs()) > 10, 10.0)
        status = {stamp_to_seconds(s.header.stamp): s.opening for s in m['gripper/status']}
        matched = [(sep, status[t]) for t, sep in probe.finger_pairs().items() if t in status]
        assert len(matched) > 5
        for separation, opening in matched:
            assert separation == pytest.approx(opening, abs=1e-9)
        assert matched[-1][0] == pytest.approx(firmware.emulator.opening, abs=1e-3)

        # The standard action moves the emulated fingers to 40 mm.
        ok, res = probe.gripper_goal(0.02, 8.0)
        assert ok and res.result.reached_goal, proc.output()
        time.sleep(0.05)
        assert firmware.emulator.opening == pytest.approx(0.040, abs=1.5e-3)
        n0 = len(m['/tf'])
        assert probe.spin_until(lambda: len(m['/tf']) > n0 + 5, 5.0)
        assert list(probe.finger_pairs().values())[-1] == pytest.approx(0.040, abs=1.5e-3)
    finally:
        probe.close()
        code = proc.stop()
        firmware.stop()
    assert code == 0, proc.output()
    assert 'Traceback' not in proc.output()
