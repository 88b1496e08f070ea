"""The standard interfaces the wheels lack (tf2_msgs, control_msgs) are the upstream types.

In wheels mode they are built from src/upstream_interfaces; with a sourced system Jazzy the
installed packages are used. Either way every tool of a full ROS 2 install must see the same
types: same names, same fields and the same RIHS01 type hashes.

Reference hashes: each was read from a source independent of this workspace's build — the
rosidl-generated C of other projects built against the released Jazzy packages (TFMessage,
control_msgs' GripperCommand message and action) and rosbags' Jazzy type store (TFMessage,
TF2Error, checked again at run time below). No independent hash of ParallelGripperCommand was
found; for it the field structure is checked.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros
serialization = pytest.importorskip('rclpy.serialization')

from ament_index_python.packages import get_package_share_directory  # noqa: E402
from control_msgs.action import GripperCommand, ParallelGripperCommand  # noqa: E402
from control_msgs.msg import GripperCommand as GripperCommandMsg  # noqa: E402
from tf2_msgs.action import LookupTransform  # noqa: E402
from tf2_msgs.msg import TF2Error, TFMessage  # noqa: E402
from tf2_msgs.srv import FrameGraph  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

REFERENCE_HASHES = {
    'tf2_msgs/msg/TFMessage':
        'RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087',
    'tf2_msgs/msg/TF2Error':
        'RIHS01_db2485e7d6a0ec75bf087e058ee45df682acc3a621ca7780503d10aac141809a',
    'control_msgs/msg/GripperCommand':
        'RIHS01_57eb8f326c9889ca8bb34ead82cc94cc09bf6bc5c3b6c09546dca3a00b589890',
    'control_msgs/action/GripperCommand':
        'RIHS01_e17c0e644eccf14bea84a0a93e0977182872c2eb7873ca6694900059b46dbc84',
}

JOINT_STATE = 'sensor_msgs/JointState'
EXPECTED_FIELDS = {
    TFMessage: {'transforms': 'sequence<geometry_msgs/TransformStamped>'},
    TF2Error: {'error': 'uint8', 'error_string': 'string'},
    FrameGraph.Request: {},
    FrameGraph.Response: {'frame_yaml': 'string'},
    LookupTransform.Goal: {
        'target_frame': 'string', 'source_frame': 'string',
        'source_time': 'builtin_interfaces/Time', 'timeout': 'builtin_interfaces/Duration',
        'target_time': 'builtin_interfaces/Time', 'fixed_frame': 'string',
        'advanced': 'boolean'},
    LookupTransform.Result: {'transform': 'geometry_msgs/TransformStamped',
                             'error': 'tf2_msgs/TF2Error'},
    LookupTransform.Feedback: {},
    GripperCommandMsg: {'position': 'double', 'max_effort': 'double'},
    GripperCommand.Goal: {'command': 'control_msgs/GripperCommand'},
    GripperCommand.Result: {'position': 'double', 'effort': 'double', 'stalled': 'boolean',
                            'reached_goal': 'boolean'},
    GripperCommand.Feedback: {'position': 'double', 'effort': 'double', 'stalled': 'boolean',
                              'reached_goal': 'boolean'},
    ParallelGripperCommand.Goal: {'command': JOINT_STATE},
    ParallelGripperCommand.Result: {'state': JOINT_STATE, 'stalled': 'boolean',
                                    'reached_goal': 'boolean'},
    ParallelGripperCommand.Feedback: {'state': JOINT_STATE},
}


def _installed_hash(type_name: str) -> str:
    """RIHS01 hash of ``pkg/kind/Name`` from the type description rosidl installed."""
    package, kind, name = type_name.split('/')
    path = Path(get_package_share_directory(package)) / kind / f'{name}.json'
    hashes = {h['type_name']: h['hash_string']
              for h in json.loads(path.read_text())['type_hashes']}
    return hashes[type_name]


@pytest.mark.parametrize('msg_type', list(EXPECTED_FIELDS), ids=lambda t: t.__qualname__)
def test_fields_are_the_upstream_ones(msg_type: type) -> None:
    assert msg_type.get_fields_and_field_types() == EXPECTED_FIELDS[msg_type]


def test_tf2_error_codes() -> None:
    codes = {name: getattr(TF2Error, name) for name in (
        'NO_ERROR', 'LOOKUP_ERROR', 'CONNECTIVITY_ERROR', 'EXTRAPOLATION_ERROR',
        'INVALID_ARGUMENT_ERROR', 'TIMEOUT_ERROR', 'TRANSFORM_ERROR')}
    assert codes == {'NO_ERROR': 0, 'LOOKUP_ERROR': 1, 'CONNECTIVITY_ERROR': 2,
                     'EXTRAPOLATION_ERROR': 3, 'INVALID_ARGUMENT_ERROR': 4,
                     'TIMEOUT_ERROR': 5, 'TRANSFORM_ERROR': 6}


@pytest.mark.parametrize('type_name', sorted(REFERENCE_HASHES))
def test_installed_type_hash_matches_upstream(type_name: str) -> None:
    assert _installed_hash(type_name) == REFERENCE_HASHES[type_name]


def test_reference_hashes_agree_with_rosbags_jazzy_store() -> None:
    """A second, independent source for the tf2_msgs message hashes."""
    typesys = pytest.importorskip('rosbags.typesys')
    store = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    for name in ('tf2_msgs/msg/TFMessage', 'tf2_msgs/msg/TF2Error'):
        assert store.hash_rihs01(name) == REFERENCE_HASHES[name]


def test_live_endpoint_advertises_the_upstream_hash(ros_context: object) -> None:
    """The hash the middleware announces for a TFMessage publisher is the upstream one."""
    import rclpy
    node = rclpy.create_node('tf_hash_probe', context=ros_context)
    try:
        node.create_publisher(TFMessage, 'tf_hash_probe', 1)
        infos = node.get_publishers_info_by_topic('tf_hash_probe')
        assert len(infos) == 1
        assert infos[0].topic_type == 'tf2_msgs/msg/TFMessage'
        type_hash = infos[0].topic_type_hash
        announced = f'RIHS{type_hash.version:02d}_{type_hash.value.hex()}'
        assert announced == REFERENCE_HASHES['tf2_msgs/msg/TFMessage']
    finally:
        node.destroy_node()


def test_messages_round_trip() -> None:
    from geometry_msgs.msg import TransformStamped
    from sensor_msgs.msg import JointState
    item = TransformStamped(child_frame_id='ft_sensor_1')
    item.header.frame_id = 'gripper_middle'
    item.transform.translation.z = -0.0368
    item.transform.rotation.w = 1.0
    samples = [
        TFMessage(transforms=[item, item]),
        TF2Error(error=TF2Error.TIMEOUT_ERROR, error_string='waited 1 s'),
        GripperCommand.Goal(command=GripperCommandMsg(position=0.05, max_effort=20.0)),
        ParallelGripperCommand.Result(state=JointState(name=['finger_1_joint'], position=[0.03]),
                                      stalled=True, reached_goal=False),
    ]
    for msg in samples:
        data = serialization.serialize_message(msg)
        assert serialization.deserialize_message(data, type(msg)) == msg


# --- build selection: built in wheels mode, left to the system install in system mode -------

def _run_build_script(tmp_path: Path, mode: str) -> tuple[list[str], set[str]]:
    """Run a copy of tools/colcon_build.sh against a recording stand-in for the venv python.

    Returns the colcon arguments and which stale upstream copies survived in ``install/``.
    """
    root = tmp_path / 'ws'
    (root / 'tools').mkdir(parents=True)
    shutil.copy(ROOT / 'tools' / 'colcon_build.sh', root / 'tools' / 'colcon_build.sh')
    shutil.copy(ROOT / 'tools' / 'heartbeat.sh', root / 'tools' / 'heartbeat.sh')
    for pkg in ('tf2_msgs', 'control_msgs', 'slip_msgs'):
        (root / 'install' / pkg).mkdir(parents=True)
    venv = tmp_path / 'venv'
    (venv / 'bin').mkdir(parents=True)
    (venv / 'local_setup.sh').write_text('')
    record = tmp_path / 'args.txt'
    fake_python = venv / 'bin' / 'python'
    fake_python.write_text(f'#!/bin/sh\nprintf "%s\\n" "$@" > "{record}"\n')
    fake_python.chmod(0o755)
    subprocess.run(['bash', str(root / 'tools' / 'colcon_build.sh'), str(venv), mode],
                   check=True, capture_output=True, env={**os.environ}, timeout=30)
    left = {p.name for p in (root / 'install').iterdir()}
    return record.read_text().split('\n'), left


def test_wheels_mode_builds_the_upstream_interfaces(tmp_path: Path) -> None:
    args, left = _run_build_script(tmp_path, 'wheels')
    assert 'build' in args and '--packages-ignore' not in args
    assert left == {'tf2_msgs', 'control_msgs', 'slip_msgs'}


def test_system_mode_uses_the_installed_interfaces(tmp_path: Path) -> None:
    args, left = _run_build_script(tmp_path, 'system')
    ignored = args[args.index('--packages-ignore') + 1:args.index('--event-handlers')]
    assert set(ignored) == {'tf2_msgs', 'control_msgs'}
    assert left == {'slip_msgs'}  # stale wheels-mode copies would shadow the system ones
