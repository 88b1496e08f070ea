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
    from slip_cell_common.bag_io import bag_info, iter_raw
    from slip_cell_common.time_conv import stamp_to_nanoseconds
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
        'replay', str(bag), '--rate', '1.0', '--start-delay', '15', '--topic', 'gripper/*'],
        tmp_path / 'replay.log', ros_env)
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
    # /clock follows the bag's stamps. Its history is one sample deep (only the latest time
    # matters), so a loaded host may skip some in between; the last one always arrives.
    clock_ns = [stamp_to_nanoseconds(c.clock) for c in clocks]
    assert clock_ns == sorted(clock_ns) and len(clocks) >= 0.5 * len(got_status)
    last_status_ns = max(stamp for topic, _, stamp, _ in iter_raw(bag)
                         if topic == '/gripper/status')
    assert clock_ns[-1] == last_status_ns
    assert 'replay finished' in proc.output()


def test_recorded_bag_reads_like_rosbag2s_own_with_the_independent_mcap_reader(
        ros_context, tmp_path: Path) -> None:
    """Real publishers (one per QoS kind) → TopicRecorder → the ``mcap`` + ``mcap_ros2`` readers:
    /tf as tf2_msgs/msg/TFMessage, schemas with their comments, latched topics received,
    ``ros_distro: jazzy`` and the publishers' real offered QoS (depth 100) in metadata.yaml."""
    import yaml
    from geometry_msgs.msg import TransformStamped
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from slip_cell_common.bag_io import bag_info
    from slip_cell_common.qos import LATCHED, SENSOR_PUB, overridable
    from slip_cell_common.recorder import TopicRecorder
    from slip_cell_common.testing import spin_until
    from slip_msgs.msg import ContactProperties, GripperStatus
    from std_msgs.msg import String
    from tf2_msgs.msg import TFMessage

    node = Node('bag_schema_probe', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    urdf = '<robot name="probe"><link name="gripper_base_link"/></robot>'
    tf_pub = node.create_publisher(TFMessage, '/tf', SENSOR_PUB,
                                   qos_overriding_options=overridable())
    tf_static = node.create_publisher(TFMessage, '/tf_static', LATCHED)
    description = node.create_publisher(String, 'robot_description', LATCHED)
    status_pub = node.create_publisher(GripperStatus, 'gripper/status', SENSOR_PUB,
                                       qos_overriding_options=overridable())
    props_pub = node.create_publisher(ContactProperties, 'contact/properties', LATCHED)
    static = TransformStamped()
    static.header.frame_id, static.child_frame_id = 'tool0', 'gripper_base_link'
    static.transform.rotation.w = 1.0
    tf_static.publish(TFMessage(transforms=[static]))
    description.publish(String(data=urdf))
    props_pub.publish(ContactProperties(preset_name='latched'))

    bag = tmp_path / 'schema_bag'
    recorder = TopicRecorder(node, bag, topics=('gripper/*', 'contact/*'))
    sent = 0

    def tick() -> None:
        nonlocal sent
        status_pub.publish(status_message(sent))
        moving = TransformStamped()
        moving.header.frame_id, moving.child_frame_id = 'gripper_base_link', 'finger_1'
        moving.transform.translation.y = 0.001 * sent
        moving.transform.rotation.w = 1.0
        tf_pub.publish(TFMessage(transforms=[moving]))
        sent += 1
    timer = node.create_timer(0.01, tick)
    try:
        assert spin_until(executor, lambda: len(recorder.topics) >= 5
                          and recorder.message_count >= 150, 20.0), recorder.topics
    finally:
        node.destroy_timer(timer)
        recorder.stop()
        executor.shutdown()
        node.destroy_node()

    with next(bag.glob('*.mcap')).open('rb') as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()], validate_crcs=True)
        summary = reader.get_summary()
        channels = {c.topic: c for c in summary.channels.values()}
        schemas = {c.topic: summary.schemas[c.schema_id] for c in channels.values()}
        decoded: dict[str, list] = {}
        for _, channel, _, msg in reader.iter_decoded_messages(log_time_order=True):
            decoded.setdefault(channel.topic, []).append(msg)
    assert {'/tf', '/tf_static', '/robot_description', '/gripper/status',
            '/contact/properties'} <= set(channels)
    assert schemas['/tf'].name == 'tf2_msgs/msg/TFMessage'
    assert all(s.encoding == 'ros2msg' for s in schemas.values())
    status_schema = schemas['/gripper/status'].data.decode()
    assert '# [rad] firmware shaft angle, relative to power-up' in status_schema
    assert '\nMSG: std_msgs/Header\n' in status_schema
    assert '# Two-integer timestamp' in status_schema  # dependency text kept verbatim too
    tf_schema = schemas['/tf'].data.decode()
    assert '\nMSG: geometry_msgs/TransformStamped\n' in tf_schema
    assert channels['/tf'].metadata['topic_type_hash'].startswith('RIHS01_')
    assert 'depth: 100' in channels['/gripper/status'].metadata['offered_qos_profiles']

    assert decoded['/tf_static'][0].transforms[0].child_frame_id == 'gripper_base_link'
    assert decoded['/robot_description'][0].data == urdf
    assert decoded['/contact/properties'][0].preset_name == 'latched'
    ys = [m.transforms[0].transform.translation.y for m in decoded['/tf']]
    assert len(ys) >= 50 and ys == sorted(ys)
    assert decoded['/gripper/status'][5].motor_angle == pytest.approx(0.05)

    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['version'] == 9 and meta['ros_distro'] == 'jazzy'
    offered = {t['topic_metadata']['name']: t['topic_metadata']['offered_qos_profiles']
               for t in meta['topics_with_message_count']}
    for topic in ('/gripper/status', '/tf'):
        assert [(q['history'], q['depth'], q['reliability'], q['durability'])
                for q in offered[topic]] == [('keep_last', 100, 'reliable', 'volatile')], topic
    assert offered['/tf'][0]['deadline'] == {'sec': 9223372036, 'nsec': 854775807}
    # A publisher without QoS-override parameters: what discovery tells, as rosbag2 stores it.
    assert [(q['reliability'], q['durability']) for q in offered['/tf_static']] == \
        [('reliable', 'transient_local')]
    info = bag_info(bag)  # rosbags re-checks every type hash against the stored schemas
    assert {t.name: t.count for t in info.topics}['/tf_static'] == 1
    assert info.ros_distro == 'jazzy'


def test_default_outputs_are_outside_the_source_tree(monkeypatch: pytest.MonkeyPatch,
                                                     tmp_path: Path) -> None:
    """Runner bags and demo outputs default to $SLIP_DATA_DIR or ~/.local/share/slip_cell."""
    from slip_cell_common.bag_io import default_bag_directory, default_data_directory
    from slip_control.core.params import ExperimentRunnerParams
    monkeypatch.setenv('SLIP_DATA_DIR', str(tmp_path / 'data'))
    assert default_bag_directory() == tmp_path / 'data' / 'bags'
    monkeypatch.delenv('SLIP_DATA_DIR')
    monkeypatch.delenv('XDG_DATA_HOME', raising=False)
    monkeypatch.setenv('HOME', str(tmp_path / 'home'))
    assert default_data_directory() == tmp_path / 'home' / '.local' / 'share' / 'slip_cell'
    repo = Path(__file__).resolve().parents[1]
    assert repo not in default_bag_directory().parents
    # The runner's parameter default means "the data directory", not a relative 'bags'.
    assert ExperimentRunnerParams().recording.directory == ''
