"""Bag tools: write/read/info/CSV, corrupt bags, in-process recording and replay over DDS."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from support.sample_bags import status_message, write_sample_bag

pytestmark = pytest.mark.ros


def test_write_read_info_and_csv(tmp_path: Path) -> None:
    from slip_cell_common.bag_io import BagError, BagWriter, bag_info, export_csv, read_messages
    bag = tmp_path / 'sample'
    write_sample_bag(bag)
    info = bag_info(bag)
    counts = {t.name: t.count for t in info.topics}
    assert counts == {'/gripper/status': 50, '/gripper/grasp_force_cmd': 5,
                      '/contact/properties': 1}
    assert info.duration_s == pytest.approx(0.099, abs=1e-6)  # 1 ms .. 100 ms
    assert (bag / 'metadata.yaml').read_text().count('version: 9') == 1

    msgs = read_messages(bag, ['/gripper/status', '/contact/properties'])
    assert [m.line_count for _, m in msgs['/gripper/status']] == list(range(50))
    assert math.isnan(msgs['/gripper/status'][3][1].opening)
    assert msgs['/contact/properties'][0][1].finger_1.mu_c == pytest.approx(0.46)

    files = export_csv(bag, tmp_path / 'csv', ['/gripper/status'])
    rows = list(csv.DictReader(files[0].open()))
    assert len(rows) == 50 and float(rows[7]['motor_angle']) == pytest.approx(0.07)
    assert rows[0]['header.stamp.sec'] == '100'

    with pytest.raises(BagError, match='already exists'):
        BagWriter(bag)
    with pytest.raises(BagError, match='no topic'):
        read_messages(bag, ['/nope'])


def test_missing_truncated_and_corrupt_bags_give_clear_errors(tmp_path: Path) -> None:
    from slip_bringup.bag_cli import main as slip_bag
    from slip_cell_common.bag_io import BagError, bag_info, read_messages
    with pytest.raises(BagError, match='does not exist'):
        bag_info(tmp_path / 'missing')

    bag = tmp_path / 'truncated'
    write_sample_bag(bag, n=400)
    data_file = next(bag.glob('*.mcap'))
    data_file.write_bytes(data_file.read_bytes()[: data_file.stat().st_size // 2])
    with pytest.raises(BagError):
        read_messages(bag)

    garbage = tmp_path / 'garbage'
    garbage.mkdir()
    (garbage / 'metadata.yaml').write_text('rosbag2_bagfile_information: {version: [}\n')
    with pytest.raises(BagError, match='cannot open bag'):
        bag_info(garbage)
    assert slip_bag(['info', str(garbage)]) == 2


def test_record_in_process_then_replay_in_another_process(ros_context, ros_env,
                                                          tmp_path: Path) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rosgraph_msgs.msg import Clock
    from slip_cell_common.recorder import TopicRecorder
    from slip_cell_common.bag_io import bag_info
    from slip_cell_common.qos import COMMAND, LATCHED, SENSOR_PUB, SENSOR_SUB
    from slip_cell_common.testing import NodeProcess, spin_until
    from slip_msgs.msg import ContactProperties, GraspForceCommand, GripperStatus

    node = Node('bag_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    status_pub = node.create_publisher(GripperStatus, 'gripper/status', SENSOR_PUB)
    cmd_pub = node.create_publisher(GraspForceCommand, 'gripper/grasp_force_cmd', COMMAND)
    latched = node.create_publisher(ContactProperties, 'contact/properties', LATCHED)
    latched.publish(ContactProperties(preset_name='latched-before-recording'))
    bag = tmp_path / 'recorded'
    recorder = TopicRecorder(node, bag, topics=('gripper/*', 'contact/*'))
    sent = 0

    def tick() -> None:
        nonlocal sent
        status_pub.publish(status_message(sent))
        cmd_pub.publish(GraspForceCommand(force=float(sent)))
        sent += 1
    assert spin_until(executor, lambda: len(recorder.topics) >= 3, 10.0)
    timer = node.create_timer(0.01, tick)
    spin_until(executor, lambda: recorder.message_count >= 120, 15.0)
    node.destroy_timer(timer)
    recorder.stop()
    counts = {t.name: t.count for t in bag_info(bag).topics}
    assert counts['/contact/properties'] == 1, 'latched message recorded'
    assert counts['/gripper/status'] >= 50 and counts['/gripper/grasp_force_cmd'] >= 50

    # Replay in another process: state topics and /clock arrive, commands do not.
    got_status: list[GripperStatus] = []
    got_cmd: list[GraspForceCommand] = []
    clocks: list[Clock] = []
    node.create_subscription(GripperStatus, 'gripper/status', got_status.append, SENSOR_PUB)
    node.create_subscription(GraspForceCommand, 'gripper/grasp_force_cmd', got_cmd.append,
                             SENSOR_SUB)
    node.create_subscription(Clock, '/clock', clocks.append, 10)
    proc = NodeProcess.python_module('slip_bringup.bag_cli', [
        'replay', str(bag), '--rate', '1.0', '--start-delay', '15', '--topic', 'gripper/*'], tmp_path / 'replay.log', ros_env)
    try:
        spin_until(executor, lambda: not proc.running(), 30.0)
        spin_until(executor, lambda: False, 0.3)
    finally:
        code = proc.stop()
        executor.shutdown()
        node.destroy_node()
    assert code == 0, proc.output()
    assert len(got_status) >= 0.9 * counts['/gripper/status'], proc.output()
    lines = [m.line_count for m in got_status]
    assert lines == sorted(lines)
    assert got_cmd == [], 'command topics must not be replayed by default'
    assert len(clocks) >= len(got_status)
    assert 'replay finished' in proc.output()
