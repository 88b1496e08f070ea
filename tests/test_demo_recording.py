"""The demo's bag holds every topic of the running simulated cell (README: "every topic").

The installed sim_gripper runs as a process; an in-process `TopicRecorder` with the demo's
topic selection (`slip_bringup.demo.RECORD_EVERY_TOPIC`, what the demo gives the runner)
records for a few simulated seconds. Every non-hidden topic that has a publisher in the graph
must be in the bag with messages, in particular ``gripper/joint_states`` and the simulator's
object pose and twist.
"""
from __future__ import annotations

from pathlib import Path

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _start_sim(tmp_path: Path, env: dict[str, str]):
    from ament_index_python.packages import get_package_prefix, get_package_share_directory
    from slip_cell_common.testing import NodeProcess
    exe = Path(get_package_prefix('friction_models')) / 'lib' / 'friction_models' / 'sim_gripper'
    config = [('slip_gripper_driver', 'cell.yaml'), ('friction_models', 'sim_gripper.yaml')]
    args = [a for pkg, name in config for a in
            ('--params-file', str(Path(get_package_share_directory(pkg)) / 'config' / name))]
    return NodeProcess([str(exe), '--ros-args', *args], tmp_path / 'sim.log', env)


def test_demo_selection_records_every_topic_of_the_sim_cell(ros_context, ros_env,
                                                             tmp_path: Path) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from slip_bringup.demo import RECORD_EVERY_TOPIC
    from slip_cell_common.bag_io import bag_info
    from slip_cell_common.recorder import TopicRecorder, is_hidden_topic
    from slip_cell_common.testing import spin_until

    sim = _start_sim(tmp_path, ros_env)
    node = Node('demo_recording_probe', context=ros_context,
                parameter_overrides=[Parameter('use_sim_time', value=True)])
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    bag = tmp_path / 'demo_bag'
    recorder = TopicRecorder(node, bag, topics=RECORD_EVERY_TOPIC)
    expected: set[str] = set()
    try:
        wanted = {'/gripper/joint_states', '/sim/object_pose', '/sim/object_twist'}
        assert spin_until(executor, lambda: wanted <= set(recorder.topics), 40.0), \
            (recorder.topics, sim.output())
        t0 = node.get_clock().now().nanoseconds
        assert spin_until(executor, lambda: node.get_clock().now().nanoseconds - t0 > 2e9
                          and recorder.message_count > 1000 and not recorder.pending, 40.0), \
            (recorder.pending, sim.output())
        expected = {topic for topic, _ in node.get_topic_names_and_types()
                    if not is_hidden_topic(topic) and node.count_publishers(topic) > 0}
    finally:
        recorder.stop()
        executor.shutdown()
        node.destroy_node()
        sim.stop()
    info = bag_info(bag)
    counts = {t.name: t.count for t in info.topics}
    # The simulator's publishers keep 100 samples (QoS-override parameters, another process).
    depths = {t.name: [q.depth for q in t.offered_qos] for t in info.topics}
    for topic in ('/gripper/status', '/gripper/joint_states', '/finger_1/ft/wrench',
                  '/finger_2/slip/twist', '/sim/object_pose'):
        assert depths[topic] == [100], (topic, depths[topic])
    assert wanted <= set(counts)
    missing = expected - set(counts)
    assert not missing, f'topics in the graph but not in the demo bag: {sorted(missing)}'
    empty = [t for t in ('/gripper/joint_states', '/sim/object_pose', '/sim/object_twist',
                         '/gripper/status', '/clock') if counts.get(t, 0) == 0]
    assert not empty, f'recorded without messages: {empty}'
