"""``foxglove_live`` answers a WebSocket client: channels with ros2msg schemas, live CDR data.

The node runs as its own process (port 0: any free port, read from its log); this test
publishes TF and a wrench with real rclpy publishers and talks the Foxglove WebSocket
protocol over a raw socket (tests/support/ws_client.py).
"""
from __future__ import annotations

import re
import struct
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros


def _advertised(frames: list) -> dict[str, dict]:
    channels: dict[str, dict] = {}
    for opcode, data in frames:
        if opcode == 0x1 and data.get('op') == 'advertise':
            channels.update({c['topic']: c for c in data['channels']})
    return channels


def test_live_view_serves_tf_and_wrenches_to_a_websocket_client(ros_context, ros_env,
                                                                tmp_path: Path) -> None:
    from geometry_msgs.msg import TransformStamped, WrenchStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.serialization import deserialize_message
    from slip_cell_common.qos import LATCHED, SENSOR_PUB
    from slip_cell_common.testing import NodeProcess, SpinThread
    from support.ws_client import WsClient
    from tf2_msgs.msg import TFMessage

    node = Node('foxglove_probe', context=ros_context)
    tf_static = node.create_publisher(TFMessage, '/tf_static', LATCHED)
    static = TransformStamped()
    static.header.frame_id, static.child_frame_id = 'tool0', 'gripper_base_link'
    static.transform.rotation.w = 1.0
    tf_static.publish(TFMessage(transforms=[static]))
    tf_pub = node.create_publisher(TFMessage, '/tf', SENSOR_PUB)
    wrench_pub = node.create_publisher(WrenchStamped, 'finger_1/ft/wrench', SENSOR_PUB)

    def tick() -> None:
        moving = TransformStamped()
        moving.header.frame_id, moving.child_frame_id = 'gripper_base_link', 'finger_1'
        moving.transform.rotation.w = 1.0
        tf_pub.publish(TFMessage(transforms=[moving]))
        wrench = WrenchStamped()
        wrench.header.frame_id = 'finger_1_ft'
        wrench.wrench.force.z = -7.5
        wrench_pub.publish(wrench)
    node.create_timer(0.02, tick)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    proc = NodeProcess.python_module('slip_bringup.foxglove_live',
                                     ['--ros-args', '-p', 'port:=0'], tmp_path / 'fox.log',
                                     ros_env)
    client = None
    try:
        with SpinThread(executor):
            deadline = time.monotonic() + 30.0
            found = None
            while found is None and proc.running() and time.monotonic() < deadline:
                time.sleep(0.1)
                found = re.search(r'ws://127\.0\.0\.1:(\d+)', proc.output())
            assert found, proc.output()
            client = WsClient('127.0.0.1', int(found.group(1)))
            wanted = {'/tf', '/tf_static', '/finger_1/ft/wrench'}
            frames = client.collect(lambda f: wanted <= set(_advertised(f)), 20.0)
            channels = _advertised(frames)
            assert frames[0][1]['op'] == 'serverInfo'
            assert wanted <= set(channels), (sorted(channels), proc.output())
            tf = channels['/tf']
            assert (tf['schemaName'], tf['schemaEncoding'], tf['encoding']) == \
                ('tf2_msgs/msg/TFMessage', 'ros2msg', 'cdr')
            wrench_schema = channels['/finger_1/ft/wrench']['schema']
            assert channels['/finger_1/ft/wrench']['schemaName'] == \
                'geometry_msgs/msg/WrenchStamped'
            assert '# A wrench with reference coordinate frame and timestamp' in wrench_schema

            # Subscribe; the SDK may answer "Unknown channel ID" for a channel advertised a
            # moment ago (its channel table is updated after the advertisement goes out):
            # then subscribe again under a new subscription id.
            topics = {'/tf_static': [], '/finger_1/ft/wrench': []}
            by_sub: dict[int, str] = {}

            def subscribe(topic: str) -> None:
                sub_id = len(by_sub) + 1
                by_sub[sub_id] = topic
                client.send_json({'op': 'subscribe', 'subscriptions': [
                    {'id': sub_id, 'channelId': channels[topic]['id']}]})
            for topic in topics:
                subscribe(topic)

            def got_both(frames: list) -> bool:
                opcode, payload = frames[-1] if frames else (0, b'')
                if opcode == 0x2 and payload[0] == 0x01:  # binary MessageData
                    topics[by_sub[struct.unpack_from('<I', payload, 1)[0]]].append(payload)
                elif opcode == 0x1 and 'Unknown channel ID' in payload.get('message', ''):
                    refused = int(payload['message'].rsplit(':', 1)[1])
                    time.sleep(0.2)
                    subscribe(next(t for t, c in channels.items() if c['id'] == refused))
                return bool(topics['/tf_static']) and len(topics['/finger_1/ft/wrench']) >= 3
            client.collect(got_both, 20.0)
    finally:
        if client is not None:
            client.close()
        code = proc.stop()
        executor.shutdown()
        node.destroy_node()
    assert topics['/tf_static'] and len(topics['/finger_1/ft/wrench']) >= 3, proc.output()
    latched = deserialize_message(topics['/tf_static'][0][13:], TFMessage)
    assert latched.transforms[0].child_frame_id == 'gripper_base_link'
    wrench = deserialize_message(topics['/finger_1/ft/wrench'][-1][13:], WrenchStamped)
    assert wrench.wrench.force.z == -7.5 and wrench.header.frame_id == 'finger_1_ft'
    assert code == 0, proc.output()
